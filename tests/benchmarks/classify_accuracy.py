"""Stiffness and category accuracy of ``labcli classify`` on the simulated rig.

Run:  python tests/benchmarks/classify_accuracy.py [--seeds 1-10] [--realism kind] [--pushes 10]
                                                  [--ideal | --only EFFECT] [--labels as-read]
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

import json
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))
sys.path.insert(0, str(Path(__file__).resolve().parent))

import pandas as pd  # noqa: E402
from acquired import Windows, acquired_air, protocol_settle_s  # noqa: E402
from rig_options import add_rig_options, bench_parser, seeds_text  # noqa: E402

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


def trials_and_pushes(
    seed: int,
    pushes: int = 10,
    rig_kw: dict | None = None,
    settle_s: float | None = None,
    repressurise_kPa: float | None = None,
    rig_class: type = SimRig,
):
    """On the rig of seed ``seed``: the force protocol's trial table, then the demo objects' push
    table with each push's rest posture (``rig_kw``: more keyword arguments of the rig; ``rig_class``
    builds it, by default the simulated rig itself), as the demo's two runs acquire them
    (tests/benchmarks/classify_heldout.py) but without the wire.

    Every baseline and every load waits ``settle_s`` before its window, by default the protocols'
    earliest acceptance of equilibrium (:func:`acquired.protocol_settle_s`: three windows and the hold,
    15 s, five time constants of the air's thermal relaxation), as ``labcli acquire`` waits at
    the least.  A shorter wait leaves the last load's thermal tail in the pressures: with
    drive.py's 6 s, the steel can's 1.3 mm deformation came out 0.5-0.6 mm short (posture
    form, tuning seeds 1-2) and its stiffness at 1.7 times true.  The chambers are supplied again
    once a baseline drifted ``repressurise_kPa`` since the last supply, by default the protocol's
    ``acquisition.repressurise_kPa`` (3.1 kPa), as ``labcli acquire`` does on a board that drives
    its valves (the demo's runs): over the longer waits a leaking chamber would otherwise move the
    arm away from the operating point the model was fitted at.
    """
    force, push = load_protocol("takuma2014"), load_protocol("takuma2014-stiffness")
    air = acquired_air(force, push, settle_s=settle_s, repressurise_kPa=repressurise_kPa)
    rig = Windows(rig_class(seed=seed, **(rig_kw or {})))
    trials = simulate_weight_trials(rig, load_plan(force), calibration=force.calibration, **air)
    rig.rest_columns(trials, force.calibration)
    # The push run opens the port anew, as a second `labcli acquire` on sim://?seed=N does: the same
    # rig seed, its air supplied from the start (on tuning seeds 1-2 the steel can's k/k_true went
    # 1.02, 0.95 -> 0.92, 0.87 with it, the acquired runs' 0.89, 0.88).
    rig = Windows(rig_class(seed=seed, **(rig_kw or {})))
    table = simulate_pushes(rig, DEMO_OBJECTS, calibration=push.calibration, pushes_per_object=pushes, **air)
    rig.rest_columns(table, push.calibration)
    return trials, table


def classify_rows(trials, table, model, policy: str = "project", angles: str = "pressure-only") -> list[dict]:
    """Per object: k / k_true, the category, whether it is right, its confidence."""
    push = load_protocol("takuma2014-stiffness")
    truth = {o.name: o.category for o in DEMO_OBJECTS}
    res = classify_pushes(
        table,
        model,
        params=POLICIES[policy],
        angles=angles,
        bands=push.settings.push.stiffness_bands_N_per_m,
        allow_unusable=True,  # an object with every push flagged: no category (a wrong one, in the counts)
        settle_s=protocol_settle_s(push),  # the thermal tail's term of the error budget, as classify_file has it
    )
    return [
        {
            "object": o.object,
            "ratio": o.k_mean_N_per_m / o.true_k_N_per_m,
            "cv": o.k_std_N_per_m / o.k_mean_N_per_m,
            "category": o.category,
            "correct": o.category == truth[o.object],
            "confidence": float(o.confidence) if o.confidence is not None else float("nan"),
        }
        for o in res.objects.itertuples()
    ]


def main() -> None:
    ap = bench_parser(__doc__)
    # The kind rig by default, the one the docs' figures were measured on.
    add_rig_options(ap, realism="kind", seeds="1-10")
    ap.add_argument("--pushes", type=int, default=10, help="pushes per object")
    ap.add_argument("--ideal", action="store_true", help="the rig with its non-idealities off")
    ap.add_argument(
        "--only",
        choices=("friction", "leak", "thermal", "backlash", "links"),
        help="the rig with this one non-ideality and no other",
    )
    ap.add_argument(
        "--labels",
        choices=("play-fitted", "as-read"),
        default="play-fitted",
        help="the angle labels the fit sees: the potentiometers' play fitted out (the default) or as read",
    )
    ap.add_argument("--figures", help="also write the figures to this JSON file ({name: value})")
    args = ap.parse_args()
    realism = args.realism
    rig_kw = {"nonideal": NonIdeal(realism=realism)}
    if args.ideal:
        rig_kw["nonideal"] = NonIdeal.ideal(realism)
    elif args.only:
        rig_kw["nonideal"] = NonIdeal(**{**NonIdeal.ideal(realism).as_dict(), args.only: 1.0}, realism=realism)
    seeds = args.seeds
    force = load_protocol("takuma2014")
    rows = []
    for seed in seeds:
        trials, table = trials_and_pushes(seed, args.pushes, rig_kw=rig_kw)
        play = "fit" if args.labels == "play-fitted" else "none"
        model = TakumaModel(geometry=force.settings.rig, protocol=force.name, label_play=play).fit(trials)
        for policy in POLICIES:
            for angles in ("pressure-only", "measured-angles"):
                for row in classify_rows(trials, table, model, policy, angles):
                    rows.append({"policy": policy, "angles": angles, **row})
    df = pd.DataFrame(rows)
    out = df.groupby(["policy", "angles", "object"], sort=False).agg(
        k_over_true=("ratio", "mean"),
        min=("ratio", "min"),
        max=("ratio", "max"),
        cv_mean=("cv", "mean"),
        cv_max=("cv", "max"),
        categories_right=("correct", "mean"),
    )
    print(f"seeds {seeds_text(seeds)}, {args.pushes} pushes per object, phi given")
    print(out.round(3).to_string())
    if args.figures:
        figures: dict = {"seeds": seeds_text(seeds), "pushes per object": args.pushes}
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
