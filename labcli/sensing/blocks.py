"""Frames to block means: the estimator's clock.

Everything the estimator decides, it decides once per *block*: a fixed number of
consecutive frames (``round(block_s * rate)``, at least one), averaged.  At 200 Hz a
0.05 s block holds 10 frames, at 1 kHz 50, so the detector, the fits and the model see
20 blocks per second whatever the frame rate, and the work per frame is one row of a
vectorised sum.  A block's spread (the variance of its frames about their mean) measures
the sensors' noise without being fooled by slow drifts.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Blocks:
    """Complete blocks, oldest first: the last frame's device time (s) and seq, the mean device
    time of the block's frames, the means and the variances of the mean (var of the frames /
    frames per block; NaN with one frame per block)."""

    t: np.ndarray  # (m,)
    tc: np.ndarray  # (m,)
    seq: np.ndarray  # (m,)
    mean: np.ndarray  # (m, k)
    var: np.ndarray  # (m, k)

    def __len__(self) -> int:
        return int(self.t.shape[0])


class BlockAverager:
    """Cuts a stream of frames into blocks of ``size`` frames; frames of an incomplete block wait."""

    def __init__(self, width: int, size: int) -> None:
        if size < 1:
            raise ValueError("a block holds at least one frame")
        self.size = int(size)
        self._t = np.empty(0)
        self._seq = np.empty(0, np.int64)
        self._x = np.empty((0, width))

    def push(self, t: np.ndarray, seq: np.ndarray, x: np.ndarray) -> Blocks:
        """Add frames (device time s, seq, SI values (n, k)); return the blocks they complete."""
        if self._t.size:
            t = np.concatenate([self._t, t])
            seq = np.concatenate([self._seq, seq])
            x = np.concatenate([self._x, x])
        m = t.shape[0] // self.size
        cut = m * self.size
        self._t, self._seq, self._x = t[cut:], seq[cut:], x[cut:]
        if not m:
            empty = np.empty((0, x.shape[1]))
            return Blocks(np.empty(0), np.empty(0), np.empty(0, np.int64), empty, empty.copy())
        # np.add.reduce over the frames and a division: np.mean's own arithmetic, without its
        # dispatch (the estimator cuts every read into blocks).
        xs = x[:cut].reshape(m, self.size, -1)
        mean = np.add.reduce(xs, axis=1) / self.size
        if self.size > 1:
            dev = xs - mean[:, None, :]
            var = np.add.reduce(dev * dev, axis=1) / ((self.size - 1) * self.size)
        else:
            var = np.full_like(mean, np.nan)
        ends = slice(self.size - 1, cut, self.size)
        tc = np.add.reduce(t[:cut].reshape(m, self.size), axis=1) / self.size
        return Blocks(t[ends], tc, seq[ends], mean, var)

    @property
    def pending(self) -> int:
        """Frames waiting for their block to complete."""
        return int(self._t.shape[0])


class Recent:
    """The last ``size`` vectors (k,) in a ring, and their median per channel (np.median's, the
    ring's order aside, which a median does not see): the estimator asks for it every idle block."""

    def __init__(self, size: int, k: int) -> None:
        self._rows = np.empty((size, k))
        self._n = 0
        self._i = 0

    def clear(self) -> None:
        self._n = self._i = 0

    def append(self, v: np.ndarray) -> None:
        size = self._rows.shape[0]
        self._rows[self._i] = v
        self._i = (self._i + 1) % size
        self._n = min(self._n + 1, size)

    def __len__(self) -> int:
        return self._n

    def median(self) -> np.ndarray:
        """np.median(rows, axis=0): the same partition, the middle one or the mean of the middle
        two, NaN in a channel that holds one."""
        n, h = self._n, self._n // 2
        part = np.partition(self._rows[:n], [h, -1] if n % 2 else [h - 1, h, -1], axis=0)
        mid = part[h].copy() if n % 2 else (part[h - 1] + part[h]) / 2.0
        nan = np.isnan(part[-1])
        if nan.any():
            mid[nan] = np.nan
        return mid
