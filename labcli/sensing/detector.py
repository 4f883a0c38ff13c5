"""Change points on the innovations: has something other than noise moved the pressures?

The detector sees one vector per block: each pressure channel's innovation (block mean minus
what the baseline, or the fitted response of the load on the rig, predicted), divided by its
standard deviation, with the common mode removed.  All chambers losing air together is the
leak or the room's temperature; a load stretches one muscle of a pair and lets the other
shorten, so it moves the pressures apart (on the simulated rig the common mode of a load's
change is under 5 % of it).  Under no change the vector is white noise in ``d = channels - 1``
dimensions.

A change of unknown direction and size starting ``m`` blocks ago is tested by the generalised
likelihood ratio ``|sum of the last m vectors|^2 / m``, chi-square with ``d`` degrees of
freedom under no change (with the reference's own wander counted, :meth:`ChangeDetector.push`); windows of 1, 2, 4 ... blocks cover a large load seen in one block
and a small one that needs a second of averaging (the lag makes every load's change grow
smoothly, so a window a few blocks long is about as good as the exact change-point scan).
The detector fires when the largest window statistic exceeds ``threshold``: at 20 blocks per
second and 7 windows, a chi-square(3) threshold of 30 is about 1e-6 per test (one false event
in hours of white noise); the figure used comes from the idle rig (tests/benchmarks/sensing_online.py).
"""

from __future__ import annotations

import numpy as np


def whiten(e: np.ndarray, var: np.ndarray) -> np.ndarray:
    """Innovations (..., k) over their standard deviations, the common mode removed: (..., k)."""
    z = e / np.sqrt(var)
    return z - np.add.reduce(z, axis=-1, keepdims=True) / z.shape[-1]  # np.mean's arithmetic, without its dispatch


class ChangeDetector:
    """Windowed GLR over whitened innovations (module docstring)."""

    def __init__(self, windows: tuple[int, ...], threshold: float, dim: int) -> None:
        self.windows = tuple(sorted(int(w) for w in windows))
        self.threshold = float(threshold)
        self.dim = dim  # degrees of freedom of one vector (channels - 1)
        size = self.windows[-1] + 1
        self._cum = np.zeros((size, dim + 1))  # ring of cumulative sums (the vectors keep k entries)
        self._i = 0
        self.n = 0
        self.last = 0.0  # the largest statistic of the last push
        self.window = 0  # its window

    def reset(self) -> None:
        self._cum[:] = 0.0
        self._i = 0
        self.n = 0
        self.last = 0.0
        self.window = 0

    def push(self, z: np.ndarray, wander: float = 0.0) -> bool:
        """Add one whitened innovation vector; True when a change is detected.

        ``wander``: how far the reference itself may be off, in the same whitened units, as a
        bias that does not average away: a window of ``m`` blocks then has the variance
        ``m + (m wander)^2`` per dimension instead of ``m``, so a long window does not turn
        the baseline's small misfit into a change.
        """
        size = self._cum.shape[0]
        prev = self._cum[self._i % size]
        self._i += 1
        cur = prev + z
        self._cum[self._i % size] = cur
        self.n += 1
        best, window = 0.0, 0
        for m in self.windows:
            if m > self.n:
                break
            diff = cur - self._cum[(self._i - m) % size]
            stat = float(diff @ diff) / (m + (m * wander) ** 2)
            if stat > best:
                best, window = stat, m
        self.last, self.window = best, window
        return best > self.threshold
