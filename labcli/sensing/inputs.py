"""From the frames a rig sends to the numbers the estimator works on.

The estimator takes frames as the reader delivers them (:class:`labcli.core.wire.FrameBatch`:
raw ADC counts, device time in microseconds) and converts them here, with the protocol's
calibration (:mod:`labcli.core.calibration`), into SI values in the model's order: the
pressures of the model's actuators (MPa gauge), then the angles of its joints (rad).
Channels are matched by their role (``actuator = "L1"``, ``joint = 1`` in the protocol file),
so a rig that sends its channels in another order still feeds the right column, and a rig
that lacks one is refused in one sentence.
"""

from __future__ import annotations

import functools
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..errors import ModelError

U32 = 1 << 32


@dataclass(frozen=True)
class Inputs:
    """Where each of the model's inputs sits among the device's channels, and its calibration.

    ``columns``: device column of each input (pressures, then angles); ``gain`` and ``zero``
    (SI per count, and the count that reads zero) of those channels; ``names`` the channel
    names; ``n_pressures`` how many of the inputs are pressures; ``span`` each channel's
    range in SI (a reading outside it is a broken sensor, not a load).
    """

    columns: tuple[int, ...]
    gain: np.ndarray
    zero: np.ndarray
    names: tuple[str, ...]
    n_pressures: int
    span: np.ndarray  # (k, 2)
    counts: bool = True  # False: the inputs come in SI already

    @classmethod
    def from_calibration(cls, calibration: Any, model: Any, channels: Sequence[str] | None = None) -> Inputs:
        """Match the model's channel roles to ``calibration`` (a protocol's) and the device's
        ``channels`` (its ``ID?`` reply; None: the calibration's own order)."""
        by_actuator = {c.actuator: c for c in calibration.channels if c.quantity == "pressure" and c.actuator}
        by_joint = {c.joint: c for c in calibration.channels if c.quantity == "angle" and c.joint}
        wanted = [("actuator", a, by_actuator.get(a)) for a in model.actuators]
        wanted += [("joint", j, by_joint.get(j)) for j in model.joints]
        lacking = [f"{role} {name}" for role, name, ch in wanted if ch is None]
        if lacking:
            raise ModelError(
                f"The protocol's calibration names no channel for {', '.join(lacking)}, which the model reads; "
                "use the protocol the model was fitted with."
            )
        chans = [ch for _, _, ch in wanted if ch is not None]
        device = list(channels) if channels is not None else list(calibration.names)
        absent = [ch.name for ch in chans if ch.name not in device]
        if absent:
            raise ModelError(
                f"The rig sends the channels {','.join(device)} but the model reads {','.join(absent)} too; "
                "connect the rig the model was fitted on, or fit a model for this one."
            )
        return cls(
            columns=tuple(device.index(ch.name) for ch in chans),
            gain=np.array([ch.gain for ch in chans], dtype=float),
            zero=np.array([ch.zero_counts for ch in chans], dtype=float),
            names=tuple(ch.name for ch in chans),
            n_pressures=len(model.actuators),
            span=np.array([ch.range for ch in chans], dtype=float),
        )

    @classmethod
    def identity(cls, model: Any) -> Inputs:
        """Inputs already in SI and in the model's order (tables, tests): no conversion."""
        k = len(model.actuators) + len(model.joints)
        names = tuple(f"P_{a}" for a in model.actuators) + tuple(f"POT{j}" for j in model.joints)
        span = np.array([[0.0, np.inf]] * len(model.actuators) + [[-np.pi, np.pi]] * len(model.joints))
        return cls(tuple(range(k)), np.ones(k), np.zeros(k), names, len(model.actuators), span, counts=False)

    @property
    def resolution(self) -> np.ndarray:
        """SI value of one count per input (0 for inputs given in SI)."""
        return np.abs(self.gain) if self.counts else np.zeros(self.width)

    @property
    def width(self) -> int:
        return len(self.columns)

    def si(self, counts: np.ndarray) -> np.ndarray:
        """Raw counts (n, device channels) -> SI values (n, k) in the model's order."""
        return (np.asarray(counts, dtype=float)[:, self._take] - self.zero) * self.gain

    @functools.cached_property
    def _take(self) -> np.ndarray:
        return np.array(self.columns, dtype=np.intp)


class DeviceClock:
    """Device time in seconds from ``t_us`` that wraps at 2**32 (about every 71.6 minutes)."""

    def __init__(self) -> None:
        self._last: int | None = None
        self._offset = 0

    def seconds(self, t_us: np.ndarray) -> np.ndarray:
        t = np.asarray(t_us, dtype=np.int64)
        if not t.size:
            return np.empty(0)
        last = int(t[-1])
        first = int(t[0])
        half = U32 >> 1
        # The common case, one batch a read with no wrap in it: no cumulative sum to take (the
        # estimator converts every read's times).
        if (self._last is None or first - self._last >= -half) and (t.size == 1 or (t[1:] - t[:-1]).min() >= -half):
            self._last = last
            return (t + self._offset * U32) * 1e-6
        prev = np.empty_like(t)
        prev[0] = t[0] if self._last is None else self._last
        prev[1:] = t[:-1]
        wraps = np.cumsum((t - prev) < -(U32 >> 1))  # a jump back by more than half the range is a wrap
        out = (t + (self._offset + wraps) * U32) * 1e-6
        self._offset += int(wraps[-1])
        self._last = int(t[-1])
        return out


def frame_arrays(frames: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """seq, t_us, values of a FrameBatch or of an iterable of Frame objects."""
    if hasattr(frames, "seq") and hasattr(frames, "values") and isinstance(frames.seq, np.ndarray):
        return frames.seq, frames.t_us, frames.values
    items: Iterable[Any] = list(frames)
    rows = [f for f in items if hasattr(f, "values")]
    if not rows:
        return np.empty(0, np.int64), np.empty(0, np.int64), np.empty((0, 0))
    return (
        np.array([f.seq for f in rows], dtype=np.int64),
        np.array([f.t_us for f in rows], dtype=np.int64),
        np.array([f.values for f in rows], dtype=float),
    )
