"""Capture windows taken as they arrive, never held whole in memory.

A ``Baseline`` or ``Capture`` step inside a trial streams its frames into the run file
(``run.windows.begin``, which holds at most one chunk of frames before writing it); the
session is handed the stored :class:`~labcli.core.window.Window`: where the frames lie in
the file, their checksum, and their running mean and variance per channel.  Outside a
trial (the air supply's check, before the run file exists) nothing of a window is stored,
so only its statistics are kept (:meth:`Window.summary <labcli.core.window.Window.summary>`).
Either way the memory a capture window takes does not grow with its length, and what the
session and the engine read from it (means, variances, the frame rate) is computed block by
block.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from ..errors import DeviceRailed
from .store.frames import WindowWriter
from .window import Stats, Window

GAP_DIGITS = 4  # significant digits kept of each gap between frames (us) in the rate's tally


class GapTally:
    """The median gap between consecutive frames of a window, from a tally of the gaps.

    Gaps are counted in whole microseconds (the rig's clock) rounded to :data:`GAP_DIGITS`
    significant digits: exact for gaps under 10 ms (rates above 100 Hz), within 0.05 %
    otherwise, and a steady clock gives a handful of distinct values however long the window.
    The median is ``numpy.median``'s over the gaps so rounded.
    """

    def __init__(self) -> None:
        self._counts: dict[int, int] = {}
        self._last: float | None = None
        self.n = 0  # gaps counted

    def add(self, t_s: np.ndarray) -> None:
        """Count the gaps of these frames' times (s), and the one from the last frame before them."""
        t = np.asarray(t_s, dtype=float).reshape(-1)
        if not t.size:
            return
        if self._last is not None:
            t = np.concatenate(([self._last], t))
        self._last = float(t[-1])
        gaps = np.rint(np.diff(t) * 1e6).astype(np.int64)
        big = gaps >= 10**GAP_DIGITS
        if big.any():
            scale = 10 ** (np.floor(np.log10(gaps[big])).astype(np.int64) - (GAP_DIGITS - 1))
            gaps[big] = np.rint(gaps[big] / scale).astype(np.int64) * scale
        values, counts = np.unique(gaps, return_counts=True)
        for v, c in zip(values.tolist(), counts.tolist(), strict=False):
            self._counts[v] = self._counts.get(v, 0) + c
        self.n += len(gaps)

    def median_s(self) -> float:
        """The median gap in seconds (NaN before two frames)."""
        if not self.n:
            return math.nan
        keys = sorted(self._counts)
        cum = np.cumsum([self._counts[k] for k in keys])
        lo = keys[int(np.searchsorted(cum, (self.n - 1) // 2, side="right"))]
        hi = keys[int(np.searchsorted(cum, self.n // 2, side="right"))]
        return (lo + hi) / 2 * 1e-6


RAILED_SHARE = 0.5  # a window is railed on a channel when most of its frames sit at an ADC end


class WindowSink:
    """Where the frames of one Baseline or Capture go as they arrive.

    ``writer``: the run file's :class:`~labcli.core.store.WindowWriter` (inside a trial), or
    None to keep the statistics only.  ``channels``: how many.  :meth:`finish` gives the
    window the session is handed; :attr:`gaps` the frame rate's tally.
    """

    def __init__(
        self,
        channels: int,
        writer: WindowWriter | None = None,
        adc: tuple[float, float] | None = None,
        names: Sequence[str] = (),
    ) -> None:
        self.writer = writer
        self.gaps = GapTally()
        self._channels = channels
        self._stats = Stats()
        self._adc = adc
        self._names = tuple(names)  # with ``adc``: a window at a rail ends in DeviceRailed naming them
        self._frames = 0
        self._railed = np.zeros(channels, dtype=np.int64)  # frames at or beyond the ADC's ends, per channel

    def add(self, w: Window) -> None:
        """Take in a block of frames (held in memory)."""
        self.gaps.add(w.t_s)
        if self._adc is not None and len(w):
            counts = np.asarray(w.counts, dtype=float).reshape(len(w), -1)
            lo, hi = self._adc
            self._railed[: counts.shape[1]] += np.sum(~((counts > lo) & (counts < hi)), axis=0)
            self._frames += len(w)
        if self.writer is not None:
            self.writer.append(w.t_s, w.seq, w.counts, w.si)
        else:
            self._stats.add(w.si)

    def railed(self, share: float = RAILED_SHARE) -> list[int]:
        """The channels whose counts sat at an end of the ADC's range (or beyond it) in more than
        ``share`` of the window's frames: a sensor pinned at a rail or a link sending counts no ADC
        gives, not a reading."""
        if not self._frames:
            return []
        return [int(j) for j in np.flatnonzero(self._railed > share * self._frames)]

    def check_rails(self, channels: Sequence[str]) -> None:
        """DeviceRailed, naming the channels, when :meth:`railed` finds any."""
        railed = self.railed()
        if railed and self._adc is not None:
            lo, hi = self._adc
            names = ", ".join(channels[j] for j in railed)
            raise DeviceRailed(
                what=f"sent counts at an end of its ADC's range ({lo:g} or {hi:g}) on {names} for most of a "
                "window (a sensor at its rail, not a reading)"
            )

    def finish(self) -> Window:
        """The window: stored in the run file, or (outside a trial) its statistics only; DeviceRailed
        when it sat at a rail (:meth:`check_rails`; the frames stay in the file, unreferenced)."""
        window = self.writer.finish() if self.writer is not None else Window.summary(self._channels, self._stats)
        if self._names:
            self.check_rails(self._names)
        return window
