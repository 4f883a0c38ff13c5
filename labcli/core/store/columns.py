"""Append-only tables: how a run file keeps its records, its session log, its splits and models.

A table is an HDF5 group holding one resizable, chunked dataset per column (gzip, byte
shuffle for whole numbers, HDF5's Fletcher32 checksum on every chunk), a ``checksum`` column (one 64-bit
checksum per row over every other column, :mod:`.checksum`) and the attribute
``@committed``: rows ``[0, @committed)`` are the table; anything past it is a write that
never finished (a kill, a full disk) and is ignored.  Appending is:

1. write the new rows after the committed ones, starting at a chunk boundary, so that no
   chunk holding a committed row is ever written again (HDF5 writes a compressed chunk whose
   size changed over its old bytes when that chunk ends the file, and a kill in that write
   would tear committed rows; rows between the last committed one and the boundary stay
   unwritten, checksum 0, and are skipped).  Rows a killed writer left past ``@committed``
   are written over by the next commit: they were never part of the table;
2. set ``@committed`` to the new end (in place);
3. flush, and make the whole change durable as one checkpoint (the caller,
   :class:`~labcli.core.store.writer.Writer`, through :mod:`.journal`).

Rows are never changed or removed.  A reader reads ``@committed`` first, then the rows, and
checks each row's checksum: a row that fails it is damaged (named, left out), a row with
checksum 0 is a gap, if its chunk was written (else its chunk's record is lost, and it is damaged).
A chunk whose Fletcher32 check fails is read again without the check, so that one damaged row
does not take the rows sharing its chunk with it.

A column whose name ends in a suffix NeXus reserves for a field's companions (``_set``,
``_errors``, ``_weights``, ``_mask``: ``plan_set`` would read as the set point of a field
``plan``) is stored as a dataset with one more ``_`` (``plan_set_``), and ``@columns`` names
the datasets, so a reader with h5py alone finds each one; labcli reads it back under the
column's own name.  Files of schema 2 and earlier hold the names as they are.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import h5py
import numpy as np

from ...errors import StoreError
from ..files import stored_text
from ..paper import Column
from .checksum import Repeated, row_checksums
from .h5 import column_name, h5_name, put

FILTERS = {"compression": "gzip", "compression_opts": 4, "shuffle": True, "fletcher32": True}
# A table's columns (trials, sessions, splits, an imported archive of 10^6 rows): gzip at level 1,
# byte shuffle for whole numbers only, Fletcher32 on every chunk as everywhere.  Measured on an
# imported 10^6-row trial table (docs/performance.md): numbers read from decimal text repeat their
# eight bytes from row to row, which shuffling splits apart, so the float columns shuffled at level 4
# took several times the CPU and twice the bytes of the same columns unshuffled at level 1
# (tests/benchmarks/table_filters.py); ids and counts keep the shuffle, which makes them smaller.
# Neither the level nor the shuffle is part of the schema: HDF5 records both with each dataset,
# and every reader is indifferent.
TABLE_FILTERS = {"compression": "gzip", "compression_opts": 1, "fletcher32": True}
CHECKSUM = Column("checksum", "1", kind="uint", what="checksum of the row's other columns")
READ_BLOCK = 65_536  # rows read and checked at a time, so memory stays bounded on large tables
GROW = 64  # rows a table written a row a commit grows by at a time (trimmed to the rows written at close)


def fill_value(c: Column) -> Any:
    """What an unwritten (or missing optional) value of ``c`` holds."""
    if c.kind == "float":
        return np.nan
    if c.kind in ("int", "flag"):
        return -1
    if c.kind == "uint":
        return 0
    return b""


@functools.lru_cache(maxsize=4096)
def fill_row(c: Column) -> np.ndarray:
    """One row of ``c``'s fill, as stored (made once: a trial leaves half its columns empty at every
    commit).  Shared: never to be written into."""
    row = fixed(c, None, 1)
    row.flags.writeable = False
    return row


def all_fill(c: Column, arr: np.ndarray) -> bool:
    """Whether every value of ``arr`` (column ``c`` as stored) is ``c``'s fill value."""
    if arr.size == 0:
        return False
    first = arr.flat[0]  # not reshape(-1): a column of a DataFrame's block is in Fortran order, and would be copied
    if c.kind == "float":  # NaN of any sign or payload is the fill's NaN: what the fill reads back
        return bool(np.isnan(first) and np.isnan(arr).all())
    fill = fill_value(c)
    return bool(first == fill and np.all(arr == fill))  # the first value decides most columns at once


def h5_dtype(c: Column) -> Any:
    if c.kind == "text":
        return h5py.string_dtype("utf-8", length=max(1, c.width))
    return c.dtype


SMALL_CHUNK = 64  # bytes: a chunk of a table's numbers this small is stored as it is, checksummed


def table_filters(c: Column, chunk_rows: int | None = None) -> dict[str, Any]:
    """The filters of a table's column ``c`` chunked by ``chunk_rows`` rows (:data:`TABLE_FILTERS`;
    shuffled when it holds whole numbers).

    A chunk of numbers of at most :data:`SMALL_CHUNK` bytes (a table written a row a commit:
    the records of an acquisition, the session log) keeps only Fletcher32: gzip makes one
    number's 8 bytes about 16, and setting up the deflate stream costs more than the write.
    Texts keep gzip (a fixed-width text is mostly zeros).  Checksums (the ``uint`` columns)
    keep only Fletcher32 too: 64 bits that look random do not compress, and deflating them
    took an eighth of an imported archive's write."""
    if c.kind == "uint" or (
        chunk_rows is not None
        and c.kind != "text"
        and chunk_rows * c.dtype.itemsize * math.prod(c.shape) <= SMALL_CHUNK
    ):
        return {"fletcher32": True}
    return {**TABLE_FILTERS, "shuffle": c.kind in ("int", "uint", "flag")}


def uncached(g: h5py.Group, name: str) -> h5py.Dataset:
    """Dataset ``name`` of ``g`` without HDF5's chunk cache.

    Frames are written in whole chunks, each once, and read in whole windows; a table written
    a row a commit has one row a chunk, written once: a cache saves nothing, and flushing it
    at every commit costs (HDF5's default would also keep the last 8 MiB written of each of
    a run's 2 + 2k frame arrays in memory).
    """
    dapl = h5py.h5p.create(h5py.h5p.DATASET_ACCESS)
    dapl.set_chunk_cache(1, 0, 1.0)
    return h5py.Dataset(h5py.h5d.open(g.id, name.encode(), dapl))


def create_dataset(
    g: h5py.Group,
    c: Column,
    chunk: int,
    length: int = 0,
    dtype: Any = None,
    by_component: bool = False,
    filters: Mapping[str, Any] = FILTERS,
) -> h5py.Dataset:
    """A resizable dataset for column ``c`` (``length`` rows, chunked by ``chunk`` rows), with its units;
    ``dtype``: a narrower one than the column's kind stores (raw counts as int32); ``by_component``:
    each component in chunks of its own (a channel's frames compress as well as they would alone)."""
    ds = g.create_dataset(
        h5_name(c.name),
        shape=(length, *c.shape),
        maxshape=(None, *c.shape),
        dtype=h5_dtype(c) if dtype is None else dtype,
        chunks=(chunk, *(1 for _ in c.shape)) if by_component else (chunk, *c.shape),
        fillvalue=fill_value(c),
        **filters,
    )
    if c.kind != "text":  # a number has a unit ('1' for a count or an id); a text has none
        put(ds, "units", c.units)
    if c.components:
        put(ds, "components", list(c.components))
    if c.what:
        put(ds, "long_name", c.what)
    return ds


def fixed(c: Column, values: Any, n: int) -> np.ndarray:
    """``values`` (or the fill, when None) as the ``(n, *shape)`` array column ``c`` stores."""
    if values is None:
        return np.full((n, *c.shape), fill_value(c), dtype=c.dtype)
    if c.kind == "text":
        if isinstance(values, np.ndarray) and values.dtype == c.dtype:
            return values.reshape(n)  # already the stored bytes (an import's columns, made whole-array)
        a = np.asarray(values, dtype=object).reshape(n)
        return np.array([v if isinstance(v, bytes) else stored_text(str(v)).encode("utf-8") for v in a], dtype=c.dtype)
    return np.asarray(values, dtype=c.dtype).reshape(n, *c.shape)


def grow(ds: h5py.Dataset, rows: int) -> None:
    """Extend ``ds`` to at least ``rows`` rows (the new ones read as its fill value until written)."""
    if rows > ds.shape[0]:
        ds.id.set_extent((rows, *ds.shape[1:]))


def append(ds: h5py.Dataset, start: int, arr: np.ndarray) -> None:
    """Write ``arr`` at rows ``[start, start + len(arr))`` of ``ds``, growing it to hold them."""
    append_all([(ds, arr)], start)


def append_all(
    items: Sequence[tuple[h5py.Dataset, np.ndarray]], start: int, extent: int | None = None, room: int | None = None
) -> None:
    """:func:`append` each ``(ds, arr)`` at ``start``, the dataspaces made once for each shape.

    ``extent``: no dataset holds more rows than this (the caller knows), so one whose rows end
    at or past it is grown to end there without its extent read first.  ``room``: every
    dataset holds exactly this many rows (the caller grew them), so rows that end within it
    are written without the extent read or changed.  A dataset never shrinks here.
    """
    # Through the low-level id: a commit makes about a hundred of these, and h5py's
    # ``Dataset.shape`` and each dataspace cost as much as a small write.
    spaces: dict[tuple[tuple[int, ...], tuple[int, ...]], tuple[h5py.h5s.SpaceID, h5py.h5s.SpaceID]] = {}
    for ds, arr in items:
        dsid = ds.id
        n = arr.shape[0]
        if room is not None and start + n <= room:
            dims: tuple[int, ...] = (room, *arr.shape[1:])
        elif extent is not None and start + n >= extent:
            dims = (start + n, *arr.shape[1:])
            dsid.set_extent(dims)
        else:
            dims = dsid.get_space().shape
            if start + n > dims[0]:
                dims = (start + n, *dims[1:])
                dsid.set_extent(dims)
        if n == 0:
            continue
        key = (dims, arr.shape)
        space = spaces.get(key)
        if space is None:
            fspace = h5py.h5s.create_simple(dims, (h5py.h5s.UNLIMITED, *dims[1:]))
            fspace.select_hyperslab((start,) + (0,) * (arr.ndim - 1), arr.shape)
            space = spaces[key] = (h5py.h5s.create_simple(arr.shape), fspace)
        dsid.write(space[0], space[1], np.ascontiguousarray(arr, dtype=dsid.dtype))


def _check_header(ds: h5py.Dataset) -> None:
    """Refuse, in one sentence, a dataset whose type, shape or chunking HDF5 cannot read."""
    try:
        ds.dtype, ds.shape, ds.chunks  # noqa: B018 - each is read from the dataset's header
    except Exception:  # noqa: BLE001 - a damaged header message can fail in any way
        raise StoreError(
            f"the dataset {ds.name} of the run file has a damaged header (HDF5 cannot read its type or "
            "shape); check the file with labcli inspect --verify and use a backup copy."
        ) from None


def read_rows(ds: h5py.Dataset, a: int, b: int) -> tuple[np.ndarray, np.ndarray]:
    """Rows ``[a, b)`` of ``ds`` and a mask of rows that could not be read at all.

    When the whole range fails (a chunk failing its Fletcher32 check, or one HDF5 cannot
    decode), it is read again chunk by chunk, so that a damaged chunk takes only its own
    rows with it (h5py offers no way to read past a failed check); those rows are fill.
    A dataset whose header HDF5 cannot read (its type or shape damaged) is one sentence.
    """
    _check_header(ds)
    if ds.shape[0] < b:  # a dataset cut short (rewritten by hand): the rows it lacks are fill, unread
        have = max(a, int(ds.shape[0]))
        out, bad = np.zeros((b - a, *ds.shape[1:]), dtype=ds.dtype), np.ones(b - a, dtype=bool)
        if have > a:
            out[: have - a], bad[: have - a] = read_rows(ds, a, have)
        return out, bad
    try:
        return ds[a:b], np.zeros(b - a, dtype=bool)
    except (OSError, ValueError, RuntimeError):
        pass
    out = np.empty((b - a, *ds.shape[1:]), dtype=ds.dtype)
    bad = np.zeros(b - a, dtype=bool)
    chunk = ds.chunks[0] if ds.chunks else b - a
    for lo in range(a - a % chunk, b, chunk):
        s, e = max(lo, a), min(lo + chunk, b)
        try:
            out[s - a : e - a] = ds[s:e]
        except (OSError, ValueError, RuntimeError):
            out[s - a : e - a] = np.zeros((e - s, *ds.shape[1:]), dtype=ds.dtype)
            bad[s - a : e - a] = True
    return out, bad


@dataclass
class Rows:
    """What a read of a table found: the good rows' positions and values, and the damaged rows."""

    rows: np.ndarray  # positions in the table of the good rows, in order
    cols: dict[str, np.ndarray]  # column -> values of the good rows
    damaged: list[tuple[int, str]] = field(default_factory=list)  # (position, what is wrong)


class Table:
    """One append-only table of an open run file (see the module docstring)."""

    def __init__(self, g: h5py.Group) -> None:
        self.g = g
        stored = [n.decode() if isinstance(n, bytes) else str(n) for n in g.attrs["columns"]]
        self.names: list[str] = [column_name(n) for n in stored]
        self.ds: dict[str, h5py.Dataset] = {column_name(n): g[n] for n in [*stored, CHECKSUM.name]}
        odd = [n for n, ds in self.ds.items() if not isinstance(ds, h5py.Dataset)]
        if odd:  # a damaged object header can make HDF5 see a dataset as another kind of object
            raise StoreError(
                f"{g.name}/{h5_name(odd[0])} of the run file is no dataset (its header is damaged); check the file "
                "with labcli inspect --verify and use a backup copy."
            )
        self.chunk = int(g.attrs["chunk_rows"])
        if self.chunk == 1:
            self.ds = {name: uncached(g, ds.name.rsplit("/", 1)[-1]) for name, ds in self.ds.items()}
        self._room: int | None = None  # rows every column holds, once this object grew them (chunks of a row)
        self._fresh: int | None = None  # rows from here on were never written before this object wrote them
        # The count this object's own last commit set: a writer holds the file's lock, so nothing
        # else moves it, and its next write need not read it back (a reader never commits).
        self._committed: int | None = None

    @classmethod
    def create(
        cls,
        parent: h5py.Group,
        name: str,
        columns: Sequence[Column],
        chunk_rows: int,
        nx_class: str = "NXcollection",
        length: int = 0,
    ) -> Table:
        g = parent.create_group(name)
        put(g, "NX_class", nx_class)
        put(g, "columns", [h5_name(c.name) for c in columns])
        g.attrs["chunk_rows"] = np.int64(chunk_rows)
        cls._set_committed(g, 0, create=True)
        for c in (*columns, CHECKSUM):
            create_dataset(g, c, chunk_rows, length, filters=table_filters(c, chunk_rows))
        return cls(g)

    @staticmethod
    def _set_committed(g: h5py.Group, n: int, create: bool = False) -> None:
        check = np.uint64(row_checksums([np.array([n], dtype="<i8")], 0)[0])
        if create:
            g.attrs["committed"], g.attrs["committed_checksum"] = np.int64(n), check
        else:  # in place, through the low-level attributes (h5py's ``modify`` checks cost more)
            h5py.h5a.open(g.id, b"committed").write(np.array(n, dtype="<i8"))
            h5py.h5a.open(g.id, b"committed_checksum").write(np.array(check, dtype="<u8"))

    @property
    def committed_ok(self) -> bool:
        """Whether ``@committed`` matches its checksum (a flipped bit, or a kill between the two)."""
        if self._committed is not None:
            return True
        try:
            n = int(self.g.attrs["committed"])
            return int(self.g.attrs["committed_checksum"]) == int(row_checksums([np.array([n], dtype="<i8")], 0)[0])
        except (KeyError, OSError, TypeError, ValueError):
            return False

    @property
    def committed(self) -> int:
        """Rows ``[0, committed)`` are the table; when the count is damaged, every row stored."""
        if self._committed is not None:
            return self._committed
        if not self.committed_ok:
            return self.stored()
        return int(self.g.attrs["committed"])

    @property
    def extent(self) -> int:
        return int(self.ds[CHECKSUM.name].shape[0])

    def stored(self) -> int:
        """Rows ever written: the extent, less the rows past the last one written that a table
        grown ahead of its writes holds (a row a commit, :data:`GROW` rows at a time)."""
        end = self.extent
        if self.chunk != 1:
            return end
        dsid = self.ds[CHECKSUM.name].id
        for row in range(end - 1, max(-1, end - 1 - GROW), -1):
            try:
                info = dsid.get_chunk_info_by_coord((row,))
            except (OSError, RuntimeError, ValueError):
                continue
            if info.byte_offset is not None and info.size > 0:
                return row + 1
        return max(0, end - GROW)

    def trim(self) -> None:
        """Give back the rows grown ahead and never written (a writer closing the file): the
        file then holds the rows written, as a reader with h5py alone expects."""
        if self.chunk != 1 or self._room is None:
            return
        end = max(self.stored(), self._committed or 0)
        if end < self._room:
            for ds in self.ds.values():
                ds.id.set_extent((end, *ds.shape[1:]))
            self._room = end

    def next_start(self) -> int:
        """Where the next rows go: after the committed rows, at a chunk boundary."""
        return -(-self.committed // self.chunk) * self.chunk

    def prepared(
        self, columns: Mapping[str, Column], values: Mapping[str, Any], n: int, unwritten_fill: bool = False
    ) -> list[np.ndarray | Repeated]:
        """Every column's ``n`` values as stored (fill where ``values`` lacks the column).

        ``unwritten_fill``: a column ``values`` lacks is a :class:`Repeated` fill, which
        :meth:`write` leaves unwritten (a bulk write of many rows: no fill spelt out, folded or
        compressed row by row).
        """
        if unwritten_fill:
            out: list[np.ndarray | Repeated] = []
            for name in self.names:
                c = columns[name]
                arr = fixed(c, values[name], n) if name in values else None
                # A column given as its fill throughout (an imported table's absent masses, all NaN)
                # is left unwritten too: it reads back the same, and its rows check the same.
                out.append(Repeated(fill_row(c), n) if arr is None or all_fill(c, arr) else arr)
            return out
        return [fixed(columns[name], values.get(name), n) for name in self.names]

    def write(self, arrays: Sequence[np.ndarray | Repeated], n: int) -> tuple[int, int]:
        """Write ``n`` rows (from :meth:`prepared`) after the committed ones; returns ``[start, stop)``.

        They are not part of the table until :meth:`commit`.
        """
        start = self.next_start()
        if self._fresh is None:
            self._fresh = min(int(ds.shape[0]) for ds in self.ds.values())
        # Rows from ``_fresh`` on were grown by this object and never written by anyone: a column
        # given as its fill there is left unwritten (its rows read back as the fill, and check the
        # same).  Before it, a killed writer of an older labcli (no journal) may have left rows past
        # ``@committed``, which only a write of every column makes the new row's own.
        fresh = start >= self._fresh
        # Grown ahead only for rows all written, or fresh (a bulk write leaves its fill columns
        # unwritten where no row was ever held).
        whole = self.chunk == 1 and (fresh or not any(isinstance(a, Repeated) for a in arrays))
        room = self._grow(start + n) if whole else None
        checks = row_checksums(arrays, start)
        items = []
        for name, arr in zip(self.names, arrays, strict=False):
            ds = self.ds[name]
            if isinstance(arr, Repeated) and (fresh or start >= ds.shape[0]):
                if room is None:
                    grow(ds, start + n)  # rows never written before read as the dataset's fill value
            else:
                items.append((ds, np.repeat(arr.row, n, axis=0) if isinstance(arr, Repeated) else arr))
        append_all([*items, (self.ds[CHECKSUM.name], checks)], start, room=room)
        return start, start + n

    def _grow(self, stop: int) -> int | None:
        """Make every column hold at least ``stop`` rows, growing them :data:`GROW` rows at a time;
        the rows they hold.  A table written a row a commit would otherwise change every column's
        extent (each dataset's header, and the flush and the journal's share of it) at every commit.
        None: the columns' lengths differ (a write cut short), and each is grown as written."""
        if self._room is None:
            self._room = min(int(ds.shape[0]) for ds in self.ds.values())
            if any(int(ds.shape[0]) != self._room for ds in self.ds.values()):
                self._room = None  # columns of different lengths (a write cut short): grown one by one
                return None
        if stop > self._room:
            room = -(-stop // GROW) * GROW
            for ds in self.ds.values():
                ds.id.set_extent((room, *ds.shape[1:]))
            self._room = room
        return self._room

    def commit(self, stop: int) -> None:
        self._committed = None
        self._set_committed(self.g, stop)
        self._committed = stop

    def read(self, want: Sequence[str] | None = None, span: tuple[int, int] | None = None) -> Rows:
        """Rows ``span`` (the committed ones when None), checked: good rows' ``want`` columns (all
        when None), damaged rows named.  A committed count past the rows stored counts as damage."""
        want = list(self.names if want is None else want)
        out: dict[str, list[np.ndarray]] = {name: [] for name in want}
        rows: list[np.ndarray] = []
        damaged: list[tuple[int, str]] = []
        lo, hi = span if span is not None else (0, self.committed)
        if span is None and not self.committed_ok:
            damaged.append(
                (
                    -1,
                    "its committed row count does not match its checksum; every row that checks out "
                    "is read, a last write that never finished included",
                )
            )
        extents = {int(ds.shape[0]) for ds in self.ds.values()}
        if hi > min(extents):
            damaged.append((min(extents), f"the table says {hi} rows are committed but holds {min(extents)}"))
            hi = min(extents)
        for a in range(lo, hi, READ_BLOCK):
            b = min(a + READ_BLOCK, hi)
            values, unreadable = {}, np.zeros(b - a, dtype=bool)
            for name in [*self.names, CHECKSUM.name]:
                values[name], bad = read_rows(self.ds[name], a, b)
                unreadable |= bad
            stored = values[CHECKSUM.name].astype(np.uint64)
            computed = row_checksums([values[name] for name in self.names], a)
            gap = (stored == 0) & ~bad  # a checksum that could not be read is no gap: its row is damaged
            if gap.any():
                gap[gap] = self._written(np.flatnonzero(gap) + a)
            wrong = ~gap & ((stored != computed) | unreadable)
            damaged += [(a + int(i), "its checksum does not match its values") for i in np.flatnonzero(wrong)]
            keep = ~gap & ~wrong
            rows.append(np.flatnonzero(keep) + a)
            for name in want:
                out[name].append(values[name][keep])
        cols = {
            name: (
                np.concatenate(parts) if parts else np.empty((0, *self.ds[name].shape[1:]), dtype=self.ds[name].dtype)
            )
            for name, parts in out.items()
        }
        return Rows(np.concatenate(rows) if rows else np.empty(0, dtype=np.int64), cols, damaged)

    def _written(self, rows: np.ndarray) -> np.ndarray:
        """Whether the chunk of the checksum column holding each row was ever written.  Gaps lie in
        written chunks only (past a commit's last row, up to the chunk's end); a chunk HDF5 holds
        no record of (a flipped bit in its index) reads as zeros too, and its rows are damaged."""
        ds = self.ds[CHECKSUM.name]
        if ds.chunks is None:
            return np.ones(len(rows), dtype=bool)
        starts = rows - rows % ds.chunks[0]
        out = np.zeros(len(rows), dtype=bool)
        for start in np.unique(starts):
            try:
                info = ds.id.get_chunk_info_by_coord((int(start), *(0,) * (ds.ndim - 1)))
            except (OSError, RuntimeError, ValueError):
                continue  # an index HDF5 cannot walk: not written, as far as anyone can tell
            out[starts == start] = info.byte_offset is not None and info.size > 0
        return out


def per_channel(units: Sequence[str], suffix: str = "") -> str:
    """One ``units`` attribute for a value per channel: the unit they share, else each channel's,
    comma-separated in the channels' order."""
    each = [f"{u or '1'}{suffix}" for u in units] or [f"1{suffix}"]
    return each[0] if len(set(each)) == 1 else ",".join(each)
