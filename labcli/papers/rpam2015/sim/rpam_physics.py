"""Physics of the simulated rPAM stand, written apart from the model it is used to check.

:mod:`labcli.papers.rpam2015.models.rpam` derives the actuator's force from a potential
(strain energy of the wall plus the gas's virtual work,
:mod:`labcli.papers.rpam2015.models.rpam_force`) and the joint's torque from Eq. 5's
moment arms.  The stand computes the same physics another way, so a
slip in either shows up as a disagreement (the tests compare the two):

* the actuator's force from the **Cauchy stresses** of the thick incompressible Ogden wall,
  integrated over its *current* radius, and the **statics of the thread cage**;
* the joint's torque as the **cross product** of each upper mount's position with the push
  along the actuator, from the mount coordinates of Table I.

Force balance of an end cap (tension F positive)
    The wall ring at current radius r (rest radius R, ``R^2 = R_o^2 - lambda (r_o^2 - r^2)``
    by incompressibility) has principal stretches ``lambda`` (axial), ``r / R`` (hoop) and
    ``R / (lambda r)`` (radial), and Cauchy stresses ``sigma_k = t_k - p`` with
    ``t_k = sum 2 mu_i / alpha_i * lambda_k^alpha_i`` (Eq. 3's Ogden convention) and p the
    pressure that incompressibility leaves free.  Radial equilibrium,
    ``d sigma_r / dr = (t_hoop - t_rad) / r``, from ``sigma_r = -P`` at the lumen gives the
    contact pressure on the thread, ``p_c = P - int (t_hoop - t_rad) / r dr``.  The wall's
    axial resultant, integrated by parts, is ``pi int (2 t_ax - t_hoop - t_rad) r dr -
    pi p_c r_o^2 + pi P r_i^2``.  The thread (inextensible, n turns of length b) carries the
    hoop load ``p_c r_o`` per unit length; the virtual work of its lateral surface gives its
    axial pull ``p_c L^2 / (2 pi n^2)``.  The gas pushes the cap over the lumen, ``P pi r_i^2``.
    So

        F = pi int (2 t_ax - t_hoop - t_rad) r dr - pi p_c r_o^2 + p_c L^2 / (2 pi n^2),

    with ``r_o`` the cage radius while ``p_c >= 0``; below that the cage is slack and r_o is
    where ``p_c = 0``.  The empirical stretch force (Eq. 7) is added on top, never clamped.

The paper's reading (an actuator whose ``force_reading`` is ``"paper"``)
    A stand whose actuators follow the paper's lumen free body, so that a model built on the
    derived force can be checked against a stand it was not built on (and the paper's model
    against one it was).  Its forces are summed here term by term on the cut through the
    lumen, not taken from the paper reading's potential as the model does: the gas pushes the
    end cap over the lumen, ``-P (pi r_c^2 - A0 / lambda)`` (the wall's section at stretch
    lambda is ``A0 / lambda``); the thread carries the whole hoop load ``P r_c`` per unit
    length and pulls ``P L^2 / (2 pi n^2)``; the wall adds its uniaxial Cauchy stress
    ``sum 2 mu_i / alpha_i (lambda^alpha_i - lambda^(-alpha_i / 2))`` over its current section
    ``A0 / lambda``.  The cage holds at every pressure (the paper's model has no slack branch).

Units: SI, pressures in MPa (gauge) as at the regulators.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..actuator import Actuator
from ..protocol import load_rpam

G_N_PER_KG = 9.80665
_MPA = 1e6
_NODES, _WEIGHTS = np.polynomial.legendre.leggauss(16)
_BISECTIONS = 60


def cage_radius(act: Actuator, L: Any) -> np.ndarray:
    """Radius (m) of n turns of the thread wound round a cylinder of length L."""
    L = np.asarray(L, dtype=float)
    return np.sqrt(act.thread_length_m**2 - L**2) / (2 * math.pi * act.n_turns)


def rest_radii(act: Actuator) -> tuple[float, float]:
    """(inner, outer) radius of the wall at rest (m); the outer one fills the cage."""
    Ro = float(cage_radius(act, act.L0_m))
    return math.sqrt(Ro**2 - act.A0_m2 / math.pi), Ro


def _t(act: Actuator, stretch: np.ndarray) -> np.ndarray:
    """``sum 2 mu_i / alpha_i * stretch^alpha_i`` in Pa (the Ogden stress without p)."""
    total = np.zeros(np.shape(stretch))
    for mu, a in zip(act.ogden_mu_MPa, act.ogden_alpha, strict=True):
        total = total + 2 * mu * _MPA / a * stretch**a
    return total


def _integrals(act: Actuator, L: np.ndarray, r_o: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(pi int (2 t_ax - t_hoop - t_rad) r dr, int (t_hoop - t_rad) / r dr)`` over the wall."""
    Ri, Ro = rest_radii(act)
    lam = (L / act.L0_m)[..., None]
    r_o = r_o[..., None]
    r_i = np.sqrt(np.clip(r_o**2 - (Ro**2 - Ri**2) / lam, 0.0, None))
    r = 0.5 * (r_o + r_i) + 0.5 * (r_o - r_i) * _NODES
    dr = 0.5 * (r_o - r_i) * _WEIGHTS
    R = np.sqrt(Ro**2 - lam * (r_o**2 - r**2))
    hoop = r / R
    t_ax, t_hoop, t_rad = _t(act, lam), _t(act, hoop), _t(act, 1.0 / (lam * hoop))
    axial = math.pi * np.sum((2 * t_ax - t_hoop - t_rad) * r * dr, axis=-1)
    radial = np.sum((t_hoop - t_rad) / r * dr, axis=-1)
    return axial, radial


def tension(act: Actuator, P_MPa: Any, L: Any) -> np.ndarray:
    """Load (N, tension +) that holds the actuator at length L under gauge pressure P.

    Its stretch force is the cubic of ``act.stretch_coefficients_N`` at every stretch: the
    stand's correction is the truth, which no fit range limits.
    """
    P, L = (np.array(v, dtype=float) for v in np.broadcast_arrays(np.asarray(P_MPa, float), np.asarray(L, float)))
    P = P * _MPA
    r_c = cage_radius(act, L)
    lam = L / act.L0_m
    if act.force_reading == "paper":
        return _lumen_free_body(act, P, L, r_c) + np.polynomial.polynomial.polyval(lam, act.stretch_coefficients_N)
    axial, radial = _integrals(act, L, r_c)
    p_c = P - radial
    F = np.array(axial - math.pi * p_c * r_c**2 + p_c * L**2 / (2 * math.pi * act.n_turns**2), dtype=float)
    slack = p_c < 0
    if slack.any():
        F[slack] = _free_tension(act, P[slack], L[slack], r_c[slack])
    return F + np.polynomial.polynomial.polyval(lam, act.stretch_coefficients_N)


def _lumen_free_body(act: Actuator, P: np.ndarray, L: np.ndarray, r_c: np.ndarray) -> np.ndarray:
    """The paper's reading: end cap on the lumen + the thread's pull + the uniaxial wall (N, P in Pa)."""
    lam = L / act.L0_m
    wall_section = act.A0_m2 / lam
    end_cap = -P * (math.pi * r_c**2 - wall_section)
    thread = P * L**2 / (2 * math.pi * act.n_turns**2)
    stress = _t(act, lam) - _t(act, lam**-0.5)  # uniaxial: the lateral stretches are 1 / sqrt(lambda)
    return np.asarray(end_cap + thread + stress * wall_section, dtype=float)


def _free_tension(act: Actuator, P: np.ndarray, L: np.ndarray, r_c: np.ndarray) -> np.ndarray:
    # The slack cage: the tube inflates until its outer surface is free (p_c = 0),
    # between the unloaded tube's radius R_o / sqrt(lambda) and the cage.
    # Vented, it is the unloaded tube's radius itself (t_hoop = t_rad throughout).
    _, Ro = rest_radii(act)
    lo = Ro / np.sqrt(L / act.L0_m)
    hi = np.where(P > 0, r_c, lo)
    for _ in range(_BISECTIONS if np.any(P > 0) else 0):
        mid = 0.5 * (lo + hi)
        inflated = _integrals(act, L, mid)[1] > P  # p_c < 0: smaller than that
        lo, hi = np.where(inflated, lo, mid), np.where(inflated, mid, hi)
    return _integrals(act, L, 0.5 * (lo + hi))[0]


def push(act: Actuator, P_MPa: Any, L: Any) -> np.ndarray:
    """Force (N) the actuator exerts on its mounts, positive when it pushes them apart."""
    return -tension(act, P_MPa, L)


def hanging_length(act: Actuator, P_MPa: float, load_N: float) -> float:
    """Length (m) at which the actuator carries ``load_N`` under P; NaN when it cannot."""
    from scipy.optimize import brentq

    Ri, Ro = rest_radii(act)
    # Shortened, the wall thickens until it fills the cage; stay clear of that.
    lo = act.L0_m * max(0.5, 1.05 * (1 - (Ri / Ro) ** 2))
    hi = 4.0 * act.L0_m

    def f(L: float) -> float:
        return float(tension(act, P_MPa, L)) - load_N

    if f(lo) > 0 or f(hi) < 0:
        return float("nan")
    return float(brentq(f, lo, hi, xtol=1e-13))


@dataclass(frozen=True)
class Links:
    """The joint's links (Fig. 4): lower mounts at (-L1, 0), (L1, 0); upper plate at L2, mounts L3 apart."""

    L1_m: float
    L2_m: float
    L3_m: float

    @property
    def toggle_rad(self) -> float:
        """Where b's upper mount lines up with its lower mount and the pivot."""
        return math.atan2(self.L2_m, self.L3_m)

    def mounts(self, alpha: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """(a_low, a_up, b_low, b_up), each ``(..., 2)``: the upper plate turned clockwise by alpha."""
        alpha = np.asarray(alpha, dtype=float)
        c, s = np.cos(alpha), np.sin(alpha)

        # The plate's rest points (-L3, L2) and (L3, L2) under the clockwise rotation.
        def turn(x: float, y: float) -> np.ndarray:
            return np.stack([x * c + y * s, -x * s + y * c], axis=-1)

        zero = np.zeros(alpha.shape)
        return (
            np.stack([zero - self.L1_m, zero], axis=-1),
            turn(-self.L3_m, self.L2_m),
            np.stack([zero + self.L1_m, zero], axis=-1),
            turn(self.L3_m, self.L2_m),
        )

    def lengths(self, alpha: Any) -> tuple[np.ndarray, np.ndarray]:
        a_low, a_up, b_low, b_up = self.mounts(alpha)
        return np.linalg.norm(a_up - a_low, axis=-1), np.linalg.norm(b_up - b_low, axis=-1)

    def torque(self, alpha: Any, push_a: Any, push_b: Any) -> np.ndarray:
        """Clockwise torque (N m) on the upper plate about the pivot from the two pushes."""
        a_low, a_up, b_low, b_up = self.mounts(alpha)
        total: Any = 0.0
        for low, up, force in ((a_low, a_up, push_a), (b_low, b_up, push_b)):
            d = up - low
            F = np.asarray(force, dtype=float)[..., None] * d / np.linalg.norm(d, axis=-1, keepdims=True)
            total = total + (up[..., 0] * F[..., 1] - up[..., 1] * F[..., 0])
        return -total  # z-torque is counter-clockwise positive


def read_stand(protocol: str | Path) -> tuple[Links, Actuator]:
    """The stand's links and its nominal actuator from an rPAM protocol (shipped name or path)."""
    settings = load_rpam(protocol).settings
    g = settings.geometry
    return Links(g.L1_m, g.L2_m, g.L3_m), settings.actuator
