"""Physical model of the two-joint McKibben test bed (Takuma et al. 2014, Sections 2-4).

Everything here is a pure function of SI quantities (m, N, Pa, rad) and numpy
arrays (the 2-D equilibrium is solved by damped Newton, so opening a ``sim://``
port does not pay for importing scipy).  Pressures are
gauge in Pa inside this module; :class:`Equilibrium` reports them in MPa gauge,
the unit the rest of the toolkit uses.

Frame and conventions
---------------------
Origin at the bottom joint (joint 1), y up, angles counter-clockwise positive.
``theta = (theta1, theta2)``: theta1 is link 1 against the base, theta2 is link 2
against link 1 (what the potentiometers read).  Actuator order everywhere is
``L1, R1, L2, R2`` (i = L/R side, j = 1 outside, 2 inside).

Tendon geometry (paper Eqs. 2-7, exact)
---------------------------------------
Base anchors at ``(+-r_j, -h1)``.  Outside tendon j=1 attaches to link 1 at
``rot(t1) (+-r1, 0)``::

    s_R1 = sqrt((h1 + r1 sin t1)^2 + (r1 - r1 cos t1)^2)      (Eq. 2)
    s_L1 = sqrt((h1 - r1 sin t1)^2 + (r1 - r1 cos t1)^2)      (Eq. 3)

Inside tendon j=2 runs base anchor -> a frictionless guide on link 1 at
``rot(t1) (+-r2, 0)`` -> its attachment on link 2 at ``joint2 + rot(t1+t2) (+-r2, 0)``
with ``joint2 = rot(t1) (0, h2)``; its path is the sum of Eq. 4 (or 5) and
Eq. 6 (or 7) read as segment lengths::

    s_R2 = sqrt((h1 + r2 sin t1)^2 + (r2 - r2 cos t1)^2) + sqrt((h2 + r2 sin t2)^2 + (r2 - r2 cos t2)^2)

At ``theta = 0`` the paths are ``h1`` and ``h1 + h2``.  Tendons are inextensible, so
an actuator's length changes by exactly its path's change.  Positive theta1
lengthens the right-hand paths: the right actuators are stretched.  (The paper's
Eq. 8 writes the left change with the opposite sign, ``(h1 - dl_L1)^2``: there
``dl_L1`` is a *shortening*.  Here every extension is ``s(theta) - s(0)``.)

Contact point and Jacobian (Section 2.2.2, as the paper's J implies)
--------------------------------------------------------------------
``C = (-h2 sin t1 - h3 sin(t1+t2), h2 cos t1 + h3 cos(t1+t2))`` and
``J = dC/dtheta`` exactly as printed.

McKibben actuator (Chou and Hannaford)
--------------------------------------
An inextensible braid of thread length ``b`` wound ``n`` turns round a tube of
length ``L``: ``V(L) = L (b^2 - L^2) / (4 pi n^2)``.  Tension is the virtual work
of the gauge pressure plus a linear rubber term::

    T = P_gauge (3 L^2 - b^2) / (4 pi n^2) + k_rubber (L - L_rubber)

(``= -P dV/dL + rubber``).  With the braid angle ``acos(L/b)`` below 54.7 deg a
pressurised actuator pulls (contracts) and stretching raises its tension; its
volume falls as it is stretched, so a closed chamber's pressure rises.

Chambers
--------
With the valves open the regulator holds the gauge pressure.  Once closed, each
chamber (actuator volume plus a dead volume of tubing and sensor) keeps its
amount of air: isothermal Boyle's law on ABSOLUTE pressure,
``(P_gauge + P_atm) (V(L) + V_dead) = const``, ``P_atm = 101325 Pa``.

Equilibrium (virtual work)
--------------------------
``J(theta)^T F_ext(theta) = sum_ij T_ij(theta) grad s_ij(theta)``: a tension pulls
to shorten its path.  ``F_ext`` is a pulley weight ``m g (cos dir, sin dir)``,
fixed in the world, or the radial-spring cylinder of Section 4 (Eq. 39) pushed
into the tip.  The links' own weight (``RigParams.link_mass_kg``, centres of
mass mid-link) adds :func:`link_weight_torques`.

Chosen parameters, and why (:func:`nominal_params`)
---------------------------------------------------
Geometry is the paper's (Section 3.1): h1 = 0.355 m, h2 = 0.130 m, h3 = 0.065 m,
r1 = 0.075 m, r2 = 0.035 m.  Supply pressure 0.30 MPa gauge (inside the
sensor's 0-1 MPa span, close to the 0.33 MPa of Figure 1c).

The paper prints no actuator dimensions and its Figure 1 has no numbers in our
text, so the actuators are tuned to the one quantitative trace of the paper's
rig that survives: its Section 3.3 coefficients.  Applied to the simulated
rig's pressures they must give the true angles and forces within a factor of
1.5 (:mod:`labcli.papers.takuma2014.sim.paper_scale` measures it): the angle coefficients fix
the pressure change per radian (Boyle's ``beta`` with the dead volume), the
force coefficients the pressure change per newton, i.e. the joint stiffness
at that ``beta``.  Ordinary hand-made muscles, 13 mm across outside and 9 mm
inside (thicker than the earlier 6 mm ones, to be stiff enough):

=========  ========  =========  ========  =======  =========  ==========  =========
actuator   length    braid ang  diameter  b        n (turns)  pretension  beta
=========  ========  =========  ========  =======  =========  ==========  =========
outside    0.220 m   41 deg     13 mm     0.292 m  4.68       69.1 N      -0.202 m
inside     0.220 m   41 deg     9 mm      0.292 m  6.76       34.9 N      -0.191 m
=========  ========  =========  ========  =======  =========  ==========  =========

Rubber: k_rubber = 700 N/m (a latex tube of that size) with a rest length 5 mm
below the mounting length, so a vented rig stays taut.  Dead volume (tubing,
fittings and the sensor) 15 mL per outside chamber (29 mL of actuator) and
6 mL per inside one (14 mL of actuator).  The thinner inside pair leaves joint
2 soft enough that the heavier loads bend it past 3 deg, where the force along
the arm (Fy) becomes observable (det J = h2 h3 sin theta2), with the pressure
change per radian of theta2 on the scale of the paper's theta2 coefficients.
0.1 rad at joint 1 changes the outside pressures by about 5 % of gauge (the
paper's sin(theta1) = 0.136 u_L1 - 1.587 u_R1 implies about 6 %).
Supplying the inside pair unequally (L2 0.40, R2 0.20 MPa) bends the rest
posture to theta2 = 12.4 deg.  ``THIN_MUSCLES`` keeps the earlier tuning (6 mm
muscles, 0.6-13 deg for 50-1000 g, about 9 times the paper's pressure change
per newton).

Resulting closed-valve joint stiffness about theta = 0 (N m/rad):
``[[32.86, 3.94], [3.94, 3.94]]``.  Tip loads (symmetric rig, valves closed;
angles in deg, pressure changes in % of gauge, L1 R1 L2 R2)::

    mass  dir     theta1  theta2   dP_L1  dP_R1  dP_L2  dP_R2
      50 g   0     -0.13   -0.34   +0.11  -0.11  +0.20  -0.20
     200 g  45     -0.35   -0.93   +0.31  -0.31  +0.56  -0.54
     500 g   0     -1.26   -3.36   +1.12  -1.06  +2.07  -1.89
     500 g 135     +0.88   +2.22   -0.75  +0.78  -1.29  +1.37
    1000 g   0     -2.52   -6.68   +2.30  -2.07  +4.31  -3.59
    1000 g -45     -1.84   -5.53   +1.65  -1.53  +3.39  -2.93
    1000 g  90      0.00    0.00    0.00   0.00   0.00   0.00

A force along the straight arm (90 or -90 deg) produces no torque on the
symmetric rig; on a varied rig its baseline is slightly bent and it does.

Actuator-to-actuator variation (:func:`varied_params`): each actuator gets its
own b (0.2 %), n (0.5 %), k_rubber (8 %), rubber rest length (1 mm), dead
volume (8 %) and a mounting error (0.4 mm) from a seeded generator.  The
mounting lengths are those at which the *nominal* actuator carries the design
pretension, so the real ones carry slightly different tensions and the
baseline posture (valves open, no load) settles where the pairs balance:
about 0.3 deg rms from zero at joint 1 and 0.9 deg rms at joint 2 (the inside
pair acts on the short moment arm r2).

Limits: tendons are assumed taut (tension may go negative on a vented rig
under load, where a real tendon would go slack); isothermal air.  The links'
weight is here (``RigParams.link_mass_kg``, zero by default); friction, leak,
heat and backlash live in the simulated rig (:mod:`.nonideal`).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

P_ATM = 101_325.0  # Pa
G = 9.80665  # m/s^2
ACTUATORS = ("L1", "R1", "L2", "R2")
_SIDE = np.array([-1.0, 1.0, -1.0, 1.0])  # L = -1, R = +1


@dataclass(frozen=True)
class Geometry:
    """Link lengths and moment arms of the test bed, m (paper Section 3.1)."""

    h1: float = 0.355
    h2: float = 0.130
    h3: float = 0.065
    r1: float = 0.075
    r2: float = 0.035


@dataclass(frozen=True)
class RigParams:
    """Geometry plus the four actuators (arrays in order L1, R1, L2, R2).

    ``L_mount`` is each actuator's length at ``theta = (0, 0)``; at any other
    posture it is ``L_mount + s(theta) - s(0)``.
    """

    geometry: Geometry = field(default_factory=Geometry)
    b: np.ndarray = field(default_factory=lambda: np.zeros(4))  # thread length, m
    n: np.ndarray = field(default_factory=lambda: np.ones(4))  # braid turns
    k_rubber: np.ndarray = field(default_factory=lambda: np.zeros(4))  # N/m
    L_rubber: np.ndarray = field(default_factory=lambda: np.zeros(4))  # m
    L_mount: np.ndarray = field(default_factory=lambda: np.zeros(4))  # m
    V_dead: np.ndarray = field(default_factory=lambda: np.zeros(4))  # m^3
    supply_pa: np.ndarray = field(default_factory=lambda: np.full(4, 0.30e6))  # gauge
    link_mass_kg: np.ndarray = field(default_factory=lambda: np.zeros(2))  # links 1, 2; centre of mass mid-link

    def to_dict(self) -> dict:
        """Plain-data form (JSON-serialisable)."""
        out: dict[str, Any] = {"geometry": vars(self.geometry).copy()}
        for k in ("b", "n", "k_rubber", "L_rubber", "L_mount", "V_dead", "supply_pa", "link_mass_kg"):
            out[k] = [float(v) for v in getattr(self, k)]
        return out


# ---------------------------------------------------------------- geometry


# The six straight tendon pieces, one per joint an actuator crosses:
# L1, R1 over joint 1 (arm r1); L2, R2 over joint 1 (arm r2); L2, R2 over joint 2 (arm r2).
_PIECE_SIDE = np.array([-1.0, 1.0, -1.0, 1.0, -1.0, 1.0])
_PIECE_JOINT = [0, 0, 0, 0, 1, 1]


def _pieces(theta, geom: Geometry, derivative: bool = False):
    """Lengths of the six tendon pieces ``(..., 6)`` (m), with ``d length / d (own joint angle)`` (m/rad).

    A piece leaves its joint at ``r`` beside the axis and runs a height ``h`` to
    the next: ``sqrt((h + side r sin t)^2 + (r - r cos t)^2)``.
    """
    theta = np.asarray(theta, dtype=float)
    t = theta[..., _PIECE_JOINT]
    h = np.array([geom.h1] * 4 + [geom.h2] * 2)
    r = np.array([geom.r1] * 2 + [geom.r2] * 4)
    sin, cos = np.sin(t), np.cos(t)
    a = h + _PIECE_SIDE * r * sin
    c = r - r * cos
    length = np.sqrt(a * a + c * c)
    if not derivative:
        return length, None
    return length, (a * _PIECE_SIDE * r * cos + c * r * sin) / length


def _paths(theta, geom: Geometry, gradients: bool = True):
    """Path lengths ``(..., 4)`` and, with ``gradients``, ``d s / d theta`` ``(..., 4, 2)``, from one pass.

    L1 and R1 are one piece each; L2 and R2 add their piece over joint 2.
    """
    length, d = _pieces(theta, geom, gradients)
    s = length[..., :4].copy()
    s[..., 2:] += length[..., 4:]
    if not gradients:
        return s, None
    grad = np.zeros(d.shape[:-1] + (4, 2))
    grad[..., 0] = d[..., :4]
    grad[..., 2:, 1] = d[..., 4:]
    return s, grad


def path_lengths(theta, geom: Geometry) -> np.ndarray:
    """Exact tendon path lengths ``(..., 4)`` in order L1, R1, L2, R2 (m)."""
    return _paths(theta, geom, gradients=False)[0]


def path_gradients(theta, geom: Geometry) -> np.ndarray:
    """Exact ``d s_ij / d theta`` as ``(..., 4, 2)`` (m/rad)."""
    return _paths(theta, geom)[1]


def rest_paths(geom: Geometry) -> np.ndarray:
    """Path lengths at ``theta = 0``: ``h1, h1, h1 + h2, h1 + h2``."""
    return np.array([geom.h1, geom.h1, geom.h1 + geom.h2, geom.h1 + geom.h2])


def contact_point(theta, geom: Geometry) -> np.ndarray:
    """Tip contact point ``C (..., 2)`` (m), origin at the bottom joint."""
    theta = np.asarray(theta, dtype=float)
    t1, t2 = theta[..., 0], theta[..., 1]
    return np.stack(
        [
            -geom.h2 * np.sin(t1) - geom.h3 * np.sin(t1 + t2),
            geom.h2 * np.cos(t1) + geom.h3 * np.cos(t1 + t2),
        ],
        axis=-1,
    )


def jacobian(theta, geom: Geometry) -> np.ndarray:
    """``J = dC/dtheta (..., 2, 2)`` as printed in Section 2.2.2."""
    theta = np.asarray(theta, dtype=float)
    t1, t2 = theta[..., 0], theta[..., 1]
    c1, s1 = np.cos(t1), np.sin(t1)
    c12, s12 = np.cos(t1 + t2), np.sin(t1 + t2)
    h2, h3 = geom.h2, geom.h3
    row0 = np.stack([-h2 * c1 - h3 * c12, -h3 * c12], axis=-1)
    row1 = np.stack([-h2 * s1 - h3 * s12, -h3 * s12], axis=-1)
    return np.stack([row0, row1], axis=-2)


def _jacobian_transpose_times(theta, geom: Geometry, F) -> np.ndarray:
    """``J(theta)^T F`` (..., 2) without building ``J`` (:func:`jacobian`): the load's generalised force (N m)."""
    theta = np.asarray(theta, dtype=float)
    t1, t2 = theta[..., 0], theta[..., 1]
    c1, s1 = np.cos(t1), np.sin(t1)
    c12, s12 = np.cos(t1 + t2), np.sin(t1 + t2)
    h2, h3 = geom.h2, geom.h3
    Fx, Fy = F[..., 0], F[..., 1]
    return np.stack(
        [(-h2 * c1 - h3 * c12) * Fx + (-h2 * s1 - h3 * s12) * Fy, (-h3 * c12) * Fx + (-h3 * s12) * Fy], axis=-1
    )


def actuator_lengths(theta, params: RigParams) -> np.ndarray:
    """Actuator lengths ``(..., 4)`` (m): mounting length plus the path change."""
    return params.L_mount + path_lengths(theta, params.geometry) - rest_paths(params.geometry)


# ---------------------------------------------------------------- actuator


def mckibben_volume(L, b, n):
    """Chamber volume of a McKibben actuator, ``L (b^2 - L^2) / (4 pi n^2)`` (m^3)."""
    L = np.asarray(L, dtype=float)
    return L * (b * b - L * L) / (4.0 * np.pi * n * n)


def mckibben_dvolume(L, b, n):
    """``dV/dL = (b^2 - 3 L^2) / (4 pi n^2)`` (m^2); negative below 54.7 deg."""
    L = np.asarray(L, dtype=float)
    return (b * b - 3.0 * L * L) / (4.0 * np.pi * n * n)


def mckibben_tension(L, p_gauge_pa, b, n, k_rubber, L_rubber):
    """Tension (N): ``P (3 L^2 - b^2) / (4 pi n^2) + k_rubber (L - L_rubber)``."""
    return -np.asarray(p_gauge_pa) * mckibben_dvolume(L, b, n) + k_rubber * (np.asarray(L) - L_rubber)


def braid_angle(L, b):
    """Braid angle (rad) between thread and actuator axis, ``acos(L / b)``."""
    return np.arccos(np.asarray(L) / b)


def boyle_beta(L, params: RigParams) -> np.ndarray:
    """Linearised Boyle coefficient ``beta = (V + V_dead) / V'(L)`` (m).

    Eq. 29 in absolute pressure with the dead volume: ``dl ~= beta (P0/P - 1)``.
    With ``V_dead = 0`` this is the paper's ``(l L^2 - l^3) / (L^2 - 3 l^2)``.
    """
    V = mckibben_volume(L, params.b, params.n)
    return (V + params.V_dead) / mckibben_dvolume(L, params.b, params.n)


# ---------------------------------------------------------------- chambers


@dataclass(frozen=True)
class Chambers:
    """Valve state: ``open`` holds ``gauge_pa``; ``closed`` keeps ``amount`` = P_abs (V + V_dead);
    ``mixed`` does the one for the chambers ``held`` and the other for the rest."""

    state: str  # "open" | "closed" | "mixed"
    gauge_pa: np.ndarray | None = None
    amount: np.ndarray | None = None  # Pa m^3 (absolute)
    held: np.ndarray | None = None  # (4,) bool, mixed only

    @staticmethod
    def mixed(held, gauge_pa, amount) -> Chambers:
        """Chambers ``held`` keep their ``amount``, the others hold ``gauge_pa`` (open or closed when all agree)."""
        held = np.asarray(held, bool)
        if not held.any():
            return Chambers.open(gauge_pa)
        if held.all():
            return Chambers("closed", amount=np.asarray(amount, float).copy())
        return Chambers(
            "mixed",
            gauge_pa=np.where(held, 0.0, gauge_pa),
            amount=np.where(held, amount, 0.0),
            held=held.copy(),
        )

    @staticmethod
    def open(gauge_pa) -> Chambers:
        return Chambers("open", gauge_pa=np.broadcast_to(np.asarray(gauge_pa, float), (4,)).copy())

    @staticmethod
    def closed_at(lengths, gauge_pa, params: RigParams) -> Chambers:
        """Close the valves with the actuators at ``lengths`` and pressures ``gauge_pa``."""
        V = mckibben_volume(lengths, params.b, params.n)
        return Chambers("closed", amount=(np.asarray(gauge_pa, float) + P_ATM) * (V + params.V_dead))

    @property
    def held_mask(self) -> np.ndarray:
        """Which chambers keep their air, (4,) bool."""
        if self.state == "mixed":
            return np.asarray(self.held, bool)
        return np.full(4, self.state == "closed")

    def gauge(self, lengths, params: RigParams) -> np.ndarray:
        """Gauge pressures (Pa) at the given actuator lengths (``(..., 4)``)."""
        if self.state == "open":
            return np.broadcast_to(np.asarray(self.gauge_pa), np.shape(lengths)).astype(float)
        V = mckibben_volume(lengths, params.b, params.n)
        closed = np.asarray(self.amount) / (V + params.V_dead) - P_ATM
        return closed if self.state == "closed" else np.where(self.held_mask, closed, np.asarray(self.gauge_pa))


# ---------------------------------------------------------------- loads


@dataclass(frozen=True)
class NoLoad:
    def force(self, theta, geom: Geometry) -> np.ndarray:
        return np.zeros(np.shape(theta)[:-1] + (2,))


@dataclass(frozen=True)
class Weight:
    """A weight on a pulley: constant force ``m g (cos dir, sin dir)`` at the tip.

    ``loss``: the share of the pull the pulley's friction holds back.  The weight settles
    downwards as the arm yields to it, so the friction acts against its descent and the tip
    feels ``(1 - loss) m g``.
    """

    mass_kg: float
    direction_rad: float
    loss: float = 0.0

    def force(self, theta, geom: Geometry) -> np.ndarray:
        pull = self.mass_kg * G if not self.loss else self.mass_kg * G * (1.0 - self.loss)
        f = pull * np.array([np.cos(self.direction_rad), np.sin(self.direction_rad)])
        return np.broadcast_to(f, np.shape(theta)[:-1] + (2,)).copy()


@dataclass(frozen=True)
class Push:
    """Section 4's cylinder (radius R, radial springs k_o) pushed d along phi.

    Before the push it just touches the tip at ``touch`` (the paper's
    ``C0 = (0, h2 + h3)`` when the baseline posture is straight) with its centre
    at ``touch + (R, 0)``; pushed, the centre is ``O2 = O1 - d (cos phi, sin phi)``
    (Eq. 39).  The tip feels ``k_o (R - |O2 C|) unit(C - O2)`` while it is inside.

    ``friction_mu`` adds Coulomb friction at the contact: the tip slips over the surface by
    ``s`` (its displacement from the surface point it first touched, which moves with the
    object, along the surface's tangent), and the surface drags it back with
    ``mu N tanh(k_t s / (mu N))``, ``N`` the normal force: stuck (a tangential spring ``k_t``)
    for small slips, sliding at ``mu N`` beyond.  ``k_t`` is ``tangential_ratio`` times ``k_o``.
    The force on the tip is then not along the radius, which Eq. 38 assumes.
    """

    radius_m: float
    distance_m: float
    phi_rad: float
    stiffness_N_per_m: float
    touch: tuple[float, float] | None = None
    friction_mu: float = 0.0
    tangential_ratio: float = 1.0

    def center(self, geom: Geometry) -> np.ndarray:
        c0 = np.array(self.touch if self.touch is not None else (0.0, geom.h2 + geom.h3))
        return (
            c0
            + np.array([self.radius_m, 0.0])
            - self.distance_m * np.array([np.cos(self.phi_rad), np.sin(self.phi_rad)])
        )

    def force(self, theta, geom: Geometry) -> np.ndarray:
        c = contact_point(theta, geom)
        v = c - self.center(geom)
        dist = np.linalg.norm(v, axis=-1, keepdims=True)
        depth = np.clip(self.radius_m - dist, 0.0, None)
        with np.errstate(invalid="ignore", divide="ignore"):
            f = self.stiffness_N_per_m * depth * v / dist
            if self.friction_mu:
                f = f + self._drag(c, v / dist, self.stiffness_N_per_m * depth, geom)
        return np.where(depth > 0, f, 0.0)

    def _drag(self, c: np.ndarray, n: np.ndarray, normal: np.ndarray, geom: Geometry) -> np.ndarray:
        """The contact's friction on the tip at ``c`` (..., 2): unit normal ``n``, normal force ``normal``."""
        t = np.stack([-n[..., 1], n[..., 0]], axis=-1)  # the surface's tangent
        # The surface point the tip first touched, carried along with the object (O1 -> O2).
        first = self.center(geom) - np.array([self.radius_m, 0.0])
        slip = np.sum((c - first) * t, axis=-1, keepdims=True)
        limit = self.friction_mu * normal
        k_t = self.tangential_ratio * self.stiffness_N_per_m
        return -limit * np.tanh(k_t * slip / np.maximum(limit, 1e-12)) * t


# ---------------------------------------------------------------- statics


def link_weight_torques(theta, geom: Geometry, link_mass_kg) -> np.ndarray:
    """Generalised force of the links' own weight (N m), ``(..., 2)``; centres of mass mid-link.

    ``Q_k = -sum_links m g d(y_com)/d(theta_k)``: zero on the upright arm and
    growing with ``sin``, so the links act as an inverted pendulum (negative stiffness).
    """
    theta = np.asarray(theta, dtype=float)
    t1, t12 = theta[..., 0], theta[..., 0] + theta[..., 1]
    m1, m2 = np.asarray(link_mass_kg, dtype=float)
    c1, c2 = 0.5 * geom.h2, 0.5 * geom.h3
    q2 = m2 * G * c2 * np.sin(t12)
    q1 = m1 * G * c1 * np.sin(t1) + m2 * G * geom.h2 * np.sin(t1) + q2
    return np.stack([q1, q2], axis=-1)


def generalised_forces(theta, params: RigParams, chambers: Chambers, load, extra_tension_N=None) -> np.ndarray:
    """Residual of virtual work ``J^T F - sum T grad s`` (N m), shape ``(..., 2)``.

    The links' weight enters when ``params.link_mass_kg`` is non-zero;
    ``extra_tension_N`` (4,) adds to each actuator's tension, e.g. sleeve
    friction (:mod:`.nonideal`).
    """
    theta = np.asarray(theta, dtype=float)
    geom = params.geometry
    s, grad = _paths(theta, geom)  # (..., 4), (..., 4, 2)
    L = params.L_mount + s - rest_paths(geom)  # actuator_lengths
    p = chambers.gauge(L, params)
    T = mckibben_tension(L, p, params.b, params.n, params.k_rubber, params.L_rubber)
    if extra_tension_N is not None:
        T = T + extra_tension_N
    load_q = _jacobian_transpose_times(theta, geom, load.force(theta, geom))  # J^T F
    r = load_q - np.einsum("...i,...ij->...j", T, grad)
    if np.any(params.link_mass_kg):
        r = r + link_weight_torques(theta, geom, params.link_mass_kg)
    return r


@dataclass(frozen=True)
class Equilibrium:
    """A solved static posture; pressures are MPa gauge, force at the contact point."""

    theta_rad: np.ndarray  # (2,)
    pressures_MPa: np.ndarray  # (4,) gauge, L1 R1 L2 R2
    force_N: np.ndarray  # (2,)
    tensions_N: np.ndarray  # (4,)
    lengths_m: np.ndarray  # (4,)
    residual_Nm: float  # max |virtual-work residual|
    stable: bool  # stiffness matrix positive definite


# Where one Newton step evaluates the residual: theta itself, then theta +- h along
# each joint for the central differences of the stiffness.
_STENCIL = np.array([[0.0, 0.0], [1.0, 0.0], [-1.0, 0.0], [0.0, 1.0], [0.0, -1.0]])


def _residual_and_stiffness(
    theta, params: RigParams, chambers: Chambers, load, extra_tension_N=None, h: float = 1e-6
) -> tuple[np.ndarray, np.ndarray]:
    """The residual (2,) and ``K = -d(residual)/d theta`` (2, 2) at ``theta``, from one batch.

    The five postures go through :func:`generalised_forces` together (every
    term broadcasts over leading axes): a Newton step costs one call, not five.
    """
    r = generalised_forces(np.asarray(theta, dtype=float) + h * _STENCIL, params, chambers, load, extra_tension_N)
    return r[0], -np.stack([r[1] - r[2], r[3] - r[4]], axis=-1) / (2 * h)


def stiffness_matrix(
    theta, params: RigParams, chambers: Chambers, load, h: float = 1e-6, extra_tension_N=None
) -> np.ndarray:
    """``K = -d(residual)/d theta`` by central differences (N m/rad)."""
    return _residual_and_stiffness(theta, params, chambers, load, extra_tension_N, h)[1]


def solve_equilibrium(
    params: RigParams,
    chambers: Chambers,
    load=None,
    theta0: Sequence[float] | np.ndarray | None = None,
    tol: float = 1e-10,
    extra_tension_N=None,
) -> Equilibrium:
    """Static equilibrium posture under ``load`` (None: unloaded).

    ``extra_tension_N`` (4,) adds to the actuators' tensions (see :func:`generalised_forces`).
    Raises ``ValueError`` if no equilibrium with a residual below ``tol`` (N m)
    is found, e.g. for a load far beyond the rig's range.
    """
    load = NoLoad() if load is None else load
    x0 = np.zeros(2) if theta0 is None else np.asarray(theta0, dtype=float)

    best = None
    # Damped Newton from the start posture; heavy loads are applied in steps
    # (continuation) so the solve stays on the physical branch.
    for steps in (1, 4, 16):
        x = x0.copy()
        for k in range(1, steps + 1):
            x, res, K = _newton(params, chambers, _scaled(load, k / steps), x, tol, extra_tension_N)
            if not np.all(np.isfinite(x)) or np.max(np.abs(x)) > 1.5:
                break
        else:
            if best is None or res < best[1]:
                best = (x, res, K)
            if res < tol:
                break
    if best is None or best[1] >= tol:
        raise ValueError("no static equilibrium found for this load (is it beyond the rig's range?)")
    x, res, K = best
    L = actuator_lengths(x, params)
    p = chambers.gauge(L, params)
    T = mckibben_tension(L, p, params.b, params.n, params.k_rubber, params.L_rubber)
    stable = bool(np.all(np.linalg.eigvalsh(0.5 * (K + K.T)) > 0))
    return Equilibrium(
        theta_rad=x,
        pressures_MPa=p / 1e6,
        force_N=load.force(x, params.geometry),
        tensions_N=T,
        lengths_m=L,
        residual_Nm=res,
        stable=stable,
    )


def _newton(params, chambers, load, x, tol: float, extra_tension_N=None, iters: int = 80):
    """Damped Newton on the virtual-work residual; returns (theta, max |residual|, stiffness there).

    A full step gets the residual and the stiffness at the new posture from
    one batch; a step that must be shortened tries the residual alone.
    """
    r, K = _residual_and_stiffness(x, params, chambers, load, extra_tension_N)
    nr = float(np.max(np.abs(r)))
    for _ in range(iters):
        if nr < tol * 1e-3:
            break
        try:
            dx = np.linalg.solve(K, r)
        except np.linalg.LinAlgError:
            break
        big = np.max(np.abs(dx))
        if big > 0.2:  # rad: keep steps where the linearisation means something
            dx *= 0.2 / big
        t, xn = 1.0, x + dx
        rn, Kn = _residual_and_stiffness(xn, params, chambers, load, extra_tension_N)
        nn = float(np.max(np.abs(rn)))
        while not nn < nr:  # halve the step until the residual falls (down to 2^-19; NaN never does)
            t *= 0.5
            if t <= 1e-6:
                return x, nr, K
            xn, Kn = x + t * dx, None  # type: ignore[assignment]  # no stiffness at a halved step
            rn = generalised_forces(xn, params, chambers, load, extra_tension_N)
            nn = float(np.max(np.abs(rn)))
        x, r, nr = xn, rn, nn
        K = Kn if Kn is not None else stiffness_matrix(x, params, chambers, load, extra_tension_N=extra_tension_N)
    return x, nr, K


def _scaled(load, s: float):
    if s == 1.0 or isinstance(load, NoLoad):
        return load
    if isinstance(load, Weight):
        return replace(load, mass_kg=load.mass_kg * s)
    if isinstance(load, Push):
        return replace(load, distance_m=load.distance_m * s)
    return load


# ---------------------------------------------------------------- parameters

SUPPLY_MPA = 0.30


@dataclass(frozen=True)
class Design:
    """The design actuators: per pair j (1 outside, 2 inside) length at the
    baseline posture (m), braid angle (deg) and diameter (m); rubber, dead volume."""

    pairs: dict  # j -> (length m, braid angle deg, diameter m)
    k_rubber: float  # N/m
    rubber_prestretch: float  # m below the mounting length
    v_dead: tuple  # m^3 per chamber, pairs 1 and 2


# The default: the paper's test bed (see the module docstring for the figures used).
PAPER_SCALE = Design(
    pairs={1: (0.220, 41.0, 0.013), 2: (0.220, 41.0, 0.009)},
    k_rubber=700.0,
    rubber_prestretch=0.005,
    v_dead=(15.0e-6, 6.0e-6),
)
# The tuning before the paper-scale retune: thin, soft muscles (0.6-13 deg for 50-1000 g).
# Kept so that runs recorded on it (``sim://?design=thin&ideal=1&flow=lag``) can be reproduced.
THIN_MUSCLES = Design(
    pairs={1: (0.220, 41.0, 0.006), 2: (0.220, 37.0, 0.006)},
    k_rubber=100.0,
    rubber_prestretch=0.005,
    v_dead=(3.0e-6, 3.0e-6),
)
DESIGNS = {"paper": PAPER_SCALE, "thin": THIN_MUSCLES}


def supply_array(supply_MPa) -> np.ndarray:
    """One supply pressure or four (L1, R1, L2, R2), MPa gauge, as four gauge Pa."""
    return np.broadcast_to(np.asarray(supply_MPa, dtype=float) * 1e6, (4,)).copy()


def nominal_params(
    geometry: Geometry | None = None, supply_MPa=SUPPLY_MPA, design: Design | str = PAPER_SCALE
) -> RigParams:
    """The symmetric design rig (no actuator-to-actuator variation).

    ``supply_MPa`` is one gauge pressure or four (L1, R1, L2, R2); ``design`` a
    :class:`Design` or a key of :data:`DESIGNS`.
    """
    geom = geometry or Geometry()
    d = DESIGNS[design] if isinstance(design, str) else design
    b, n, L0 = np.empty(4), np.empty(4), np.empty(4)
    for i, j in enumerate((1, 1, 2, 2)):
        L, alpha, D = d.pairs[j]
        a = np.radians(alpha)
        b[i] = L / np.cos(a)
        n[i] = L * np.tan(a) / (np.pi * D)
        L0[i] = L
    return RigParams(
        geometry=geom,
        b=b,
        n=n,
        k_rubber=np.full(4, d.k_rubber),
        L_rubber=L0 - d.rubber_prestretch,
        L_mount=L0,
        V_dead=np.repeat(np.asarray(d.v_dead, dtype=float), 2),
        supply_pa=supply_array(supply_MPa),
    )


def varied_params(
    seed: int, geometry: Geometry | None = None, supply_MPa=SUPPLY_MPA, design: Design | str = PAPER_SCALE
) -> RigParams:
    """A hand-built rig: each actuator differs from the design by a few percent.

    Mounting lengths are the nominal ones (where the design actuator carries
    its pretension) plus a sub-millimetre mounting error, so the real
    actuators carry slightly different pretensions.
    """
    nom = nominal_params(geometry, supply_MPa, design)
    rng = np.random.default_rng([int(seed), 0x4D4B])
    return replace(
        nom,
        b=nom.b * (1 + 0.002 * rng.standard_normal(4)),
        n=nom.n * (1 + 0.005 * rng.standard_normal(4)),
        k_rubber=nom.k_rubber * (1 + 0.08 * rng.standard_normal(4)),
        L_rubber=nom.L_rubber + 0.001 * rng.standard_normal(4),
        L_mount=nom.L_mount + 0.0004 * rng.standard_normal(4),
        V_dead=nom.V_dead * (1 + 0.08 * rng.standard_normal(4)),
    )
