"""Accuracy and time: N captures of each load, averaged, against one (the pressure sensors' floor).

The pressure sensors' repeatability is a fresh error per reading (pressure_floor.py: it sets the
angles' floor of one trial's readings on the literature's rig).  Fresh errors average down: a
protocol that takes each plan load N times over (unload, re-settle the arm, baseline, load, capture)
and averages the N trials' pressures and labels into one row divides the repeatability's variance by
N.  Each capture is preceded by a supply pulse (``acquisition.friction_relief_s`` = 3 s, the chambers
supplied and held again: the arm re-settles and the sensors read afresh) or by the relief (a 2 s
vent of the L actuators first, ``friction_relief_vent_s``, docs/rig-realism.md "Friction relief"),
the N captures of a load taken one after the other.

For each rig seed (literature's rig), arm (straight: takuma2014, bent: takuma2014-bent; 108 plan
trials, fitted on the 90 fit trials, checked on the 18 validation ones, taken as ``labcli acquire``
takes them, tests/benchmarks/acquired.py) and N: the posture form without friction terms (the
issue's estimator) on a run of single captures without pulse (``ref``); on the pulsed runs (``pulse``)
the same form; on the relieved runs (``relief``) ``PostureModel(friction="relieved")``.  Reported:
RMSE over every validation trial with a 95 % interval from a bootstrap over seeds, its ratio to
``ref``'s (paired bootstrap), Fy's trials reported, and the rig's clock per plan trial (s).

    nice python tests/benchmarks/multi_capture.py [--seeds 1-10] [--captures 1,2,3] [--cache FILE] [--figures OUT]

Nothing here is tuned: the pulse and vent are the relief's, chosen on seeds 1-10 before.
"""

from __future__ import annotations

import math
import sys
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

ROOT = Path(__file__).resolve().parents[2]
ARMS = {"straight": "takuma2014", "bent": "takuma2014-bent"}
QUANTITIES = ("theta1", "theta2", "Fx", "Fy")
MODES = {"pulse": (3.0, 0.0), "relief": (3.0, 2.0)}  # (supply pulse s, vent s) before each capture
BOOTSTRAP = 2000
AVERAGED = ("P_L10", "P_R10", "P_L20", "P_R20", "P_L1", "P_R1", "P_L2", "P_R2") + (
    "theta1_deg",
    "theta2_deg",
    "theta1_0_deg",
    "theta2_0_deg",
)


def repeated_plan(plan: Any, captures: int) -> Any:
    """The plan with each row taken ``captures`` times in a row (its trial number kept)."""
    if captures < 1:
        raise ValueError(f"the captures of a load must be at least 1, got {captures}")
    return plan.loc[plan.index.repeat(captures)].reset_index(drop=True)


def averaged(table: Any, captures: int) -> Any:
    """The table of a repeated plan with each load's ``captures`` consecutive rows averaged into one:
    the pressures, the deflection labels and the rest posture; the rest is the first row's."""
    if len(table) % captures:
        raise ValueError(f"{len(table)} rows are not whole groups of {captures} captures")
    group = np.arange(len(table)) // captures
    first = table.groupby(group, sort=True).first()
    means = table[list(AVERAGED)].groupby(group, sort=True).mean()
    for c in AVERAGED:
        first[c] = means[c]
    return first.reset_index(drop=True)


def run(arm: str, seed: int, captures: int, mode: str | None, realism: str = "literature") -> tuple[Any, Any, float]:
    """One run on the ``realism`` rig: the protocol, its averaged table, the rig's seconds per plan trial."""
    from acquired import acquired_air
    from sensing_accuracy import BENT_SUPPLY_MPA, _Recorder

    from labcli.core.protocol import load_protocol
    from labcli.papers.takuma2014.protocol import load_plan
    from labcli.papers.takuma2014.sim.drive import simulate_weight_trials
    from labcli.papers.takuma2014.sim.nonideal import NonIdeal
    from labcli.papers.takuma2014.sim.rig import SimRig

    proto = load_protocol(ARMS[arm])
    kw: dict[str, Any] = {"nonideal": NonIdeal(realism=realism)}
    if arm == "bent":
        kw["supply_MPa"] = BENT_SUPPLY_MPA
    rig = _Recorder(SimRig(seed=seed, **kw))
    plan = load_plan(proto)
    pulse, vent = MODES[mode] if mode else (0.0, 0.0)
    table = simulate_weight_trials(
        rig,
        repeated_plan(plan, captures),
        calibration=proto.calibration,
        relief_s=pulse,
        relief_vent_s=vent,
        **acquired_air(proto),
    )
    rig.rest_columns(table, proto.calibration)
    return proto, averaged(table, captures), float(rig.time_s) / len(plan)


def errors(proto: Any, table: Any, friction: Any) -> dict[str, Any]:
    """The posture form's validation errors (deg, N), which it reports, and whether its 95 % interval covers."""
    from labcli.papers.takuma2014.models.metrics import evaluate
    from labcli.papers.takuma2014.models.posture import PostureModel, limits_from_protocol

    model = PostureModel(geometry=proto.settings.rig, limits=limits_from_protocol(proto), friction=friction)
    return error_records(evaluate(model.fit(table), table))


def error_records(ev: dict[str, Any]) -> dict[str, Any]:
    """Per quantity of an evaluation: each validation trial's error, whether it is reported, and
    whether its 95 % interval covers the truth (the records :func:`figures` reads)."""
    out: dict[str, Any] = {}
    for q in QUANTITIES:
        err = np.asarray(ev["calculated"][q] - ev["observed"][q], dtype=float)
        out[f"{q}/err"] = err.tolist()
        out[f"{q}/ok"] = np.asarray(ev["ok"][q], dtype=bool).tolist()
        out[f"{q}/inside"] = (np.abs(err) <= 1.96 * np.asarray(ev["se"][q])).tolist()
    return out


def measure(seed: int, captures: tuple[int, ...], realism: str = "literature") -> dict[str, Any]:
    """Per arm, the reference and each mode at each number of captures: errors and time per trial."""
    out: dict[str, Any] = {}
    for arm in ARMS:
        proto, table, secs = run(arm, seed, 1, None, realism)
        out.update({f"{arm}/ref/{k}": v for k, v in errors(proto, table, False).items()})
        out[f"{arm}/ref/seconds"] = secs
        for mode in MODES:
            for n in captures:
                proto, table, secs = run(arm, seed, n, mode, realism)
                form = "relieved" if mode == "relief" else False
                out.update({f"{arm}/{mode}{n}/{k}": v for k, v in errors(proto, table, form).items()})
                out[f"{arm}/{mode}{n}/seconds"] = secs
    return out


def _rmse(parts: list[np.ndarray]) -> float:
    x = np.concatenate(parts) if parts else np.array([])
    return float(np.sqrt(np.mean(x**2))) if x.size else math.nan


def figures(raw: dict[int, dict[str, Any]], forms: list[str]) -> dict[str, Any]:
    """Per arm, form and quantity: RMSE [95 %], ratio to ``ref`` [95 %, paired over seeds], Fy
    reported, coverage of the 95 % intervals; per arm and form: the rig's seconds per plan trial."""
    rng = np.random.default_rng(20261127)
    seeds = sorted(raw)
    picks = [rng.integers(0, len(seeds), len(seeds)) for _ in range(BOOTSTRAP)]
    out: dict[str, Any] = {}
    for arm in ARMS:
        for form in ["ref", *forms]:
            out[f"{arm}/{form}/seconds_per_trial"] = float(np.mean([raw[s][f"{arm}/{form}/seconds"] for s in seeds]))
            for q in QUANTITIES:
                err = {f: [np.asarray(raw[s][f"{arm}/{f}/{q}/err"]) for s in seeds] for f in ("ref", form)}
                whole = {f: _rmse(e) for f, e in err.items()}
                boots = np.array([[_rmse([err[f][i] for i in p]) for f in ("ref", form)] for p in picks])
                k = f"{arm}/{form}/{q}"
                out[f"{k}/rmse"] = whole[form]
                out[f"{k}/rmse_ci95"] = [float(v) for v in np.nanpercentile(boots[:, 1], [2.5, 97.5])]
                out[f"{k}/ratio"] = whole[form] / whole["ref"]
                out[f"{k}/ratio_ci95"] = [float(v) for v in np.nanpercentile(boots[:, 1] / boots[:, 0], [2.5, 97.5])]
                ok = np.concatenate([np.asarray(raw[s][f"{k}/ok"], dtype=bool) for s in seeds])
                inside = np.concatenate([np.asarray(raw[s][f"{k}/inside"], dtype=bool) for s in seeds])
                out[f"{k}/reported"] = int(ok.sum())
                out[f"{k}/coverage"] = float(inside[ok].mean()) if ok.any() else math.nan
            out[f"{arm}/{form}/time_ratio"] = (
                out[f"{arm}/{form}/seconds_per_trial"] / out[f"{arm}/ref/seconds_per_trial"]
            )
        out[f"{arm}/trials"] = int(sum(len(raw[s][f"{arm}/ref/Fx/err"]) for s in seeds))
    return out


def main(argv: list[str] | None = None) -> None:
    from figures_file import cached, write_figures
    from rig_options import add_rig_options, bench_parser, seeds_text

    ap = bench_parser(__doc__)
    add_rig_options(ap, realism="literature", seeds="1-10")  # 1-10: the tuning seeds
    ap.add_argument("--captures", default="1,2,3", help="numbers of captures of each load (default 1,2,3)")
    ap.add_argument("--cache", type=Path, default=None, help="JSON-lines file of measured seeds (resumable)")
    ap.add_argument(
        "--figures", "--json", dest="json", type=Path, default=ROOT / "docs" / "figures" / "multi-capture.json"
    )
    args = ap.parse_args(argv)
    try:
        captures = tuple(int(c) for c in args.captures.split(","))
    except ValueError:
        ap.error(f"--captures takes whole numbers separated by commas, not {args.captures!r}")
    if min(captures) < 1:
        ap.error(f"--captures takes numbers of 1 or more, not {args.captures!r}")
    kind = f"captures {list(captures)} {args.realism}"
    raw = cached(args.cache, kind, args.seeds, lambda s: measure(s, captures, args.realism))
    forms = [f"{m}{n}" for m in MODES for n in captures]
    figs = figures(raw, forms)
    print(
        f"seeds {seeds_text(args.seeds)}, {args.realism} rig: RMSE (deg, N) [95 %], ratio to one capture without pulse [95 %]"
    )
    for arm in ARMS:
        for form in ["ref", *forms]:
            cells = []
            for q in QUANTITIES:
                k = f"{arm}/{form}/{q}"
                lo, hi = figs[f"{k}/ratio_ci95"]
                cells.append(f"{q} {figs[f'{k}/rmse']:.3f} x{figs[f'{k}/ratio']:.2f} [{lo:.2f},{hi:.2f}]")
            cells.append(f"Fy reported {figs[f'{arm}/{form}/Fy/reported']}/{figs[f'{arm}/trials']}")
            cells.append(f"{figs[f'{arm}/{form}/seconds_per_trial']:.0f} s/trial")
            print(f"{arm:8s} {form:8s} " + "; ".join(cells))
    meta = {"meta/seeds": seeds_text(args.seeds), "meta/realism": args.realism, "meta/captures": args.captures}
    write_figures(args.json, {**meta, "meta/bootstrap": BOOTSTRAP}, figs)


if __name__ == "__main__":
    main()
