"""A linear sensing model with closed-form answers, and synthetic pressure streams written out
from the physics (first-order lag, the heat of a fast stretch, a leak, noise), for the
estimator's tests.

The stream is written here with its own formulas, not with ``labcli.sensing.transient``: a
slip in one would not be shared by the other.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from labcli.sensing.model import Prediction

P0 = np.array([0.30, 0.30, 0.30, 0.30])  # MPa gauge


class LinearModel:
    """``x`` (a state, rad) and ``f`` (a load, N) linear in the pressure drops, with fixed standard errors."""

    quantities = ("x", "f")
    units = ("rad", "N")
    kinds = ("state", "load")
    actuators = ("L1", "R1", "L2", "R2")
    joints = (1, 2)
    protocol = "toy"

    def __init__(
        self, C: np.ndarray | None = None, se: Sequence[float] = (0.002, 0.05), corrected: bool = True
    ) -> None:
        # 1 kPa of antagonistic drop on the first pair: 0.01 rad; on the second pair: 1 N.
        self.C = np.array([[10.0, -10.0, 0.0, 0.0], [0.0, 0.0, 500.0, -500.0]]) if C is None else np.asarray(C)
        self.se = np.asarray(se, dtype=float)
        self.p0_leak_corrected = corrected
        self.baseline_gap_s: float | None = None
        self.calls = 0

    def predict(self, P0: np.ndarray, P: np.ndarray, rest: np.ndarray) -> Prediction:
        self.calls += 1
        dP = np.asarray(P0, dtype=float) - np.asarray(P, dtype=float)
        values = dP @ self.C.T
        return Prediction(values, np.tile(self.se, (len(dP), 1)), [() for _ in range(len(dP))])

    def truth(self, dP: np.ndarray) -> np.ndarray:
        return np.asarray(dP) @ self.C.T


@dataclass
class Load:
    """A change of the settled pressures by ``A`` (MPa, 4) from ``on_s`` to ``off_s``."""

    on_s: float
    off_s: float
    A: np.ndarray


def response(s: np.ndarray, tau: float, thermal_tau: float, kappa: float) -> tuple[np.ndarray, np.ndarray]:
    """Lag and heat of a unit step ``s`` seconds ago: ``1 - exp(-s/tau)`` and the heat's solution
    of ``dx/dt = -kappa dlnV/dt - x/thermal_tau`` with ``lnV`` following the lag."""
    s = np.maximum(s, 0.0)
    lag = 1.0 - np.exp(-s / tau)
    heat = kappa * thermal_tau / (thermal_tau - tau) * (np.exp(-s / thermal_tau) - np.exp(-s / tau))
    return lag, heat


def stream(
    seconds: float,
    *,
    rate: float = 200.0,
    loads: Sequence[Load] = (),
    leak_MPa_s: Sequence[float] = (0.0, 0.0, 0.0, 0.0),
    noise_MPa: float = 1.5e-4,
    tau: float = 0.7,
    thermal_tau: float = 3.0,
    kappa: float = 0.4,
    seed: int = 0,
    t0: float = 0.0,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Device times (s), SI values (n, 6: four pressures, two angles) and the true settled drop
    P0 - P of the load on at each frame (n, 4)."""
    rng = np.random.default_rng(seed)
    t = t0 + np.arange(1, int(round(seconds * rate)) + 1) / rate
    P = np.tile(P0, (len(t), 1)) + np.outer(t, leak_MPa_s)
    settled = np.zeros((len(t), 4))
    for ld in loads:
        for edge, sign in ((ld.on_s, 1.0), (ld.off_s, -1.0)):
            lag, heat = response(t - edge, tau, thermal_tau, kappa)
            P += sign * np.outer(lag + heat, ld.A)
        settled[(t >= ld.on_s) & (t < ld.off_s)] += ld.A
    x = np.column_stack([P + noise_MPa * rng.standard_normal(P.shape), 1e-4 * rng.standard_normal((len(t), 2))])
    return t, x, -settled
