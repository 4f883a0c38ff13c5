"""The estimator's offline twin: the same model, the same estimates, on data already recorded.

* :func:`predict_rows`: rows of baseline pressures, pressures and rest postures (a table of new
  trials, with or without their truth): each row's estimate, standard errors and flags, exactly
  the model's answer (the estimator's own, less the transient: a table row is a settled pair);
* :func:`replay`: a recorded stream (device times and SI values, as a run file's raw frames
  hold them) through a fresh :class:`~.estimator.Estimator`: the estimates and events the live
  estimator gave, again.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from .config import EstimatorConfig
from .estimator import Estimator
from .model import SensingModel, check_model, uses_history
from .results import Estimate, Event

CHUNK = 50_000  # rows per call of the model: a million-row table is not held in the model's arrays at once


@dataclass(frozen=True)
class RowEstimates:
    """Per row: values and standard errors (n, q) in SI, and flags."""

    quantities: tuple[str, ...]
    units: tuple[str, ...]
    values: np.ndarray
    se: np.ndarray
    flags: list[tuple[str, ...]]

    def columns(self) -> dict[str, Any]:
        """Table columns in the units people read: ``theta1_deg``, ``theta1_deg_se``, ..., ``flags``."""
        out: dict[str, Any] = {}
        for j, (q, u) in enumerate(zip(self.quantities, self.units, strict=True)):
            unit, factor = ("deg", 180.0 / np.pi) if u == "rad" else (u, 1.0)
            out[f"{q}_{unit}"] = self.values[:, j] * factor
            out[f"{q}_{unit}_se"] = self.se[:, j] * factor
        out["flags"] = [";".join(f) for f in self.flags]
        return out


def predict_rows(model: SensingModel, P0: Any, P: Any, rest: Any, motion_in: Any = None) -> RowEstimates:
    """The model's estimate of each row: ``P0``, ``P`` (n, actuators) MPa, ``rest`` (n, joints) rad;
    ``motion_in`` (n, joints) rad, each row's motion into its baseline, for a model that reads the
    history of loads (:class:`~.model.HistoryModel`; None: unknown)."""
    m = check_model(model)
    P0, P, rest = (np.atleast_2d(np.asarray(a, dtype=float)) for a in (P0, P, rest))
    moved = None if motion_in is None or not uses_history(m) else np.atleast_2d(np.asarray(motion_in, dtype=float))
    values, se, flags = [], [], []
    for lo in range(0, max(len(P), 1), CHUNK):
        if lo >= len(P):
            break
        rows = slice(lo, lo + CHUNK)
        if moved is None:
            pred = m.predict(P0[rows], P[rows], rest[rows])
        else:
            pred = m.predict(P0[rows], P[rows], rest[rows], motion_in=moved[rows])  # type: ignore[call-arg]
        values.append(pred.values)
        se.append(pred.se)
        flags += list(pred.flags)
    q = len(m.quantities)
    return RowEstimates(
        tuple(m.quantities),
        tuple(m.units),
        np.vstack(values) if values else np.empty((0, q)),
        np.vstack(se) if se else np.empty((0, q)),
        flags,
    )


def replay(
    model: SensingModel,
    t_s: Any,
    values: Any,
    seq: Any = None,
    *,
    rate_hz: float | None = None,
    config: EstimatorConfig | None = None,
    batch: int = 0,
) -> list[Estimate | Event]:
    """A recorded stream (device time s, SI values in the model's order) through a new estimator.

    ``batch`` frames at a time (0: all at once); the estimates do not depend on it.
    """
    est = Estimator(model, rate_hz=rate_hz, config=config)
    t = np.asarray(t_s, dtype=float)
    x = np.asarray(values, dtype=float)
    s = None if seq is None else np.asarray(seq, dtype=np.int64)
    step = batch if batch > 0 else max(len(t), 1)
    out: list[Estimate | Event] = []
    for lo in range(0, len(t), step):
        out += est.update_si(t[lo : lo + step], x[lo : lo + step], None if s is None else s[lo : lo + step])
    return out
