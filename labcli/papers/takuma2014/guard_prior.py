"""What a pulley weight must do to the McKibben rig before the run's own trials can say: the load
check's prior (:class:`labcli.core.guard.ResponsePrior`).

The run's trials teach the load check what a load does on this rig (:class:`labcli.core.guard.ResponseModel`),
from the third trial along a direction already pulled.  Before that, the expected response comes
from a force model of the rig: an earlier run's fit (the model's coefficients), or the paper's own
coefficients, which the protocol carries (``[paper_coefficients]``).  The model reads the force in
the trial's pressures and deflection (Eq. 36-37 with the measured angles); a trial whose readings
it reads as less than :data:`labcli.core.guard.PRIOR_SHARE` of the load asked for, on a force
component it can read (not near the singular posture, and a component carrying at least
:data:`MIN_COMPONENT` of the load), was not loaded as the prompt said.

Why a tenth.  The paper's coefficients are another rig's: on the simulated rig they read Fx at
-0.8 times the truth (its sign flipped; docs/figures/paper-scale.json), so only the size counts,
and friction holds light loads back (a 200 g pull can move the pressures by a fifth of what 800 g
does).  What the prior leaves unjudged, the run's own trials judge as soon as they can.  A
component is judged only where a tenth of the load is :data:`labcli.core.guard.PRIOR_NOISE` times
what one noise floor on each pressure makes of it, so that a light weight is never taken for none.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from ...core.guard import PRIOR_NOISE, PRIOR_SHARE, PriorReading, Watch

# The rig's channels (as session.py names them; the session imports this module).
PRESSURE_NAMES = ("P_L1", "P_R1", "P_L2", "P_R2")
POT_NAMES = ("POT1", "POT2")
MIN_COMPONENT = 0.3  # a force component carrying less of the load than this says little of it


class ModelPrior:
    """The load check's prior from a fitted (or the paper's) Eq. 34-37 model on ``protocol``'s channels."""

    def __init__(self, protocol: Any, model: Any) -> None:
        self.model = model
        watch = Watch.of(protocol)
        names = list(watch.names)
        self._p = [names.index(n) for n in PRESSURE_NAMES]
        self._a = [names.index(n) for n in POT_NAMES]
        self._cols = list(watch.cols)

    @classmethod
    def of(cls, protocol: Any, coefficients: Mapping[str, float] | None = None) -> ModelPrior | None:
        """The prior from ``coefficients`` (default: the protocol's paper coefficients), None when
        they are not all there or the protocol lacks the rig's channels or geometry."""
        from .models.takuma import COEFFICIENT_NAMES, TakumaModel

        settings = getattr(protocol, "settings", None)
        coefficients = coefficients or getattr(settings, "paper_coefficients", None) or {}
        rig = getattr(settings, "rig", None)
        if rig is None or not all(n in coefficients for n in COEFFICIENT_NAMES):
            return None
        try:
            names = Watch.of(protocol).names
        except (AttributeError, TypeError, ValueError):
            return None
        if not all(n in names for n in PRESSURE_NAMES + POT_NAMES):
            return None
        model = TakumaModel(geometry=rig, protocol=protocol.name, coefficients=dict(coefficients))
        return cls(protocol, model)

    def _forces(self, P0: np.ndarray, P: np.ndarray, theta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        out = self.model.predict(P0, P, mode="measured-angles", theta=theta)
        return np.column_stack([out["Fx_N"], out["Fy_N"]]), np.column_stack([out["ok"]["Fx"], out["ok"]["Fy"]])

    def __call__(self, load: Sequence[float], baseline: Any, loaded: Any, floors: np.ndarray) -> PriorReading | None:
        F = np.asarray(load, dtype=float)
        size = float(np.linalg.norm(F))
        if not size > 0:
            return None
        b = np.asarray(baseline.mean()[self._cols], dtype=float)
        m = np.asarray(loaded.mean()[self._cols], dtype=float)
        P0, P, theta = b[self._p], m[self._p], m[self._a] - b[self._a]
        # The reading, then each pressure moved by one floor more: what noise makes of the force.
        P_all = np.vstack([P, P + np.diag(floors[self._p])])
        Fh, ok = self._forces(np.broadcast_to(P0, P_all.shape), P_all, np.broadcast_to(theta, (len(P_all), 2)))
        if not np.all(np.isfinite(Fh)):
            return None
        noise = np.sqrt(((Fh[1:] - Fh[0]) ** 2).sum(axis=0))
        judged = ok[0] & (np.abs(F) >= MIN_COMPONENT * size) & (PRIOR_SHARE * np.abs(F) >= PRIOR_NOISE * noise)
        if not judged.any():
            return None
        shares = np.abs(Fh[0][judged]) / np.abs(F[judged])
        k = int(np.argmax(shares))  # the component that reads most of its part: the reading most kind to the trial
        name = ("Fx", "Fy")[int(np.flatnonzero(judged)[k])]
        seen = f"{name} {abs(Fh[0][judged][k]):.2f} N read for {abs(F[judged][k]):.2f} N"
        return PriorReading(float(shares[k]), PRIOR_SHARE, seen)
