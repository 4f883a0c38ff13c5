"""Accuracy, not time: how often each estimate's 95 % interval holds the truth, per rig, arm and quantity.

For each rig (the literature's and the kind one), arm (the straight protocol takuma2014 and the bent
one) and seed, the trials are taken as ``labcli acquire`` takes them (sensing_accuracy.trials) and
the posture form is fitted as ``labcli fit`` fits it by default (with the sleeves' friction terms)
on the plan's fit trials, then checked pressure-only on its validation trials (18 in the shipped
plans; the count is read from the plan), as ``labcli validate`` checks them.  Printed per cell and
quantity: trials reported (not flagged) of those planned, the coverage of the 95 % intervals
(+-1.96 standard errors) over them with a 95 % interval from a bootstrap over
seeds (a seed's trials share its fit, so the seed is what is resampled), the RMSE and the RMS of
the standard errors.

``--diagnose`` adds why a cell is off.  The standard errors come from the fit's own held-out
errors (models/posture.py, models/routes.py), so beside each cell it prints those: the held-out
RMSE of the fit trials under the route's form (the route choice's folds: one pulley position left
out at a time, predicted pressure-only), and the validation RMSE over it.  Then two splits of
both sets of trials: for the angles, the trials whose joint moved less than HELD_DEG under the
load (the sleeves' friction held it) against the rest; for Fx, the loads of at most LIGHT_G
against the heavier ones.  A cell whose validation trials differ from its fit trials in such a
share, or err differently within it, is off by its plan, not by its standard error's formula.

    nice python tests/benchmarks/interval_coverage.py [--seeds 11-30] [--realism literature,kind] [--diagnose]
                                                      [--figures OUT.json]

``--realism`` and ``--seeds`` as every benchmark takes them (rig_options.py); both rigs by default.
"""

from __future__ import annotations

import contextlib
import json
import math
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

import sensing_accuracy as sa  # noqa: E402
from baseline_estimator import wilson  # noqa: E402
from rig_options import add_rig_options, bench_parser, seeds_text  # noqa: E402

ARMS = {"straight": "takuma2014", "bent": "takuma2014-bent"}
QUANTITIES = ("theta1", "theta2", "Fx", "Fy")
COLUMNS = {"theta1": "theta1_deg", "theta2": "theta2_deg", "Fx": "Fx_N", "Fy": "Fy_N"}
HELD_DEG = 0.1  # a joint that moved less than this under its load was held by friction (the pots read 0.005 deg)
LIGHT_G = 150.0  # the plan's light loads: 50 and 100 g fitted, 75 and 150 g checked
BOOTSTRAP = 2000
Z95 = 1.959963984540054


@contextlib.contextmanager
def held_out_capture() -> Iterator[dict[str, Any]]:
    """The route choice's held-out errors of the fit trials, as the fit computes them (models/routes.py)."""
    from labcli.papers.takuma2014.models import routes as rt

    seen: dict[str, Any] = {}
    original = rt.held_out_errors

    def capture(fit_rows, *args, **kw):
        seen["rows"] = fit_rows
        seen["cv"] = original(fit_rows, *args, **kw)
        return seen["cv"]

    rt.held_out_errors = capture
    try:
        yield seen
    finally:
        rt.held_out_errors = original


def route_errors(model: Any, seen: dict[str, Any], q: str) -> np.ndarray:
    """The fit trials' held-out errors (deg, N) of the estimate ``q`` takes: its route's form, or the blend."""
    cv = seen["cv"]
    scale = math.degrees(1.0) if q.startswith("theta") else 1.0
    po = np.where(cv["posture_ok"][q], cv["posture"][q], np.nan)
    pa = np.where(cv["paper_ok"][q], cv["paper"][q], np.nan)
    route = model.route(q)
    if route == "posture":
        return scale * po
    if route == "paper":
        return scale * pa
    w = model.blends[q]["posture_weight"]
    return scale * np.where(np.isfinite(pa), w * po + (1.0 - w) * pa, po)


def measure(rig: str, arm: str, seed: int, diagnose: bool = False) -> dict[str, Any]:
    """One run's validation errors, standard errors, labels and loads per quantity (and the fit trials' held-out ones)."""
    from labcli.papers.takuma2014.models.metrics import evaluate
    from labcli.papers.takuma2014.models.posture import PostureModel, limits_from_protocol

    proto, table = sa.trials(ARMS[arm], seed, realism=rig)
    model = PostureModel(geometry=proto.settings.rig, limits=limits_from_protocol(proto), friction=True)
    with held_out_capture() as seen:
        model.fit(table)
    ev = evaluate(model, table)
    mass = np.asarray(table.loc[table["set"] == "validation", "mass_g"], dtype=float)
    out: dict[str, Any] = {"planned": planned_validation(proto)}
    for q in QUANTITIES:
        ok = ev["ok"][q] & np.isfinite(ev["observed"][q])
        out[q] = {
            "err": (ev["calculated"][q] - ev["observed"][q])[ok],
            "se": ev["se"][q][ok],
            "label": ev["observed"][q][ok],
            "mass": mass[ok],
        }
        if diagnose and "cv" in seen:
            e = route_errors(model, seen, q)
            keep = np.isfinite(e)
            rows = seen["rows"]
            out[q]["fit"] = {
                "err": e[keep],
                "label": np.asarray(rows[COLUMNS[q]], dtype=float)[keep],
                "mass": np.asarray(rows["mass_g"], dtype=float)[keep],
            }
    return out


def planned_validation(proto: Any) -> int:
    """How many validation trials the protocol's plan holds (each cell reports over these)."""
    from labcli.papers.takuma2014.protocol import load_plan

    return int(np.count_nonzero(np.asarray(load_plan(proto)["set"]) == "validation"))


def rms(x: np.ndarray) -> float:
    return float(np.sqrt(np.mean(np.square(x)))) if np.size(x) else math.nan


def coverage_ci(runs: list[dict[str, Any]], q: str, rng: np.random.Generator) -> tuple[float, float, float]:
    """Pooled coverage and its 95 % interval from a bootstrap over seeds."""
    hits = np.array([np.sum(np.abs(r[q]["err"]) <= Z95 * r[q]["se"]) for r in runs], dtype=float)
    n = np.array([len(r[q]["err"]) for r in runs], dtype=float)
    if n.sum() == 0:
        return math.nan, math.nan, math.nan
    picks = rng.integers(0, len(runs), size=(BOOTSTRAP, len(runs)))
    boot = hits[picks].sum(axis=1) / np.maximum(n[picks].sum(axis=1), 1)
    lo, hi = np.percentile(boot, [2.5, 97.5])
    return float(hits.sum() / n.sum()), float(lo), float(hi)


def split(q: str, label: np.ndarray, mass: np.ndarray) -> np.ndarray:
    """The trials of the diagnosis's first group: a joint held by friction (angles), a light load (forces)."""
    return np.abs(label) < HELD_DEG if q.startswith("theta") else mass <= LIGHT_G


def cell_figures(runs: list[dict[str, Any]], q: str, rng: np.random.Generator) -> dict[str, Any]:
    """A cell's figures for one quantity (and its diagnosis when the runs carry the fit trials' errors)."""
    cat = {k: np.concatenate([r[q][k] for r in runs]) for k in ("err", "se", "label", "mass")}
    p, lo, hi = coverage_ci(runs, q, rng)
    n = len(cat["err"])
    hits = int(np.sum(np.abs(cat["err"]) <= Z95 * cat["se"]))
    _, wlo, whi = wilson(hits, n)
    out: dict[str, Any] = {
        "reported": n,
        "trials": sum(r["planned"] for r in runs),
        "rmse": rms(cat["err"]),
        "rms se": rms(cat["se"]),
    }
    if n:
        out.update({"cover pct": 100 * p, "cover ci lo": 100 * lo, "cover ci hi": 100 * hi})
        out.update({"cover wilson lo": 100 * wlo, "cover wilson hi": 100 * whi})
    if n and all("fit" in r[q] for r in runs):
        fit = {k: np.concatenate([r[q]["fit"][k] for r in runs]) for k in ("err", "label", "mass")}
        out["fit held-out rmse"] = rms(fit["err"])
        out["rmse over fit held-out"] = out["rmse"] / out["fit held-out rmse"]
        first_fit, first_val = split(q, fit["label"], fit["mass"]), split(q, cat["label"], cat["mass"])
        out["fit first share"], out["val first share"] = float(first_fit.mean()), float(first_val.mean())
        out["fit first rmse"], out["fit rest rmse"] = rms(fit["err"][first_fit]), rms(fit["err"][~first_fit])
        out["val first rmse"], out["val rest rmse"] = rms(cat["err"][first_val]), rms(cat["err"][~first_val])
        out["val first rms se"], out["val rest rms se"] = rms(cat["se"][first_val]), rms(cat["se"][~first_val])
    return out


def show(key: str, q: str, f: dict[str, Any]) -> None:
    unit = "deg" if q.startswith("theta") else "N"
    if not f["reported"]:
        print(f"{key:20s} {q:6s} none of {f['trials']} reported")
        return
    print(
        f"{key:20s} {q:6s} {f['reported']:>3d}/{f['trials']}  cover {f['cover pct']:5.1f} % "
        f"[{f['cover ci lo']:.1f}, {f['cover ci hi']:.1f}]  RMSE {f['rmse']:.3g} {unit}  RMS se {f['rms se']:.3g}"
    )
    if "fit held-out rmse" in f:
        what = f"joint moved < {HELD_DEG} deg" if q.startswith("theta") else f"load <= {LIGHT_G:.0f} g"
        print(
            f"{'':27s}fit held-out RMSE {f['fit held-out rmse']:.3g} (validation / it {f['rmse over fit held-out']:.2f}); "
            f"{what}: fit {100 * f['fit first share']:.0f} % of trials, RMSE {f['fit first rmse']:.3g} "
            f"(rest {f['fit rest rmse']:.3g}); validation {100 * f['val first share']:.0f} %, RMSE "
            f"{f['val first rmse']:.3g} se {f['val first rms se']:.3g} (rest {f['val rest rmse']:.3g} "
            f"se {f['val rest rms se']:.3g})"
        )


def main(argv: list[str] | None = None) -> None:
    ap = bench_parser(__doc__)
    add_rig_options(ap, realism="literature,kind", seeds="11-30", several=True)  # 11-30 held out, 1-10 tuning
    ap.add_argument("--diagnose", action="store_true", help="also the fit trials' held-out errors and the splits")
    ap.add_argument("--figures", help="also write the figures to this JSON file ({name: value})")
    args = ap.parse_args(argv)
    seeds = args.seeds
    rng = np.random.default_rng(20261127)
    figures: dict[str, Any] = {"seeds": seeds_text(seeds), "held deg": HELD_DEG, "light g": LIGHT_G}
    for rig in args.realism:
        for arm in ARMS:
            runs = [measure(rig, arm, s, args.diagnose) for s in seeds]
            for q in QUANTITIES:
                f = cell_figures(runs, q, rng)
                show(f"{rig} {arm}", q, f)
                figures.update({f"{rig} {arm} {q} {k}": v for k, v in f.items()})
    if args.figures:
        clean = {k: (None if isinstance(v, float) and math.isnan(v) else v) for k, v in figures.items()}
        Path(args.figures).write_text(json.dumps(clean, indent=1) + "\n")


if __name__ == "__main__":
    main()
