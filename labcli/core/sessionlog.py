"""Which rig a run was recorded on, and what each session at the rig did: the seam to the run file.

A run may take several sessions (a quit, a Ctrl-C, a lost rig, the next morning), so the
run file keeps a log of them: when each began and ended, on which port and rig, at which
baud rate, which records it added, redid and skipped, and how it ended.  The engine
reports to the run file's ``run.sessions`` (:class:`SessionLog`); a session started without
the facts a log records (a test driving the engine) reports to :class:`NoSessionLog`.

:class:`RigIdentity` is what identifies a rig to a resumed run: the ``ID?`` reply's device
and firmware, the channel names, and the calibration (gain and offset per channel, SI).
:func:`recorded_identity` reads it from a run file: the identity of the rig that recorded
its latest session where the run logged one, else what every run file has
recorded since its creation (root attributes ``device``, ``firmware``, ``channels`` and the
``calibration`` group).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, Protocol, runtime_checkable

# How a session ended (SessionLog.end): the engine's outcome, or why it stopped.
ENDINGS = ("finished", "quit", "interrupted", "no input", "rig lost", "error")


@dataclass(frozen=True)
class RigIdentity:
    """What identifies a rig: ``ID?`` device and firmware, channel names, calibration (SI per count, SI)."""

    device: str
    firmware: str
    channels: tuple[str, ...]
    gain: tuple[float, ...] = ()
    offset: tuple[float, ...] = ()

    @classmethod
    def of(cls, info: Any, calibration: Any) -> RigIdentity:
        """The identity of an open rig (``Device.info``) read with ``calibration``."""
        gain, offset = calibration_vectors(calibration, len(info.channels))
        return cls(str(info.device), str(info.firmware), tuple(info.channels), gain, offset)

    def differences(self, other: RigIdentity) -> list[str]:
        """What differs from ``other`` (the rig at hand), one phrase each, in the words of the ID reply."""
        out = []
        if self.device != other.device:
            out.append(f"device {other.device!r}, not {self.device!r}")
        if self.firmware != other.firmware:
            out.append(f"firmware {other.firmware!r}, not {self.firmware!r}")
        if self.channels != other.channels:
            out.append(f"channels {','.join(other.channels)}, not {','.join(self.channels)}")
        elif self.gain and other.gain:
            changed = [
                name
                for name, g0, g1, o0, o1 in zip(
                    self.channels, self.gain, other.gain, self.offset, other.offset, strict=False
                )
                if not (_same(g0, g1) and _same(o0, o1))
            ]
            if changed:
                out.append(f"another calibration of {describe(changed)}")
        return out


def _same(a: float, b: float) -> bool:
    if math.isnan(a) or math.isnan(b):
        return math.isnan(a) and math.isnan(b)
    return math.isclose(a, b, rel_tol=1e-9, abs_tol=1e-12)


def calibration_vectors(calibration: Any, k: int) -> tuple[tuple[float, ...], tuple[float, ...]]:
    """Gain (SI per count) and offset (SI at 0 counts) of a linear calibration, per channel."""
    if calibration is None or not hasattr(calibration, "to_si"):
        return (), ()
    if len(getattr(calibration, "names", ())) != k:
        # Another rig's channels: the setup check refuses it with its own sentence.
        return (), ()
    import numpy as np

    probe = np.array([[0.0] * k, [1000.0] * k])
    si = np.asarray(calibration.to_si(probe), dtype=float)
    return tuple(float(x) for x in (si[1] - si[0]) / 1000.0), tuple(float(x) for x in si[0])


@dataclass(frozen=True)
class SessionInfo:
    """The start of one session at the rig, as the log records it."""

    started: str  # ISO 8601 UTC with microseconds
    port: str
    baud: int
    rig: RigIdentity
    operator: str = ""
    command: str = ""  # the command line that continues the run
    resumed: bool = False
    other_rig: bool = False  # resumed on a rig other than the run's, with --allow-other-rig


@runtime_checkable
class SessionLog(Protocol):
    """What the engine tells a run file about each session (the run file's session-log API)."""

    def begin(self, info: SessionInfo) -> None:
        """A session starts writing to the run (before its first record)."""

    def added(self, rid: int) -> None:
        """Record ``rid`` was stored whole by this session."""

    def redone(self, rid: int) -> None:
        """The experimenter (or a check) redid record ``rid`` before storing it."""

    def skipped(self, rid: int) -> None:
        """Record ``rid`` was skipped: not stored by this session."""

    def end(self, how: str) -> None:
        """The session ended: one of :data:`ENDINGS`, at the time of the call."""

    def rig_identity(self) -> RigIdentity | None:
        """The rig of the run's latest session (None: no session recorded yet)."""


class NoSessionLog:
    """For a session without the facts a log records: every report is dropped."""

    def begin(self, info: SessionInfo) -> None:
        pass

    def added(self, rid: int) -> None:
        pass

    def redone(self, rid: int) -> None:
        pass

    def skipped(self, rid: int) -> None:
        pass

    def end(self, how: str) -> None:
        pass

    def rig_identity(self) -> RigIdentity | None:
        return None


def recorded_identity(run: Any) -> RigIdentity:
    """The rig a run file was recorded on (its latest session's, else the one that created it)."""
    latest = run.sessions.rig_identity()
    if latest is not None:
        return latest
    attrs = run.attrs
    channels = tuple(str(c) for c in run.channels)
    cal = run.calibration() if callable(run.calibration) else run.calibration
    gain = tuple(float(x) for x in cal.get("gain", ())) if cal else ()
    offset = tuple(float(x) for x in cal.get("offset", ())) if cal else ()
    return RigIdentity(str(attrs.get("device", "")), str(attrs.get("firmware", "")), channels, gain, offset)


def describe(differences: Sequence[str]) -> str:
    """``a, b and c``."""
    items = list(differences)
    return items[0] if len(items) == 1 else ", ".join(items[:-1]) + " and " + items[-1]
