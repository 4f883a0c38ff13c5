"""Stiffness and category accuracy of ``labcli classify`` on the simulated rig.

Run:  python tests/benchmarks/classify_accuracy.py [--seeds 1-10] [--pushes 10]

For each rig seed (actuator variation, sensor offsets, noise): fit the paper's
model on the takuma2014 plan's weight trials, push the demo objects of
:mod:`labcli.papers.takuma2014.sim.objects` with phi given, and classify from the pressures with
the protocol's bands.  Two policies for the model's ``singular-jacobian`` flag
on Fy are compared in the same run on the same pushes: ``project`` (the
default: force from Fx along O2 -> C) against ``accept`` (the model's own Fy),
each with pressure-only and with measured angles.  Printed per object: mean
k/k_true over seeds, its range, the mean and worst coefficient of variation
over an object's pushes, and the share of seeds with the right category.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

import pandas as pd  # noqa: E402

from labcli.core.protocol import load_protocol  # noqa: E402
from labcli.papers.takuma2014.models.classify import classify_pushes  # noqa: E402
from labcli.papers.takuma2014.models.takuma import TakumaModel  # noqa: E402
from labcli.papers.takuma2014.protocol import load_plan  # noqa: E402
from labcli.papers.takuma2014.sim.drive import simulate_pushes, simulate_weight_trials  # noqa: E402
from labcli.papers.takuma2014.sim.objects import DEMO_OBJECTS  # noqa: E402
from labcli.papers.takuma2014.sim.rig import SimRig  # noqa: E402

POLICIES = {
    "project": {},
    "accept": {"singular_component": "exclude", "accept_model_flags": ["singular-jacobian"]},
}


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--seeds", default="1-10", help="rig seeds, e.g. 1-10")
    ap.add_argument("--pushes", type=int, default=10, help="pushes per object")
    args = ap.parse_args()
    lo, _, hi = args.seeds.partition("-")
    seeds = range(int(lo), int(hi or lo) + 1)
    force, push = load_protocol("takuma2014"), load_protocol("takuma2014-stiffness")
    truth = {o.name: o.category for o in DEMO_OBJECTS}
    rows = []
    for seed in seeds:
        rig = SimRig(seed=seed)
        trials = simulate_weight_trials(rig, load_plan(force), calibration=force.calibration)
        model = TakumaModel(geometry=force.settings.rig, protocol=force.name).fit(trials)
        table = simulate_pushes(rig, DEMO_OBJECTS, calibration=push.calibration, pushes_per_object=args.pushes)
        for policy, params in POLICIES.items():
            for angles in ("pressure-only", "measured-angles"):
                res = classify_pushes(
                    table, model, params=params, angles=angles, bands=push.settings.push.stiffness_bands_N_per_m
                )
                for o in res.objects.itertuples():
                    rows.append(
                        {
                            "policy": policy,
                            "angles": angles,
                            "object": o.object,
                            "ratio": o.k_mean_N_per_m / o.true_k_N_per_m,
                            "cv": o.k_std_N_per_m / o.k_mean_N_per_m,
                            "correct": o.category == truth[o.object],
                        }
                    )
    df = pd.DataFrame(rows)
    out = df.groupby(["policy", "angles", "object"], sort=False).agg(
        k_over_true=("ratio", "mean"),
        min=("ratio", "min"),
        max=("ratio", "max"),
        cv_mean=("cv", "mean"),
        cv_max=("cv", "max"),
        categories_right=("correct", "mean"),
    )
    print(f"seeds {seeds.start}-{seeds.stop - 1}, {args.pushes} pushes per object, phi given")
    print(out.round(3).to_string())


if __name__ == "__main__":
    main()
