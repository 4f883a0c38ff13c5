"""The last N seconds of a stream: rolling statistics and a rolling terminal plot.

:class:`Rolling` keeps per-channel sums over bins of device time (0.1 s by default) for the
last ``window_s``; its mean and standard deviation are those of every frame in the bins
kept, so they follow the rig as it is now rather than since the stream began.  The bins'
means are the traces :func:`spark` draws, one line of block characters per channel, each
scaled to its own range (printed beside it by :func:`trace_rows`).

Used by ``labcli monitor`` (and meant for any live view, ``labcli sense`` among them): it
needs numpy only; :func:`trace_table` builds the rich table and imports rich when called.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

BARS = " ▁▂▃▄▅▆▇█"


def spark(values: Any, width: int) -> str:
    """``values`` as ``width`` block characters, low to high over their own range (right-aligned).

    Non-finite values are left out; more values than ``width`` are thinned to the last of
    each of ``width`` equal stretches; a flat trace is one level throughout.
    """
    v = np.asarray(values, dtype=float)
    v = v[np.isfinite(v)]
    if not v.size or width <= 0:
        return " " * max(width, 0)
    if v.size > width:
        v = v[np.linspace(0, v.size - 1, width).round().astype(int)]
    lo, hi = float(v.min()), float(v.max())
    if hi - lo <= 0:
        k = np.ones(v.size, dtype=int)
    else:
        k = np.rint((v - lo) / (hi - lo) * (len(BARS) - 2)).astype(int) + 1
    return "".join(BARS[i] for i in k).rjust(width)


class Rolling:
    """Per-channel statistics and traces over the last ``window_s`` seconds of device time."""

    def __init__(self, k: int, window_s: float, bin_s: float = 0.1) -> None:
        if not window_s > 0 or not bin_s > 0:
            raise ValueError("the window and its bins must be longer than 0 s")
        self.k = k
        self.window_s = float(window_s)
        self.bin_s = float(bin_s)
        # (bin index, frames, sum, sum of squares): one entry per bin of device time
        self._bins: deque[tuple[int, int, np.ndarray, np.ndarray]] = deque()

    def add(self, t_s: np.ndarray, x: np.ndarray) -> None:
        """Frames at device times ``t_s`` (s, increasing) with values ``x`` ``(n, k)``."""
        t = np.asarray(t_s, dtype=float)
        if not t.size:
            return
        x = np.asarray(x, dtype=float).reshape(t.size, self.k)
        idx = np.floor(t / self.bin_s).astype(np.int64)
        starts = np.flatnonzero(np.r_[True, idx[1:] != idx[:-1]])
        ends = np.r_[starts[1:], t.size]
        for a, b in zip(starts, ends, strict=True):
            i, part = int(idx[a]), x[a:b]
            n, s, q = b - a, part.sum(axis=0), (part * part).sum(axis=0)
            if self._bins and self._bins[-1][0] == i:
                _, n0, s0, q0 = self._bins[-1]
                self._bins[-1] = (i, n0 + n, s0 + s, q0 + q)
            else:
                self._bins.append((i, n, s, q))
        last = self._bins[-1][0]
        keep = int(round(self.window_s / self.bin_s))
        while self._bins and self._bins[0][0] <= last - keep:
            self._bins.popleft()

    @property
    def n(self) -> int:
        """Frames in the window."""
        return sum(b[1] for b in self._bins)

    @property
    def span_s(self) -> float:
        """Device time the window's bins cover (at most ``window_s``)."""
        if not self._bins:
            return 0.0
        return (self._bins[-1][0] - self._bins[0][0] + 1) * self.bin_s

    @property
    def mean(self) -> np.ndarray:
        n = self.n
        if not n:
            return np.full(self.k, np.nan)
        return np.asarray(sum(b[2] for b in self._bins) / n, dtype=float)

    @property
    def std(self) -> np.ndarray:
        """Sample standard deviation of the frames in the window (0 with fewer than two)."""
        n = self.n
        if n < 2:
            return np.zeros(self.k)
        s = sum(b[2] for b in self._bins)
        q = sum(b[3] for b in self._bins)
        var = (q - s * s / n) / (n - 1)
        return np.sqrt(np.maximum(var, 0.0))

    def trace(self, j: int) -> np.ndarray:
        """Channel ``j``'s mean per bin, oldest first."""
        return np.array([b[2][j] / b[1] for b in self._bins]) if self._bins else np.empty(0)


def trace_rows(
    rolling: Rolling,
    names: Sequence[str],
    units: Sequence[str],
    width: int,
    show: Callable[[np.ndarray], np.ndarray] = lambda v: v,
) -> list[tuple[str, str, str]]:
    """(channel, its range over the window in ``units``, its trace) per channel.

    ``show`` turns the window's values into the units shown (SI to MPa, deg), all channels at once.
    """
    if not rolling.n:
        return [(name, "", " " * width) for name in names]
    shown = show(np.stack([rolling.trace(j) for j in range(rolling.k)], axis=1))
    rows = []
    for j, (name, unit) in enumerate(zip(names, units, strict=True)):
        tr = shown[:, j]
        digits = 4 if unit == "MPa" else 2
        rows.append((name, f"{tr.min():.{digits}f}..{tr.max():.{digits}f} {unit}", spark(tr, width)))
    return rows


def trace_table(
    rolling: Rolling,
    names: Sequence[str],
    units: Sequence[str],
    width: int = 40,
    show: Callable[[np.ndarray], np.ndarray] = lambda v: v,
) -> Any:
    """The traces as a rich table (channel, range, trace), titled with the window's length."""
    from rich.table import Table

    table = Table(box=None, title=f"last {rolling.window_s:g} s", title_justify="left", show_header=False)
    table.add_column("channel")
    table.add_column("range", justify="right")
    table.add_column("trace", no_wrap=True)
    for row in trace_rows(rolling, names, units, width, show):
        table.add_row(*row)
    return table
