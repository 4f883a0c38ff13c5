"""The one write path of a run file: every change is one commit.

Adding anything (a record, a batch of imported records, a split, a model, the session
log's events) is one commit, and every commit goes through :meth:`Writer.commit`:

1. the space it may need is reserved past the end of the file (:mod:`.space`; a full disk
   or ``ulimit -f`` stops it here, before anything is written);
2. raw frames (already written by a :class:`~.frames.WindowWriter`) and rows are written
   after the committed ones at fresh chunk boundaries (:meth:`.columns.Table.write`, which
   resizes each column and writes into it);
3. each table's ``@committed`` is set to its new end (in place);
4. HDF5 flushes, and the file takes everything as one checkpoint (:mod:`.journal`): every
   byte written since the last one (the new bytes, and what HDF5 rewrote in place: its
   headers and B-tree nodes, the superblock, ``@committed``) becomes one record of the
   journal, synced, before the rewrites reach the file.

The new rows only count once ``@committed`` says so, and the checkpoint makes HDF5's
bookkeeping change whole or not at all; what a kill or a power cut interrupts before that
is ignored, and the next commit writes over it.  Nothing committed is ever written again
(:mod:`.columns` says why that needs fresh chunks).

A failed HDF5 write (an I/O error, or memory running out) marks the file broken: nothing more is written to it
and closing it does not flush HDF5's half-written state.  The session log's events that
ride on the next commit (:mod:`.sessions`) join whichever commit comes first.
"""

from __future__ import annotations

import contextlib
import errno
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass
from typing import Any, Protocol

import h5py

from ...errors import DiskFull, StoreError
from ..paper import Column
from . import space
from .columns import Table
from .journal import JournalFile

AHEAD = 1 << 20  # bytes of room reserved at a time past the end of the file (given back at close)


@dataclass(frozen=True)
class Write:
    """``n`` rows of ``table``: column name -> values (first axis the rows), as ``columns`` define them."""

    table: Table
    columns: Mapping[str, Column]
    values: Mapping[str, Any]
    n: int


class Riders(Protocol):
    """Rows that ride on the next commit, whatever it is (the session log's events)."""

    def pending(self) -> Write | None:
        """The rows waiting (None: none)."""

    def committed(self) -> None:
        """They were committed: forget them."""


class Writer:
    """The write path of one open run file (see the module docstring).

    ``file``: gives the open HDF5 file; ``kept``: what is safe when a write fails ("the 11
    trials stored before are intact"), for the one sentence that says so.
    """

    def __init__(
        self,
        path: str,
        mode: str,
        file: Callable[[], h5py.File],
        kept: Callable[[], str],
        io: Callable[[], JournalFile | None],
    ) -> None:
        self.path = path
        self.mode = mode
        self.broken = False
        self.riders: Riders | None = None
        self._file = file
        self._kept = kept
        self._io = io
        self._room = 0  # the file's bytes up to here (and space.SLACK past them) are reserved

    def check(self) -> None:
        """Refuse a write to a file open read-only, or one that met a write error."""
        if self.mode == "r":
            raise StoreError(f"{self.path} is open read-only; open it with mode 'a' to add records.")
        if self.broken:
            raise StoreError(f"{self.path} met a write error earlier; close it and open it again.")

    def sync(self, doing: str = "the change", publishing: bool = False) -> None:
        """Push everything written so far to the disk, as one change (flush, then a checkpoint).

        ``publishing``: the file, built under a temporary name, is about to be put in place.

        A checkpoint refused for want of room (its journal) leaves the file as the last one left
        it; HDF5's state in memory is ahead of it, so nothing more is written through it.
        """
        self._file().flush()
        try:
            self._journal().checkpoint(publishing)
        except OSError as e:
            if e.errno not in (errno.ENOSPC, errno.EDQUOT, errno.EFBIG):
                raise
            self.broken = True
            raise space.no_room(e.errno, self.path, doing, self._kept()) from None

    def flush(self, doing: str) -> None:
        """Push a window's frames written so far into the file, where a viewer sees them (a checkpoint)."""
        with self.writing(doing):
            self.sync(doing)

    def reserve(self, nbytes: int, doing: str) -> None:
        """Make sure ``nbytes`` more can be written, or raise DiskFull naming ``doing`` and what is safe.

        Room is reserved :data:`AHEAD` bytes at a time (or just what is asked, when that much
        is not to be had), so most commits find theirs reserved already and ask the disk nothing.
        """
        io = self._journal()
        end, need = io.end(), int(nbytes)
        if end + need <= self._room:
            return
        ask = max(need, AHEAD)
        try:
            space.reserve(io.fd, end, ask, self.path, doing, self._kept)
        except DiskFull:
            if ask == need:
                raise
            ask = need
            space.reserve(io.fd, end, ask, self.path, doing, self._kept)
        self._room = end + ask

    def _journal(self) -> JournalFile:
        io = self._io()
        if io is None:
            raise StoreError(f"{self.path} is open read-only; open it with mode 'a' to add records.")
        return io

    @contextlib.contextmanager
    def writing(self, doing: str) -> Iterator[None]:
        """Turn a failed HDF5 write into one sentence, and keep HDF5 from flushing its half-written state later."""
        try:
            yield
        except DiskFull:
            raise
        except MemoryError:  # HDF5's state may be half-written: never flushed into the file
            self.broken = True
            raise
        except OSError as e:
            self.broken = True
            raise StoreError(
                f"{self.path} could not be written ({e.strerror or e}), so {doing} was not stored; {self._kept()}."
            ) from None

    def commit(self, writes: Sequence[Write], frames: int = 0, doing: str = "the change") -> list[tuple[int, int]]:
        """Write rows into tables in one commit; their ``[start, stop)``.

        ``frames``: bytes of raw frames already written for it (for the reservation).  Columns
        without values, or given as their fill throughout, are left unwritten where no row was
        ever held (:meth:`Table.prepared`, :meth:`Table.write`): a trial leaves about half of
        its table's columns empty, and the session log's ``added`` row most of its own.
        """
        riding = self.riders.pending() if self.riders is not None else None
        everything = [*writes, *([riding] if riding is not None else [])]
        arrays = [(w.table, w.table.prepared(w.columns, w.values, w.n, unwritten_fill=True), w.n) for w in everything]
        self.reserve(sum(a.nbytes for _, arrs, _ in arrays for a in arrs) + frames, doing)
        with self.writing(doing):
            spans = [t.write(arrs, n) for t, arrs, n in arrays]
            for (t, _, _), (_, stop) in zip(arrays, spans, strict=True):
                t.commit(stop)
            self.sync(doing)
        if self.riders is not None:
            self.riders.committed()
        return spans[: len(writes)]

    def commit_row(
        self,
        table: Table,
        columns: Mapping[str, Column],
        make_row: Callable[[], dict[str, Any]],
        nbytes: int,
        doing: str,
    ) -> None:
        """Commit one row of ``table`` whose data (a split's ids, a model's JSON) ``make_row`` writes first.

        The room for both is reserved before the data is written, so a full disk or ``ulimit -f``
        stops the change before HDF5 writes anything.
        """
        self.check()
        self.reserve(nbytes, doing)
        with self.writing(doing):
            row = make_row()
        self.commit([Write(table, columns, {k: [v] for k, v in row.items()}, 1)], nbytes, doing)
