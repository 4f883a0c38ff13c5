"""A window of frames: what the engine reads from the rig, a session is handed, a record keeps.

One type from capture to storage.  A :class:`Window` is ``n`` frames of ``k`` channels: each
frame's counter (``seq``), the rig's clock (``t_us``, as sent, wrapping at 2**32, and ``t_s``,
unwrapped, in s), the values as sent (``counts``) and calibrated (``si``: MPa, rad, m).  Its
frames are in one of three places:

* **in memory** (:meth:`Window.of`): a block of frames the engine has just read, the setup
  check's half second, a window a test makes up, a record of a schema-1 file;
* **in a run file** (:attr:`Window.stored`): a Baseline or Capture inside a trial, streamed
  into the file as it arrived (``run.windows.begin``), or a window read back from a record.
  Only where the frames lie is held (frames ``[start, stop)`` and their checksum), with the
  running mean and variance per channel when it was just captured; the frames are read from
  the file when asked for;
* **nowhere** (:meth:`Window.summary`): a window read outside a trial, before the run file
  exists (the air supply's check): only its statistics are kept, and no record can take it.

Whatever the place, :func:`len`, :meth:`Window.mean`, :meth:`Window.var` and
:meth:`Window.std` answer (per channel, SI), so a window of any length takes the same memory
where a session only needs its statistics.  A record's ``raw`` holds Windows (``{"baseline":
w, "load": w}``); the run file writes the frames of those held in memory and refers to those
already in it.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np

from ..errors import ConfigError

U32 = 1 << 32
NOT_KEPT = (
    "a window read outside a trial is not kept in the run file, so no record can take it: "
    "begin the trial (BeginTrial) before its Baseline or Capture."
)


class FrameSource(Protocol):
    """Where stored frames are read from (a run file's ``run.windows``)."""

    def frames(self, start: int, stop: int) -> Window:
        """Frames ``[start, stop)``, in memory."""
        ...


@dataclass(frozen=True)
class Stored:
    """Where a window's frames lie in a run file: frames ``[start, stop)`` of ``source``, and their checksum."""

    source: FrameSource
    start: int
    stop: int
    checksum: int


class Stats:
    """Running count, mean and sum of squared deviations per channel (Chan et al.'s pairwise update)."""

    def __init__(self) -> None:
        self.n = 0
        self.mean: np.ndarray | None = None
        self.m2: np.ndarray | None = None

    def add(self, x: np.ndarray) -> None:
        """Take in frames ``x`` (n, k)."""
        nb = x.shape[0]
        if nb == 0:
            return
        mb = x.mean(axis=0)
        m2b = ((x - mb) ** 2).sum(axis=0)
        if self.n == 0 or self.mean is None or self.m2 is None:
            self.n, self.mean, self.m2 = nb, mb, m2b
            return
        n = self.n + nb
        delta = mb - self.mean
        self.mean = self.mean + delta * (nb / n)
        self.m2 = self.m2 + m2b + delta**2 * (self.n * nb / n)
        self.n = n

    def means(self, k: int) -> np.ndarray:
        """Mean per channel (``k`` of them; NaN before any frame)."""
        return np.array(self.mean) if self.n and self.mean is not None else np.full(k, np.nan)

    def variances(self, k: int, ddof: int = 0) -> np.ndarray:
        """Variance per channel with ``ddof`` delta degrees of freedom (NaN without more frames than ``ddof``)."""
        if self.m2 is None or self.n <= ddof:
            return np.full(k, np.nan)
        return np.asarray(self.m2 / (self.n - ddof))


@dataclass(frozen=True)
class _Frames:
    """The arrays of a window held in memory."""

    seq: np.ndarray  # (n,) int64, the frame counter as sent
    t_us: np.ndarray  # (n,) int64, the rig's clock as sent (wraps at 2**32)
    counts: np.ndarray  # (n, k), values as sent
    si: np.ndarray  # (n, k) float64, calibrated
    t_s: np.ndarray  # (n,) float64, the rig's clock unwrapped


class Window:
    """``n`` frames of ``k`` channels (see the module docstring).  Make one with :meth:`of`;
    the run file and the engine make the stored and summarised ones."""

    __slots__ = ("channels", "stored", "_frames", "_stats")

    def __init__(
        self, channels: int, *, frames: _Frames | None = None, stats: Stats | None = None, stored: Stored | None = None
    ) -> None:
        self.channels = channels
        self.stored = stored
        self._frames = frames
        self._stats = stats

    # ------------------------------------------------------------ making one
    @classmethod
    def of(
        cls,
        seq: Any,
        counts: Any,
        si: Any,
        *,
        t_us: Any = None,
        t_s: Any = None,
    ) -> Window:
        """A window held in memory.  Give the rig's clock as sent (``t_us``), unwrapped (``t_s``,
        s), or both; the other is worked out.  Shapes are checked where a window is stored."""
        if t_us is None and t_s is None:
            raise ConfigError("a window needs the rig's clock: give t_us (as sent) or t_s (unwrapped, s).")
        t_s = unwrap_us(t_us) if t_s is None else np.asarray(t_s, dtype=np.float64)
        t_us = np.rint(t_s * 1e6).astype(np.int64) % U32 if t_us is None else np.asarray(t_us, dtype=np.int64)
        counts = np.asarray(counts)
        si = np.asarray(si, dtype=np.float64)
        k = si.shape[1] if si.ndim == 2 else 0
        return cls(k, frames=_Frames(np.asarray(seq, dtype=np.int64), t_us, counts, si, t_s))

    @classmethod
    def summary(cls, channels: int, stats: Stats) -> Window:
        """A window of which only the statistics were kept (read outside a trial)."""
        return cls(channels, stats=stats)

    @classmethod
    def concat(cls, parts: Sequence[Window]) -> Window:
        """Windows held in memory, one after the other."""
        if len(parts) == 1:
            return parts[0]
        fr = [p._memory() for p in parts]
        return cls(
            parts[0].channels,
            frames=_Frames(*(np.concatenate([getattr(f, name) for f in fr]) for name in _Frames.__annotations__)),
        )

    def __getitem__(self, index: slice) -> Window:
        """Frames ``index`` (a slice) of a window held in memory."""
        f = self._memory()
        return Window(
            self.channels, frames=_Frames(f.seq[index], f.t_us[index], f.counts[index], f.si[index], f.t_s[index])
        )

    # ------------------------------------------------------------ what a session reads
    def __len__(self) -> int:
        if self._frames is not None:
            return len(self._frames.seq)
        if self.stored is not None:
            return self.stored.stop - self.stored.start
        return self._stats.n if self._stats is not None else 0

    @property
    def kept(self) -> bool:
        """Whether the frames can be read (in memory or in a run file), not only the statistics."""
        return self._frames is not None or self.stored is not None

    def mean(self) -> np.ndarray:
        """Mean per channel, SI."""
        if self._stats is not None:
            return self._stats.means(self.channels)
        return self.si.mean(axis=0) if len(self) else np.full(self.channels, np.nan)

    def var(self, ddof: int = 0) -> np.ndarray:
        """Variance per channel, SI squared (``ddof`` as numpy's; NaN without more frames than ``ddof``)."""
        if self._stats is not None:
            return self._stats.variances(self.channels, ddof)
        si = self.si
        return si.var(axis=0, ddof=ddof) if len(si) > ddof else np.full(self.channels, np.nan)

    def std(self) -> np.ndarray:
        """Population standard deviation per channel, SI."""
        return np.sqrt(self.var())

    # ------------------------------------------------------------ the frames
    @property
    def seq(self) -> np.ndarray:
        """(n,) int64: the frame counter as sent."""
        return self._memory().seq

    @property
    def t_us(self) -> np.ndarray:
        """(n,) int64: the rig's clock as sent, in us (wraps at 2**32)."""
        return self._memory().t_us

    @property
    def t_s(self) -> np.ndarray:
        """(n,) float64: the rig's clock, unwrapped, in s."""
        return self._memory().t_s

    @property
    def counts(self) -> np.ndarray:
        """(n, k): the values as sent (int32 when every one is a whole number)."""
        return self._memory().counts

    @property
    def si(self) -> np.ndarray:
        """(n, k) float64: the calibrated values (MPa, rad, m)."""
        return self._memory().si

    def _memory(self) -> _Frames:
        """The frames: in memory, or read from the run file (the whole window, each time asked)."""
        if self._frames is not None:
            return self._frames
        if self.stored is not None:
            s = self.stored
            return s.source.frames(s.start, s.stop)._memory()
        raise ConfigError(NOT_KEPT)

    def __repr__(self) -> str:
        where = [*(["in memory"] if self._frames is not None else [])]
        if self.stored is not None:
            where.append(f"frames {self.stored.start}-{self.stored.stop} of a run file")
        return f"<Window of {len(self)} frames x {self.channels} channels, {', '.join(where) or 'statistics only'}>"


def unwrap_us(t_us: Any) -> np.ndarray:
    """The rig's clock in s from its 32-bit microsecond count, which wraps."""
    t = np.asarray(t_us, dtype=np.int64)
    if t.size == 0:
        return np.zeros(0, dtype=np.float64)
    wraps = np.concatenate([[0], np.cumsum(np.diff(t) < 0)])
    return (t + wraps * U32) * 1e-6
