"""``run.records``: the records of a run, written whole and read back checked.

:meth:`Records.write` takes the record a session commits (SI) and :meth:`Records.read`
gives it back; :meth:`Records.append` takes many records as columns at once (imports: a
million rows in seconds); :meth:`Records.table` gives the CSV exchange table, in the units
people type, degrees and grams rounded to 12 significant digits
(:func:`~labcli.core.store.h5.to_edge`), which makes table -> run file -> table exact.  What
a record holds is its record type's business (:class:`labcli.core.paper.RecordType`); the
run file writes the columns every record shares (:mod:`.rows`).

Reading gives only committed records and checks each one's checksum; a record that fails
it, or holds a value no rig can produce, is named in a
:class:`~labcli.errors.LabcliWarning` (once) and left out.  A reader that meets a commit
under way (a torn read while another process writes) reads again, afresh.

>>> with RunFile.open("run.h5") as run:       # doctest: +SKIP
...     run.records.ids()[:3], run.records.read(12)["P_MPa"]
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from typing import TYPE_CHECKING, Any, cast

import numpy as np

from ...errors import StoreError
from ..paper import RecordType
from ..record import Record, Settle, StoredRecord
from ..window import Window
from .columns import fill_value
from .layout import common_columns, extra_name, window_columns
from .opening import READ_ERRORS, read_afresh
from .rows import bulk_values, exportable, record_id, record_row, settle_of, split_flags
from .view import RecordColumns, from_v1, from_v2
from .writer import Write

if TYPE_CHECKING:
    from .runfile import RunFile

# What every record carries beyond its exchange table (``table(all_columns=True)``, ``labcli export
# --all-columns``): named as the run file's own columns, so ``labcli import`` takes them back.
ALL_COLUMNS = tuple(
    c for c in (*common_columns("id")[1:], *window_columns()) if not c.name.endswith(("_start", "_stop", "_checksum"))
)


class Records:
    """``run.records`` (see the module docstring)."""

    def __init__(self, run: RunFile) -> None:
        self._run = run
        self._cols: RecordColumns | None = None  # the last read, until something is written
        self._done: set[int] | None = None  # ids complete in the file
        self._order: list[int] | None = None  # ... in recording order
        # Ids of bulk appends not yet in the two above: an import's million become Python ints
        # only if something asks for them as such (the split checks them as an array).
        self._bulk: list[np.ndarray] = []

    # ------------------------------------------------------------ writing
    def write(self, record: Record) -> None:
        """Write one record of the run's kind whole; it counts only once it is committed.

        ``record``: what the run's record type takes (the session's ``Commit``, or an
        imported table row), plus what every record may carry (:class:`~labcli.core.record.Record`):
        ``started``/``ended`` (ISO 8601; ``ended`` defaults to now), ``settle``
        (``{"baseline": ..., "load": ...}``), ``raw`` (its windows, each a
        :class:`~labcli.core.window.Window` the engine streamed into this file, or held in memory), ``accepted``,
        ``flags`` (a list of one-sentence notes), ``extra`` (imported columns).  Raises
        StoreError if the record is already complete in the file or is malformed (nothing is
        written then), DiskFull if there is no room for it (nothing is written then either).
        """
        run = self._run
        rt = run.record_type
        run.writer.check()
        rid, label = record_id(record, rt.id_column)
        run.check_v2(label)
        if rid in self._ids():
            raise StoreError(f"{label} is already complete in {run.path}; a stored record is never overwritten.")
        tables = run.tables
        row = record_row(rt, tables.columns, record, label, rid, run)
        windows = run.windows.checked(record, label)
        where, frames = run.windows.store(windows, label)
        row.update(where)
        undo = run.sessions.stage_added(rid)  # the session log's "added", committed with the record
        try:
            run.writer.commit(
                [Write(tables.records, tables.columns, {k: [v] for k, v in row.items()}, 1)], frames, label
            )
        except BaseException:
            undo()
            raise
        self._written([int(rid)])

    def write_many(self, records: Sequence[Record]) -> None:
        """Write several records of the run's kind, each whole with its windows, in one commit.

        What :meth:`write` does for one record, for a stream that commits what it gathered
        every second or so (``labcli sense --record``): every record is checked before
        anything is written; their windows' frames are written, then the rows and the moved
        ``@committed`` in one commit, so a kill leaves all of them or none.  The records must
        give the same columns.
        """
        if not records:
            return
        run = self._run
        rt = run.record_type
        run.writer.check()
        run.check_v2("the records")
        tables = run.tables
        have = self._ids()
        rows, checked, ids = [], [], []
        for record in records:
            rid, label = record_id(record, rt.id_column)
            if rid in have or rid in ids:
                raise StoreError(f"{label} is already complete in {run.path}; a stored record is never overwritten.")
            rows.append(record_row(rt, tables.columns, record, label, rid, run, table_check=False))
            checked.append((run.windows.checked(record, label), label))
            ids.append(rid)
        exportable(rt, rows, ids, [label for _, label in checked], run)
        keys = set(rows[0])
        if any(set(r) != keys for r in rows[1:]):
            raise StoreError(f"the batch of {rt.count(len(rows))} does not give the same columns for each record.")
        nbytes = 0
        for row, (windows, label) in zip(rows, checked, strict=True):
            where, frames = run.windows.store(windows, label)
            row.update(where)
            nbytes += frames
        undos = [run.sessions.stage_added(rid) for rid in ids]
        # A record without a window (an event among estimates) holds the fill a lone write gives it.
        names = sorted({k for r in rows for k in r})
        values = {k: [r[k] if k in r else fill_value(tables.columns[k]) for r in rows] for k in names}
        try:
            run.writer.commit(
                [Write(tables.records, tables.columns, values, len(rows))],
                nbytes,
                f"the batch of {rt.count(len(rows))}",
            )
        except BaseException:
            for undo in reversed(undos):
                undo()
            raise
        self._written(ids)

    def append(self, columns: Mapping[str, Any]) -> int:
        """Commit many records at once, given as columns (the bulk write of ``labcli import``).

        ``columns``: column name -> values over the records (sequence or array, first axis
        the records): the id column, the record type's columns (optional ones may be left
        out), and any of ``started``, ``ended``, ``accepted``, ``flags`` and the table's
        extra columns.  Checked whole first (ids new and unique, values of the right shape
        and in range, texts short enough); then one commit.  Returns the number of records.
        About a million trial rows take a few seconds (``tests/benchmarks/bench_store.py``).
        """
        run = self._run
        rt = run.record_type
        run.writer.check()
        run.check_v2("the records")
        ids = np.asarray(columns[rt.id_column], dtype=np.int64).reshape(-1)
        n = ids.shape[0]
        tables = run.tables
        values = bulk_values(rt, tables.columns, columns, ids, self._ids(), run.path)
        run.writer.commit([Write(tables.records, tables.columns, values, n)], 0, f"the batch of {rt.count(n)}")
        self._written(ids)
        return n

    def _written(self, ids: list[int] | np.ndarray) -> None:
        """Note records committed; ``ids`` plain Python ints, or an array of a bulk append (kept as it is)."""
        self._cols = None
        if isinstance(ids, np.ndarray):
            self._bulk.append(ids)
            return
        self._ids().update(ids)
        self._recorded().extend(ids)

    def _take_bulk(self) -> None:
        """Fold the ids of bulk appends into the id set and order (both read before any append)."""
        if not self._bulk:
            return
        fresh = np.concatenate(self._bulk).tolist()
        self._bulk = []
        assert self._done is not None and self._order is not None
        self._done.update(fresh)
        self._order.extend(fresh)

    def id_array(self) -> np.ndarray:
        """:meth:`ids` as an int64 array (a bulk append's ids as they were given, never made Python ints)."""
        if self._bulk and self._order is not None:
            return np.concatenate([np.asarray(self._order, dtype=np.int64), *self._bulk])
        return np.asarray(self.ids(), dtype=np.int64)

    # ------------------------------------------------------------ reading
    def columns(self) -> RecordColumns:
        """The good records, as columns; damaged ones named in a warning (once) and left out."""
        if self._cols is not None:
            return self._cols
        run = self._run

        def read() -> RecordColumns:
            return (
                from_v1(run.v1, run.record_type) if run.v1 is not None else from_v2(run.tables.records, run.record_type)
            )

        try:
            rec = read_afresh(run, read, lambda r: bool(r.damaged))
        except READ_ERRORS:
            raise StoreError(
                f"{run.path} is damaged or truncated and HDF5 cannot read it; use a backup copy."
            ) from None
        if rec.damaged:
            run.warn(damage_sentence(run.path, rec.damaged))
        self._cols = rec
        self._bulk = []  # read back with the rest
        self._done = set(rec.ids)
        self._order = list(rec.ids)
        return rec

    def _ids(self) -> set[int]:
        self._take_bulk()
        if self._done is None:
            self._done = set(self.ids())
        return self._done

    def _recorded(self) -> list[int]:
        self._take_bulk()
        if self._order is None:
            self.columns()
        assert self._order is not None
        return self._order

    def ids(self) -> list[int]:
        """Ids of the complete records (trials, pushes, points: the run's kind), in recording order."""
        self._take_bulk()
        if self._cols is None and self._order is not None:
            return list(self._order)
        return list(self.columns().ids)

    def __len__(self) -> int:
        return len(self.ids())

    def __contains__(self, rid: object) -> bool:
        return isinstance(rid, (int, np.integer)) and int(rid) in self._ids()

    def incomplete_ids(self) -> list[int]:
        """Ids with only an interrupted write (a kill's leftovers), never counted."""
        done = self._ids()
        return sorted(i for i in self.columns().incomplete if i not in done)

    def first_incomplete(self, plan_ids: Iterable[int]) -> int | None:
        """The first id of ``plan_ids`` not yet complete in the file (None: all done)."""
        done = self._ids()
        for i in plan_ids:
            if int(i) not in done:
                return int(i)
        return None

    def damaged(self) -> list[tuple[str, str]]:
        """(what, why) of every record left out as damaged."""
        return list(self.columns().damaged)

    def read(self, rid: int) -> StoredRecord:
        """One complete record back as the writer gave it (SI), with its windows (read into memory).

        The record type's values (:meth:`labcli.core.paper.RecordType.read`) and every key of
        :class:`~labcli.core.record.StoredRecord`.  A window whose frames fail their checksum is
        left out with a warning.
        """
        run = self._run
        rec = self.columns()
        i = rec.position(int(rid))
        if i is None:
            raise StoreError(f"{run.record_type.noun} {rid} is not a complete record in {run.path}.")
        row = {name: v[i] for name, v in rec.cols.items()}
        raw: dict[str, Window] = {}
        settle: dict[str, Settle] = {}
        for name, key in (("baseline", "baseline"), ("loaded", "load")):
            w = run.windows.of_record(rec, i, name)
            if w is not None:
                raw[key] = w
            s = settle_of(row, name)
            if s:
                settle[key] = s
        common: StoredRecord = {
            "started": str(row["started"]),
            "ended": str(row["ended"]),
            "accepted": str(row["accepted"]),
            # Where it was recorded: its table row (schema 2), which a damaged record before
            # it does not shift; its position among the good records (schema 1).
            "order": int(rec.sources[i]) if run.v1 is None else i,
            "raw": raw,
            "settle": settle,
            "extra": {extra_name(name): _plain(row[name]) for name in rec.extras},
            "flags": split_flags(row.get("flags", "")),
        }
        # The record type's values first, as the writer gave them: a TypedDict of its kind.
        return cast(StoredRecord, {**run.record_type.read(row), **common})

    def table(self, kind: RecordType | None = None, all_columns: bool = False) -> Any:
        """The CSV exchange table of the complete records (DataFrame), in recording order.

        The record type's columns, then the columns of an imported table labcli does not
        know; with ``all_columns``, then what every record carries (:data:`ALL_COLUMNS`: when
        it began and was stored, how it was accepted, its flags, how each window settled).
        ``kind``: another record type to read (a run holds only its own kind's records, so
        another kind gives an empty table).
        """
        run = self._run
        rt = kind or run.record_type
        if rt.kind != run.record_type.kind:
            empty = {c.name: np.empty((0, *c.shape), dtype=object if c.kind == "text" else c.dtype) for c in rt.columns}
            return rt.table(run, [], empty)
        rec = self.columns()
        df = rt.table(run, list(rec.ids), rec.cols)
        for name in rec.extras:
            v = rec.cols[name]
            df[extra_name(name)] = [x.item() if isinstance(x, np.generic) else x for x in v] if v.dtype == object else v
        if all_columns:
            for c in ALL_COLUMNS:
                v = rec.cols[c.name]
                df[c.name] = (
                    [str(x) for x in v] if c.kind == "text" else v.astype(np.int64 if c.kind == "flag" else v.dtype)
                )
        return df


def _plain(v: Any) -> Any:
    return v.item() if isinstance(v, (np.integer, np.floating, np.bool_)) else v


def damage_sentence(path: str, damaged: list[tuple[str, str]]) -> str:
    """The warning that names the damaged records left out."""
    first = "; ".join(f"{what}: {why}" for what, why in damaged[:3])
    more = f" (and {len(damaged) - 3} more)" if len(damaged) > 3 else ""
    return (
        f"{path}: {len(damaged)} damaged {'record is' if len(damaged) == 1 else 'records are'} left out "
        f"({first}{more}); the file changed after it was written. "
        "`labcli inspect --verify` lists everything damaged."
    )
