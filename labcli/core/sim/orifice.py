"""Compressible flow through a valve's orifice into and out of a chamber (ISO 6358).

A pneumatic valve with its fittings and tubing is characterised by its sonic conductance ``C``
(m^3/(s Pa); catalogues print dm^3/(s bar), 1 dm^3/(s bar) = 1e-8 m^3/(s Pa)) and its critical
pressure ratio ``b``.  The mass flow from an upstream pressure ``p1`` to a downstream ``p2``
(both absolute) is ISO 6358's::

    q_m = C p1 rho0 sqrt(T0 / T1) phi(p2 / p1)
    phi(r) = 1                                     (choked, r <= b)
    phi(r) = sqrt(1 - ((r - b) / (1 - b))^2)       (subsonic, b < r <= 1)

with the standard reference air ``rho0 = 1.185 kg/m^3`` at ``T0 = 293.15 K``.

The chamber's air is isothermal at ``T0``, so its pressure follows ``V dP/dt = R T0 q_m`` and its
volume is held at the value it has when the valve acts (:func:`pressure_at`).  Isothermal because
the rest of the simulated rig is (Boyle's law on the closed chambers, air from the regulator at
the wall's temperature), and because a closed form then exists for the whole transient, which the
rig evaluates at any frame's time without stepping an integrator: with ``k = C R T0 rho0 / V``
(1/s) and ``tau = k t``,

* **filling** (chamber below the source, ``x = P / P_s``): ``dx/dtau = phi(x)``, so ``x`` rises
  linearly while choked (``x <= b``) and then as ``b + (1 - b) sin((tau - tau_b) / (1 - b))``,
  reaching ``P_s`` exactly at ``tau = b + (1 - b) pi / 2`` from ``x = 0``;
* **emptying** (chamber above the sink, ``y = P_s / P``): ``dy/dtau = y phi(y)``, so ``P`` decays
  exponentially while choked and then reaches ``P_s`` in a finite time (:func:`empty_tau`, the
  integral in closed form).

An adiabatic fill would raise the pressure up to 1.4 times faster and then sag as the air cools
(the rig's thermal relaxation is 3 s, :mod:`labcli.papers.takuma2014.sim.nonideal`); for the
simulated rig's small chambers the difference is in how long a supply takes, not where it ends.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np

RHO0 = 1.185  # kg/m^3, ISO 6358 reference air
T0 = 293.15  # K
R_AIR = 287.05  # J/(kg K)
DM3_PER_S_BAR = 1e-8  # m^3/(s Pa) in one dm^3/(s bar), the catalogues' unit of C


@dataclass(frozen=True)
class Orifice:
    """A valve's flow path: sonic conductance ``C_m3_per_s_Pa`` and critical pressure ratio ``b``."""

    C_m3_per_s_Pa: float
    b: float

    def __post_init__(self) -> None:
        if not self.C_m3_per_s_Pa > 0 or not 0 < self.b < 1:
            raise ValueError("an orifice needs a sonic conductance C > 0 and a critical pressure ratio 0 < b < 1")

    def mass_flow(self, p_up, p_down) -> np.ndarray:
        """ISO 6358 mass flow (kg/s) from absolute ``p_up`` to ``p_down`` (Pa); negative when reversed."""
        p_up, p_down = np.asarray(p_up, dtype=float), np.asarray(p_down, dtype=float)
        hi, lo = np.maximum(p_up, p_down), np.minimum(p_up, p_down)
        q = self.C_m3_per_s_Pa * hi * RHO0 * flow_factor(lo / hi, self.b)
        return np.where(p_up >= p_down, q, -q)

    def rate(self, volume_m3) -> np.ndarray:
        """``k = C R T0 rho0 / V`` (1/s): the choked fill's pressure rise per second, as a share of the source."""
        return self.C_m3_per_s_Pa * R_AIR * T0 * RHO0 / np.asarray(volume_m3, dtype=float)


def flow_factor(r, b: float) -> np.ndarray:
    """ISO 6358's ``phi(r)`` for pressure ratios ``r = p_down / p_up`` in 0..1."""
    r = np.clip(np.asarray(r, dtype=float), 0.0, 1.0)
    u = np.clip((r - b) / (1.0 - b), 0.0, 1.0)
    return np.where(r <= b, 1.0, np.sqrt(1.0 - u * u))


def fill_tau(x, b: float) -> np.ndarray:
    """Dimensionless time ``k t`` a chamber filled from ``x = 0`` takes to reach ``x = P / P_s`` (0..1)."""
    x = np.clip(np.asarray(x, dtype=float), 0.0, 1.0)
    return np.where(x <= b, x, b + (1.0 - b) * np.arcsin(np.clip((x - b) / (1.0 - b), 0.0, 1.0)))


def fill_x(tau, b: float) -> np.ndarray:
    """Inverse of :func:`fill_tau`: ``P / P_s`` after a dimensionless time ``tau`` (1 once filled)."""
    tau = np.asarray(tau, dtype=float)
    sub = b + (1.0 - b) * np.sin(np.clip((tau - b) / (1.0 - b), 0.0, math.pi / 2))
    return np.where(tau <= b, np.clip(tau, 0.0, None), sub)


def empty_tau(y, b: float) -> np.ndarray:
    """Dimensionless time ``k t`` of an emptying chamber at ``y = P_s / P``, counted from ``y = b``.

    Choked (``y <= b``): ``ln(y / b)``.  Subsonic: with ``y = b + (1 - b) sin(psi)``,
    ``tau = (1 - b) * integral_0^psi dpsi' / (b + (1 - b) sin psi')`` in closed form
    (substituting ``s = tan(psi / 2)``).
    """
    y = np.clip(np.asarray(y, dtype=float), 1e-300, 1.0)
    psi = np.arcsin(np.clip((y - b) / (1.0 - b), 0.0, 1.0))
    sub = (1.0 - b) * _sin_integral(psi, b, 1.0 - b)
    return np.where(y <= b, np.log(y / b), sub)


def _sin_integral(psi, p: float, q: float) -> np.ndarray:
    """``integral_0^psi dpsi' / (p + q sin psi')`` for ``0 <= psi <= pi/2``, ``p, q > 0``."""
    s = np.tan(np.asarray(psi, dtype=float) / 2.0)
    if math.isclose(p, q):
        return 2.0 / p - 2.0 / (p * (s + 1.0))
    if q > p:
        d = math.sqrt(q * q - p * p)
        r_hi, r_lo = (-q + d) / p, (-q - d) / p
        return (np.log((s - r_hi) / (s - r_lo)) - math.log(r_hi / r_lo)) / d
    d = math.sqrt(p * p - q * q)
    return 2.0 / d * (np.arctan((p * s + q) / d) - math.atan(q / d))


@functools.lru_cache(maxsize=16)
def _empty_table(b: float) -> tuple[np.ndarray, np.ndarray]:
    """The subsonic emptying curve tabulated: ``tau`` (increasing) and ``y`` from ``b`` to 1."""
    psi = np.linspace(0.0, math.pi / 2, 4097)
    y = b + (1.0 - b) * np.sin(psi)
    return empty_tau(y, b), y


def empty_y(tau, b: float) -> np.ndarray:
    """Inverse of :func:`empty_tau`: ``P_s / P`` after a dimensionless time ``tau`` (1 once emptied)."""
    tau = np.asarray(tau, dtype=float)
    taus, ys = _empty_table(float(b))
    return np.where(tau <= 0.0, b * np.exp(np.minimum(tau, 0.0)), np.interp(tau, taus, ys))


def pressure_at(t, p_start, p_source, rate, b: float) -> np.ndarray:
    """Absolute pressure (Pa) of chambers open to ``p_source`` (Pa, absolute) ``t`` seconds after the
    valve opened at ``p_start``; ``rate`` is :meth:`Orifice.rate` of each chamber.

    ``t`` (...,) broadcasts against the chambers' arrays (k,): the result is ``(..., k)``.
    """
    t = np.clip(np.asarray(t, dtype=float), 0.0, None)[..., None]
    p0, ps = np.asarray(p_start, dtype=float), np.asarray(p_source, dtype=float)
    tau = np.asarray(rate, dtype=float) * t
    filling = fill_x(fill_tau(p0 / ps, b) + tau, b) * ps
    emptying = ps / empty_y(empty_tau(ps / p0, b) + tau, b)
    return np.where(p0 < ps, filling, np.where(p0 > ps, emptying, ps))


def time_to(p_end, p_start, p_source, rate, b: float) -> np.ndarray:
    """Seconds a chamber open to ``p_source`` takes from ``p_start`` to ``p_end`` (Pa, absolute, all
    on the same side of the source): the inverse of :func:`pressure_at`."""
    p_end, p0, ps = (np.asarray(v, dtype=float) for v in (p_end, p_start, p_source))
    fill = fill_tau(p_end / ps, b) - fill_tau(p0 / ps, b)
    empty = empty_tau(ps / p_end, b) - empty_tau(ps / p0, b)
    return np.where(p0 <= ps, fill, empty) / np.asarray(rate, dtype=float)
