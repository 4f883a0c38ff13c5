"""What makes the simulated McKibben rig unkind: friction, leaks, heat, play, weight, sensor errors.

Each effect has a level (the constants below) and a scale in :class:`NonIdeal` (1 = the
level, 0 = off); ``NonIdeal.ideal()`` turns them all off, and
:class:`labcli.papers.takuma2014.sim.rig.SimRig` then follows the ideal model
(:mod:`labcli.papers.takuma2014.sim.physics`) exactly.

Two sets of default scales (``realism``):

* ``"literature"``, the default (:data:`REALISM_DEFAULT`): every effect at the level the McKibben
  literature and the reference rig's datasheets give (docs/simulated-rig.md and the page on the
  levels it links cite each beside its number);
* ``"kind"``, opt-in (``sim://?realism=kind``): the rig as it was before those levels and the
  default until they became it: sleeve friction at a quarter of the
  literature's level (0.5 % of the pressure force), no drift, and none of the effects added
  with them (contact and pulley friction, potentiometer scale and linearity errors, the
  pressure sensors' repeatability).  With the valves' earlier lag it reproduces that rig's frames
  byte for byte, so that figures measured on it can be remade (``sim://?realism=kind&flow=lag``).

A scale multiplies the realism's level: ``realism=kind&friction=2`` is twice the kind rig's
friction (1 %), ``friction=2`` twice the literature's (4 %); an effect the kind rig lacks is
switched on at the literature's level by its scale (``realism=kind&contact=1``).

The models and their magnitudes (the sources are in docs/simulated-rig.md and the page it links):

* **Sleeve friction with hysteresis** (Chou & Hannaford 1996, who measured hysteresis loops
  in the force-length curves of McKibben muscles at constant pressure and traced them to
  friction in the braid; Tondu & Lopez 2000, who model it as a dry friction force
  proportional to the pressure; Tondu 2012's review, which finds the hysteresis is
  strand-on-strand friction in the weave).  Each actuator carries a Coulomb friction force
  that is a fraction (:data:`FRICTION_FRACTION`, by realism) of its pressure force
  ``P (-dV/dL)``: 2 % (a loop of 4 % of the force) on the literature's rig, about 1.3 N on the
  paper-scale rig at 0.30 MPa; 0.5 % on the kind rig.  It opposes the actuator's motion.  After
  a change the arm moves from its posture towards the new frictionless equilibrium and stops
  where the spring forces no longer overcome friction, or does not move at all if they never
  do (stiction).  So a load-unload cycle leaves a loop and the unloaded posture depends on the
  previous load (:func:`friction_equilibrium`).
* **Chamber leak**: a closed chamber loses air exponentially,
  ``n(t) = n0 exp(-(t - t_closed) / tau_leak)`` with ``tau_leak = LEAK_TAU_S /
  leak`` (6 h: about 1.1 kPa/min at 0.30 MPa gauge, a push-in fitting that
  is not quite tight) times a seeded per-chamber factor (lognormal, 40 %), so
  the chambers leak at different rates.  Assumed level.
* **Thermal relaxation**: a fast stretch compresses the air nearly
  adiabatically (``kappa = 1.4`` for air), then heat flows to the wall and the
  pressure relaxes to the isothermal (Boyle) value with time constant
  ``THERMAL_TAU_S`` (3 s, the order reported for small pneumatic chambers).
  The gas temperature excess ``x = T/T0 - 1`` obeys
  ``dx/dt = -(kappa - 1) d(ln V)/dt - x / tau_th``; the pressure is the Boyle
  value times ``1 + x``.  ``thermal`` scales ``kappa - 1``.  The posture
  follows the isothermal equilibrium (the few-percent pressure excess moves
  it far less than the friction band).
* **Potentiometer backlash**: play of ``BACKLASH_RAD`` (0.2 deg full width) in
  each pot's coupling: the shaft follows the joint only once the play is taken
  up, so the reading lags by up to half the play, on the side of the last motion.
* **Link weight**: link 1 ``LINK_MASS_KG[0]`` (80 g) and link 2 with its tip
  ``LINK_MASS_KG[1]`` (30 g), centres of mass mid-link: an inverted pendulum
  on the upright arm (:func:`labcli.papers.takuma2014.sim.physics.link_weight_torques`).  Assumed
  masses; the paper gives none.
* **Contact friction** (``contact``): where the tip presses a pushed object it also drags on
  its surface, a Coulomb force of ``CONTACT_MU`` (0.3) times the normal force against the tip's
  slip over the surface, with a stick region as stiff as the object
  (:class:`labcli.papers.takuma2014.sim.physics.Push`).  Eq. 38 assumes the force is radial; with
  an oblique push it is not.
* **Pulley friction** (``pulley``): the rope's pulley loses ``PULLEY_LOSS`` (2 %) of the
  weight's pull while the weight settles downwards, so the tip feels ``(1 - loss) m g``
  (:class:`labcli.papers.takuma2014.sim.physics.Weight`) while the table records ``m g``.
* **Potentiometer scale and linearity** (``potscale``, ``potlin``): each potentiometer's gain
  is off by ``POT_SCALE_SD`` (1 % rms) and its output departs from a straight line by up to
  ``POT_LINEARITY`` (0.5 %) of its 340 deg span
  (:class:`labcli.core.sim.sensors.GainLinearity`).
* **Pressure repeatability** (``repeat``): each new reading of a pressure sensor comes back
  off by ``PRESSURE_REPEAT_SD_MPA`` rms (drawn afresh at every change of the rig, settling with
  it): averaging a window does not remove it.
* **Sensor zero drift** (``drift``, the ``sim://`` URL's own option): slow sinusoids of a few
  counts (:class:`labcli.papers.takuma2014.sim.rig.SimRig`), on at 1 on the literature's rig.

Not modelled: rubber creep.  The latex carries about 5 % of an actuator's tension on this
design (700 N/m x 5 mm against 69 N), a deflection changes its force by a few tenths of a
newton, and a relaxation of 10 % of that is some 40 times below the sleeves' friction.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields
from typing import Any

import numpy as np

from . import physics as ph

REALISMS = ("literature", "kind")
REALISM_DEFAULT = "literature"  # the harsher rig by default; realism="kind" opts into the kinder one
FRICTION_FRACTION = {"literature": 0.02, "kind": 0.005}  # of the pressure force P (-dV/dL)
LEAK_TAU_S = 6 * 3600.0  # amount of air, e-folding time at leak = 1
LEAK_SPREAD = 0.4  # lognormal sigma of the per-chamber leak rate
KAPPA = 1.4  # adiabatic exponent of air
THERMAL_TAU_S = 3.0
BACKLASH_RAD = math.radians(0.2)
LINK_MASS_KG = (0.080, 0.030)
CONTACT_MU = 0.3  # Coulomb coefficient at the tip-object contact
CONTACT_STIFFNESS = 1.0  # the contact's tangential stiffness before it slips, in units of the object's
PULLEY_LOSS = 0.02  # share of the weight's pull the pulley holds back while the weight settles
POT_SCALE_SD = 0.01  # rms relative gain error of a potentiometer
POT_LINEARITY = 0.005  # largest deviation from the straight line, share of the span
PRESSURE_REPEAT_SD_MPA = 2.0e-3 / 6  # rms of a reading's non-repeatability (docs/simulated-rig.md)

_SCALES = ("friction", "leak", "thermal", "backlash", "links", "contact", "pulley", "potscale", "potlin", "repeat")
# Default scales of each realism (drift included: the sim:// URL's drift option, when given, replaces it).
DEFAULT_SCALES = {
    "literature": {**{name: 1.0 for name in _SCALES}, "drift": 1.0},
    "kind": {
        **{name: 1.0 for name in ("friction", "leak", "thermal", "backlash", "links")},
        **{name: 0.0 for name in ("contact", "pulley", "potscale", "potlin", "repeat")},
        "drift": 0.0,
    },
}


_DEFAULT = math.nan  # a scale not given: its realism's default


@dataclass(frozen=True)
class NonIdeal:
    """Scales of the non-idealities (1 = the realism's level, 0 = off); a scale left out takes
    its realism's default (:data:`DEFAULT_SCALES`)."""

    friction: float = _DEFAULT
    leak: float = _DEFAULT
    thermal: float = _DEFAULT
    backlash: float = _DEFAULT
    links: float = _DEFAULT
    contact: float = _DEFAULT
    pulley: float = _DEFAULT
    potscale: float = _DEFAULT
    potlin: float = _DEFAULT
    repeat: float = _DEFAULT
    drift: float = _DEFAULT
    realism: str = REALISM_DEFAULT

    def __post_init__(self) -> None:
        if self.realism not in REALISMS:
            raise ValueError(f"the realism must be one of {', '.join(REALISMS)}, got {self.realism!r}")
        for name in self.scale_names():
            v = getattr(self, name)
            if isinstance(v, float) and math.isnan(v):
                object.__setattr__(self, name, DEFAULT_SCALES[self.realism][name])
            elif not (isinstance(v, (int, float)) and math.isfinite(v) and v >= 0):
                raise ValueError(f"the {name} scale must be a number >= 0, got {v!r}")
            else:
                object.__setattr__(self, name, float(v))

    @staticmethod
    def scale_names() -> tuple[str, ...]:
        return tuple(f.name for f in fields(NonIdeal) if f.name != "realism")

    @classmethod
    def ideal(cls, realism: str = REALISM_DEFAULT) -> NonIdeal:
        """Every effect off: the ideal model."""
        return cls(**{name: 0.0 for name in cls.scale_names()}, realism=realism)

    @property
    def is_ideal(self) -> bool:
        return not any(getattr(self, name) for name in self.scale_names())

    def as_dict(self) -> dict[str, float]:
        """The scales (not the realism)."""
        return {name: float(getattr(self, name)) for name in self.scale_names()}

    def magnitudes(self) -> dict[str, Any]:
        """The configured magnitudes in SI, for ``true_state`` and reports."""
        return {
            "realism": self.realism,
            "friction_fraction": FRICTION_FRACTION[self.realism] * self.friction,
            "leak_tau_s": LEAK_TAU_S / self.leak if self.leak else math.inf,
            "thermal_kappa": 1.0 + (KAPPA - 1.0) * self.thermal,
            "thermal_tau_s": THERMAL_TAU_S,
            "backlash_rad": BACKLASH_RAD * self.backlash,
            "link_mass_kg": [m * self.links for m in LINK_MASS_KG],
            "contact_mu": CONTACT_MU * self.contact,
            "pulley_loss": PULLEY_LOSS * self.pulley,
            "pot_scale_sd": POT_SCALE_SD * self.potscale,
            "pot_linearity": POT_LINEARITY * self.potlin,
            "pressure_repeat_sd_MPa": PRESSURE_REPEAT_SD_MPA * self.repeat,
            "drift": self.drift,
        }


# ---------------------------------------------------------------- friction


def friction_forces(theta, params: ph.RigParams, chambers: ph.Chambers, fraction: float) -> np.ndarray:
    """Coulomb friction force of each actuator (N) at posture ``theta``: a fraction of ``P (-dV/dL)``."""
    L = ph.actuator_lengths(theta, params)
    p = np.clip(chambers.gauge(L, params), 0.0, None)
    return fraction * p * np.abs(ph.mckibben_dvolume(L, params.b, params.n))


def friction_equilibrium(
    params: ph.RigParams, chambers: ph.Chambers, load, theta_from, fraction: float
) -> ph.Equilibrium:
    """Where the arm stops when it starts at ``theta_from`` with sleeve friction.

    Each actuator's friction force (fixed at its ``theta_from`` value) opposes
    its motion: it adds to the tension of a stretching actuator and subtracts
    from a shortening one.  The directions are those of the frictionless
    motion, refined once from the frictional result; if the arm would have to
    move backwards, static friction holds it where it is.  A simplification of
    set-valued friction statics that keeps the essential: the arm stops short
    by (stiffness)^-1 (friction torque), on the side it came from.
    """
    theta_from = np.asarray(theta_from, dtype=float)
    free = ph.solve_equilibrium(params, chambers, load, theta0=theta_from)
    if fraction <= 0:
        return free
    ff = friction_forces(theta_from, params, chambers, fraction)
    s_from = ph.path_lengths(theta_from, params.geometry)

    def motion(theta) -> np.ndarray:
        """Each actuator's direction from ``theta_from`` to ``theta``: +1 stretching, -1 shortening, 0."""
        return np.sign(np.round((ph.path_lengths(theta, params.geometry) - s_from) * 1e9))

    sign = motion(free.theta_rad)
    result = free
    for _ in range(2):
        if not np.any(sign):
            return _held(params, chambers, load, theta_from)

        # Friction resists each actuator's motion: a stretching one pulls harder, a shortening
        # one less.  Started from the last posture found (the frictionless one first): friction
        # moves the arm by a fraction of a degree from it, so Newton needs a step or two.
        result = ph.solve_equilibrium(params, chambers, load, theta0=result.theta_rad, extra_tension_N=ff * sign)
        step = result.theta_rad - theta_from
        if float(step @ (free.theta_rad - theta_from)) <= 0:
            return _held(params, chambers, load, theta_from)
        new_sign = motion(result.theta_rad)
        if np.array_equal(new_sign, sign):
            break
        sign = new_sign
    return result


def _held(params, chambers, load, theta) -> ph.Equilibrium:
    """The arm held by static friction at ``theta``."""
    L = ph.actuator_lengths(theta, params)
    p = chambers.gauge(L, params)
    T = ph.mckibben_tension(L, p, params.b, params.n, params.k_rubber, params.L_rubber)
    return ph.Equilibrium(
        theta_rad=np.array(theta, dtype=float),
        pressures_MPa=p / 1e6,
        force_N=load.force(theta, params.geometry),
        tensions_N=T,
        lengths_m=L,
        residual_Nm=0.0,
        stable=True,
    )


# ---------------------------------------------------------------- thermal


def thermal_excess(dt, x0, dlnV, kappa_minus_1: float, tau_lag: float, tau_th: float):
    """Gas temperature excess ``T/T0 - 1`` at ``dt`` after a change (``(..., 4)``).

    ``x0``: the excess at the change; ``dlnV``: the change of ``ln V`` the
    first-order lag (time constant ``tau_lag``) drives, ``ln V(t) = ln V0 +
    dlnV (1 - exp(-t/tau_lag))``.  Solves ``dx/dt = -(kappa-1) dlnV/dt - x/tau_th``.
    """
    dt = np.clip(np.asarray(dt, dtype=float), 0.0, None)[..., None]
    decay = np.exp(-dt / tau_th)
    if abs(tau_th - tau_lag) < 1e-9 * tau_th:
        g = dt / tau_lag * decay
    else:
        g = tau_th * (decay - np.exp(-dt / tau_lag)) / (tau_th - tau_lag)
    return x0 * decay - kappa_minus_1 * dlnV * g


# ---------------------------------------------------------------- backlash


def play(shaft0, theta, width: float):
    """Potentiometer shafts after play of ``width`` (rad) along a monotonic joint path ``theta``."""
    if width <= 0:
        return theta
    h = 0.5 * width
    return np.clip(shaft0, theta - h, theta + h)


def leak_factors(seed: int, leak: float) -> np.ndarray:
    """Per-chamber leak rates (1/s), seeded: ``leak / LEAK_TAU_S`` times a lognormal spread."""
    rng = np.random.default_rng([int(seed), 4])
    return leak / LEAK_TAU_S * np.exp(LEAK_SPREAD * rng.standard_normal(4))
