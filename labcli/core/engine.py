"""The run engine: executes a session's steps against a rig, a run file and a UI.

A paper's session of steps (:mod:`labcli.core.steps`) says *what* happens in a run;
this module does it: it reads frames from the rig (:mod:`labcli.core.stream`), judges
equilibrium (:mod:`labcli.core.settle`), writes finished records to the run file
(:class:`~labcli.core.store.RunFile`) and talks to the experimenter through a UI
(:mod:`labcli.core.ui`); at a simulated rig, the :class:`~.simoperator.SimulatedOperator` it is given acts.

A trial's capture windows (``Baseline``, ``Capture``) are streamed into the run file as
their frames arrive (:mod:`labcli.core.capture`), so memory stays flat however long a
window is; but nothing counts until the ``Commit`` step commits the trial's record (its
row, statistics and window checksums) last.  An unplugged rig, a quit, Ctrl-C, a kill or a
full disk therefore discard only the trial in progress: its frames stay in the file,
referenced by no record, and are never read as a trial.

The run file: a resumed run's is opened by the caller and handed to the engine, whose
session log begins when the session does; a new run's is created by :meth:`RunEngine.open_run`
when its first trial begins (or its session finishes with none), from the :class:`NewRun`
the engine was given, so a session that stops during the setup or the air supply leaves no
file behind.  An attended run whose rig is lost asks the experimenter to reconnect it
(:mod:`labcli.core.reconnect`) and starts the session afresh (setup check, air supply, then
the interrupted trial from its baseline); an unattended one ends with the command that
resumes it (:mod:`labcli.core.outcome`).
"""

from __future__ import annotations

import contextlib
import math
import time
from collections.abc import Callable, Generator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import ConfigError, DeviceClockError, DeviceDisconnected, DeviceError, DeviceTimeout, DiskFull
from . import interrupts
from .air import SlopeSums
from .capture import WindowSink
from .device import RigLink
from .outcome import Outcome, Where, ended, out_of_memory, plural, rig_lost
from .reconnect import wait_for_rig
from .record import Record
from .sessionlog import NoSessionLog, SessionInfo, SessionLog
from .settle import SettleCriteria, SettleDetector
from .setupcheck import check_readings, check_rig_matches
from .simoperator import Connection, SimulatedOperator
from .steps import (
    Ask,
    Baseline,
    BeginTrial,
    Capture,
    Commit,
    Finish,
    Hold,
    HoldReport,
    Note,
    Problem,
    Prompt,
    Review,
    SettleReport,
    SetupCheck,
    Valves,
    WaitSettle,
)
from .store import RunFile
from .stream import FrameStream
from .timestamps import utc_now
from .ui import InputEnded, QuitRequested
from .window import Window

__all__ = ["NewRun", "Outcome", "RunEngine"]

SILENT_S = 5.0  # wall-clock seconds without a frame before the rig counts as silent
SETUP_S = 0.5  # device seconds of readings for the setup check
LOST_RIG = (DeviceDisconnected, DeviceTimeout, DeviceClockError)


@dataclass(frozen=True)
class NewRun:
    """A run file still to be created: everything :meth:`RunFile.create` is given for it."""

    path: str
    protocol: Any
    kind: str
    device_info: Any
    port: str
    operator: str = ""
    plan: Any = None
    force: bool = False

    def create(self) -> RunFile:
        return RunFile.create(
            self.path,
            protocol=self.protocol,
            kind=self.kind,
            device_info=self.device_info,
            port=self.port,
            operator=self.operator,
            plan=self.plan,
            force=self.force,
        )


class RunEngine:
    """Drive one session to its end.

    ``device``: an open :class:`labcli.core.device.Device`; ``run``: the run file, open for
    writing (a :class:`~labcli.core.store.RunFile`), or the :class:`NewRun` to create when the
    first record begins; ``ui``: :class:`labcli.core.ui.RichUI` or
    :class:`labcli.core.ui.UnattendedUI`; ``resume_command``: the exact command line that
    continues this run, quoted in every "how to resume" sentence; ``simulated_operator``: who
    does what the prompts ask at a simulated rig (None: a person at a real one); ``valves``:
    ``"hand"`` keeps the prompts on a board that could drive its valves (default: the protocol's).
    Subscribers (``subscribe``) see every step and its reply, for logging and tests.
    With ``session`` (port, baud, rig, ...), the run file's session log
    (``run.sessions``) is told how the session began, what it did and how it ended.
    """

    def __init__(
        self,
        device: RigLink,
        run: RunFile | NewRun,
        protocol: Any,
        ui: Any,
        *,
        run_path: str | Path,
        resume_command: str,
        simulated_operator: SimulatedOperator | None = None,
        rate_hz: float | None = None,
        silent_s: float = SILENT_S,
        noun: str = "trial",
        session: SessionInfo | None = None,
        valves: str | None = None,
    ) -> None:
        self._new_run = run if isinstance(run, NewRun) else None
        self.run_file: RunFile | None = None if isinstance(run, NewRun) else run
        self.protocol = protocol
        self.ui = ui
        self.run_path = str(run_path)
        self.resume_command = resume_command
        self.simulated_operator = simulated_operator
        self.rate_hz = rate_hz
        self.criteria = SettleCriteria.from_settling(protocol.settling)
        self.stream = FrameStream(device, protocol.calibration, self._port, silent_s)
        self._noun = noun  # what one record is called in sentences ("trial", "push", "point")
        units = tuple(protocol.calibration.units)
        self._pcols = [i for i, u in enumerate(units) if u == "MPa"]
        self._acols = [i for i, u in enumerate(units) if u == "rad"]
        # Length channels (a draw-wire sensor) settle only under a protocol giving their limit, else not watched.
        self._length_spread_m = getattr(protocol.settling, "length_spread_m", None)
        self._lcols = [i for i, u in enumerate(units) if u == "m"] if self._length_spread_m else []
        self._settle_cols = (self._pcols, self._acols, self._lcols, self._length_spread_m)
        self._subscribers: list[Callable[[Any, Any], None]] = []
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
        self._rate_warned: set[float] = set()
        self._flags: list[str] = []  # what the stream did wrong during the trial in progress
        self._valves_driven = False  # the board's valves were set by command: set them to rest at the end
        self._valves_mode = valves  # "hand" overrides the protocol's acquisition.valves
        self._note = ""  # the experimenter's note on the trial in progress (n at its review)

    @property
    def device(self) -> Any:
        """The rig's link (another one once a lost rig is reconnected)."""
        return self.stream.device

    def subscribe(self, callback: Callable[[Any, Any], None]) -> None:
        """Call ``callback(step, reply)`` after every executed step."""
        self._subscribers.append(callback)

    # ------------------------------------------------------------------ the run file
    def open_run(self) -> RunFile:
        """The run file: created now if the engine was given a :class:`NewRun` (whole, or not at
        all, should Ctrl-C come), with the session's start logged in it."""
        if self.run_file is None:
            assert self._new_run is not None
            with interrupts.deferred():  # Ctrl-C during the creation: the file exists whole, or not at all
                self.run_file = self._new_run.create()
                self._begin_log(self.run_file)
        return self.run_file

    def _begin_log(self, run: RunFile) -> None:
        if self._session is not None:  # without a session's facts there is nothing to log
            self._log = run.sessions
            self._log.begin(self._session)

    # ------------------------------------------------------------------ main loop
    def run(
        self,
        session: Generator[Any, Any, None],
        *,
        restart: Callable[[tuple[int, ...]], Generator[Any, Any, None]] | None = None,
        reopen: Callable[[], Connection] | None = None,
    ) -> Outcome:
        """Execute ``session`` to its end and say how it ended.

        With ``reopen`` (opens the same port again: the rig and its operator) and ``restart``
        (a new session given the ids already stored or skipped), an attended run survives a
        lost rig: the experimenter is asked to reconnect it, and the new session redoes the
        setup and the interrupted trial from its baseline.  Without them, or unattended, a
        lost rig ends the run with a DeviceError whose sentence gives the resume command.
        """
        if self.ui.unattended and self.simulated_operator is None:
            raise ConfigError(
                f"--unattended drives the simulated rig only, and {self._port()} is a real port: "
                "run without --unattended and follow the prompts."
            )
        self._t_start = time.monotonic()
        if self.run_file is not None:  # a resumed run: its session begins now
            self._begin_log(self.run_file)
        how = "error"
        try:
            with interrupts.kept():  # a Ctrl-C landing in h5py's clean-up is kept, not lost
                outcome = self._run(session, restart, reopen)
            how = outcome.status
            return outcome
        except LOST_RIG:
            how = "rig lost"
            raise
        except (DiskFull, MemoryError) as e:  # no room or no memory: what is committed is whole
            how = "disk full" if isinstance(e, DiskFull) else "out of memory"
            raise e if isinstance(e, DiskFull) else out_of_memory(self._where()) from None
        finally:
            self._rest_valves()
            self._log.end(how)

    def _run(self, session: Generator[Any, Any, None], restart: Any, reopen: Any) -> Outcome:
        while True:
            try:
                return self._drive(session)
            except LOST_RIG as e:
                lost = e
            wait = restart is not None and reopen is not None and not self.ui.unattended and lost.reconnects
            try:
                back = wait and self._reconnect(lost, reopen)
            except KeyboardInterrupt:
                return self._outcome("interrupted", ())
            if not back:
                raise type(lost)(rig_lost(_what(lost), self._port(), self._where())) from lost
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
        except (InputEnded, QuitRequested, KeyboardInterrupt) as e:
            session.close()
            self.stream.stop_quietly()
            if isinstance(e, InputEnded):
                return self._outcome("no input", (), why=e.why)
            if isinstance(e, QuitRequested):
                return self._outcome("quit", ())
            if self._finished:  # Ctrl-C after the last step: the run is complete
                return self._outcome("finished", tuple(dict.fromkeys(self._skipped)))
            return self._outcome("interrupted", ())
        except (*LOST_RIG, MemoryError):
            session.close()
            self.stream.stop_quietly()
            raise

    def _reviewed(self, reply: str) -> None:
        """A trial redone (by a review or a settling timeout) or skipped: the session log hears of it."""
        assert self._trial is not None
        rid = self._trial.trial
        if reply == "skip":
            if self._note:  # a skipped trial's note is the run's, naming it
                self.open_run().notes.add(f"{self._noun} {rid} (skipped): {self._note}")
                self._note = ""
            self._skipped.append(rid)
            self._trial = None
            self._log.skipped(rid)
        else:
            self._log.redone(rid)
        self._flags = []

    def _done_ids(self) -> list[int]:
        stored = self.run_file.records.ids() if self.run_file is not None else []
        return stored + [t for t in self._skipped if t not in stored]

    def _reconnect(self, e: Exception, reopen: Callable[[], Connection]) -> bool:
        """Wait for the lost rig (:func:`~labcli.core.reconnect.wait_for_rig`); True once it is back."""
        back = wait_for_rig(self.ui, self.device, self._port(), _what(e), self._lost_during(), reopen)
        if back is None:
            return False
        self.stream.reconnected(back.device)
        self.simulated_operator = back.operator
        self._trial = None
        self._trials_begun = False  # the new session starts with the setup
        return True

    # ------------------------------------------------------------------ where the session stands
    def _port(self) -> str:
        info = getattr(self.stream.device, "info", None)
        return getattr(info, "port", None) or "the port"

    def _current(self) -> str:
        if self._trial is not None:
            return f"{self._noun} {self._trial.trial}"
        if self._trials_begun:
            return f"the pause between {plural(self._noun)}"
        return "the setup"

    def _lost_during(self) -> str:
        """What the rig was lost during, and what happens once it is back."""
        if self._trial is not None:
            return (
                f"during {self._current()}, which was not stored; it will be redone from its baseline "
                "once the rig is back"
            )
        return f"during {self._current()}; the setup will be redone once the rig is back"

    def _where(self) -> Where:
        complete = len(self.run_file.records.ids()) if self.run_file is not None else 0
        return Where(
            self._noun,
            self.run_path,
            self.resume_command,
            self.run_file is not None,
            complete,
            self._current(),
            self._trial is not None,
        )

    def _outcome(self, status: str, skipped: tuple[int, ...], why: str = "ended") -> Outcome:
        return ended(status, self._where(), self._stored, skipped, time.monotonic() - self._t_start, why)

    # ------------------------------------------------------------------ steps
    def _execute(self, step: Any) -> Any:
        if isinstance(step, (Prompt, Ask, Review, Problem)):
            self.stream.stop()
        if isinstance(step, SetupCheck):
            return self._setup_check()
        if isinstance(step, Prompt):
            return self._prompt(step)
        if isinstance(step, Problem):
            return self._problem(step)
        if isinstance(step, Ask):
            return self.ui.ask(step, simulated=self.simulated_operator is not None)
        if isinstance(step, BeginTrial):
            return self._begin(step)
        if isinstance(step, WaitSettle):
            return self._wait_settle(step.label, step.drift_per_s)
        if isinstance(step, (Baseline, Capture)):
            self.stream.start()
            return self._capture(step.capture_s)
        if isinstance(step, Review):
            decision = self.ui.review(step.row, step.warnings, step.default)
            note = getattr(self.ui, "take_note", lambda: "")()
            if note:  # typed at the review (n): kept through a redo, stored with the record
                self._note = note
            return decision
        if isinstance(step, Commit):
            return self._commit(step)
        if isinstance(step, Finish):
            return self._finish(step)
        if isinstance(step, Valves):
            return self._set_valves(step.state, step.channels)
        if isinstance(step, Note):
            self.ui.info(step.text)
            return None
        if isinstance(step, Hold):
            self.stream.start()
            return self._hold(step.duration_s)
        raise TypeError(f"unknown step {step!r}")

    def _prompt(self, step: Prompt) -> Any:
        change = self.ui.prompt(step)
        if change is not None:
            return change  # new values typed instead of Enter: nothing was done at the rig yet
        if self.simulated_operator is not None and step.action is not None:
            # Nobody stands at a simulated rig: its operator does what the prompt asked
            # once the prompt is answered.
            self.simulated_operator.act(step.action)
        return None

    def _problem(self, step: Problem) -> Any:
        if self.ui.unattended:
            # Nobody stands at a simulated rig to fix it: the session ends here.
            raise DeviceError(f"{step.text.rstrip('.')}; {self._where().stored()}.")
        self.ui.warn(step.text)
        return self._prompt(step.fix)

    def _begin(self, step: BeginTrial) -> None:
        self.open_run()  # the run file exists from the first trial on, so every resume hint works
        self._trial = step
        self._flags = []
        self._note = ""
        self._trials_begun = True
        self._trial_wall_start = time.monotonic()
        self._trial_started = utc_now()
        elapsed = time.monotonic() - self._t_start
        remaining = None
        if self._trial_walls:
            per = sum(self._trial_walls) / len(self._trial_walls)
            remaining = per * (step.total - step.index + 1)
        self.ui.begin_trial(step, self._stored, elapsed, remaining)

    def _capture(self, duration_s: float) -> Window:
        """A Baseline or Capture window, streamed into the run file inside a trial (see :mod:`.capture`).

        Only the committed record makes the window count: a window of a trial that is redone,
        skipped or killed stays in the file unreferenced, and is never read as a trial.
        """
        k = len(self.protocol.channels)
        writer = None
        if self._trial is not None:
            writer = self.open_run().windows.begin(f"{self._noun} {self._trial.trial}")
        sink = WindowSink(k, writer, adc=tuple(self.protocol.calibration.adc_range), names=self.protocol.channels)
        self.stream.stream(duration_s, sink.add)
        window = sink.finish()
        self._check_rate(len(window), sink.gaps.median_s())
        return window

    def _check_rate(self, frames: int, gap: float) -> None:
        """Flag the trial in progress (and warn, once a rate) when a window runs off the rate the rig confirmed."""
        problem = self.stream.rate_problem(frames, gap)
        if problem is None:
            return
        text, rate = problem
        if self._trial is not None and text not in self._flags:
            self._flags.append(text)
        key = round(rate, 1)
        if key not in self._rate_warned:
            self._rate_warned.add(key)
            self.ui.warn(f"{text}; each trial recorded so carries a flag")

    def _wait_settle(self, label: str, drift_per_s: tuple[float, ...] = ()) -> SettleReport | str:
        self.stream.start()
        detector = SettleDetector(self.criteria, *self._settle_cols, drift_per_s=drift_per_s or None)
        while True:
            # The live status line is closed before any question is asked.
            with self.ui.settling(label, self.criteria) as show:
                while True:
                    w = self.stream.next_block()
                    status = detector.update(w.t_s, w.si)
                    key = show(status)  # q or r pressed during the wait acts now, not at the next question
                    if key == "quit":
                        raise QuitRequested("quit")
                    if key == "redo":
                        self.ui.info(f"  {label}: redone at your request (r)")
                        return "redo"
                    if detector.consumed < len(w):
                        # Frames after the decision belong to what follows (capture, or more waiting).
                        self.stream.keep(w[detector.consumed :])
                    if status.settled or status.timed_out:
                        break
            if status.settled:
                report = self._report(status, True, status.settle_time_s, detector.leak_note)
                break
            choice = self.ui.settle_timeout(label, status, self.criteria)
            if choice == "wait":
                detector.extend_timeout()
                continue
            if choice == "redo":
                return "redo"
            report = self._report(status, False, status.elapsed_s, detector.leak_note + " (timed out, accepted)")
            break
        self.ui.settled(label, report)
        return report

    def _report(self, status: Any, settled: bool, settle_time_s: float, note: str) -> SettleReport:
        return SettleReport(
            settled,
            settle_time_s,
            status.elapsed_s,
            status.pressure_spread_MPa,
            status.angle_spread_rad,
            self.criteria.describe() + note,
        )

    def _commit(self, step: Commit) -> None:
        record: Record = step.record.copy()
        record.setdefault("started", self._trial_started)
        if self._flags:
            record["flags"] = [*record.get("flags", ()), *self._flags]
        run = self.open_run()
        with interrupts.deferred():
            run.records.write(record)
            # Inside the deferral, so a Ctrl-C held during the write finds the trial stored.
            self._stored += 1
            self._trial_walls.append(time.monotonic() - self._trial_wall_start)
            if self._trial is not None:
                self._log.added(self._trial.trial)
                if self._note:  # typed at its review (n): the record's note, in the same deferral
                    run.notes.add(self._note, record=self._trial.trial)
            self._trial = None
            self._flags = []
            self._note = ""
            # Only now may an unattended run say so: a line on the screen is a trial in the file.
            getattr(self.ui, "stored", lambda: None)()

    def _finish(self, step: Finish) -> None:
        self.stream.stop()
        run = self.open_run()  # a session that recorded nothing still leaves its (empty) run
        with interrupts.deferred():  # a Ctrl-C now finds the split whole and the run finished
            if step.split:
                # Only stored trials join (a session restarted after a lost rig counts skips as done).
                stored = set(run.records.ids())
                fit = sorted(t for t, s in step.split.items() if s == "fit" and t in stored)
                val = sorted(t for t, s in step.split.items() if s == "validation" and t in stored)
                run.split.set(fit, val, "plan")
            self._finished = True

    # ------------------------------------------------------------------ valves (labcli.core.air)
    def _set_valves(self, state: str, channels: tuple[str, ...] = ()) -> dict[str, str] | None:
        """The board's valves (``channels``' only, if named) set to ``state``, or None when the experimenter's."""
        air, caps = getattr(self.protocol, "air", None), getattr(self.device, "caps", None)
        mode = self._valves_mode or (air.valves if air is not None else "hand")
        if mode == "hand" or caps is None or not caps.valves:
            return None
        for channel in channels or (None,):
            states = self.device.set_valves(state, channel)
        self._valves_driven = True
        return dict(states)

    def _rest_valves(self) -> None:
        """However the session ended, valves it drove are left as the protocol says (hold or vent),
        never supplying; a board that is gone is left to its own pressure limit."""
        if not self._valves_driven:
            return
        with contextlib.suppress(Exception):
            self.device.set_valves(self.protocol.air.end_valves)

    def _hold(self, duration_s: float) -> HoldReport:
        """Each channel's least-squares slope (SI per s) and mean over ``duration_s`` of device time."""
        sums = SlopeSums(len(self.protocol.channels))
        self.stream.stream(
            duration_s, lambda w: sums.add(np.asarray(w.t_s, dtype=float), np.asarray(w.si, dtype=float))
        )
        slope, mean = sums.result()
        return HoldReport(slope, mean, sums.n, duration_s)

    # ------------------------------------------------------------------ setup
    def _setup_check(self) -> None:
        """The rig is the protocol's, runs at its rate, and reads plausible values (:mod:`.setupcheck`)."""
        info = self.device.info
        check_rig_matches(info, self.protocol)
        rate = self.rate_hz or float(self.protocol.rate_hz)
        got = self.device.set_rate(rate)
        if got and abs(float(got) - rate) > 1e-6 * rate:
            self.ui.warn(f"the rig runs at {float(got):g} Hz, not the requested {rate:g} Hz")
        self.stream.rate_set = float(got) if got else rate
        self.stream.start()
        window = self.stream.collect(SETUP_S)
        self.stream.stop()
        self._check_rate(len(window), float(np.median(np.diff(window.t_s))) if len(window) > 1 else math.nan)
        problems = check_readings(window, self.protocol, self._pcols, self._acols)
        if problems:
            raise DeviceError(f"The readings from {info.port} are not plausible: " + "; ".join(problems) + ".")
        self.ui.info(
            f"Rig {info.device} (firmware {info.firmware}) on {info.port}: channels "
            f"{','.join(info.channels)} match protocol {self.protocol.name}; readings in range."
        )


def _what(e: Exception) -> str:
    """What a lost rig did, for "the rig on PORT {what} during trial 3"."""
    return getattr(e, "what", None) or "stopped sending data"
