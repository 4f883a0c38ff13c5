"""Accuracy, not time: the posture form with the sleeves' friction terms against the posture form alone.

On the literature's rig (docs/rig-realism.md) for each held-out rig seed, the straight and the bent
protocol (108 trials; fitted on the 90 fit trials, checked on the 18 validation trials,
pressure-only), the posture form as ``labcli fit`` makes it and the same with
``PostureModel(friction=True)`` (models/posture.py, ``friction_columns``), on the same trials.
Reported per protocol and quantity: RMSE over every validation trial and over the trials both
report, with 95 % intervals from a bootstrap over seeds (a seed's trials share its fit, so the seed
is what is resampled), the ratio friction / plain with its interval, the trials each reports, and
the coverage of each form's 95 % intervals with a Wilson interval.

With ``--relief S``: the same seeds' runs acquired again with the protocol's friction relief
(``acquisition.friction_relief_s = S``; ``--vent V`` vents the ``--vent-side`` actuators for V s
first, ``friction_relief_vent_s``), and beside the posture form without relief (the reference,
``plain``) the posture form on the relieved run (``relief_plain``) and, with ``--vent``, with the
relieved run's friction terms (``relief_terms``, ``PostureModel(friction="relieved")``) and with
them and each P0 the mean of RELIEVED_BASELINES baselines (``relieved``, what ``labcli fit``
makes of such a run).  The plan, the rig seed and its draws are the same; the
runs differ by the relief alone.  Ratios are each form's RMSE over the reference's.

    nice python tests/benchmarks/friction_estimator.py [--seeds 11-30] [--realism literature] [--cache FILE]
                                                       [--figures OUT]
    nice python tests/benchmarks/friction_estimator.py --relief 3 --vent 2 [--vent-side L] ...

The friction terms' fade (FRICTION_MOTION_RAD) and the relief's pulse and vent were chosen on
seeds 1-10; nothing here is tuned.
"""

from __future__ import annotations

import math
import sys
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from baseline_estimator import wilson  # noqa: E402
from figures_file import cached_seeds, write_figures  # noqa: E402
from rig_options import add_rig_options, bench_parser, seeds_text  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
PROTOCOLS = {"straight": "takuma2014", "bent": "takuma2014-bent"}
FORMS = ("plain", "friction")
QUANTITIES = ("theta1", "theta2", "Fx", "Fy")
BOOTSTRAP = 2000
OLD_CONFIG = {"relief": 0.0, "vent": 0.0, "side": "L"}  # a record of before --relief: none


def forms_of(relief: float, vent: float) -> tuple[str, ...]:
    """The forms measured: the reference (``plain``, no relief) first."""
    if relief <= 0:
        return FORMS
    return ("plain", "relief_plain", "relief_terms", "relieved") if vent > 0 else ("plain", "relief_plain")


def measure(
    seed: int, relief: float = 0.0, vent: float = 0.0, side: str = "L", realism: str = "literature"
) -> dict[str, Any]:
    """Per protocol, form and quantity: the validation errors, which trials are reported, interval hits."""
    from sensing_accuracy import trials

    from labcli.papers.takuma2014.models.metrics import evaluate
    from labcli.papers.takuma2014.models.posture import RELIEVED_BASELINES, PostureModel, limits_from_protocol
    from labcli.papers.takuma2014.sim.nonideal import NonIdeal

    out: dict[str, Any] = {}
    friction = {
        "plain": False,
        "friction": True,
        "relief_plain": False,
        "relief_terms": "relieved",
        "relieved": "relieved",
    }
    for short, name in PROTOCOLS.items():
        rig_kw = {"nonideal": NonIdeal(realism=realism)}
        runs = {"": trials(name, seed, rig_kw=rig_kw)}
        if relief > 0:  # the relief before each baseline, the same wait and re-supply rule as acquired
            runs["relief"] = trials(name, seed, rig_kw=rig_kw, relief_s=relief, relief_vent_s=vent, relief_vent=side)
        for form in forms_of(relief, vent):
            proto, table = runs["relief" if form.startswith("relie") else ""]
            model = PostureModel(
                geometry=proto.settings.rig,
                limits=limits_from_protocol(proto),
                friction=friction[form],
                baseline_mean=RELIEVED_BASELINES if form == "relieved" else 1,
            ).fit(table)
            ev = evaluate(model, table)
            for q in QUANTITIES:
                err = np.asarray(ev["calculated"][q] - ev["observed"][q], dtype=float)
                out[f"{short}/{form}/{q}/err"] = err.tolist()
                out[f"{short}/{form}/{q}/ok"] = np.asarray(ev["ok"][q], dtype=bool).tolist()
                out[f"{short}/{form}/{q}/inside"] = (np.abs(err) <= 1.96 * np.asarray(ev["se"][q])).tolist()
            out[f"{short}/{form}/terms"] = [t for t in model.torque_terms if t.startswith("friction")]
    return out


def _rms(x: np.ndarray) -> float:
    return float(np.sqrt(np.mean(x**2))) if x.size else math.nan


def _ratio_key(form: str, short: str, q: str, which: str) -> str:
    # The friction terms' ratio keeps the key the docs have quoted since before the relief.
    return f"{short}/{q}/ratio_{which}" if form == "friction" else f"{short}/{q}/{form}/ratio_{which}"


def _rmses(err: dict, ok: dict, forms: tuple[str, ...], picks: list, key: Any) -> dict[str, Any]:
    """Each form's RMSE with its bootstrap interval, and its ratio to the first form's, over every
    trial (``all``) and over the trials the first form and it both report (``both``)."""
    out: dict[str, Any] = {}
    ref, n = forms[0], len(err[forms[0]])
    for f in forms[1:]:
        both = [ok[ref][i] & ok[f][i] for i in range(n)]
        for which, mask in (("all", None), ("both", both)):

            def rmse(form: str, idx: Any, mask: Any = mask) -> float:
                parts = [err[form][i] if mask is None else err[form][i][mask[i]] for i in idx]
                return _rms(np.concatenate(parts)) if parts else math.nan

            whole = {g: rmse(g, range(n)) for g in (ref, f)}
            boots = np.array([[rmse(g, p) for g in (ref, f)] for p in picks])
            for k, g in enumerate((ref, f)):
                if which == "all" or g == f or len(forms) == 2:
                    lo, hi = np.nanpercentile(boots[:, k], [2.5, 97.5])
                    out[key(g, f"rmse_{which}")] = whole[g]
                    out[key(g, f"rmse_{which}_ci95")] = [float(lo), float(hi)]
            lo, hi = np.nanpercentile(boots[:, 1] / boots[:, 0], [2.5, 97.5])
            out[key(("ratio", f), which)] = whole[f] / whole[ref]
            out[key(("ratio", f), which) + "_ci95"] = [float(lo), float(hi)]
        out[key(("both", f), "")] = int(sum(int(b.sum()) for b in both))
    return out


def figures(raw: dict[int, dict[str, Any]], forms: tuple[str, ...] = FORMS) -> dict[str, Any]:
    rng = np.random.default_rng(20261126)
    seeds = sorted(raw)
    picks = [rng.integers(0, len(seeds), len(seeds)) for _ in range(BOOTSTRAP)]
    out: dict[str, Any] = {}
    for short in PROTOCOLS:
        for q in QUANTITIES:
            err = {f: [np.asarray(raw[s][f"{short}/{f}/{q}/err"]) for s in seeds] for f in forms}
            ok = {f: [np.asarray(raw[s][f"{short}/{f}/{q}/ok"], dtype=bool) for s in seeds] for f in forms}

            def key(form: Any, what: str, short: str = short, q: str = q) -> str:
                if isinstance(form, tuple) and form[0] == "ratio":
                    return _ratio_key(form[1], short, q, what)
                if isinstance(form, tuple):  # the trials both report
                    return f"{short}/{q}/both_reported" + ("" if len(forms) == 2 else f"/{form[1]}")
                return f"{short}/{q}/{form}/{what}"

            out.update(_rmses(err, ok, forms, picks, key))
            for f in forms:
                out[f"{short}/{q}/{f}/reported"] = int(sum(int(o.sum()) for o in ok[f]))
                inside = np.concatenate(
                    [
                        np.asarray(raw[s][f"{short}/{f}/{q}/inside"], dtype=bool)[o]
                        for s, o in zip(seeds, ok[f], strict=True)
                    ]
                )
                p, lo, hi = wilson(int(inside.sum()), int(inside.size))
                out[f"{short}/{q}/{f}/coverage"] = p
                out[f"{short}/{q}/{f}/coverage_ci95"] = [lo, hi]
            out[f"{short}/trials"] = int(sum(len(raw[s][f"{short}/plain/Fx/err"]) for s in seeds))
        for f in [g for g in forms if g in ("friction", "relief_terms", "relieved")]:
            kept = [raw[s][f"{short}/{f}/terms"] for s in seeds]
            name = "friction_terms_kept_seeds" if f == "friction" else f"{f}_terms_kept_seeds"
            out[f"{short}/{name}"] = int(sum(bool(k) for k in kept))
    return out


def main(argv: list[str] | None = None) -> None:
    ap = bench_parser(__doc__)
    add_rig_options(ap, realism="literature", seeds="11-30")  # 11-30: the held-out seeds
    ap.add_argument("--cache", type=Path, default=None, help="JSON-lines file of measured seeds (resumable)")
    ap.add_argument("--relief", type=float, default=0.0, help="the friction relief's supply pulse, s (0: none)")
    ap.add_argument("--vent", type=float, default=0.0, help="with --relief: vent one side this long first, s")
    ap.add_argument("--vent-side", default="L", choices=("L", "R"), help="the actuators vented (default L)")
    ap.add_argument("--figures", "--json", dest="json", type=Path, default=None)
    args = ap.parse_args(argv)
    if args.vent > 0 and args.relief <= 0:
        ap.error("--vent needs --relief (the supply pulse that fills the vented chambers again)")
    name = "friction-relief" if args.relief > 0 else "friction-estimator"
    args.json = args.json or ROOT / "docs" / "figures" / f"{name}.json"
    forms = forms_of(args.relief, args.vent)
    config = {"relief": args.relief, "vent": args.vent, "side": args.vent_side, "realism": args.realism}
    seeds = args.seeds
    done = cached_seeds(
        args.cache,
        seeds,
        lambda seed: measure(seed, args.relief, args.vent, args.vent_side, args.realism),
        tag={"config": config},
        # a record of before --realism: the literature's rig
        same=lambda rec: {"realism": "literature", **rec.get("config", OLD_CONFIG)} == config,
    )
    figs = figures(done, forms)
    print(f"held-out seeds {seeds_text(seeds)}, {args.realism} rig ({config}): RMSE of {' / '.join(forms)}")
    for short in PROTOCOLS:
        for q in QUANTITIES:
            k = f"{short}/{q}"
            parts = [f"{figs[f'{k}/plain/rmse_all']:.3f}"]
            for f in forms[1:]:
                r = _ratio_key(f, short, q, "all")
                lo, hi = figs[f"{r}_ci95"]
                parts.append(
                    f"{f} {figs[f'{k}/{f}/rmse_all']:.3f} (ratio {figs[r]:.2f} [{lo:.2f}, {hi:.2f}], "
                    f"reported {figs[f'{k}/{f}/reported']}, coverage {figs[f'{k}/{f}/coverage']:.2f})"
                )
            print(f"{k:16s} plain {' -> '.join(parts)}; plain coverage {figs[f'{k}/plain/coverage']:.2f}")
    meta = {"meta/seeds": seeds_text(seeds), "meta/bootstrap": BOOTSTRAP}
    if args.realism != "literature":
        meta["meta/realism"] = args.realism
    if args.relief > 0:
        meta.update({"meta/relief_s": args.relief, "meta/vent_s": args.vent, "meta/vent_side": args.vent_side})
    write_figures(args.json, meta, figs)


if __name__ == "__main__":
    main()
