"""A second forward model of the 2-DoF McKibben joint, written from the paper's geometry alone.

Nothing here comes from labcli's simulated rig: the actuators, the statics and the sensors are
derived afresh, so that an estimator that holds on this data holds beyond the simulator it was
tuned on.  labcli is used only for what a lab would use it for, reading the tables this module
writes (``docs/table-formats.md``).

Geometry (Takuma et al. 2014, Eqs. 2-7, used exactly, without the paper's small-extension
approximation of Eqs. 8-13): the outside pair (j = 1) spans the bottom joint on moment arm r1;
the inside pair (j = 2) spans both joints on r2, its extension at the bottom joint adding to the
one at the top.  The contact point is C(theta) = (-h2 sin t1 - h3 sin(t1 + t2),
h1 + h2 cos t1 + h3 cos(t1 + t2)), angles counter-clockwise; the left actuator shortens for
positive angles (Eq. 3's minus sign).

Actuators: the ideal braided muscle (Chou & Hannaford 1996), not the paper's Eq. 1.  A braid of
thread length b wound n times encloses V(l) = l (b^2 - l^2) / (4 pi n^2); the pressure's tension
is T = -P dV/dl = P (3 l^2 - b^2) / (4 pi n^2); the rubber adds k_rubber (l - l_free).  Each
actuator is filled to its supply at the rest posture and closed, so under load its absolute
pressure follows Boyle's law, P_abs V(l) = const.

Statics by virtual work: the joint torques are -sum_j T_j dl_j/dtheta, balanced by J(theta)^T F
(J = dC/dtheta).  A pulley weight gives a constant F; a pushed object is a ring of radial springs
about its centre O2 (Eqs. 39 and 42): F = k_o (R - |C - O2|) (C - O2) / |C - O2| when positive.

Sensors: gauge pressures with Gaussian noise per capture window, potentiometers with a scale
error and noise.  The geometry and the muscles differ from the values the estimator assumes
(h2, h3, r1, r2 by a few per cent), which is the point.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np
from scipy.optimize import root

P_ATM = 101_325.0  # Pa
G = 9.80665  # m/s^2
MUSCLES = ("L1", "R1", "L2", "R2")


@dataclass(frozen=True)
class SecondRig:
    """Plain data of the second rig (SI).  The nominal arm is the protocol's (h1 0.355, h2 0.130,
    h3 0.065, r1 0.075, r2 0.035 m); this one is built a few per cent off it."""

    h1: float = 0.355
    h2: float = 0.1325
    h3: float = 0.0630
    r1: float = 0.0725
    r2: float = 0.0365
    # Actuator at theta = 0: active length, braid thread length, turns, rubber stiffness.
    l_ref: float = 0.200
    braid: float = 0.300
    turns: float = 4.9
    k_rubber: float = 1000.0
    supply_MPa: tuple[float, float, float, float] = (0.15, 0.15, 0.45, 0.15)
    p_noise_kPa: float = 0.5  # per capture window (a PSE530 averaged over 1 s)
    pot_noise_deg: float = 0.1
    pot_scale: tuple[float, float] = (1.02, 0.985)

    def lengths(self, theta: np.ndarray) -> np.ndarray:
        """Actuator lengths (L1, R1, L2, R2), m, from Eqs. 2-7 taken exactly."""
        t1, t2 = float(theta[0]), float(theta[1])

        def ext(h: float, r: float, t: float, side: float) -> float:
            return math.hypot(h + side * r * math.sin(t), r - r * math.cos(t)) - h

        out = []
        for side in (-1.0, 1.0):  # left shortens for positive angles (Eq. 3), right lengthens (Eq. 2)
            out.append(self.l_ref + ext(self.h1, self.r1, t1, side))
        for side in (-1.0, 1.0):
            out.append(self.l_ref + ext(self.h1, self.r2, t1, side) + ext(self.h2, self.r2, t2, side))
        return np.array(out)

    def length_jacobian(self, theta: np.ndarray, eps: float = 1e-7) -> np.ndarray:
        """d l / d theta, shape (4, 2), by central differences."""
        cols = []
        for k in range(2):
            dt = np.zeros(2)
            dt[k] = eps
            cols.append((self.lengths(theta + dt) - self.lengths(theta - dt)) / (2 * eps))
        return np.stack(cols, axis=1)

    def contact(self, theta: np.ndarray) -> np.ndarray:
        t1, t2 = float(theta[0]), float(theta[1])
        return np.array(
            [
                -self.h2 * math.sin(t1) - self.h3 * math.sin(t1 + t2),
                self.h1 + self.h2 * math.cos(t1) + self.h3 * math.cos(t1 + t2),
            ]
        )

    def contact_jacobian(self, theta: np.ndarray) -> np.ndarray:
        t1, t2 = float(theta[0]), float(theta[1])
        a, b = math.cos(t1), math.cos(t1 + t2)
        c, s = math.sin(t1), math.sin(t1 + t2)
        return np.array([[-self.h2 * a - self.h3 * b, -self.h3 * b], [-self.h2 * c - self.h3 * s, -self.h3 * s]])

    def volume(self, length: np.ndarray) -> np.ndarray:
        return length * (self.braid**2 - length**2) / (4 * math.pi * self.turns**2)

    def tension(self, length: np.ndarray, p_gauge: np.ndarray) -> np.ndarray:
        return p_gauge * (3 * length**2 - self.braid**2) / (4 * math.pi * self.turns**2) + self.k_rubber * (
            length - self.l_ref
        )


class Arm:
    """The second rig pressurised at its rest posture with its valves closed."""

    def __init__(self, rig: SecondRig, seed: int):
        self.rig = rig
        self.rng = np.random.default_rng(seed)
        supply = np.array(rig.supply_MPa) * 1e6
        self.rest = self._solve(lambda th: supply, np.zeros(2), lambda th: np.zeros(2))
        self.gas = (supply + P_ATM) * rig.volume(rig.lengths(self.rest))  # P_abs V, per actuator

    def pressures(self, theta: np.ndarray) -> np.ndarray:
        """Gauge pressures, Pa, with the valves closed (Boyle's law)."""
        return self.gas / self.rig.volume(self.rig.lengths(theta)) - P_ATM

    def _solve(self, pressure, start, force) -> np.ndarray:
        rig = self.rig

        def residual(th: np.ndarray) -> np.ndarray:
            muscle = -rig.length_jacobian(th).T @ rig.tension(rig.lengths(th), pressure(th))
            return muscle + rig.contact_jacobian(th).T @ force(th)

        sol = root(residual, start, method="hybr")
        if np.max(np.abs(residual(sol.x))) > 1e-6:  # hybr may stop at the precision limit, still balanced
            raise RuntimeError(f"the second rig found no equilibrium: {sol.message}")
        return sol.x

    def loaded(self, force, start: np.ndarray | None = None) -> np.ndarray:
        """Joint angles (absolute, rad) under ``force(theta)`` (N at the contact point)."""
        return self._solve(self.pressures, self.rest if start is None else start, force)

    def read(self, theta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """One capture window: gauge pressures (MPa) and potentiometer angles (rad)."""
        p = self.pressures(theta) / 1e6 + self.rng.normal(0.0, self.rig.p_noise_kPa * 1e-3, 4)
        pot = np.asarray(self.rig.pot_scale) * theta + self.rng.normal(0.0, math.radians(self.rig.pot_noise_deg), 2)
        return p, pot


def _row(arm: Arm, loaded: np.ndarray) -> dict:
    p0, pot0 = arm.read(arm.rest)
    p1, pot1 = arm.read(loaded)
    out = dict(zip(("P_L10", "P_R10", "P_L20", "P_R20"), p0, strict=True))
    out.update(zip(("P_L1", "P_R1", "P_L2", "P_R2"), p1, strict=True))
    out["theta1_deg"], out["theta2_deg"] = np.degrees(pot1 - pot0)
    out["theta1_0_deg"], out["theta2_0_deg"] = np.degrees(pot0)
    return out


def weight_trials(plan, seed: int, rig: SecondRig | None = None):
    """The trial table of a plan (columns ``trial, set, mass_g, direction_deg``) on the second rig."""
    import pandas as pd

    arm = Arm(rig or SecondRig(), seed)
    rows = []
    for _, p in plan.iterrows():
        a = math.radians(float(p["direction_deg"]))
        F = float(p["mass_g"]) * 1e-3 * G * np.array([math.cos(a), math.sin(a)])
        row = {"trial": int(p["trial"]), "set": p["set"], **_row(arm, arm.loaded(lambda th, F=F: F))}
        row.update(
            {"Fx_N": F[0], "Fy_N": F[1], "mass_g": float(p["mass_g"]), "direction_deg": float(p["direction_deg"])}
        )
        rows.append(row)
    return pd.DataFrame(rows)


# Section 4's objects (radius m, lateral stiffness N/m, push distance m, category); the same
# classes as the stiffness protocol's bands, restated here as data.
OBJECTS = (
    ("pet-1", 0.033, 420.0, 0.010, "soft"),
    ("pet-2", 0.0325, 520.0, 0.010, "soft"),
    ("pet-3", 0.035, 610.0, 0.010, "soft"),
    ("can-al-1", 0.033, 1800.0, 0.015, "medium"),
    ("can-al-2", 0.033, 2400.0, 0.015, "medium"),
    ("can-steel-1", 0.037, 8000.0, 0.020, "hard"),
)
PHI_DEG = (0.0, 15.0, -15.0, 30.0, -30.0, 7.5, -7.5, 22.5, -22.5, 0.0)


def push_table(seed: int, rig: SecondRig | None = None, pushes_per_object: int = 10, phi_known: bool = False):
    """The push table (``docs/table-formats.md``) on the second rig; ``phi_deg`` blank unless
    ``phi_known``.  Extra columns ``true_stiffness_N_per_m, true_category, true_phi_deg, true_Fx_N, true_Fy_N``."""
    import pandas as pd

    arm = Arm(rig or SecondRig(), seed)
    c0 = arm.rig.contact(arm.rest)
    rows = []
    for name, R, k_o, d, category in OBJECTS:
        for i in range(pushes_per_object):
            phi = math.radians(PHI_DEG[i % len(PHI_DEG)])
            theta = arm.rest
            steps = max(4, math.ceil(d / 0.5e-3))
            for step in np.arange(1, steps + 1) / steps:  # the object moves in; each equilibrium starts the next
                o2 = c0 + np.array([R - step * d * math.cos(phi), -step * d * math.sin(phi)])

                def force(th, o2=o2, R=R, k_o=k_o):
                    v = arm.rig.contact(th) - o2
                    dist = float(np.hypot(*v))
                    return k_o * max(0.0, R - dist) * v / dist

                theta = arm.loaded(force, theta)
            row = {"push": len(rows) + 1, "object": name, "R_m": R, "d_m": d}
            row["phi_deg"] = math.degrees(phi) if phi_known else math.nan
            row.update(_row(arm, theta))
            row["true_Fx_N"], row["true_Fy_N"] = force(theta)
            row.update({"true_stiffness_N_per_m": k_o, "true_category": category, "true_phi_deg": math.degrees(phi)})
            rows.append(row)
    return pd.DataFrame(rows)


def harsher(rig: SecondRig | None = None, **changes) -> SecondRig:
    return replace(rig or SecondRig(), **changes)


def force_floor(rig: SecondRig | None = None, seed: int = 1, pots: bool = False) -> np.ndarray:
    """The smallest standard errors (N) of (Fx, Fy) any estimator can reach from one trial's readings
    at the rest posture, knowing this rig's physics exactly (the Cramer-Rao bound of the linearised
    statics): pressures, and with ``pots`` also the potentiometers, each read twice (baseline and
    load) with the rig's noise.  On the bent arm the pressures barely see Fy: the outside pair not at
    all (its joint carries Fy's torque only through the tip's small sideways offset), the inside pair
    a fifth of what it sees of Fx."""
    rig = rig or SecondRig()
    if rig.p_noise_kPa == 0 or (pots and rig.pot_noise_deg == 0):
        return np.zeros(2)  # a reading without noise: the statics give the force exactly
    arm = Arm(rig, seed)
    dp, dth = np.zeros((4, 2)), np.zeros((2, 2))
    for k in range(2):
        unit = np.zeros(2)
        unit[k] = 1.0  # 1 N each way: the response's slope, free of its curvature
        up, down = arm.loaded(lambda th, F=unit: F), arm.loaded(lambda th, F=-unit: F)
        dp[:, k] = (arm.pressures(up) - arm.pressures(down)) / 2  # Pa per N
        dth[:, k] = np.asarray(rig.pot_scale) * (up - down) / 2  # rad per N, as the pots read it
    rows = [dp / (rig.p_noise_kPa * 1e3 * math.sqrt(2))]
    if pots:
        rows.append(dth / (math.radians(rig.pot_noise_deg) * math.sqrt(2)))
    info = sum(r.T @ r for r in rows)
    return np.sqrt(np.diag(np.linalg.inv(info)))
