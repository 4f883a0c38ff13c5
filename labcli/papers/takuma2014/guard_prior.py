"""What a pulley weight must do to the McKibben rig before the run's own trials can say: the load
check's prior (:class:`labcli.core.guard.ResponsePrior`).

The run's trials teach the load check what a load does on this rig (:class:`labcli.core.guard.ResponseModel`),
from the third trial along a direction already pulled.  Before that, two priors say it, and a
trial is judged by the rig's statics where the protocol gives the rig's geometry, else by a force model:

* :class:`PhysicsPrior`, the rig's statics: the load's torque on each joint (``tau = J^T F`` at
  the baseline posture) against the closed chambers' stiffness at the baseline's pressures
  (Boyle's law and the McKibben actuators of the paper's design, :mod:`.sim.physics`), less what
  the sleeves' friction can hold.  Friction can hold the arm twice over: the last load may have
  left it up to one friction band towards this load's side, and the load must then overcome the
  friction of its own motion.  So only the torque beyond ``2 FRICTION_SHARE`` of the actuators'
  pressure forces (times their moment arms) must move the joints; what it must move them by, the
  potentiometers read.  It judges the straight arm too, where no force can be read from the
  pressures (theta2 = 0), and from the first trial: the shipped protocols' 15 s settle leaves an
  arm with no weight hung exactly where it was.
* :class:`ModelPrior`, a force model of the rig: an earlier run's fit (the model's coefficients),
  or the paper's own coefficients, which the protocol carries (``[paper_coefficients]``).  It
  reads the force in the trial's pressures and deflection (Eq. 36-37 with the measured angles); a
  component it can read (not near the singular posture, and carrying at least
  :data:`MIN_COMPONENT` of the load) must show at least :data:`labcli.core.guard.PRIOR_SHARE` of it.

Why a tenth.  The paper's coefficients are another rig's: on the simulated rig they read Fx at
-0.8 times the truth (its sign flipped; docs/figures/paper-scale.json), so only the size counts;
the design's statics are the paper's rig's, not a lab's own.  What the priors leave unjudged, the
run's own trials judge as soon as they can.  A trial is judged only where a tenth of what the
load must do is :data:`labcli.core.guard.PRIOR_NOISE` times what one noise floor on each channel
makes of it, so that a light weight is never taken for none.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from ...core.guard import PRIOR_NOISE, PRIOR_SHARE, PriorReading, Watch
from .models.geometry import jacobian

# The rig's channels (as session.py names them; the session imports this module).
PRESSURE_NAMES = ("P_L1", "P_R1", "P_L2", "P_R2")
POT_NAMES = ("POT1", "POT2")
MIN_COMPONENT = 0.3  # a force component carrying less of the load than this says little of it
# The sleeves' friction the physics prior allows for, a share of each actuator's pressure force:
# the literature's level (2 %, docs/rig-realism.md) with a quarter more.  Chosen on the tuning seeds
# 1-2 of the literature's rig, where proper trials then read at least 0.26 of the least motion.
FRICTION_SHARE = 0.025


class _RigChannels:
    """Where a prior finds the rig's pressures and angles among the protocol's watched channels."""

    def __init__(self, protocol: Any) -> None:
        watch = Watch.of(protocol)
        names = list(watch.names)
        self._p = [names.index(n) for n in PRESSURE_NAMES]
        self._a = [names.index(n) for n in POT_NAMES]
        self._cols = list(watch.cols)

    def _means(self, baseline: Any, loaded: Any) -> tuple[np.ndarray, np.ndarray]:
        """The baseline's and the loaded window's means on the watched channels, SI."""
        b = np.asarray(baseline.mean()[self._cols], dtype=float)
        return b, np.asarray(loaded.mean()[self._cols], dtype=float)


class ModelPrior(_RigChannels):
    """The load check's prior from a fitted (or the paper's) Eq. 34-37 model on ``protocol``'s channels."""

    def __init__(self, protocol: Any, model: Any) -> None:
        super().__init__(protocol)
        self.model = model

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
        b, m = self._means(baseline, loaded)
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


class PhysicsPrior(_RigChannels):
    """The load check's prior from the rig's statics (the module's docstring): the least motion of
    the joints a load must cause past the sleeves' friction, against the potentiometers'."""

    def __init__(self, protocol: Any, geometry: Mapping[str, float]) -> None:
        from .sim import physics

        self._ph = physics
        self.params = physics.nominal_params(physics.Geometry(**geometry))
        super().__init__(protocol)

    @classmethod
    def of(cls, protocol: Any) -> PhysicsPrior | None:
        """The prior for ``protocol``'s rig, None when the protocol lacks its geometry or channels."""
        from ...errors import ModelError
        from .models.takuma import GEOMETRY_KEYS, normalise_geometry

        rig = getattr(getattr(protocol, "settings", None), "rig", None)
        try:
            names = Watch.of(protocol).names
            geometry = normalise_geometry(rig or {})
        except (AttributeError, TypeError, ValueError, ModelError):
            return None
        if not all(n in names for n in PRESSURE_NAMES + POT_NAMES) or not all(k in geometry for k in GEOMETRY_KEYS):
            return None
        return cls(protocol, {k: geometry[k] for k in GEOMETRY_KEYS})

    def least_motion(self, theta0: np.ndarray, P0_MPa: np.ndarray, load: np.ndarray) -> np.ndarray:
        """The joints' least deflection (rad) under ``load`` (N) from the baseline posture ``theta0``
        (rad) with the chambers closed at ``P0_MPa`` (gauge)."""
        ph, params = self._ph, self.params
        L = ph.actuator_lengths(theta0, params)
        gauge = np.clip(P0_MPa, 0.0, None) * 1e6
        K = ph.stiffness_matrix(theta0, params, ph.Chambers.closed_at(L, gauge, params), ph.NoLoad())
        g = params.geometry
        tau = jacobian(theta0[0], theta0[1], g.h2, g.h3)[0].T @ load  # Section 2.2.2: tau = J^T F
        held = (
            2.0
            * FRICTION_SHARE
            * (gauge * np.abs(ph.mckibben_dvolume(L, params.b, params.n)))
            @ np.abs(ph.path_gradients(theta0, params.geometry))
        )
        beyond = np.sign(tau) * np.clip(np.abs(tau) - held, 0.0, None)
        try:
            return np.linalg.solve(K, beyond)
        except np.linalg.LinAlgError:
            return np.zeros(2)

    def __call__(self, load: Sequence[float], baseline: Any, loaded: Any, floors: np.ndarray) -> PriorReading | None:
        b, m = self._means(baseline, loaded)
        if not (np.all(np.isfinite(b)) and np.all(np.isfinite(m))):
            return None
        least = self.least_motion(b[self._a], b[self._p], np.asarray(load, dtype=float))
        size = float(np.linalg.norm(least))
        if not size > 0:
            return None
        along = least / size
        noise = float(np.sqrt(np.sum((floors[self._a] * along) ** 2)))
        if not PRIOR_SHARE * size >= PRIOR_NOISE * noise:
            return None
        moved = float((m[self._a] - b[self._a]) @ along)
        seen = (
            f"the joints moved {math.degrees(moved):.2f} deg of the at least {math.degrees(size):.2f} deg "
            "it bends them past the sleeves' friction"
        )
        return PriorReading(max(0.0, moved / size), PRIOR_SHARE, seen)  # a move the other way is none
