"""Stiffness and category accuracy of ``labcli classify`` on the simulated rig.

Run:  python tests/benchmarks/classify_accuracy.py [--seeds 1-10] [--pushes 10] [--ideal | --only EFFECT]
                                                  [--figures FILE.json]

For each rig seed (actuator variation, sensor offsets, noise): fit the paper's
model on the takuma2014 plan's weight trials, push the demo objects of
:mod:`labcli.papers.takuma2014.sim.objects` with phi given, and classify from the pressures with
the protocol's bands.  Two policies for the model's ``singular-jacobian`` flag
on Fy are compared in the same run on the same pushes: ``project`` (the
default: force from Fx along O2 -> C) against ``accept`` (the model's own Fy),
each with pressure-only and with measured angles.  Printed per object: mean
k/k_true over seeds, its range, the mean and worst coefficient of variation
over an object's pushes, and the share of seeds with the right category.  ``--ideal`` turns
the rig's non-idealities off; ``--only friction`` (or leak, thermal, backlash, links) keeps that
one alone, to see what each costs.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

import pandas as pd  # noqa: E402

from labcli.core.protocol import load_protocol  # noqa: E402
from labcli.papers.takuma2014.models.classify import classify_pushes  # noqa: E402
from labcli.papers.takuma2014.models.takuma import TakumaModel  # noqa: E402
from labcli.papers.takuma2014.protocol import load_plan  # noqa: E402
from labcli.papers.takuma2014.sim.drive import simulate_pushes, simulate_weight_trials  # noqa: E402
from labcli.papers.takuma2014.sim.nonideal import NonIdeal  # noqa: E402
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
    ap.add_argument("--ideal", action="store_true", help="the rig with its non-idealities off")
    ap.add_argument(
        "--only",
        choices=("friction", "leak", "thermal", "backlash", "links"),
        help="the rig with this one non-ideality and no other",
    )
    ap.add_argument("--figures", help="also write the figures to this JSON file ({name: value})")
    args = ap.parse_args()
    rig_kw = {}
    if args.ideal:
        rig_kw["nonideal"] = NonIdeal.ideal()
    elif args.only:
        rig_kw["nonideal"] = NonIdeal(**{**NonIdeal.ideal().as_dict(), args.only: 1.0})
    lo, _, hi = args.seeds.partition("-")
    seeds = range(int(lo), int(hi or lo) + 1)
    force, push = load_protocol("takuma2014"), load_protocol("takuma2014-stiffness")
    truth = {o.name: o.category for o in DEMO_OBJECTS}
    rows = []
    for seed in seeds:
        rig = SimRig(seed=seed, **rig_kw)
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
    if args.figures:
        figures: dict = {"seeds": args.seeds, "pushes per object": args.pushes}
        for (policy, angles, obj), row in out.iterrows():
            for col, v in row.items():
                figures[f"{policy} {angles} {obj} {col}"] = float(v)
        default = out.loc[("project", "pressure-only")]
        figures["project pressure-only k_over_true min"] = float(default["k_over_true"].min())
        figures["project pressure-only k_over_true max"] = float(default["k_over_true"].max())
        figures["project pressure-only categories right min"] = float(default["categories_right"].min())
        Path(args.figures).write_text(json.dumps(figures, indent=1) + "\n")


if __name__ == "__main__":
    main()
