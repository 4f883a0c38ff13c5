"""Where a 95 % interval's width comes from, and where the fit trials err (captures_acquired.py --diagnose).

The posture form's variance of an estimate (models/posture.py) is the sum of three shares, each
found here by predicting the validation trials again with the later ones taken away:

* ``direction``: the fit plan's direction term (models/routes.py ``held_out_variances``);
* ``angle``: the deflection estimate's error carried into the estimate (``angle_resid_cov``,
  which also sets the friction terms' fade);
* ``torque``: what is left, the torque regression's residual share (``torque_resid_cov``).

An angle, and a force on the paper's route or a blend, has only ``direction`` and ``own`` (its
route's own variance) apart.  Beside the shares are the validation trials' mean squared errors: pressure-only
(``mse``) and, for a force, with the measured deflections (``mse_measured``: the torque share's
error alone, the angle estimate's taken away).  A share much larger than the error it stands for
names the over-wide part.

:func:`fit_direction_rmse` is the other half of the diagnosis: the fit trials' own errors per load
direction, predicted as a validation trial is (pressure-only, the fit's own model).  A direction
that errs several times the others carries most of every residual variance the intervals pool.
"""

from __future__ import annotations

import copy
import math
from typing import Any

import numpy as np

PARTS = ("total", "direction", "own", "angle", "torque", "mse", "mse_measured")


def _evaluate(model: Any, table: Any, mode: str = "pressure-only") -> dict[str, Any]:
    from labcli.papers.takuma2014.models.metrics import evaluate

    with np.errstate(all="ignore"):
        return evaluate(model, table, mode=mode)


def variance_parts(model: Any, table: Any, quantities: tuple[str, ...] = ("theta1", "theta2", "Fx")) -> dict[str, Any]:
    """Per quantity, the mean over its reported validation trials of each share of the interval's
    variance and of the squared errors (deg^2, N^2; module docstring): ``{q: {part: value}}``,
    ``angle`` and ``torque`` None off the posture route."""
    ev = _evaluate(model, table)
    own = copy.copy(model)
    own.held_out_variance = {}
    ev_own = _evaluate(own, table)
    posture = copy.copy(own)  # the posture form's own estimate, routes aside, for the torque share
    posture.routes, posture.blends = {}, {}
    torque = copy.copy(posture)
    torque.angle_resid_cov = [[0.0, 0.0], [0.0, 0.0]]
    ev_tq = _evaluate(torque, table)
    ev_meas = _evaluate(posture, table, mode="measured-angles")
    out: dict[str, Any] = {}
    for q in quantities:
        ok = np.asarray(ev["ok"][q], dtype=bool) & np.isfinite(ev["observed"][q])
        if not ok.any():
            out[q] = dict.fromkeys(PARTS)
            continue

        def mean(x: Any, use: np.ndarray = ok) -> float:
            return float(np.mean(np.asarray(x, dtype=float)[use]))

        split = model.route(q) == "posture" and q in ("Fx", "Fy")  # an angle has no torque share
        err = ev["calculated"][q] - ev["observed"][q]
        parts: dict[str, Any] = {
            "total": mean(ev["se"][q] ** 2),
            "own": mean(ev_own["se"][q] ** 2),
            "mse": mean(err**2),
            "torque": mean(ev_tq["se"][q] ** 2) if split else None,
        }
        parts["direction"] = parts["total"] - parts["own"]
        parts["angle"] = parts["own"] - parts["torque"] if split else None
        meas = ev_meas["calculated"][q] - ev_meas["observed"][q]
        parts["mse_measured"] = mean(meas**2) if split else None
        out[q] = parts
    return out


def fit_direction_rmse(model: Any, table: Any, q: str = "Fx") -> dict[float, float]:
    """The fit trials' RMSE (deg, N) per load direction (deg), each predicted pressure-only by the
    fit's own model as a validation trial is (in-sample: the folds' held-out errors are larger)."""
    if "direction_deg" not in table.columns:
        return {}
    swapped = table.copy()
    swapped["set"] = swapped["set"].map({"fit": "validation", "validation": "fit"}).fillna(swapped["set"])
    ev = _evaluate(model, swapped)
    rows = swapped[swapped["set"] == "validation"]
    direction = np.asarray(rows["direction_deg"], dtype=float)
    err = np.asarray(ev["calculated"][q] - ev["observed"][q], dtype=float)
    keep = np.isfinite(err) & np.isfinite(direction)
    return {float(d): float(np.sqrt(np.mean(err[keep & (direction == d)] ** 2))) for d in np.unique(direction[keep])}


def records(model: Any, table: Any) -> dict[str, Any]:
    """The diagnosis as flat cache keys: ``parts/{q}/{part}`` and ``fitdir/Fx/{direction}``."""
    out: dict[str, Any] = {}
    for q, parts in variance_parts(model, table).items():
        out.update({f"parts/{q}/{k}": v for k, v in parts.items()})
    out.update({f"fitdir/Fx/{d:g}": v for d, v in fit_direction_rmse(model, table).items()})
    return out


def show(raw: dict[int, dict[str, Any]], prefix: str) -> None:
    """Print the diagnosis under ``prefix`` (``arm/form/``) averaged over the seeds that carry it."""
    seeds = [s for s in sorted(raw) if f"{prefix}parts/Fx/total" in raw[s]]
    if not seeds:
        print(f"  {prefix}: no diagnosis in these records (measured before it was kept)")
        return

    def avg(key: str) -> float | None:
        vals = [raw[s][key] for s in seeds if raw[s].get(key) is not None]
        return float(np.mean(vals)) if vals else None

    for q in ("theta1", "theta2", "Fx"):
        cells = []
        for part in PARTS:
            v = avg(f"{prefix}parts/{q}/{part}")
            cells.append(f"{part} {v:.4g}" if v is not None else f"{part} -")
        unit = "deg^2" if q.startswith("theta") else "N^2"
        print(f"  {prefix}{q} ({unit}, mean over the validation trials, {len(seeds)} seeds): " + ", ".join(cells))
    dirs = sorted({float(k.rsplit("/", 1)[1]) for s in seeds for k in raw[s] if k.startswith(f"{prefix}fitdir/Fx/")})
    per = [f"{d:g}: {avg(f'{prefix}fitdir/Fx/{d:g}') or math.nan:.2f}" for d in dirs]
    print(f"  {prefix}Fx fit trials' RMSE (N) by load direction (deg): " + ", ".join(per))
