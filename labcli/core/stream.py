"""The rig's frames as the engine reads them: in blocks, timed by the rig's own clock, checked as they come.

:class:`FrameStream` starts and stops the rig's stream, reads its frames in blocks (each a
:class:`~labcli.core.window.Window` held in memory, calibrated by the protocol), and hands
out exactly the frames that cover a stretch of the rig's time, keeping the frames past the
end for whatever reads next.  Timing is device time (the frames' ``t_us``, unwrapped), so a
simulated rig in virtual time runs a whole protocol in seconds; only the "rig silent" check
uses the wall clock, because a silent rig has no clock to read.

Every block is checked against the rig's clock: a clock that stands still, goes back or
jumps (a board that restarted mid-stream) and frames arriving far faster than the clock
says they were sampled are refused (:class:`~labcli.errors.DeviceClockError`); a window
whose frames come off the rate the rig confirmed is flagged (:meth:`FrameStream.rate_problem`).
"""

from __future__ import annotations

import contextlib
import math
import time
from collections.abc import Callable
from typing import Any

import numpy as np

from ..errors import DeviceClockError, DeviceTimeout
from . import interrupts
from .settle import TimeUnwrapper
from .window import Window

RATE_TOLERANCE = 0.05  # a stream whose own clock says it runs 5 % off the rate set is flagged
MAX_STEP_US = 60_000_000  # a step of the rig's clock between two frames beyond 60 s: not a clock
# Frames arriving 50x faster than the rig's clock says it sampled them: a capture window would
# take 50x its length (a clock counting in the wrong unit), so the rig is refused.  Below that
# the stream is only off its rate (a timer set wrong, 10x or 0.1x): flagged (RATE_TOLERANCE).
SLOW_CLOCK = 50.0


class FrameStream:
    """The frames of one rig (``device``), calibrated by ``calibration`` (see the module docstring).

    ``port``: the port as sentences name it; ``silent_s``: wall-clock seconds without a frame
    before the rig counts as silent (the device's own limit usually comes first).
    """

    def __init__(self, device: Any, calibration: Any, port: Callable[[], str], silent_s: float) -> None:
        self.device = device
        self.calibration = calibration
        self.silent_s = silent_s
        self.rate_set: float | None = None  # the rate the firmware confirmed
        self._port = port
        self._streaming = False
        self._unwrap = TimeUnwrapper()
        self._pending: Window | None = None  # frames read past what was asked, for what reads next
        self._clock: tuple[int, int, float] | None = None  # (last t_us, frames, device s) of this stream

    def start(self) -> None:
        """Start the rig's stream (unless it runs): a new stream, a new clock."""
        if not self._streaming:
            self.device.start()
            self._streaming = True
            self._unwrap = TimeUnwrapper()
            self._clock = None
            self._pending = None

    def stop(self) -> None:
        """Stop the rig's stream (unless it is stopped); frames read past the last window are dropped."""
        if self._streaming:
            self._streaming = False
            self._pending = None
            self.device.stop()

    def stop_quietly(self) -> None:
        """Stop the stream if the rig still answers (after a quit, an interrupt, a lost rig)."""
        with contextlib.suppress(Exception):
            self.stop()

    def reconnected(self, device: Any) -> None:
        """The rig was opened again (``device``): nothing of the old stream carries over."""
        self.device = device
        self._streaming = False
        self._pending = None

    def keep(self, rest: Window) -> None:
        """Frames read past what a reader needed, handed to whatever reads next."""
        self._pending = rest if len(rest) else None

    def next_block(self) -> Window:
        """The next frames; frames kept back first.  Raises DeviceTimeout if the rig goes silent."""
        if self._pending is not None and len(self._pending):
            w, self._pending = self._pending, None
            return w
        # The device raises DeviceTimeout itself after its own silence limit;
        # this wall-clock deadline is the backstop for a device that does not.
        deadline = time.monotonic() + self.silent_s
        while True:
            interrupts.check()
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                raise DeviceTimeout(f"no data for {self.silent_s:g} s")
            batch = self.device.read(timeout=min(remaining, 1.0))
            if len(batch):
                t_us = np.asarray(batch.t_us, dtype=np.int64)
                self._check_clock(t_us)
                counts = np.asarray(batch.values, dtype=float)
                return Window.of(
                    np.asarray(batch.seq, dtype=np.int64),
                    counts,
                    np.asarray(self.calibration.to_si(counts), dtype=float),
                    t_us=t_us,
                    t_s=self._unwrap(batch.t_us),
                )

    def stream(self, duration_s: float, take: Callable[[Window], None]) -> None:
        """Hand ``take`` the frames covering ``duration_s`` of device time from the next frame on, block by block."""
        t0: float | None = None
        while True:
            w = self.next_block()
            if t0 is None:
                t0 = float(w.t_s[0])
            n = int(np.searchsorted(w.t_s, t0 + duration_s, side="left"))
            if n < len(w):
                if n:
                    take(w[:n])
                self.keep(w[n:])
                return
            take(w)

    def collect(self, duration_s: float) -> Window:
        """Frames covering ``duration_s`` of device time, in memory (the setup check's half second)."""
        parts: list[Window] = []
        self.stream(duration_s, parts.append)
        return Window.concat(parts)

    def _check_clock(self, t_us: np.ndarray) -> None:
        """The rig's clock must move forward, by less than a minute a frame, and not far slower than frames come.

        A step of ``t_us`` (modulo the 32-bit wrap) of zero or of more than :data:`MAX_STEP_US`
        is a clock that stood still or went back (a board that restarted mid-stream does
        this); frames arriving :data:`SLOW_CLOCK` times faster than the rig's clock says it
        sampled them would fill a capture window forever.
        """
        last, frames, span = self._clock if self._clock is not None else (int(t_us[0]) - 1, 0, 0.0)
        steps = np.diff(np.concatenate(([last], t_us))) % (1 << 32)
        bad = np.flatnonzero((steps == 0) | (steps > MAX_STEP_US))
        if len(bad):
            i = int(bad[0])
            before = last if i == 0 else int(t_us[i - 1])
            what = (
                f"sent a timestamp that does not follow the one before (t_us {int(t_us[i])} after {before}), "
                "as a clock that went back or a board that restarted does"
            )
            raise DeviceClockError(f"The rig on {self._port()} {what}.", what=what)
        frames += len(t_us)
        span += float(steps.sum()) * 1e-6
        self._clock = (int(t_us[-1]), frames, span)
        if self.rate_set and frames > 1000 and frames > SLOW_CLOCK * self.rate_set * span:
            what = (
                f"sent {frames} frames over only {span:.3g} s of its own clock, "
                f"{frames / span if span else math.inf:.4g} frames per second at {self.rate_set:g} Hz set"
            )
            raise DeviceClockError(f"The rig on {self._port()} {what}.", what=what)

    def rate_problem(self, frames: int, gap: float) -> tuple[str, float] | None:
        """What is wrong with a window of ``frames`` frames whose median ``gap`` (s, rig's clock) is off
        the rate the rig confirmed: the sentence, and the rate (Hz); None when it is on it."""
        if not self.rate_set or frames < 10:
            return None
        rate = 1.0 / gap if gap > 0 else math.inf
        if abs(rate / self.rate_set - 1.0) <= RATE_TOLERANCE:
            return None
        text = (
            f"the rig streams at {rate:.4g} Hz by its own clock, not the {self.rate_set:g} Hz it confirmed; "
            "check its firmware's timer"
        )
        return text, rate
