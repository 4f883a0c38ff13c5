"""The McKibben paper's fitted models as :class:`labcli.sensing.SensingModel`: what the run-time
estimator applies.

Each form is applied exactly as ``labcli validate`` applies it, by the model's own
``predict`` in the pressure-only mode: the posture-aware form (``models/posture.py``, routes
and blends included) with the rest posture, the paper's Eqs. 34-37 (``models/takuma.py``)
without.  The adapter only reshapes what ``predict`` returns:

* values and standard errors (n, 4) for theta1, theta2 (rad, the deflections from the rest
  posture) and Fx, Fy (N).  The posture form gives its own standard errors; the paper's form
  has none, so it gets the held-out form of them the posture form uses for its paper routes
  (``routes.paper_standard_errors``) with each equation's fit residual as the variance;
* flags: ``bad-pressure`` is ``bad-input``; a quantity the model does not report (its
  standard error over the protocol's ``[sensing]`` limit, the paper form's near-singular
  Jacobian or clipped arcsine) is ``unobservable:q``; inputs or estimates outside what the
  fit trials covered (the model file's ``calibrated_range``, with a share of each span as margin,
  10 % unless ``--range-margin`` says otherwise, at least 10 % of the level for the baseline
  pressures and 2 deg for the rest posture) are
  ``out-of-range`` (an input) or ``out-of-range:q`` (an estimate).

Angles are ``state`` quantities (the arm as it is now), forces ``load`` quantities (the cause,
estimated from the pressures the rig settles to).

A posture form with the sleeves' friction terms (``labcli fit``'s default) reads the
history of loads (:class:`labcli.sensing.model.HistoryModel`): ``predict`` takes the joints'
motion into each baseline (``motion_in``), and ``deflections`` gives the posture form's own
deflections, the ones ``PostureModel.predict_table`` (``labcli validate``) reads that motion from.

The estimator asks about a dozen-odd rows a block; for those (up to ``FAST_ROWS``) the posture
form is applied by its compiled twin (``models/posture_fast.py``: everything that does not
depend on the pressures worked out when the model is read), which gives the model's own
estimates to rounding and hands the rows it does not cover back to ``predict``
(tests/papers/takuma2014/test_sensing_fast.py).  ``TakumaSensing(model, fast=False)`` takes
the model's own ``predict`` throughout.
"""

from __future__ import annotations

import functools
import math
from typing import Any

import numpy as np

from ...errors import ModelError
from ...sensing.model import BAD_INPUT, LOAD, OUT_OF_RANGE, STATE, UNOBSERVABLE, Prediction
from .models import routes as rt
from .models.posture import PostureModel, force_model_from_json
from .models.posture_fast import CompiledPosture
from .models.takuma import SCHEMA, TakumaModel
from .options import RANGE_MARGIN, SensingOptions

QUANTITIES = ("theta1", "theta2", "Fx", "Fy")
# Up to this many rows a call takes the compiled form (the estimator asks 9 or 18 a block); a table
# (``labcli predict``) takes the model's own predict, validate's arithmetic to the last bit.
FAST_ROWS = 64
LEAK_PAD = 0.10  # share of the baseline pressures' level they may drift beyond their calibrated range


class TakumaSensing:
    """A posture-aware or paper-form model as the estimator sees it (module docstring)."""

    quantities: tuple[str, ...] = QUANTITIES
    units: tuple[str, ...] = ("rad", "rad", "N", "N")
    kinds: tuple[str, ...] = (STATE, STATE, LOAD, LOAD)
    actuators: tuple[str, ...] = ("L1", "R1", "L2", "R2")
    joints: tuple[int, ...] = (1, 2)
    record_kind = "sense"  # the run kind of a live session's run file (.sense_records)

    def __init__(self, model: PostureModel | TakumaModel, *, margin: float = RANGE_MARGIN, fast: bool = True) -> None:
        if not model.is_fitted:
            raise ModelError("The model has no coefficients yet; fit it on a run first (`labcli fit RUN.h5`).")
        self.model = model
        self.margin = margin  # share of a calibrated span allowed beyond its ends
        self.protocol = model.protocol
        self.form = getattr(model, "form", "paper")
        self.p0_leak_corrected = bool(getattr(model, "p0_leak_corrected", False))
        gap = getattr(model, "baseline_gap_s", None)
        self.baseline_gap_s = float(gap) if gap is not None else None
        self.captures_per_load = int(getattr(model, "captures_per_load", 1))  # each fit row's (models/calibrated.py)
        self.calibrated_range: dict[str, Any] = dict(getattr(model, "calibrated_range", None) or {})
        self._paper_var = _paper_variances(model) if isinstance(model, TakumaModel) else None
        # The posture form's predict worked out once for the estimator's few rows a call
        # (models/posture_fast.py); ``fast=False`` keeps the table form (the reference) throughout.
        self._compiled = CompiledPosture.compile(model) if fast and isinstance(model, PostureModel) else None
        # The friction terms read the joints' motion into each baseline (module docstring).
        self.uses_history = isinstance(model, PostureModel) and model.uses_history

    @property
    def geometry(self) -> dict[str, float]:
        return dict(self.model.geometry)

    def push_hook(self, protocol: Any, plan_path: Any) -> Any:
        """The settled-load hook that classifies the pushes of a push plan online (:mod:`.pushes`),
        with ``protocol``'s stiffness bands and settings (ConfigError, TableError in one sentence)."""
        from .push_plan import load_push_plan
        from .pushes import PlannedPush, PushClassifier

        plan = load_push_plan(plan_path)
        pushes = [
            PlannedPush(
                str(row["object"]),
                float(row["R_mm"]) * 1e-3,
                float(row["d_mm"]) * 1e-3,
                math.radians(float(row["phi_deg"])) if _given(row.get("phi_deg")) else math.nan,
            )
            for row in plan.to_dict("records")
        ]
        return PushClassifier.from_protocol(protocol, self.model, pushes)

    def deflections(self, P0: np.ndarray, P: np.ndarray) -> np.ndarray:
        """The posture form's own deflections (n, 2) rad, routes aside: what the history reads."""
        if not isinstance(self.model, PostureModel):
            raise ModelError("A model of the paper's form reads no history of loads.")
        return self.model.deflections(_rows(P0), _rows(P))

    def predict(
        self, P0: np.ndarray, P: np.ndarray, rest: np.ndarray, motion_in: np.ndarray | None = None
    ) -> Prediction:
        """(n, 4) baselines and pressures (MPa), (n, 2) rest postures (rad), and for a model with
        the friction terms the joints' motion into each baseline (n, 2) rad (None: unknown): the
        model's estimate."""
        P0, P, rest = _rows(P0), _rows(P), _rows(rest)
        moved = _rows(motion_in) if motion_in is not None and self.uses_history else None
        few = self._compiled is not None and len(P) <= FAST_ROWS
        fast = self._compiled.predict(P0, P, rest, moved) if few else None  # type: ignore[union-attr]
        if fast is not None:
            values, se, ok = fast
            return Prediction(values, se, self._raise(np.zeros(len(values), bool), ok, P0, P, rest, values))
        if isinstance(self.model, PostureModel):
            out = self.model.predict(P0, P, rest, mode="pressure-only", motion_in=moved)
            se = np.column_stack([out["se"][q] for q in QUANTITIES])
        else:
            out = self.model.predict(P0, P, mode="pressure-only")
            th = np.column_stack([out["theta1_rad"], out["theta2_rad"]])
            s = rt.paper_standard_errors(self.model, out, P0, P, th, self._paper_var or {})
            se = np.column_stack([s[q] for q in QUANTITIES])
        values = np.column_stack([out[rt.VALUE_KEYS[q]] for q in QUANTITIES])
        return Prediction(values, se, self._flags(out, P0, P, rest, values))

    def _flags(
        self, out: dict[str, Any], P0: np.ndarray, P: np.ndarray, rest: np.ndarray, values: np.ndarray
    ) -> list[tuple[str, ...]]:
        bad = np.array(["bad-pressure" in f for f in out["flags"]])
        ok = np.column_stack([np.asarray(out["ok"][q], dtype=bool) for q in QUANTITIES])
        return self._raise(bad, ok, P0, P, rest, values)

    def _raise(
        self, bad: np.ndarray, ok: np.ndarray, P0: np.ndarray, P: np.ndarray, rest: np.ndarray, values: np.ndarray
    ) -> list[tuple[str, ...]]:
        """Each row's flags from its bad-input mark, the quantities the model reports (``ok``) and the ranges."""
        inputs_out, values_out = self._outside(P0, P, rest, values)
        raised = np.empty((len(ok), 9), bool)
        raised[:, 0] = inputs_out
        np.logical_not(ok, out=raised[:, 1:5])
        np.logical_and(values_out, ok, out=raised[:, 5:])
        code = raised @ FLAG_BITS
        return [(BAD_INPUT,) if b else _flag_tuple(c) for b, c in zip(bad.tolist(), code.tolist(), strict=True)]

    def _outside(
        self, P0: np.ndarray, P: np.ndarray, rest: np.ndarray, values: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """Rows whose inputs, and estimates whose values, lie outside the calibrated range: the
        inputs side by side (P0 and P0 - P in MPa, the rest posture in deg) against their ends, the
        estimates (theta in deg, F in N) against theirs (a range the model file lacks: no end)."""
        lo_in, hi_in, lo_est, hi_est = self._ends()
        n, p = P0.shape
        inputs = np.empty((n, 2 * p + rest.shape[1]))
        inputs[:, :p] = P0
        np.subtract(P0, P, out=inputs[:, p : 2 * p])
        np.multiply(rest, 180 / math.pi, out=inputs[:, 2 * p :])
        est = np.empty((n, 4))
        np.degrees(values[:, :2], out=est[:, :2])
        est[:, 2:] = values[:, 2:]
        outside = np.logical_or.reduce((inputs < lo_in) | (inputs > hi_in), axis=1)
        return outside, (est < lo_est) | (est > hi_est)

    def _ends(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """The calibrated ranges' ends with their margin, (low, high) of the inputs and of the
        estimates in :meth:`_outside`'s order, worked out once per margin: the estimator asks every block."""
        key = (self.margin, id(self.calibrated_range))
        if getattr(self, "_ends_key", None) != key:
            ends = []
            for names, widths in ((INPUT_RANGES, (4, 4, 2)), (ESTIMATE_RANGES, (2, 2))):
                lo, hi = [], []
                for name, width in zip(names, widths, strict=True):
                    raw = self.calibrated_range.get(name)
                    if raw is None:
                        lo.append(np.full(width, -np.inf))
                        hi.append(np.full(width, np.inf))
                        continue
                    ranges = np.asarray(raw, dtype=float)
                    low, high = _limits(ranges, self.margin, MIN_PAD.get(name, lambda r: 0.0)(ranges))
                    lo.append(low)
                    hi.append(high)
                ends += [np.concatenate(lo), np.concatenate(hi)]
            self._ends_cache, self._ends_key = (ends[0], ends[1], ends[2], ends[3]), key
        return self._ends_cache


# The calibrated ranges the inputs and the estimates are held to, in _outside's order.
INPUT_RANGES = ("P0_MPa", "dP_MPa", "rest_deg")
ESTIMATE_RANGES = ("theta_deg", "F_N")

# The flags an estimate row may raise, in the order of _flags' columns.
FLAG_NAMES = np.array(
    [OUT_OF_RANGE] + [f"{UNOBSERVABLE}:{q}" for q in QUANTITIES] + [f"{OUT_OF_RANGE}:{q}" for q in QUANTITIES]
)

FLAG_BITS = 1 << np.arange(len(FLAG_NAMES))


@functools.cache
def _flag_tuple(code: int) -> tuple[str, ...]:
    """The flags a row raises, from the bits of FLAG_BITS it sets (a few codes recur block after block)."""
    return tuple(str(name) for k, name in enumerate(FLAG_NAMES) if code >> k & 1)


# The least margin of an input's range: the baseline pressures may drift by a tenth of their level (the
# leak over a session), the rest posture by 2 deg (friction leaves it a little elsewhere after every load).
MIN_PAD = {
    "P0_MPa": lambda r: LEAK_PAD * np.abs(r).max(axis=1),
    "rest_deg": lambda r: 2.0,
}


def _limits(ranges: np.ndarray, margin: float, least: Any = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """The ends of [lo, hi] (ranges (m, 2)) moved out by ``margin`` of the span (``least`` at least)."""
    lo, hi = ranges[:, 0], ranges[:, 1]
    pad = np.maximum(margin * (hi - lo), least)
    return lo - pad, hi + pad


def _rows(a: Any) -> np.ndarray:
    """``a`` as rows of floats (n, m): as it is when it is so already (the estimator's every block)."""
    if type(a) is np.ndarray and a.ndim == 2 and a.dtype == np.float64:
        return a
    return np.atleast_2d(np.asarray(a, dtype=float))


def _given(v: Any) -> bool:
    return v is not None and v != "" and not (isinstance(v, float) and math.isnan(v))


def _paper_variances(model: TakumaModel) -> dict[str, float]:
    """Each equation's fit residual (sin theta, N) squared: the paper form's error scale."""
    out = {}
    for q in QUANTITIES:
        rmse = model.fit_stats.get(q, {}).get("rmse")
        out[q] = float(rmse) ** 2 if isinstance(rmse, (int, float)) and math.isfinite(rmse) else 0.0
    return out


def sensing_model(text: str, name: str, options: SensingOptions | None = None) -> TakumaSensing | None:
    """The sensing model of a model file's JSON, None when it is no McKibben model."""
    if f'"{SCHEMA}"' not in text:
        return None
    margin = (options or SensingOptions()).range_margin
    return TakumaSensing(force_model_from_json(text, name=name), margin=margin)
