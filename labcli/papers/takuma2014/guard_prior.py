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
  potentiometers read, and the closed chambers' pressures with them (Boyle's law) until the run
  refines the friction.  It judges the straight arm too, where no force can be read from the
  pressures (theta2 = 0), and from the first trial: the shipped protocols' 15 s settle leaves an
  arm with no weight hung exactly where it was.  Where the friction relief vents, before each
  baseline, the side the load pulls the arm towards (:meth:`PhysicsPrior.pulled_side`), the
  baseline leans the other way and no band holds the load back at its start: one band, half the
  allowance, is left on each joint the load pulls that way, two on a joint it pulls the other way
  (:meth:`PhysicsPrior.joint_bands`).  From :data:`LEARN_MIN` accepted trials on, the
  friction allowed for is the run's own (:meth:`PhysicsPrior.learn`): the most friction any of
  its trials showed, times :data:`LEARN_MARGIN`, and never less than :data:`LEARN_FLOOR`.  Refined
  so, the least motion is the run's own
  prediction, judged as the run's trials judge theirs (four floors to judge, a quarter to pass),
  and it also judges loads the run's trials predict too vaguely: a light load early in the run
  (the shipped plan's trial 4, 300 g) on a rig with less friction than the literature's, whose
  leak scatters the first trials' pressure responses.
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

from ...core.guard import EXPECT_FLOORS, PRIOR_NOISE, PRIOR_SHARE, WEAK_FRACTION, PriorReading, Watch
from .models.geometry import jacobian

# The rig's channels (as session.py names them; the session imports this module).
PRESSURE_NAMES = ("P_L1", "P_R1", "P_L2", "P_R2")
POT_NAMES = ("POT1", "POT2")
MIN_COMPONENT = 0.3  # a force component carrying less of the load than this says little of it
# The sleeves' friction the physics prior allows for, a share of each actuator's pressure force:
# the literature's level (2 %, docs/rig-realism.md) with a quarter more.  Chosen on the tuning seeds
# 1-2 of the literature's rig, where proper trials then read at least 0.26 of the least motion.
FRICTION_SHARE = 0.025
# Once the run has shown this many trials, the friction allowed for is the most any of them showed,
# times the margin: a rig with less friction than the literature's (the default rig) has its light
# loads judged too, one with more is not judged by more than it shows.  The first trial alone can
# show one band instead of two (the arm starts where the rig was made, not where a load left it).
# The first trials can show much less friction than the rig has (on the kind rig at three times
# its friction, seed 6, trials 1-3 showed at most 0.8 % and trial 5 showed 2 %), so the run's own
# allowance never falls below LEARN_FLOOR: with less, a 300 g trial friction held entirely was taken
# for one never hung.  Chosen on the tuning seeds 1-10 (bench_guard.py).
LEARN_MIN = 2
LEARN_MARGIN = 1.5
LEARN_FLOOR = 0.015
PULL_MIN_RAD = 1e-9  # a load bending the joints by less pulls the arm towards no side (pulled_side)
SHARE_MAX = 0.2  # a trial that moved no further than this much friction allows shows at least it
_SHARES = np.linspace(0.0, SHARE_MAX, 401)


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

    refined = False  # a model's coefficients are what they are: the run's trials do not change them

    def learn(self, load: Sequence[float], baseline: Any, loaded: Any) -> None:
        """Nothing: the run's own trials judge on their own as soon as they can."""

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
        self._shown: list[float] = []  # the friction share each accepted trial showed
        # The friction bands that can hold a load back before the run's trials show their friction
        # (:attr:`friction_share`): two, or one where the relief vents per load (:meth:`of`).
        self.bands = 2
        # The last accepted trial's baseline (posture rad, gauge MPa): the rest, straight, on the
        # design's supply before any (:meth:`pulled_side`).
        self._posture = (np.zeros(2), self.params.supply_pa / 1e6)
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
        prior = cls(protocol, {k: geometry[k] for k in GEOMETRY_KEYS})
        air = getattr(protocol, "air", None)
        if getattr(air, "friction_relief_vent_s", 0.0) > 0 and getattr(air, "friction_relief_vent", "") == "load":
            # Vented on the side each load pulls towards, the baseline leans the other way and no
            # friction band holds the load back at its start: one band (its own motion's) is left.
            prior.bands = 1
        return prior

    def _statics(
        self, theta0: np.ndarray, P0_MPa: np.ndarray, load: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """At the baseline posture ``theta0`` (rad) with the chambers closed at ``P0_MPa`` (gauge):
        the closed rig's stiffness (N m/rad), the load's torque (N m) and the torque one unit of
        friction share holds on each joint, twice over (N m)."""
        ph, params = self._ph, self.params
        L = ph.actuator_lengths(theta0, params)
        gauge = np.clip(P0_MPa, 0.0, None) * 1e6
        K = ph.stiffness_matrix(theta0, params, ph.Chambers.closed_at(L, gauge, params), ph.NoLoad())
        g = params.geometry
        tau = jacobian(theta0[0], theta0[1], g.h2, g.h3)[0].T @ load  # Section 2.2.2: tau = J^T F
        held = 2.0 * (gauge * np.abs(ph.mckibben_dvolume(L, params.b, params.n))) @ np.abs(ph.path_gradients(theta0, g))
        return K, tau, held

    @staticmethod
    def _motion(K: np.ndarray, tau: np.ndarray, held: np.ndarray, share: np.ndarray) -> np.ndarray:
        """The joints' deflection (rad) past ``share`` of friction, for each share given: (n, 2)."""
        beyond = np.sign(tau) * np.clip(np.abs(tau) - np.outer(share, held), 0.0, None)
        try:
            return np.linalg.solve(K, beyond.T).T
        except np.linalg.LinAlgError:
            return np.zeros_like(beyond)

    @property
    def friction_share(self) -> float:
        """The share of the actuators' pressure forces the sleeves are taken to hold: the run's
        own once it has shown :data:`LEARN_MIN` trials (:meth:`learn`; never below
        :data:`LEARN_FLOOR`), else :data:`FRICTION_SHARE` (half of it with one band, where the
        friction relief vents the side each load pulls towards)."""
        if len(self._shown) < LEARN_MIN:
            return FRICTION_SHARE * self.bands / 2
        return max(LEARN_FLOOR, LEARN_MARGIN * max(self._shown))

    @property
    def refined(self) -> bool:
        """Whether the run's own trials have set the friction allowed for (:meth:`learn`)."""
        return len(self._shown) >= LEARN_MIN

    def least_motion(self, theta0: np.ndarray, P0_MPa: np.ndarray, load: np.ndarray) -> np.ndarray:
        """The joints' least deflection (rad) under ``load`` (N) from the baseline posture ``theta0``
        (rad) with the chambers closed at ``P0_MPa`` (gauge), past :attr:`friction_share` (on each
        joint the bands :meth:`joint_bands` allows, before the run refines it)."""
        K, tau, held = self._statics(theta0, P0_MPa, load)
        if not self.refined:
            held = held * self.joint_bands(theta0, K, tau, load) / self.bands
        return self._motion(K, tau, held, np.array([self.friction_share]))[0]

    def joint_bands(self, theta0: np.ndarray, K: np.ndarray, tau: np.ndarray, load: Any) -> np.ndarray:
        """The friction bands that may hold ``load`` back on each joint before the run shows its
        friction: :attr:`bands` on both, except where the relief vents per load.  There a joint that
        the load pulls towards the side vented (:meth:`pulled_side`: the side whose actuator the
        joint's own motion shortens) leans the other way, and only its own motion's band is left; a
        joint the load pulls the other way (on a bent arm some directions pull the two joints
        opposite ways) is pulled towards its lean, and both bands are."""
        out = np.full(2, float(self.bands))
        if self.bands != 1:
            return out
        try:
            moved = np.linalg.solve(K, tau)
        except np.linalg.LinAlgError:
            return out
        vented = self.pulled_side(load) or "L"  # the session vents L where the load pulls no way
        g = self._ph.path_gradients(theta0, self.params.geometry)
        own = np.array([g[0, 0] * moved[0], g[2, 1] * moved[1]])  # L1's and L2's change of length per joint
        towards = np.where(own < 0, "L", "R")
        return np.where((towards == vented) | (np.abs(moved) <= PULL_MIN_RAD), 1.0, 2.0)

    def shown_share(self, theta0: np.ndarray, P0_MPa: np.ndarray, load: np.ndarray, moved: np.ndarray) -> float | None:
        """The friction share that accounts for a trial's motion ``moved`` (rad): the least share at
        which the statics bend the joints no further along the frictionless deflection than they
        moved (0 when they moved as far or further; the share that holds the whole load when they
        did not move that way at all); None where the load bends the joints by nothing to speak of."""
        K, tau, held = self._statics(theta0, P0_MPa, load)
        free = self._motion(K, tau, held, np.zeros(1))[0]
        size = float(np.linalg.norm(free))
        if not size > 0:
            return None
        along = free / size
        past = self._motion(K, tau, held, _SHARES) @ along
        # A joint that did not move, or moved back, shows only that friction held the whole load.
        seen = max(0.0, float(moved @ along))
        reached = np.flatnonzero(past <= seen)
        return float(_SHARES[reached[0]]) if len(reached) else SHARE_MAX

    def learn(self, load: Sequence[float], baseline: Any, loaded: Any) -> None:
        """A trial accepted: the friction share its motion shows joins the run's (:attr:`friction_share`)."""
        b, m = self._means(baseline, loaded)
        self.learn_change(load, b, m - b)

    def learn_change(
        self, load: Sequence[float], base: Sequence[float] | np.ndarray, change: Sequence[float] | np.ndarray
    ) -> None:
        """:meth:`learn` from the baseline's and the change's values on the watched channels (SI)."""
        b, c = np.asarray(base, dtype=float), np.asarray(change, dtype=float)
        if not (np.all(np.isfinite(b)) and np.all(np.isfinite(c))):
            return
        self._posture = (b[self._a], b[self._p])
        shown = self.shown_share(b[self._a], b[self._p], np.asarray(load, dtype=float), c[self._a])
        if shown is not None:
            self._shown.append(shown)

    def pulled_side(self, load: Sequence[float]) -> str | None:
        """The side, ``"L"`` or ``"R"``, whose actuators ``load`` (N) shortens as it bends the joints
        from the last accepted trial's baseline (the rest before any): the side it pulls the arm
        towards, None where it bends them by nothing to speak of.

        The friction relief vents that side (``acquisition.friction_relief_vent = "load"``): the
        other side swings the arm over, and supplied again it leans that way, a friction band short
        of its rest.  The load then pulls the arm away from the lean and moves it as the
        frictionless statics say, where a load pulling towards the lean must first overcome two
        bands, which hold a light load entirely on the literature's rig (docs/load-check.md)."""
        F = np.asarray(load, dtype=float)
        if F.shape != (2,) or not np.all(np.isfinite(F)):
            return None
        theta0, P0 = self._posture
        K, tau, _ = self._statics(theta0, P0, F)
        try:
            moved = np.linalg.solve(K, tau)
        except np.linalg.LinAlgError:
            return None
        if not float(np.linalg.norm(moved)) > PULL_MIN_RAD:
            return None
        # Each actuator's change of length (L1, R1, L2, R2); a pair's two change oppositely.
        left = float((self._ph.path_gradients(theta0, self.params.geometry) @ moved)[[0, 2]].sum())
        return "L" if left < 0 else "R"

    def pressure_change(self, theta0: np.ndarray, P0_MPa: np.ndarray, moved: np.ndarray) -> np.ndarray:
        """The closed chambers' pressure change (MPa) when the joints move by ``moved`` (rad) from
        ``theta0`` with the valves closed at ``P0_MPa`` (Boyle's law: a change of length alone, so
        friction does not enter)."""
        ph, params = self._ph, self.params
        gauge = np.clip(P0_MPa, 0.0, None) * 1e6
        chambers = ph.Chambers.closed_at(ph.actuator_lengths(theta0, params), gauge, params)
        return (chambers.gauge(ph.actuator_lengths(theta0 + moved, params), params) - gauge) / 1e6

    def __call__(self, load: Sequence[float], baseline: Any, loaded: Any, floors: np.ndarray) -> PriorReading | None:
        b, m = self._means(baseline, loaded)
        if not (np.all(np.isfinite(b)) and np.all(np.isfinite(m))):
            return None
        least = self.least_motion(b[self._a], b[self._p], np.asarray(load, dtype=float))
        size = float(np.linalg.norm(least))
        if not size > 0:
            return None
        # Before the run refines it, the least motion is read on the angles and, through Boyle's law,
        # on the closed chambers' pressures together (each channel in its noise floors): the
        # potentiometers' linearity error can read the rest posture where the angles alone fall
        # just short of standing clear of the noise (docs/load-check.md).  Refined, it is the run's
        # own prediction of the angles, judged as the run's trials judge theirs.
        expected = np.zeros(len(b))
        expected[self._a] = least
        if not self.refined:
            expected[self._p] = self.pressure_change(b[self._a], b[self._p], least)
        lowest, clear = (WEAK_FRACTION, EXPECT_FLOORS) if self.refined else (PRIOR_SHARE, PRIOR_NOISE / PRIOR_SHARE)
        weighted = expected / floors
        span = float(np.linalg.norm(weighted))
        if not span >= clear:
            return None
        share = float(((m - b) / floors) @ weighted) / span**2
        moved = float((m[self._a] - b[self._a]) @ least) / size
        past = "the friction this run's trials show" if self.refined else "the sleeves' friction"
        seen = (
            f"the joints moved {math.degrees(moved):.2f} deg of the at least {math.degrees(size):.2f} deg "
            f"it bends them past {past}"
        )
        return PriorReading(max(0.0, share), lowest, seen)  # a move the other way is none
