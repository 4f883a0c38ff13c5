"""The baseline: each channel's level and slope while nothing loads the rig.

A closed McKibben chamber leaks (about 1 kPa/min through a push-in fitting that is not quite
tight, each chamber at its own rate) and its sensor drifts, so the pressure the rig rests at
is a moving line, not a number.  Each channel is tracked as a local linear trend, a Kalman
filter on the state (level, slope)::

    level(t + dt) = level(t) + slope(t) dt + w_level,   var(w_level) = q_level dt
    slope(t + dt) = slope(t) + w_slope,                  var(w_slope) = q_slope dt
    block mean    = level + noise,                        var(noise) = the block's variance

so the level follows the leak along its slope and the slope itself adapts over minutes.
While a load is on, the tracker is frozen and its line extrapolated (the leak goes on under
the load); its variance grows with the extrapolation (``at``).  At a release the level is
set anew (:meth:`TrendTracker.reset`), the slope kept: the chamber leaks as before, but the
rest posture after an unload differs from the one before it (sleeve friction).

The units are those of the channels (MPa, rad) and seconds.
"""

from __future__ import annotations

import numpy as np


class TrendTracker:
    """Local linear trends of ``k`` channels (vectorised: every array has the channels first)."""

    def __init__(self, q_level: np.ndarray, q_slope: np.ndarray, slope_sd: np.ndarray) -> None:
        self.q_level = np.asarray(q_level, dtype=float)
        self.q_slope = np.asarray(q_slope, dtype=float)
        self.slope_sd = np.asarray(slope_sd, dtype=float)  # prior spread of a slope never seen
        k = self.q_level.shape[0]
        self.t: float | None = None
        self.x = np.zeros((k, 2))  # level, slope
        self.P = np.zeros((k, 2, 2))
        # The last extrapolation and the state it was made from (the estimator asks twice a block).
        self._version = 0
        self._last_at: tuple[float, int, tuple[np.ndarray, np.ndarray]] | None = None

    def start(self, t: float, level: np.ndarray, level_var: np.ndarray) -> None:
        """Begin at ``level`` (variance ``level_var``) with an unknown slope."""
        self._version += 1
        self.t = float(t)
        self.x = np.column_stack([np.asarray(level, dtype=float), np.zeros_like(self.q_level)])
        self.P = np.zeros((len(self.q_level), 2, 2))
        self.P[:, 0, 0] = level_var
        self.P[:, 1, 1] = self.slope_sd**2

    def reset(self, t: float, level: np.ndarray, level_var: np.ndarray) -> None:
        """A new level at ``t`` (after a release); the slope and its spread are kept."""
        self._version += 1
        slope, slope_var = self.x[:, 1].copy(), self.P[:, 1, 1].copy()
        self.t = float(t)
        self.x = np.column_stack([np.asarray(level, dtype=float), slope])
        self.P = np.zeros_like(self.P)
        self.P[:, 0, 0] = level_var
        self.P[:, 1, 1] = slope_var

    def at(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        """The extrapolated level at ``t`` and its variance (the state is not changed)."""
        t = float(t)
        last = self._last_at
        if last is not None and last[0] == t and last[1] == self._version:
            return last[2]
        dt = t - float(self.t or 0.0)
        level = self.x[:, 0] + self.x[:, 1] * dt
        P = self.P
        var = P[:, 0, 0] + 2 * dt * P[:, 0, 1] + dt * dt * P[:, 1, 1] + self.q_level * abs(dt)
        self._last_at = (t, self._version, (level, var))
        return level, var

    @property
    def slope(self) -> np.ndarray:
        return self.x[:, 1].copy()

    def update(self, t: float, y: np.ndarray, r: np.ndarray) -> None:
        """Take a block mean ``y`` (variance ``r``) at ``t``."""
        self._version += 1
        dt = max(0.0, float(t) - float(self.t or t))
        x, P = self.x, self.P
        # Predict: level += slope dt.
        x[:, 0] += x[:, 1] * dt
        p00 = P[:, 0, 0] + 2 * dt * P[:, 0, 1] + dt * dt * P[:, 1, 1] + self.q_level * dt
        p01 = P[:, 0, 1] + dt * P[:, 1, 1]
        p11 = P[:, 1, 1] + self.q_slope * dt
        # Update with the level observed.
        s = p00 + r
        k0, k1 = p00 / s, p01 / s
        e = y - x[:, 0]
        x[:, 0] += k0 * e
        x[:, 1] += k1 * e
        P[:, 0, 0] = (1 - k0) * p00
        P[:, 0, 1] = P[:, 1, 0] = (1 - k0) * p01
        P[:, 1, 1] = p11 - k1 * p01
        self.t = float(t)

    def snapshot(self) -> tuple[float | None, np.ndarray, np.ndarray]:
        return self.t, self.x.copy(), self.P.copy()

    def restore(self, snap: tuple[float | None, np.ndarray, np.ndarray]) -> None:
        self._version += 1
        self.t, self.x, self.P = snap[0], snap[1].copy(), snap[2].copy()
