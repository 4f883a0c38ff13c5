"""The run engine: executes a session's steps against a device, a run file and a UI.

A paper's session of steps (:mod:`labcli.core.steps`) says *what* happens in a run;
this module does it: it reads frames from the :class:`~labcli.core.device.Device`, converts them with the
protocol's calibration, judges equilibrium (:mod:`labcli.core.settle`), writes
finished records to the :class:`~labcli.core.store.RunFile` and talks to the
experimenter through a UI (:mod:`labcli.core.ui`).

Timing is device time (the frames' ``t_us``, unwrapped), so a simulated rig in
virtual time runs a whole protocol in seconds.  Only the "rig silent" check
uses the wall clock, because a silent rig has no clock to read.

A trial's capture windows (``Baseline``, ``Capture``) are streamed into the run file as
their frames arrive (:mod:`labcli.core.capture`), so memory stays flat however long a
window is; but nothing counts until the ``Commit`` step commits the trial's record (its
row, statistics and window checksums) last.  An unplugged rig, a quit, Ctrl-C, a kill or a
full disk therefore discard only the trial in progress: its frames stay in the file,
referenced by no record, and are never read as a trial.  A new run's file is created when
its first trial begins (or its session finishes with none), so a session that stops during
the setup or the air supply leaves no file behind.  An attended run whose rig is lost asks the
experimenter to reconnect it, opens the same port again and starts the session
afresh (setup check, air supply, then the interrupted trial from its
baseline); an unattended one ends with the command that resumes it.
"""

from __future__ import annotations

import contextlib
import math
import signal
import threading
import time
from collections.abc import Callable, Generator, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import ConfigError, DeviceClockError, DeviceDisconnected, DeviceError, DeviceTimeout, DiskFull
from . import interrupts
from .capture import WindowSink
from .sessionlog import NoSessionLog, SessionInfo, SessionLog
from .settle import SettleCriteria, SettleDetector, TimeUnwrapper
from .steps import (
    Ask,
    Baseline,
    BeginTrial,
    Capture,
    Commit,
    Finish,
    Problem,
    Prompt,
    Review,
    SettleReport,
    SetupCheck,
    WaitSettle,
    Window,
)
from .timestamps import utc_now
from .ui import InputEnded, QuitRequested

SILENT_S = 5.0  # wall-clock seconds without a frame before the rig counts as silent
SETUP_S = 0.5  # device seconds of readings for the setup check
PRESSURE_MARGIN_MPA = 0.02  # sensor noise and offset allowed outside the 0-1 MPa span
RATE_TOLERANCE = 0.05  # a stream whose own clock says it runs 5 % off the rate set is flagged
MAX_STEP_US = 60_000_000  # a step of the rig's clock between two frames beyond 60 s: not a clock
# Frames arriving 50x faster than the rig's clock says it sampled them: a capture window would
# take 50x its length (a clock counting in the wrong unit), so the rig is refused.  Below that
# the stream is only off its rate (a timer set wrong, 10x or 0.1x): flagged (RATE_TOLERANCE).
SLOW_CLOCK = 50.0
LOST_RIG = (DeviceDisconnected, DeviceTimeout, DeviceClockError)


@dataclass
class Outcome:
    """How a session ended; ``message`` is the sentence to print."""

    status: str  # "finished" | "quit" | "interrupted" | "no input"
    message: str
    stored: int  # trials committed by this session
    complete: int  # trials complete in the file
    skipped: tuple[int, ...] = ()
    wall_s: float = 0.0

    @property
    def exit_code(self) -> int:
        return {"finished": 0, "quit": 0, "interrupted": 130, "no input": 1}[self.status]


class RunEngine:
    """Drive one session to its end.

    ``device``: an open :class:`labcli.core.device.Device`; ``store``: a writable
    :class:`labcli.core.store.RunFile`; ``ui``: :class:`labcli.core.ui.RichUI` or
    :class:`labcli.core.ui.UnattendedUI`; ``resume_command``: the exact command line
    that continues this run, quoted in every "how to resume" sentence.
    Subscribers (``subscribe``) see every step and its reply, for logging and tests.
    A store that keeps a session log (:class:`labcli.core.sessionlog.SessionLog`) is told
    how the session began (``session``: port, baud, rig, ...), what it did, how it ended.
    """

    def __init__(
        self,
        device: Any,
        store: Any,
        protocol: Any,
        ui: Any,
        *,
        run_path: str | Path,
        resume_command: str,
        rate_hz: float | None = None,
        silent_s: float = SILENT_S,
        noun: str = "trial",
        session: SessionInfo | None = None,
    ) -> None:
        self.device = device
        # A callable store is created on first use, so a session that fails its
        # setup check leaves no run file behind.
        self._store = None if callable(store) else store
        self._store_factory = store if callable(store) else None
        self.protocol = protocol
        self.ui = ui
        self.run_path = str(run_path)
        self.resume_command = resume_command
        self.rate_hz = rate_hz
        self.silent_s = silent_s
        self.criteria = SettleCriteria.from_settling(protocol.settling)
        self._noun = noun  # what one record is called in sentences ("trial", "push", "point")
        units = tuple(protocol.calibration.units)
        self._pcols = [i for i, u in enumerate(units) if u == "MPa"]
        self._acols = [i for i, u in enumerate(units) if u == "rad"]
        # Length channels (a draw-wire sensor) settle only under a protocol that gives
        # their limit; without one they are not watched.
        self._length_spread_m = getattr(protocol.settling, "length_spread_m", None)
        self._lcols = [i for i, u in enumerate(units) if u == "m"] if self._length_spread_m else []
        self._subscribers: list[Callable[[Any, Any], None]] = []
        self._streaming = False
        self._unwrap = TimeUnwrapper()
        self._pending: Window | None = None
        self._trial: BeginTrial | None = None  # the trial in progress (None between trials)
        self._trials_begun = False
        self._finished = False
        self._skipped: list[int] = []
        self._stored = 0
        self._t_start = 0.0
        self._trial_walls: list[float] = []
        self._trial_wall_start = 0.0
        self._trial_started = ""
        self._session = session
        self._log: SessionLog = NoSessionLog()
        self._logging = False
        self._rate_set: float | None = None  # the rate the firmware confirmed
        self._rate_warned: set[float] = set()
        self._flags: list[str] = []  # what the stream did wrong during the trial in progress
        self._clock: tuple[int, int, float] | None = None  # (last t_us, frames, device s) of this stream

    @property
    def store(self) -> Any:
        if self._store is None:
            self._store = self._store_factory()
        if not self._logging:
            self._logging = True
            if self._session is not None:  # without a session's facts there is nothing to log
                self._log = self._store.sessions
                self._log.begin(self._session)
        return self._store

    @property
    def store_created(self) -> bool:
        return self._store is not None

    def subscribe(self, callback: Callable[[Any, Any], None]) -> None:
        """Call ``callback(step, reply)`` after every executed step."""
        self._subscribers.append(callback)

    # ------------------------------------------------------------------ main loop
    def run(
        self,
        session: Generator[Any, Any, None],
        *,
        restart: Callable[[tuple[int, ...]], Generator[Any, Any, None]] | None = None,
        reopen: Callable[[], Any] | None = None,
    ) -> Outcome:
        """Execute ``session`` to its end and say how it ended.

        With ``reopen`` (opens the same port again, returns a Device) and
        ``restart`` (a new session given the ids already stored or skipped), an
        attended run survives a lost rig: the experimenter is asked to reconnect
        it, and the new session redoes the setup and the interrupted trial from
        its baseline.  Without them, or unattended, a lost rig ends the run with
        a DeviceError whose sentence gives the resume command.
        """
        if self.ui.unattended and getattr(self.device, "rig", None) is None:
            raise ConfigError(
                f"--unattended drives the simulated rig only, and {self._port()} is a real port: "
                "run without --unattended and follow the prompts."
            )
        self._t_start = time.monotonic()
        if self._store is not None:
            self.store  # a resumed run: the session begins now
        how = "error"
        try:
            with interrupts.kept():  # a Ctrl-C landing in h5py's clean-up is kept, not lost
                outcome = self._run(session, restart, reopen)
            how = outcome.status
            return outcome
        except LOST_RIG:
            how = "rig lost"
            raise
        except DiskFull:
            how = "disk full"
            raise
        finally:
            if self._logging:
                self._log.end(how)

    def _run(self, session: Generator[Any, Any, None], restart: Any, reopen: Any) -> Outcome:
        while True:
            try:
                return self._drive(session)
            except LOST_RIG as e:
                lost = e
            wait = restart is not None and reopen is not None and not self.ui.unattended
            try:
                back = wait and self._wait_for_rig(lost, reopen)
            except KeyboardInterrupt:
                return self._outcome("interrupted", ())
            if not back:
                raise type(lost)(self._lost_rig_message(lost)) from lost
            session = restart(tuple(self._done_ids()))

    def _drive(self, session: Generator[Any, Any, None]) -> Outcome:
        reply: Any = None
        try:
            while True:
                try:
                    step = session.send(reply)
                except StopIteration:
                    return self._outcome("finished", tuple(self._skipped))
                reply = self._execute(step)
                interrupts.check()
                for cb in self._subscribers:
                    cb(step, reply)
                if isinstance(step, (Review, WaitSettle)) and self._trial is not None and reply in ("redo", "skip"):
                    self._reviewed(reply)
                if isinstance(step, Finish):
                    session.close()
                    return self._outcome("finished", tuple(dict.fromkeys([*self._skipped, *step.skipped])))
        except InputEnded:
            session.close()
            self._stop_quietly()
            return self._outcome("no input", ())
        except QuitRequested:
            session.close()
            self._stop_quietly()
            return self._outcome("quit", ())
        except KeyboardInterrupt:
            session.close()
            self._stop_quietly()
            if self._finished:  # Ctrl-C after the last step: the run is complete
                return self._outcome("finished", tuple(dict.fromkeys(self._skipped)))
            return self._outcome("interrupted", ())
        except LOST_RIG:
            session.close()
            self._stop_quietly()
            raise

    def _reviewed(self, reply: str) -> None:
        """A trial redone (by a review or a settling timeout) or skipped: the session log hears of it."""
        rid = self._trial.trial
        if reply == "skip":
            self._skipped.append(rid)
            self._trial = None
            if self._logging:
                self._log.skipped(rid)
        elif self._logging:
            self._log.redone(rid)
        self._flags = []

    def _done_ids(self) -> list[int]:
        stored = list(self._store.records.ids()) if self._store is not None else []
        return stored + [t for t in self._skipped if t not in stored]

    def _wait_for_rig(self, e: Exception, reopen: Callable[[], Any]) -> bool:
        """Ask for the lost rig until it opens again (True) or the experimenter stops (False)."""
        port = self._port()
        what = _what(e)
        if self._trial is not None:
            then = (
                f"during {self._current()}, which was not stored; it will be redone from its baseline "
                "once the rig is back"
            )
        else:
            then = f"during {self._current()}; the setup will be redone once the rig is back"
        self.ui.warn(f"The rig on {port} {what} {then}.")
        with contextlib.suppress(Exception):
            self.device.close()
        while True:
            try:
                self.ui.prompt(Prompt(f"Rig lost on {port}; reconnect it and press Enter to retry"))
            except QuitRequested:
                return False
            try:
                device = reopen()
            except DeviceError as err:
                self.ui.warn(str(err))
                continue
            self.device = device
            self._streaming = False
            self._pending = None
            self._trial = None
            self._trials_begun = False  # the new session starts with the setup
            return True

    # ------------------------------------------------------------------ messages
    def _port(self) -> str:
        info = getattr(self.device, "info", None)
        return getattr(info, "port", None) or "the port"

    def _complete(self) -> int:
        if self._store is None:
            return 0
        return len(list(self._store.records.ids()))

    def _current(self) -> str:
        if self._trial is not None:
            return f"{self._noun} {self._trial.trial}"
        if self._trials_begun:
            return f"the pause between {_plural(self._noun)}"
        return "the setup"

    def _lost_rig_message(self, e: Exception) -> str:
        what = _what(e)
        if not self.store_created:
            return (
                f"The rig on {self._port()} {what} during the setup, before anything was written to "
                f"{self.run_path}. Check the cable and power, then run the same command again."
            )
        n = self._complete()
        lost = f"that {self._noun} was not stored and " if self._trial is not None else ""
        return (
            f"The rig on {self._port()} {what} during {self._current()}; {lost}"
            f"the {_count(n, 'completed ' + self._noun)} in {self.run_path} {'is' if n == 1 else 'are'} unchanged. "
            f"Check the cable and power, then resume with: {self.resume_command}"
        )

    def _outcome(self, status: str, skipped: tuple[int, ...]) -> Outcome:
        complete = self._complete()
        wall = time.monotonic() - self._t_start
        stored = _count(complete, self._noun)
        if status == "finished":
            msg = f"Session complete: {stored} stored in {self.run_path} ({self._stored} this session, {wall:.1f} s)."
            if skipped:
                msg += (
                    f" Skipped {_count(len(skipped), self._noun)} ({', '.join(map(str, skipped))}) "
                    f"not stored; record {'it' if len(skipped) == 1 else 'them'} with: {self.resume_command}"
                )
        elif not self.store_created:
            why = {
                "quit": "Stopped at your request",
                "interrupted": "Interrupted",
                "no input": "No input (standard input ended)",
            }[status]
            again = (
                "run the command where someone at the rig can answer its prompts"
                if status == "no input"
                else "run the same command again to start the run"
            )
            msg = f"{why} during the setup, before anything was written to {self.run_path}; {again}."
        elif status == "quit":
            msg = (
                f"Stopped at your request during {self._current()}, which was not stored; "
                f"{stored} stored in {self.run_path}. Resume with: {self.resume_command}"
            )
        elif status == "no input":
            lost = f", so {self._current()} was not stored" if self._trial is not None else ""
            msg = (
                f"No input: standard input ended at a question during {self._current()}{lost}; {stored} stored "
                f"in {self.run_path}. Resume where someone at the rig can answer: {self.resume_command}"
            )
        else:
            what = ", which was discarded" if self._trial is not None else ""
            msg = (
                f"Interrupted during {self._current()}{what}; {stored} stored in "
                f"{self.run_path} {'is' if complete == 1 else 'are'} safe. Resume with: {self.resume_command}"
            )
        return Outcome(status, msg, self._stored, complete, tuple(skipped), wall)

    # ------------------------------------------------------------------ streaming
    def _start(self) -> None:
        if not self._streaming:
            self.device.start()
            self._streaming = True
            self._unwrap = TimeUnwrapper()
            self._clock = None
            self._pending = None

    def _stop(self) -> None:
        if self._streaming:
            self._streaming = False
            self._pending = None
            self.device.stop()

    def _stop_quietly(self) -> None:
        with contextlib.suppress(Exception):
            self._stop()

    def _next_batch(self) -> Window:
        """The next frames as a Window; pending frames first.  Raises if the rig goes silent."""
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
                self._check_clock(np.asarray(batch.t_us, dtype=np.int64))
                counts = np.asarray(batch.values, dtype=float)
                return Window.of(
                    np.asarray(batch.seq, dtype=np.int64),
                    counts,
                    np.asarray(self.protocol.calibration.to_si(counts), dtype=float),
                    t_us=np.asarray(batch.t_us, dtype=np.int64),
                    t_s=self._unwrap(batch.t_us),
                )

    def _stream(self, duration_s: float, take: Callable[[Window], None]) -> None:
        """Hand ``take`` the frames covering ``duration_s`` of device time from the next frame on, batch by batch."""
        t0: float | None = None
        while True:
            w = self._next_batch()
            if t0 is None:
                t0 = float(w.t_s[0])
            n = int(np.searchsorted(w.t_s, t0 + duration_s, side="left"))
            if n < len(w):
                if n:
                    take(_slice(w, 0, n))
                self._pending = _slice(w, n, len(w))
                return
            take(w)

    def _collect(self, duration_s: float) -> Window:
        """Frames covering ``duration_s`` of device time, in memory (the setup check's half second)."""
        parts: list[Window] = []
        self._stream(duration_s, parts.append)
        return _concat(parts)

    def _capture(self, duration_s: float) -> Any:
        """A Baseline or Capture window, streamed into the run file inside a trial (see :mod:`.capture`).

        Only the committed record makes the window count: a window of a trial that is redone,
        skipped or killed stays in the file unreferenced, and is never read as a trial.
        """
        k = len(self.protocol.channels)
        sink = WindowSink(
            k, self.store.windows.begin(f"{self._noun} {self._trial.trial}") if self._trial is not None else None
        )
        self._stream(duration_s, sink.add)
        window = sink.finish()
        self._check_rate(len(window), sink.gaps.median_s())
        return window

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
        if self._rate_set and frames > 1000 and frames > SLOW_CLOCK * self._rate_set * span:
            what = (
                f"sent {frames} frames over only {span:.3g} s of its own clock, "
                f"{frames / span if span else math.inf:.4g} frames per second at {self._rate_set:g} Hz set"
            )
            raise DeviceClockError(f"The rig on {self._port()} {what}.", what=what)

    def _check_rate(self, frames: int, gap: float) -> None:
        """Flag a window of ``frames`` frames whose median ``gap`` (s, rig's clock) is off the rate it confirmed."""
        if not self._rate_set or frames < 10:
            return
        rate = 1.0 / gap if gap > 0 else math.inf
        if abs(rate / self._rate_set - 1.0) <= RATE_TOLERANCE:
            return
        text = (
            f"the rig streams at {rate:.4g} Hz by its own clock, not the {self._rate_set:g} Hz it confirmed; "
            "check its firmware's timer"
        )
        if self._trial is not None and text not in self._flags:
            self._flags.append(text)
        key = round(rate, 1)
        if key not in self._rate_warned:
            self._rate_warned.add(key)
            self.ui.warn(f"{text}; each trial recorded so carries a flag")

    # ------------------------------------------------------------------ steps
    def _execute(self, step: Any) -> Any:
        if isinstance(step, (Prompt, Ask, Review, Problem)):
            self._stop()
        if isinstance(step, SetupCheck):
            return self._setup_check()
        if isinstance(step, Prompt):
            return self._prompt(step)
        if isinstance(step, Problem):
            return self._problem(step)
        if isinstance(step, Ask):
            return self.ui.ask(step, simulated=getattr(self.device, "rig", None) is not None)
        if isinstance(step, BeginTrial):
            return self._begin(step)
        if isinstance(step, WaitSettle):
            return self._wait_settle(step.label)
        if isinstance(step, (Baseline, Capture)):
            self._start()
            return self._capture(step.capture_s)
        if isinstance(step, Review):
            return self.ui.review(step.row, step.warnings, step.default)
        if isinstance(step, Commit):
            return self._commit(step)
        if isinstance(step, Finish):
            return self._finish(step)
        raise TypeError(f"unknown step {step!r}")

    def _create_store(self) -> None:
        with _sigint_deferred():  # Ctrl-C during the creation: the file exists whole, or not at all
            self.store

    def _prompt(self, step: Prompt) -> Any:
        change = self.ui.prompt(step)
        if change is not None:
            return change  # new values typed instead of Enter: nothing was done at the rig yet
        if getattr(self.device, "rig", None) is not None:
            # The simulated rig has no one standing at it: it does what the
            # prompt asked once the prompt is answered.
            self._act(step.action)
        return None

    def _problem(self, step: Problem) -> None:
        if self.ui.unattended:
            # Nobody stands at a simulated rig to fix it: the session ends here.
            stored = (
                f"the {_count(self._complete(), 'completed ' + self._noun)} in {self.run_path} "
                f"{'is' if self._complete() == 1 else 'are'} unchanged"
                if self.store_created
                else f"nothing was written to {self.run_path}"
            )
            raise DeviceError(f"{step.text.rstrip('.')}; {stored}.")
        self.ui.warn(step.text)
        return self._prompt(step.fix)

    def _commit(self, step: Commit) -> None:
        record = dict(step.record)
        record.setdefault("started", self._trial_started)
        if self._flags:
            record["flags"] = [*record.get("flags", ()), *self._flags]
        with _sigint_deferred():
            self.store.records.write(record)
            # Inside the deferral, so a Ctrl-C held during the write finds the trial stored.
            self._stored += 1
            self._trial_walls.append(time.monotonic() - self._trial_wall_start)
            if self._trial is not None:
                self._log.added(self._trial.trial)
            self._trial = None
            self._flags = []
        return None

    def _act(self, action: Any) -> None:
        if action is None:
            return
        try:
            action.act_on(self.device.rig)
        except ValueError as e:
            raise ConfigError(f"The simulated rig cannot do {action}: {str(e).rstrip('.')}.") from None

    def _begin(self, step: BeginTrial) -> None:
        self._create_store()  # the run file exists from the first trial on, so every resume hint works
        self._trial = step
        self._flags = []
        self._trials_begun = True
        self._trial_wall_start = time.monotonic()
        self._trial_started = utc_now()
        elapsed = time.monotonic() - self._t_start
        remaining = None
        if self._trial_walls:
            per = sum(self._trial_walls) / len(self._trial_walls)
            remaining = per * (step.total - step.index + 1)
        self.ui.begin_trial(step, self._stored, elapsed, remaining)

    def _wait_settle(self, label: str) -> SettleReport | str:
        self._start()
        detector = SettleDetector(self.criteria, self._pcols, self._acols, self._lcols, self._length_spread_m)
        while True:
            # The live status line is closed before any question is asked.
            with self.ui.settling(label, self.criteria) as show:
                while True:
                    w = self._next_batch()
                    status = detector.update(w.t_s, w.si)
                    show(status)
                    if detector.consumed < len(w):
                        # Frames after the decision belong to what follows (capture, or more waiting).
                        self._pending = _slice(w, detector.consumed, len(w))
                    if status.settled or status.timed_out:
                        break
            if status.settled:
                report = SettleReport(
                    True,
                    status.settle_time_s,
                    status.elapsed_s,
                    status.pressure_spread_MPa,
                    status.angle_spread_rad,
                    self.criteria.describe(),
                )
                break
            choice = self.ui.settle_timeout(label, status, self.criteria)
            if choice == "wait":
                detector.extend_timeout()
                continue
            if choice == "redo":
                return "redo"
            report = SettleReport(
                False,
                status.elapsed_s,
                status.elapsed_s,
                status.pressure_spread_MPa,
                status.angle_spread_rad,
                self.criteria.describe() + " (timed out, accepted)",
            )
            break
        self.ui.settled(label, report)
        return report

    def _finish(self, step: Finish) -> None:
        self._stop()
        self._create_store()  # a session that recorded nothing still leaves its (empty) run
        with _sigint_deferred():  # a Ctrl-C now finds the split whole and the run finished
            if step.split:
                # Only stored trials join (a session restarted after a lost rig counts skips as done).
                stored = set(self.store.records.ids())
                fit = sorted(t for t, s in step.split.items() if s == "fit" and t in stored)
                val = sorted(t for t, s in step.split.items() if s == "validation" and t in stored)
                self.store.split.set(fit, val, "plan")
            self._finished = True

    # ------------------------------------------------------------------ setup
    def _setup_check(self) -> None:
        info = self.device.info
        spec = getattr(self.protocol, "device", None)
        if spec is not None and not spec.matches(info.device):
            raise DeviceError(
                f"The device on {info.port} is '{info.device}', but protocol {self.protocol.name} is for "
                f"'{spec.name}': connect that rig, or pass the matching --protocol."
            )
        want = tuple(self.protocol.channels)
        have = tuple(info.channels)
        if have != want:
            raise DeviceError(
                f"The rig on {info.port} reports channels {','.join(have)} but protocol "
                f"{self.protocol.name} expects {','.join(want)}: check the firmware, or pass the "
                "matching --protocol."
            )
        rate = self.rate_hz or float(self.protocol.rate_hz)
        got = self.device.set_rate(rate)
        if got and abs(float(got) - rate) > 1e-6 * rate:
            self.ui.warn(f"the rig runs at {float(got):g} Hz, not the requested {rate:g} Hz")
        self._rate_set = float(got) if got else rate
        self._start()
        window = self._collect(SETUP_S)
        self._stop()
        self._check_rate(len(window), float(np.median(np.diff(window.t_s))) if len(window) > 1 else math.nan)
        problems = self._check_readings(window)
        if problems:
            raise DeviceError(f"The readings from {info.port} are not plausible: " + "; ".join(problems) + ".")
        self.ui.info(
            f"Rig {info.device} (firmware {info.firmware}) on {info.port}: channels "
            f"{','.join(have)} match protocol {self.protocol.name}; readings in range."
        )

    def _check_readings(self, window: Window) -> list[str]:
        names = list(self.protocol.channels)
        ranges = self.protocol.calibration.ranges
        lo = window.si.min(axis=0)
        hi = window.si.max(axis=0)
        problems = []
        for i in self._pcols:
            a, b = ranges[i]
            if lo[i] < a - PRESSURE_MARGIN_MPA or hi[i] > b + PRESSURE_MARGIN_MPA:
                problems.append(
                    f"{names[i]} reads {lo[i]:.3f} to {hi[i]:.3f} MPa, outside the sensor span {a:g} to {b:g} MPa "
                    "(check that sensor's cable and supply)"
                )
        for i in self._acols:
            a, b = ranges[i]
            if lo[i] < a or hi[i] > b:
                problems.append(
                    f"{names[i]} reads {math.degrees(lo[i]):.1f} to {math.degrees(hi[i]):.1f} deg, outside the "
                    f"plausible {math.degrees(a):.0f} to {math.degrees(b):.0f} deg (check the potentiometer's "
                    "wiring and centring)"
                )
        return problems


def _what(e: Exception) -> str:
    """What a lost rig did, for "the rig on PORT {what} during trial 3"."""
    return getattr(e, "what", None) or "stopped sending data"


def _plural(noun: str) -> str:
    return noun + ("es" if noun.endswith(("sh", "ch", "s")) else "s")


def _count(n: int, noun: str) -> str:
    return f"{n} {noun}" if n == 1 else f"{n} {_plural(noun)}"


def _slice(w: Window, a: int, b: int) -> Window:
    return w[a:b]


def _concat(parts: list[Window]) -> Window:
    return Window.concat(parts)


@contextlib.contextmanager
def _sigint_deferred() -> Iterator[None]:
    """Hold Ctrl-C until a trial is written whole (the store's write is not interruptible)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    caught: list[Any] = []
    previous = signal.signal(signal.SIGINT, lambda *a: caught.append(a))
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)
        if caught:
            raise KeyboardInterrupt
        interrupts.check()
