"""Accuracy of the fitted regression on the validation trials (the paper's Figure 7).

Errors are ``calculated - observed`` in degrees for the angles and newtons for the forces.  A
paper-form model fitted with the potentiometers' play (models/labels.py) is judged against the
validation labels corrected for the same play.
Trials whose prediction is flagged (clipped arcsin, near-singular Jacobian, bad pressure, or in
the posture-aware form a standard error over the protocol's limit) are counted apart and left out
of the measures, so one bad posture cannot hide or dominate the accuracy of the rest.
``rmse_all`` is the RMSE over every trial, flagged ones included (the forms' stand-in values), for
comparing forms that flag differently; ``coverage95`` (posture-aware form) is the share of the
reported trials whose error lies inside the estimate's 95 % interval (+-1.96 standard errors).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np

from ....errors import ModelError
from .force_model import ForceModel
from .takuma import FLAG_TEXT, select_set

QUANTITIES: dict[str, tuple[str, str, str]] = {
    # name: (table column, unit, label)
    "theta1": ("theta1_deg", "deg", "angle theta1"),
    "theta2": ("theta2_deg", "deg", "angle theta2"),
    "Fx": ("Fx_N", "N", "force Fx"),
    "Fy": ("Fy_N", "N", "force Fy"),
}
MEASURES: tuple[str, ...] = ("rmse", "mae", "max_abs", "bias", "r2", "pct_range")
MODES: tuple[str, ...] = ("pressure-only", "measured-angles")


def error_metrics(observed: Any, calculated: Any) -> dict[str, Any]:
    """RMSE, MAE, max |error|, bias, R^2 and RMSE as % of the observed range.

    ``None`` where a measure is undefined (no trials; R^2 and % of range need a spread).
    """
    obs = np.asarray(observed, dtype=float)
    calc = np.asarray(calculated, dtype=float)
    n = int(obs.size)
    out: dict[str, Any] = {"n": n, **{m: None for m in MEASURES}, "range": None}
    if n == 0:
        return out
    err = calc - obs
    rmse = float(np.sqrt(np.mean(err**2)))
    out.update(rmse=rmse, mae=float(np.mean(np.abs(err))), max_abs=float(np.max(np.abs(err))), bias=float(np.mean(err)))
    spread = float(np.max(obs) - np.min(obs))
    out["range"] = spread
    ss_tot = float(np.sum((obs - obs.mean()) ** 2))
    if ss_tot > 0:
        out["r2"] = 1.0 - float(np.sum(err**2)) / ss_tot
    if spread > 0:
        out["pct_range"] = 100.0 * rmse / spread
    return out


def _unplayed(model: Any, table: Any) -> Any:
    """The table's angle labels corrected for the play the model fitted (models/labels.py), so that
    its predictions are judged against the labels it was fitted to; as read otherwise.  The states
    run over the whole table in trial order, as in the fit."""
    from .labels import apply_play, fitted_play

    fitted = fitted_play(getattr(model, "play", None))
    return table if fitted is None else apply_play(table, *fitted)


def evaluate(model: ForceModel, table: Any, mode: str = "pressure-only", source: str = "the run") -> dict[str, Any]:
    """Predict the validation trials of ``table`` and measure the errors.

    Returns ``{"mode", "trial", "observed", "calculated", "ok", "flags", "metrics"}``:
    arrays per quantity in degrees / N (calculated values of flagged trials are finite
    stand-ins, marked False in ``ok``), and ``metrics[q]`` from :func:`error_metrics` plus
    ``unit``, ``n_flagged`` and ``n_missing`` (observed value absent).
    """
    if mode not in MODES:
        raise ModelError(f"Unknown validation mode '{mode}'; use pressure-only or measured-angles.")
    whole = _unplayed(model, table)
    rows = select_set(whole, "validation", source)
    if getattr(model, "uses_history", False):  # the friction terms: each trial's history from the whole run
        pred = model.predict_table(rows, mode=mode, history=whole)  # type: ignore[call-arg]
    else:
        pred = model.predict_table(rows, mode=mode)
    calculated = {
        "theta1": np.degrees(pred["theta1_rad"]),
        "theta2": np.degrees(pred["theta2_rad"]),
        "Fx": np.asarray(pred["Fx_N"], dtype=float),
        "Fy": np.asarray(pred["Fy_N"], dtype=float),
    }
    observed = {}
    for q, (col, _, _) in QUANTITIES.items():
        observed[q] = np.asarray(rows[col], dtype=float) if col in rows.columns else np.full(len(rows), np.nan)
    metrics: dict[str, dict[str, Any]] = {}
    se = _standard_errors(pred)
    for q, (_, unit, _) in QUANTITIES.items():
        have = np.isfinite(observed[q])
        ok = np.asarray(pred["ok"][q], dtype=bool)
        use = have & ok
        m = error_metrics(observed[q][use], calculated[q][use])
        m.update(unit=unit, n_flagged=int(np.sum(have & ~ok)), n_missing=int(np.sum(~have)))
        every = have & np.isfinite(calculated[q])
        m["rmse_all"] = error_metrics(observed[q][every], calculated[q][every])["rmse"]
        if se is not None:
            inside = np.abs(calculated[q] - observed[q]) <= Z95 * se[q]
            m["coverage95"] = float(np.mean(inside[use])) if use.any() else None
        metrics[q] = m
    if all(metrics[q]["n"] == 0 for q in QUANTITIES):
        raise ModelError(
            f"No validation trial of {source} gives a usable prediction "
            f"({_flag_summary(pred['flags'])}); check the pressures and the model."
        )
    return {
        "mode": mode,
        "form": getattr(model, "form", "paper"),
        "trial": np.asarray(pred["trial"], dtype=int),
        "observed": observed,
        "calculated": calculated,
        "se": se,
        "ok": {q: np.asarray(pred["ok"][q], dtype=bool) for q in QUANTITIES},
        "flags": pred["flags"],
        "metrics": metrics,
        "routes": pred.get("routes"),
        "blends": pred.get("blends"),
    }


Z95 = 1.959963984540054


def _standard_errors(pred: Mapping[str, Any]) -> dict[str, np.ndarray] | None:
    """The prediction's standard errors in degrees / N, when its form gives them."""
    if "se" not in pred:
        return None
    return {
        q: (np.degrees(pred["se"][q]) if q.startswith("theta") else np.asarray(pred["se"][q], dtype=float))
        for q in QUANTITIES
    }


def _flag_summary(flags: list[list[str]]) -> str:
    counts: dict[str, int] = {}
    for fl in flags:
        for f in fl:
            counts[f] = counts.get(f, 0) + 1
    if not counts:
        return "no flags"
    return ", ".join(f"{n} x {FLAG_TEXT.get(f, f)}" for f, n in sorted(counts.items()))


def _num(x: Any) -> float | None:
    x = float(x)
    return x if math.isfinite(x) else None


def evaluation_to_dict(ev: dict[str, Any]) -> dict[str, Any]:
    """Plain-JSON view: metrics, and per trial observed / calculated (null when flagged)."""
    trials = []
    for i, t in enumerate(ev["trial"]):
        trials.append(
            {
                "trial": int(t),
                "observed": {q: _num(ev["observed"][q][i]) for q in QUANTITIES},
                "calculated": {q: (_num(ev["calculated"][q][i]) if ev["ok"][q][i] else None) for q in QUANTITIES},
                "flags": [{"flag": f, "reason": FLAG_TEXT.get(f, f)} for f in ev["flags"][i]],
            }
        )
        if ev.get("se") is not None:
            trials[-1]["standard_error"] = {q: _num(ev["se"][q][i]) for q in QUANTITIES}
    units = {q: QUANTITIES[q][1] for q in QUANTITIES}
    metrics = {q: {k: (_num(v) if isinstance(v, float) else v) for k, v in m.items()} for q, m in ev["metrics"].items()}
    out = {"mode": ev["mode"], "form": ev.get("form", "paper"), "units": units, "metrics": metrics, "trials": trials}
    if ev.get("routes"):
        out["routes"] = dict(ev["routes"])
    if ev.get("blends"):
        out["blends"] = {q: dict(b) for q, b in ev["blends"].items()}
    if "forms" in ev:
        out["forms"] = {
            f: {q: {k: (_num(v) if isinstance(v, float) else v) for k, v in m.items()} for q, m in ms.items()}
            for f, ms in ev["forms"].items()
        }
    return out
