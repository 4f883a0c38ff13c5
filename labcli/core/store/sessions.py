"""``run.sessions``: the session log, one row per event of an acquisition session.

A run may take several sessions (a quit, a Ctrl-C, a lost rig, the next morning); the engine
reports each to the run file through this facet, which is the run file's side of
:class:`labcli.core.sessionlog.SessionLog`:

=========  ================================================================================
event      what the row holds
=========  ================================================================================
begin      time, port, baud, the rig's ID reply (device, firmware, channels), the
           calibration in force (gain, offset per channel), command line, host name
added      a record stored in this session (``record``)
redone     a record the experimenter chose to redo
skipped    a record skipped
end        time and how the session ended (``how``: finished, quit, interrupted, rig lost,
           no input, ...), and a note
=========  ================================================================================

A record's ``added`` row is committed with the record itself, so the log never claims a
record the file lacks, nor misses one it holds; ``redone`` and ``skipped`` rows ride on the
next commit (:class:`~.writer.Riders`); ``begin`` and ``end`` are committed at once.  A
session without an ``end`` row ended without a word (a kill, a power cut).
"""

from __future__ import annotations

import math
import socket
from collections.abc import Callable
from typing import TYPE_CHECKING, Any, TypedDict

import numpy as np

from ...errors import StoreError
from ..files import stored_text
from ..sessionlog import RigIdentity, SessionInfo
from ..timestamps import utc_now
from .blobs import cell_text
from .columns import Table, fill_value
from .layout import session_columns
from .unused import mark as mark_unused
from .writer import Write

if TYPE_CHECKING:
    from .runfile import RunFile

HOW = ("finished", "quit", "interrupted", "rig lost", "no input", "disk full", "out of memory", "error")


class Calibration(TypedDict):
    gain: list[float]
    offset: list[float]


class Session(TypedDict):
    """One session of the log, folded from its events."""

    number: int
    started: str
    ended: str
    how: str | None  # None: ended without a word (a kill, a power cut)
    note: str
    port: str
    baud: int | None
    device: str
    firmware: str
    channels: list[str]
    calibration: Calibration | None
    command_line: str
    host_name: str
    operator: str
    resumed: bool
    other_rig: bool
    added: list[int]
    redone: list[int]
    skipped: list[int]


class Sessions:
    """``run.sessions`` (see the module docstring)."""

    def __init__(self, run: RunFile) -> None:
        self._run = run
        self._number: int | None = None  # the session writing now
        self._added: set[int] = set()
        self._queued: list[dict[str, Any]] = []  # events riding on the next commit

    # ------------------------------------------------------------ the engine's reports
    def begin(self, info: SessionInfo) -> None:
        """A session starts writing to the run (before its first record); committed at once."""
        run = self._run
        run.writer.check()
        run.check_v2("a session")
        sessions, _ = read_sessions(run.tables.sessions)
        number = max((s["number"] for s in sessions), default=0) + 1
        self._queued.append(begin_event(number, info, socket.gethostname()))
        marks = mark_unused(run, "interrupted", None, number, resuming=True)  # what a kill left
        run.writer.commit([marks] if marks else [], 0, "the session's start")
        self._number, self._added = number, set()

    def added(self, rid: int) -> None:
        """Record ``rid`` was stored whole by this session (already logged with the record)."""
        self._note("added", rid)

    def redone(self, rid: int) -> None:
        """Record ``rid`` is redone before it is stored (logged with the next commit, or at once
        with the marks of the raw frames it leaves, :mod:`.unused`)."""
        self._note("redone", rid)
        self._mark("redone", rid)

    def skipped(self, rid: int) -> None:
        """Record ``rid`` was skipped by this session (logged as :meth:`redone` is)."""
        self._note("skipped", rid)
        self._mark("skipped", rid)

    def _mark(self, why: str, rid: int) -> None:
        marks = mark_unused(self._run, why, rid, self._number)
        if marks is not None:
            self._run.writer.commit([marks], 0, f"the marks of {self._run.record_type.noun} {rid}'s raw frames")

    def end(self, how: str) -> None:
        """The session ended: one of :data:`HOW`; committed at once.  A session with no end row
        ended without a word (a kill, a power cut)."""
        number = self._number
        if number is None:
            raise StoreError(f"no session is open in {self._run.path}; there is none to end.")
        if self._run.writer.broken:  # a write failed half-way (an I/O error, memory): nothing more is written
            self._number = None
            return
        self._queued.append(end_event(number, how))
        marks = mark_unused(self._run, "interrupted", None, number)  # the windows of a record cut off
        self._run.writer.commit([marks] if marks else [], 0, "the session's end")
        self._number = None

    def stage_added(self, rid: int) -> Callable[[], None]:
        """Queue the ``added`` event of a record about to be committed (when a session is open);
        the function that takes it back should that commit fail."""
        if self._number is None:
            return lambda: None
        mark = len(self._queued)
        self._note("added", rid)

        def undo() -> None:
            del self._queued[mark:]
            self._added.discard(int(rid))

        return undo

    def _note(self, event: str, rid: int) -> None:
        number = self._number
        if number is None:
            raise StoreError(f"no session is open in {self._run.path}; begin one before noting {event} records.")
        if event == "added":
            if int(rid) in self._added:
                return
            self._added.add(int(rid))
        self._queued.append(record_event(number, event, rid))

    # ------------------------------------------------------------ riding on the next commit
    def pending(self) -> Write | None:
        """The queued events as rows of the session log (:class:`~.writer.Riders`)."""
        if not self._queued:
            return None
        columns = session_columns(len(self._run.channels))
        values: dict[str, Any] = {}
        for c in columns:
            vs = [e.get(c.name) for e in self._queued]
            if any(v is not None for v in vs):
                values[c.name] = [_filled(c, v) for v in vs]
        return Write(self._run.tables.sessions, {c.name: c for c in columns}, values, len(self._queued))

    def committed(self) -> None:
        self._queued.clear()

    @property
    def waiting(self) -> bool:
        """Whether events wait for a commit (closing the file commits them)."""
        return bool(self._queued)

    # ------------------------------------------------------------ reading
    def all(self) -> list[Session]:
        """Every session that recorded into the run, in order; [] for schema 1 (it kept no log)."""
        run = self._run
        if run.v1 is not None:
            return []
        out, problems = run.read_checked(
            lambda: read_sessions(run.tables.sessions), "its session log", lambda got: bool(got[1])
        )
        if problems:
            run.warn(f"{run.path}: {problems[0]}; that event is left out of the session log.")
        return out

    def rig_identity(self) -> RigIdentity | None:
        """The rig of the run's latest session, or None when no session is logged.

        (:func:`labcli.core.sessionlog.recorded_identity` falls back on the run's metadata.)
        """
        for s in reversed(self.all()):
            if s["started"]:
                cal = s["calibration"] or {"gain": [], "offset": []}
                keep = all(math.isfinite(x) for x in (*cal["gain"], *cal["offset"]))
                return RigIdentity(
                    device=s["device"],
                    firmware=s["firmware"],
                    channels=tuple(s["channels"]),
                    gain=tuple(cal["gain"]) if keep else (),
                    offset=tuple(cal["offset"]) if keep else (),
                )
        return None


def _filled(c: Any, v: Any) -> Any:
    """An event's value for column ``c``, or what an unwritten value of it holds."""
    if v is not None:
        return v
    return np.full(c.shape, fill_value(c)) if c.shape else (fill_value(c) if c.kind != "text" else "")


def begin_event(number: int, info: SessionInfo, host_name: str) -> dict[str, Any]:
    """The ``begin`` row of session ``number``."""
    rig = info.rig
    return {
        "session": number,
        "event": "begin",
        "time": cut(str(info.started or utc_now()), 40),
        "port": cut(info.port, 256),
        "baud": -1 if info.baud is None else int(info.baud),
        "device": cut(rig.device, 64),
        "firmware": cut(rig.firmware, 64),
        "channels": cut(",".join(rig.channels), 256),
        "gain": np.asarray(rig.gain or np.nan, dtype=float),
        "offset": np.asarray(rig.offset or np.nan, dtype=float),
        "command_line": cut(info.command, 1024),
        "host_name": cut(host_name, 128),
        "operator": cut(info.operator, 128),
        "resumed": int(bool(info.resumed)),
        "other_rig": int(bool(info.other_rig)),
    }


def record_event(number: int, event: str, rid: int) -> dict[str, Any]:
    """An ``added``, ``redone`` or ``skipped`` row of session ``number``."""
    return {"session": number, "event": event, "time": utc_now(), "record": int(rid)}


def end_event(number: int, how: str) -> dict[str, Any]:
    """The ``end`` row of session ``number``: how it ended (one of :data:`HOW`)."""
    if how not in HOW:
        raise StoreError(f"a session ends as one of {', '.join(HOW)}, not {how!r}.")
    return {"session": number, "event": "end", "time": utc_now(), "how": how}


def cut(s: Any, width: int) -> str:
    """``s`` as text of at most ``width`` UTF-8 bytes (ending in "..." when cut)."""
    s = stored_text(str(s))
    data = s.encode("utf-8")
    if len(data) <= width:
        return s
    return data[: width - 3].decode("utf-8", "ignore") + "..."


def _new_session(n: int) -> Session:
    return {
        "number": n,
        "started": "",
        "ended": "",
        "how": None,
        "note": "",
        "port": "",
        "baud": None,
        "device": "",
        "firmware": "",
        "channels": [],
        "calibration": None,
        "command_line": "",
        "host_name": "",
        "operator": "",
        "resumed": False,
        "other_rig": False,
        "added": [],
        "redone": [],
        "skipped": [],
    }


def _begun(s: Session, c: dict[str, Any], i: int) -> None:
    """Fold a ``begin`` row into its session."""
    baud = int(c["baud"][i])
    s["started"] = cell_text(c["time"][i])
    s["port"] = cell_text(c["port"][i])
    s["baud"] = None if baud < 0 else baud
    s["device"] = cell_text(c["device"][i])
    s["firmware"] = cell_text(c["firmware"][i])
    s["channels"] = [x for x in cell_text(c["channels"][i]).split(",") if x]
    s["calibration"] = {"gain": [float(x) for x in c["gain"][i]], "offset": [float(x) for x in c["offset"][i]]}
    s["command_line"] = cell_text(c["command_line"][i])
    s["host_name"] = cell_text(c["host_name"][i])
    s["operator"] = cell_text(c["operator"][i])
    s["resumed"] = int(c["resumed"][i]) == 1
    s["other_rig"] = int(c["other_rig"][i]) == 1


def read_sessions(t: Table) -> tuple[list[Session], list[str]]:
    """The sessions of the log, in order, each folded from its events; and what was found damaged."""
    rows = t.read()
    problems = [f"session log row {r}: {why}" for r, why in rows.damaged]
    c = rows.cols
    sessions: dict[int, Session] = {}
    for i in range(len(rows.rows)):
        n, event = int(c["session"][i]), cell_text(c["event"][i])
        s = sessions.setdefault(n, _new_session(n))
        if event == "begin":
            _begun(s, c, i)
        elif event == "added":
            s["added"].append(int(c["record"][i]))
        elif event == "redone":
            s["redone"].append(int(c["record"][i]))
        elif event == "skipped":
            s["skipped"].append(int(c["record"][i]))
        elif event == "end":
            s["ended"], s["how"], s["note"] = cell_text(c["time"][i]), cell_text(c["how"][i]), cell_text(c["note"][i])
    return [sessions[k] for k in sorted(sessions)], problems
