"""Raw frames that belong to no record: a redone or skipped trial's windows, an interrupted one's.

The engine streams a window into ``/entry/raw`` as it arrives (:mod:`.windows`), before it knows
whether the record will be kept.  A trial redone, skipped or cut off by a quit, a Ctrl-C, a lost
rig or a kill leaves its frames there, referenced by no committed record.  They are marked in
``/entry/raw/unused``, an append-only table (:mod:`.columns`), one row per range of frames:

===========  ======================================================================
column       what it holds
===========  ======================================================================
start, stop  the frames ``[start, stop)`` of ``raw/`` (only frames written: never the
             unwritten tail of a chunk a window leaves before the next one)
why          ``redone``, ``skipped``, ``retaken`` (a window its record took again: a baseline
             after the air was supplied again), ``interrupted``, or ``unknown`` (found on
             resuming a run recorded before labcli marked them)
record       the record the frames were taken for (-1: not known)
session      the session of the log that marked them (-1: none)
time         when they were marked (ISO 8601)
===========  ======================================================================

A range is marked by one commit through the write path (crash-safe like any other): when the
session log hears of a redo or a skip (:meth:`.sessions.Sessions.redone`), when a session ends,
and when the next session begins (what a kill or a power cut left).  A run file of schema 1,
or one of schema 2 or 3 without the table, reads as it always did; :func:`unused` then finds
its unmarked frames (``why`` is ``unmarked``) without changing the file.

>>> [(u.start, u.stop, u.why) for u in unused(run)]        # doctest: +SKIP
[(256, 301, 'redone'), (1024, 1100, 'interrupted')]
"""

from __future__ import annotations

from typing import TYPE_CHECKING, NamedTuple

import numpy as np

from ..timestamps import utc_now
from .blobs import cell_text
from .columns import Table
from .layout import UNUSED, UNUSED_COLUMNS, WINDOWS
from .nexus import home
from .opening import metadata_checksum, metadata_ok
from .writer import Write

if TYPE_CHECKING:
    from .runfile import RunFile

WHY = ("redone", "skipped", "retaken", "interrupted", "unknown")
UNMARKED = "unmarked"  # found by reading, not stored: a run being recorded, or one from before the marks


class Unused(NamedTuple):
    """Frames ``[start, stop)`` of ``raw/`` that belong to no record, and why."""

    start: int
    stop: int
    why: str
    record: int | None
    session: int | None

    @property
    def frames(self) -> int:
        return self.stop - self.start


def unused(run: RunFile) -> list[Unused]:
    """Every range of raw frames no committed record references, in order: the marked ones as
    marked, the rest as :data:`UNMARKED`.  [] for schema 1 (its windows are the records' own).
    A damaged row of the marks is left out, with a warning."""
    ranges, damage = read_unused(run)
    if damage:
        run.warn(damage)
    return ranges


def read_unused(run: RunFile) -> tuple[list[Unused], str | None]:
    """:func:`unused`, and the sentence its first damaged row of marks would warn (None: none).

    Nothing is said here, so a reader can read again first: a row copied in by a writer's
    checkpoint while it was read fails its checksum just as a damaged one does
    (:func:`.opening.read_afresh`)."""
    if run.v1 is not None:
        return [], None
    marked, damage = _marked_rows(run)
    loose = [Unused(a, b, UNMARKED, None, None) for a, b in _loose(run, marked)]
    return sorted([*marked, *loose]), damage


def mark(run: RunFile, why: str, record: int | None, session: int | None, resuming: bool = False) -> Write | None:
    """The rows marking every unmarked range (None: there is none), to commit.

    A range past the last committed record's windows is the record in progress's: ``why``
    (``record``).  One before it is a window its record took again (a baseline after the air
    was supplied again): ``retaken``, of the record after it; found on ``resuming`` a run that
    had no marks yet (recorded before them), such a range may as well be a redo's: ``unknown``.
    The table is made first in a run that has none (see :func:`_table`).
    """
    if run.v1 is not None:
        return None
    loose = _loose(run, _marked(run))
    if not loose:
        return None
    had_table = _table(run) is not None
    t = _table(run, create=True)
    assert t is not None
    windows = sorted(_record_windows(run))
    last = max((b for _, b, _ in windows), default=0)
    whys, records = [], []
    for _, b in loose:
        if b > last:
            whys.append(why)
            records.append(-1 if record is None else int(record))
        else:
            whys.append("retaken" if had_table or not resuming else "unknown")
            records.append(next((rid for a, _, rid in windows if a >= b), -1))
    values = {
        "start": [a for a, _ in loose],
        "stop": [b for _, b in loose],
        "why": whys,
        "record": records,
        "session": [-1 if session is None else int(session)] * len(loose),
        "time": [utc_now()] * len(loose),
    }
    return Write(t, {c.name: c for c in UNUSED_COLUMNS}, values, len(loose))


def counts(ranges: list[Unused]) -> dict[str, int]:
    """Frames per reason, in :data:`WHY`'s order (then ``unmarked``), reasons with none left out."""
    out: dict[str, int] = {}
    for why in (*WHY, UNMARKED):
        n = sum(u.frames for u in ranges if u.why == why)
        if n:
            out[why] = n
    return out


def _table(run: RunFile, create: bool = False) -> Table | None:
    """``raw/unused``; None when the run has none, unless ``create``: then it is made (a run
    recorded before the marks), the file's attribute checksum taken again when it checked out."""
    raw = run.h5["entry/raw"]
    if UNUSED in raw:
        return Table(raw[UNUSED])
    if not create:
        return None
    ok = metadata_ok(run.h5)
    run.writer.reserve(64 * 1024, "the marks of unused raw frames")
    with run.writer.writing("the marks of unused raw frames"):
        t = Table.create(raw, UNUSED, UNUSED_COLUMNS, 16)
        if ok:
            home(run.h5).modify("metadata_checksum", np.uint64(metadata_checksum(run.h5)))
    return t


def _marked(run: RunFile) -> list[Unused]:
    marked, damage = _marked_rows(run)
    if damage:
        run.warn(damage)
    return marked


def _marked_rows(run: RunFile) -> tuple[list[Unused], str | None]:
    """The marks that check out, and the sentence naming the first damaged row (None: none)."""
    t = _table(run)
    if t is None:
        return [], None
    rows = t.read()
    damage = None
    if rows.damaged:
        damage = f"{run.path}: row {rows.damaged[0][0]} of raw/unused: {rows.damaged[0][1]}; it is left out."
    c = rows.cols
    out = []
    for i in range(len(rows.rows)):
        rid, session = int(c["record"][i]), int(c["session"][i])
        why = cell_text(c["why"][i])
        out.append(
            Unused(
                int(c["start"][i]), int(c["stop"][i]), why, None if rid < 0 else rid, None if session < 0 else session
            )
        )
    return out, damage


def _record_windows(run: RunFile) -> list[tuple[int, int, int]]:
    """``[start, stop)`` and record id of every window the committed rows reference (read
    unchecked: a damaged row's frames are still its own, not unused)."""
    t = run.tables.records
    n = t.committed
    names = [f"{w}_{e}" for w in WINDOWS for e in ("start", "stop")]
    try:
        ids = np.asarray(t.ds[run.record_type.id_column][:n], dtype=np.int64)
        cols = {name: np.asarray(t.ds[name][:n], dtype=np.int64) for name in names}
    except (KeyError, OSError):  # a damaged chunk: the rows that check out
        rec = run.records.columns()
        ids = np.asarray(rec.ids, dtype=np.int64)
        cols = {name: np.asarray(rec.cols[name], dtype=np.int64) for name in names}
    out: list[tuple[int, int, int]] = []
    for w in WINDOWS:
        a, b = cols[f"{w}_start"], cols[f"{w}_stop"]
        out += [(int(x), int(y), int(i)) for x, y, i in zip(a, b, ids, strict=False) if 0 <= x < y]
    return out


def _loose(run: RunFile, marked: list[Unused]) -> list[tuple[int, int]]:
    """Ranges of written frames neither a committed record nor a mark takes.

    Every window starts at a chunk boundary (:mod:`.frames`), so what lies between the end of
    one taken range and the next boundary was never written: only the spans from a boundary are
    read (their ``time``; an unwritten frame holds its fill, NaN).
    """
    frames = run.tables.frames
    taken = sorted([*((a, b) for a, b, _ in _record_windows(run)), *((u.start, u.stop) for u in marked)])
    chunk, extent = frames.chunk, frames.extent
    gaps, at = [], 0
    for a, b in [*taken, (extent, extent)]:
        lo = -(-at // chunk) * chunk
        if lo < min(a, extent):
            gaps.append((lo, min(a, extent)))
        at = max(at, b)
    out: list[tuple[int, int]] = []
    for lo, hi in gaps:
        written = np.isfinite(np.asarray(frames.time[lo:hi], dtype=np.float64))
        edges = np.flatnonzero(np.diff(np.concatenate([[0], written.astype(np.int8), [0]])))
        out += [(lo + int(s), lo + int(e)) for s, e in zip(edges[::2], edges[1::2], strict=True)]
    return out


def describe(ranges: list[Unused], noun: str = "record") -> str | None:
    """One line for ``inspect``: how many raw frames belong to no record and why (None: none)."""
    c = counts(ranges)
    if not c:
        return None
    total = sum(c.values())
    parts = ", ".join(
        f"{n} not marked: recorded before the marks, or in progress" if why == UNMARKED else f"{n} {why}"
        for why, n in c.items()
    )
    return f"{total} frame{'s' if total != 1 else ''} in no {noun} ({parts})"
