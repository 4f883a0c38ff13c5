"""Equilibrium detection: has the joint stopped moving?

The paper waits "a certain interval of time" after loading the joint before it
reads the pressures (Section 3.2).  A fixed interval is either wasteful or too
short, so the toolkit judges equilibrium from the data instead:

* samples are grouped into blocks of ``window_s / BLOCKS`` seconds of device
  time and each block is averaged (so sensor noise, about one ADC count, does
  not masquerade as motion);
* the *spread* of a channel is the range (max - min) of the last ``BLOCKS``
  block means, i.e. how far the signal wandered over one window;
* a spread alone accepts a slow exponential tail too early (a tail with time
  constant tau wanders only ``window_s / tau`` of what is left of it over a
  window; the air's thermal relaxation after a fast load has tau of seconds).
  So the detector also estimates what is left: from the means A, B, C of the
  last three windows, ``d1 = B - A`` and ``d2 = C - B``; a decaying trend
  (same sign or stopped, ``|d2| < |d1|``) is an exponential with ratio ``r = d2 / d1``
  per window, whose remaining change after C is ``|d2| r / (1 - r)`` (Aitken's
  extrapolation), capped at ``TAIL_MAX |d2|``; a trend that does not decay
  (a creep, e.g. a leak) counts ``TAIL_MAX |d2|``, and a change of sign
  (noise, or a hump such as a pressure that overshoots) counts the larger of
  ``|d1|`` and ``|d2|``;
* the joint is settled when every pressure spread and remaining tail is under
  ``pressure_spread_MPa`` and every angle spread and tail under
  ``angle_spread_rad``, and has stayed so for ``hold_s`` seconds of device
  time.  The tail needs three windows of data, so the earliest acceptance is
  ``3 window_s + hold_s`` after the wait begins;
* a chamber that leaks steadily drifts by the same amount every window: a trend that does not
  decay, which the tail would count as ``TAIL_MAX`` windows of it (a leak of 3.6 kPa/min is
  0.24 kPa of the 0.31 kPa limit, and the noise of single windows pushes it over).  A steady
  drift known beforehand (``drift_per_s``, per channel: each chamber's leak as the hold check
  measured it, :func:`labcli.core.air.hold_problem`) is taken out of the block means before the
  spread and the tail are judged, so a constant leak is no tail while a decaying one on top of
  it still is; a drift that changes (a leak that steps up, a valve that starts to pass) leaves
  the difference in the means, and that difference is a trend like any other;
* a length channel (the rPAM stand's draw-wire sensor) has its own limit, and
  counts as motion with the angles: its spread is reported as the angle spread
  that is the same fraction of the angle limit.

Time is always device time (seconds, from the frames' ``t_us``), so the same
rule holds on a real rig, on the simulated rig in virtual time, and on
synthetic signals in tests.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

BLOCKS = 10  # block means per window
TAIL_WINDOWS = 3  # windows of history behind the tail estimate
# Largest remaining tail counted, in multiples of the last window-to-window change:
# r / (1 - r) = 4 at r = 0.8, an exponential with a time constant of 4.5 windows.
TAIL_MAX = 4.0


def remaining_tail(A: np.ndarray, B: np.ndarray, C: np.ndarray) -> np.ndarray:
    """Estimated change still to come after the means ``C`` of three consecutive windows.

    Aitken's extrapolation of an exponential approach (see the module docstring).
    """
    d1, d2 = B - A, C - B
    trend = d1 * d2 >= 0
    decaying = trend & (np.abs(d2) < np.abs(d1))
    with np.errstate(divide="ignore", invalid="ignore"):
        r = np.where(decaying, d2 / d1, 0.0)
        factor = np.where(decaying, np.minimum(r / (1.0 - r), TAIL_MAX), TAIL_MAX)
    return np.where(trend, np.abs(d2) * factor, np.maximum(np.abs(d1), np.abs(d2)))


@dataclass(frozen=True)
class SettleCriteria:
    """Thresholds of the equilibrium rule, SI (s, MPa, rad)."""

    window_s: float
    hold_s: float
    pressure_spread_MPa: float
    angle_spread_rad: float
    timeout_s: float

    def __post_init__(self) -> None:
        for name in ("window_s", "pressure_spread_MPa", "angle_spread_rad", "timeout_s"):
            if not getattr(self, name) > 0:
                raise ValueError(f"settling {name} must be positive, got {getattr(self, name)!r}")
        if self.hold_s < 0:
            raise ValueError(f"settling hold_s must be zero or positive, got {self.hold_s!r}")

    @classmethod
    def from_settling(cls, settling: object) -> SettleCriteria:
        """Build from a protocol's ``settling`` section (attributes or a mapping)."""
        get: Callable[[str], Any] = settling.get if isinstance(settling, dict) else lambda k: getattr(settling, k)
        return cls(
            window_s=float(get("window_s")),
            hold_s=float(get("hold_s")),
            pressure_spread_MPa=float(get("pressure_spread_MPa")),
            angle_spread_rad=float(get("angle_spread_rad")),
            timeout_s=float(get("timeout_s")),
        )

    def describe(self) -> str:
        """The rule in one line, with units, as recorded next to each trial."""
        return (
            f"range of {BLOCKS} block means over {self.window_s:g} s and the tail extrapolated "
            f"from {TAIL_WINDOWS} windows below "
            f"{self.pressure_spread_MPa * 1e3:g} kPa (pressures) and "
            f"{np.degrees(self.angle_spread_rad):.3g} deg (angles) for {self.hold_s:g} s"
        )

    def as_dict(self) -> dict[str, float | str]:
        return {
            "window_s": self.window_s,
            "hold_s": self.hold_s,
            "pressure_spread_MPa": self.pressure_spread_MPa,
            "angle_spread_rad": self.angle_spread_rad,
            "timeout_s": self.timeout_s,
            "rule": self.describe(),
        }


@dataclass(frozen=True)
class SettleStatus:
    """Where the detector stands after the latest samples."""

    elapsed_s: float  # device time since the wait began
    pressure_spread_MPa: float  # largest pressure spread of the last full window (nan before one)
    angle_spread_rad: float  # largest angle spread of the last full window (nan before one)
    quiet_s: float  # how long the spreads have stayed under the thresholds
    settled: bool
    settle_time_s: float  # elapsed time at which the final quiet period began (nan until settled)
    timed_out: bool


class SettleDetector:
    """Feed device-time samples with :meth:`update`; it says when the joint is settled.

    ``pressure_cols``, ``angle_cols`` and ``length_cols`` index the SI columns
    that the thresholds apply to; length columns need ``length_spread_m``, their
    limit.  ``drift_per_s`` (shape (k,), SI units per second, zero where none is
    known) is each channel's steady drift, taken out before the spreads and the
    tail are judged (the module docstring).  ``t_s`` must be non-decreasing device
    time in seconds (already unwrapped); its origin is the first sample seen.
    """

    def __init__(
        self,
        criteria: SettleCriteria,
        pressure_cols: tuple[int, ...] | list[int],
        angle_cols: tuple[int, ...] | list[int],
        length_cols: tuple[int, ...] | list[int] = (),
        length_spread_m: float | None = None,
        drift_per_s: np.ndarray | tuple[float, ...] | None = None,
    ) -> None:
        self.criteria = criteria
        drift = np.zeros(0) if drift_per_s is None else np.asarray(drift_per_s, dtype=float)
        if not np.all(np.isfinite(drift)):
            raise ValueError(f"settling drift_per_s must be finite, got {drift_per_s!r}")
        # The drift over each block of the tail's history, oldest first: subtracted from the block means.
        steps = np.arange(TAIL_WINDOWS * BLOCKS)[:, None] * (criteria.window_s / BLOCKS)
        self._drift = steps * drift[None, :] if np.any(drift) else None
        self._pcols = list(pressure_cols)
        self._acols = list(angle_cols)
        self._lcols = list(length_cols)
        if self._lcols and not (length_spread_m and length_spread_m > 0):
            raise ValueError(f"settling length_spread_m must be positive, got {length_spread_m!r}")
        # Lands the length limit on the angle limit, so one motion spread covers both.
        self._length_scale = criteria.angle_spread_rad / length_spread_m if self._lcols and length_spread_m else 0.0
        self._block_s = criteria.window_s / BLOCKS
        self._timeout_s = criteria.timeout_s
        self._t0: float | None = None
        self._block_index = 0
        self._sum = np.zeros(0)  # the open block's running sum (sized by the first samples)
        self._count = 0
        self._means = np.zeros((0, 0))  # the last TAIL_WINDOWS * BLOCKS block means, oldest first
        self._quiet_since: float | None = None  # block-end time when the quiet run began
        self._status = SettleStatus(0.0, float("nan"), float("nan"), 0.0, False, float("nan"), False)
        self.consumed = 0

    @property
    def origin_s(self) -> float:
        """Device time of the first sample (the zero of ``elapsed_s``); 0 before any."""
        return self._t0 or 0.0

    @property
    def status(self) -> SettleStatus:
        return self._status

    @property
    def leak_note(self) -> str:
        """What the wait's criterion adds when it takes a steady drift out of the pressures
        (``", less the leaks (up to 3.6 kPa/min)"``: the run file keeps 192 bytes of it), or ``""``."""
        if self._drift is None or not self._pcols:
            return ""
        largest = float(np.abs(self._drift[1, self._pcols]).max()) / self._block_s
        return f", less the leaks (up to {largest * 60e3:.2g} kPa/min)" if largest > 0 else ""

    def extend_timeout(self, extra_s: float | None = None) -> None:
        """Wait longer: push the timeout out by ``extra_s`` (default: one more timeout)."""
        self._timeout_s += self.criteria.timeout_s if extra_s is None else extra_s
        s = self._status
        self._status = SettleStatus(
            s.elapsed_s,
            s.pressure_spread_MPa,
            s.angle_spread_rad,
            s.quiet_s,
            s.settled,
            s.settle_time_s,
            False,
        )

    def update(self, t_s: np.ndarray, si: np.ndarray) -> SettleStatus:
        """Add samples (``t_s`` shape (n,), ``si`` shape (n, k)) and return the new status.

        Samples after the moment of decision (settled, or the timeout) are not
        consumed; :attr:`consumed` says how many of this call's samples were.
        """
        t_s = np.asarray(t_s, dtype=float)
        si = np.asarray(si, dtype=float)
        self.consumed = 0
        if t_s.size == 0 or self._status.settled or self._status.timed_out:
            return self._status
        if self._t0 is None:
            if self._drift is not None and self._drift.shape[1] != si.shape[1]:
                raise ValueError(f"settling drift_per_s has {self._drift.shape[1]} channels, the samples {si.shape[1]}")
            self._t0 = float(t_s[0])
            self._sum = np.zeros(si.shape[1])
            self._means = np.zeros((0, si.shape[1]))
        rel = t_s - self._t0
        # Consume up to and including the first sample at or past the timeout.
        stop = min(len(rel), int(np.searchsorted(rel, self._timeout_s, side="left")) + 1)
        idx = np.floor(rel[:stop] / self._block_s).astype(np.int64)
        # Split the batch where the block index changes; every completed block
        # is one evaluation point, whatever the size of the read batches.
        starts = np.concatenate(([0], np.flatnonzero(np.diff(idx)) + 1))
        ends = np.append(starts[1:], stop)
        blocks = idx[starts]
        # Row by row, as a running sum adds them (np.add.reduceat rounds differently).
        sums = np.array([si[i:k].sum(axis=0) for i, k in zip(starts, ends, strict=False)])
        counts = ends - starts
        if blocks[0] == self._block_index:  # the batch goes on with the open block
            sums[0] += self._sum
            counts[0] += self._count
        else:  # it completes the open block at its first sample
            starts = np.concatenate(([0], starts))
            blocks = np.concatenate(([self._block_index], blocks))
            sums = np.concatenate(([self._sum], sums))
            counts = np.concatenate(([self._count], counts))
        self._block_index, self._sum, self._count = int(blocks[-1]), sums[-1], int(counts[-1])
        if len(blocks) > 1:
            decided = self._judge(blocks[:-1], sums[:-1], counts[:-1])
            if decided is not None:
                self.consumed = int(starts[decided + 1])  # the sample that completed the deciding block
                return self._status
        self.consumed = stop
        elapsed = float(rel[stop - 1])
        s = self._status
        timed_out = elapsed >= self._timeout_s
        self._status = SettleStatus(
            elapsed,
            s.pressure_spread_MPa,
            s.angle_spread_rad,
            s.quiet_s,
            s.settled,
            s.settle_time_s,
            timed_out,
        )
        return self._status

    def _judge(self, blocks: np.ndarray, sums: np.ndarray, counts: np.ndarray) -> int | None:
        """Judge completed blocks in order, the windows' arithmetic for all of them at once.

        A block without samples adds nothing to the history of block means but
        is still judged.  Sets the status of the first settled block, or else of
        the last, and returns the position of the settled one (None if none is).
        """
        c = self.criteria
        full = counts > 0
        history = np.concatenate([self._means, sums[full] / counts[full, None]])
        self._means = history[-TAIL_WINDOWS * BLOCKS :]
        # History length after each block: one window of it gives the spreads, three the tail.
        length = len(history) - int(full.sum()) + np.cumsum(full)
        spread_p, spread_a = np.full((2, len(blocks)), np.nan)
        tail_p, tail_a = np.full((2, len(blocks)), np.inf)  # no tail estimate yet: not quiet
        one = np.flatnonzero(length >= BLOCKS)
        if len(one):
            m = self._steady(history[length[one, None] + np.arange(-BLOCKS, 0)])
            spread_p[one], spread_a[one] = self._largest(m.max(axis=1) - m.min(axis=1))
        three = np.flatnonzero(length >= TAIL_WINDOWS * BLOCKS)
        if len(three):
            m = self._steady(history[length[three, None] + np.arange(-TAIL_WINDOWS * BLOCKS, 0)])
            A, B, C = np.moveaxis(m.reshape(len(three), TAIL_WINDOWS, BLOCKS, -1).mean(axis=2), 1, 0)
            tail_p[three], tail_a[three] = self._largest(remaining_tail(A, B, C))
        quiet = (np.maximum(spread_p, tail_p) < c.pressure_spread_MPa) & (
            np.maximum(spread_a, tail_a) < c.angle_spread_rad
        )
        # The run of quiet blocks and the hold, block by block (plain floats: a few per batch).
        t_end, quiet, length = ((blocks + 1) * self._block_s).tolist(), quiet.tolist(), length.tolist()
        settled = False
        for j in range(len(t_end)):
            if length[j] < BLOCKS:
                continue  # not one window yet: nothing to judge (and nothing was quiet before)
            if not quiet[j]:
                self._quiet_since = None
            elif self._quiet_since is None:
                self._quiet_since = t_end[j]
            if quiet[j] and t_end[j] - self._quiet_since >= c.hold_s - 1e-9:
                settled = True
                break
        if length[j] < BLOCKS:
            self._status = SettleStatus(t_end[j], float("nan"), float("nan"), 0.0, False, float("nan"), False)
            return None
        quiet_s = 0.0 if self._quiet_since is None else t_end[j] - self._quiet_since
        self._status = SettleStatus(
            t_end[j],
            float(spread_p[j]),
            float(spread_a[j]),
            quiet_s,
            settled,
            self._quiet_since if settled and self._quiet_since is not None else float("nan"),
            False,
        )
        return j if settled else None

    def _steady(self, means: np.ndarray) -> np.ndarray:
        """Block means (evaluations, blocks, channels) less the steady drift since their first block."""
        if self._drift is None:
            return means
        return means - self._drift[None, : means.shape[1], :]

    def _largest(self, per_channel: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Largest pressure and motion (angle, or length as the same share of its limit) values per row."""
        none = np.zeros(per_channel.shape[:-1])
        ps = per_channel[..., self._pcols].max(axis=-1) if self._pcols else none
        an = per_channel[..., self._acols].max(axis=-1) if self._acols else none
        if self._lcols:
            an = np.maximum(an, per_channel[..., self._lcols].max(axis=-1) * self._length_scale)
        return ps, an


class TimeUnwrapper:
    """Turn the device's wrapping 32-bit microsecond clock into seconds.

    Consecutive frames are assumed less than 2**32 us (71 min) apart, which any
    streaming rig satisfies.
    """

    WRAP = 1 << 32

    def __init__(self) -> None:
        self._last: int | None = None
        self._offset = 0  # us added to raw t_us

    def __call__(self, t_us: np.ndarray) -> np.ndarray:
        t = np.asarray(t_us, dtype=np.int64)
        if t.size == 0:
            return np.zeros(0)
        prev = np.concatenate(([t[0] if self._last is None else self._last], t[:-1]))
        step = (t - prev) % self.WRAP
        if self._last is None:
            base = int(t[0])
        else:
            base = self._last + self._offset
        absolute = base + np.cumsum(step)
        self._offset = int(absolute[-1]) - int(t[-1])
        self._last = int(t[-1])
        return absolute.astype(float) * 1e-6
