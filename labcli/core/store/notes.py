"""``run.notes``: what people wrote about a run and its records, kept in the run file.

A note is about the run (``labcli note RUN.h5 "..."``) or about one record (``n`` at a
trial's review).  Notes are an append-only table (:mod:`.columns`), ``/entry/notes``, one
row per note: when it was written, the record it is about (-1: the run) and its text.  A
note is never changed or removed; a second note on the same record is added after the first.

The table is made by the first note, so a run nobody annotated is the file it always was;
making it changes the file's attributes, whose checksum (:func:`.opening.metadata_checksum`)
is then taken again, and only when it checked out before.

>>> run.notes.add("valve 2 replaced before trial 40")     # doctest: +SKIP
>>> run.notes.add("the weight swung", record=12)          # doctest: +SKIP
>>> [n["text"] for n in run.notes.all()]                  # doctest: +SKIP
['valve 2 replaced before trial 40', 'the weight swung']
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, TypedDict

import numpy as np

from ...errors import StoreError
from ..files import stored_text
from ..paper import Column
from ..timestamps import utc_now
from .blobs import cell_text
from .columns import Table
from .layout import TIME_WIDTH, text_column
from .nexus import home
from .opening import metadata_checksum, metadata_ok

if TYPE_CHECKING:
    from .runfile import RunFile

NOTE_BYTES = 2000  # a paragraph; longer notes are refused in one sentence
NOTE_COLUMNS = [
    text_column("time", TIME_WIDTH, "when the note was written (ISO 8601)"),
    Column("record", "1", kind="int", what="the record the note is about; -1: the run"),
    text_column("text", NOTE_BYTES, "the note, as typed"),
]
GROUP = "notes"


class Note(TypedDict):
    time: str
    record: int | None  # None: the run
    text: str


class Notes:
    """``run.notes`` (see the module docstring)."""

    def __init__(self, run: RunFile) -> None:
        self._run = run

    def _table(self) -> Table | None:
        run = self._run
        if run.v1 is not None or GROUP not in run.h5["entry"]:
            return None
        return Table(run.h5["entry"][GROUP])

    def all(self) -> list[Note]:
        """Every note, in the order written (a damaged row is named in a warning and left out)."""
        t = self._table()
        if t is None:
            return []
        rows = t.read()
        if rows.damaged:
            self._run.warn(f"{self._run.path}: note row {rows.damaged[0][0]}: {rows.damaged[0][1]}; it is left out.")
        c = rows.cols
        out: list[Note] = []
        for i in range(len(rows.rows)):
            rid = int(c["record"][i])
            out.append(
                {"time": cell_text(c["time"][i]), "record": None if rid < 0 else rid, "text": cell_text(c["text"][i])}
            )
        return out

    def of_run(self) -> list[str]:
        """The notes about the run, in order."""
        return [n["text"] for n in self.all() if n["record"] is None]

    def of_records(self) -> dict[int, list[str]]:
        """Record id -> its notes, in order."""
        out: dict[int, list[str]] = {}
        for n in self.all():
            if n["record"] is not None:
                out.setdefault(n["record"], []).append(n["text"])
        return out

    def add(self, text: str, record: int | None = None) -> Note:
        """Keep a note about the run (``record`` None) or about a stored record; returns it."""
        run = self._run
        run.writer.check()
        run.check_v2("a note")
        text = " ".join(stored_text(str(text)).split())  # one line: a note is a sentence or a paragraph, not a layout
        if not text:
            raise StoreError("a note needs some text; nothing was added.")
        size = len(text.encode("utf-8"))
        if size > NOTE_BYTES:
            raise StoreError(f"a note holds at most {NOTE_BYTES} bytes, and this one has {size}; nothing was added.")
        if record is not None and int(record) not in run.records:
            from .summary import record_noun

            raise StoreError(f"{run.path} has no complete {record_noun(run)} {record}, so the note was not added.")
        t = self._table() or self._create()
        note: Note = {"time": utc_now(), "record": None if record is None else int(record), "text": text}
        row = {"time": note["time"], "record": -1 if record is None else int(record), "text": text}
        run.writer.commit_row(t, {c.name: c for c in NOTE_COLUMNS}, lambda: row, size + 64, "the note")
        return note

    def _create(self) -> Table:
        """The notes table, made in a run that has none, the file's attribute checksum taken again."""
        run = self._run
        if not metadata_ok(run.h5):
            raise StoreError(
                f"{run.path}: the run's metadata do not match their checksum, so labcli adds no note to it; "
                "check it with labcli inspect --verify."
            )
        run.writer.reserve(64 * 1024, "the note")
        with run.writer.writing("the note"):
            t = Table.create(run.h5["entry"], GROUP, NOTE_COLUMNS, 16)
            home(run.h5).modify("metadata_checksum", np.uint64(metadata_checksum(run.h5)))
            run.writer.sync()
        return t


def with_notes(df: Any, id_column: str, notes: list[Note]) -> Any:
    """``df`` (a record table) with a ``note`` column when any of its records has a note (" | " between two).

    The run's own notes go into ``df.attrs["provenance"]["notes"]`` (the table's description).
    """
    by_record: dict[int, list[str]] = {}
    for n in notes:
        if n["record"] is not None:
            by_record.setdefault(n["record"], []).append(n["text"])
    if by_record and "note" not in df.columns:
        df["note"] = [" | ".join(by_record.get(int(i), [])) for i in df[id_column]]
    about_run = [n["text"] for n in notes if n["record"] is None]
    if about_run:
        df.attrs.setdefault("provenance", {})["notes"] = about_run
    return df
