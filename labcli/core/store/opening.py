"""Opening a run file: what is checked before HDF5 is trusted with it, and the metadata's checksum.

A path that is not a run file (missing, a folder, a device, not HDF5, another program's
HDF5, a schema newer than this labcli) is refused in one sentence before anything reads it.
Readers open without HDF5's file lock (so a run can be read while it is recorded); writers
take it (:mod:`.space` says why one lock serves every writer).
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Protocol, TypeVar

import h5py
import numpy as np

from ...errors import StoreError
from ..paper import Column, RecordType
from . import space
from .checksum import row_checksums
from .columns import Table
from .frames import Frames
from .h5 import text
from .journal import JournalFile, journal_path, lock, recover, replay
from .layout import SCHEMA, SCHEMA_VERSION, common_columns, record_columns, window_columns
from .nexus import field_parts, home

# Attributes a commit changes in place: left out of the metadata's checksum.
MUTABLE_ATTRS = ("committed", "committed_checksum", "metadata_checksum")
READ_RETRIES = 8  # torn reads while a writer commits: tries before the damage is believed
# What HDF5 raises on a torn read (a B-tree node or an object header copied in beside old ones) or a
# damaged header (a dataspace of 0 rows: IndexError from h5py).
READ_ERRORS = (OSError, KeyError, ValueError, RuntimeError, TypeError, IndexError)
T = TypeVar("T")


class Reopens(Protocol):
    """A run file open for reading that can say whether a writer may have torn a read, and open afresh."""

    def may_be_torn(self) -> bool:
        """Whether a writer held the file at any time since it was opened (at its opening, or now)."""

    def reopen(self) -> None:
        """Open the file afresh."""


def read_afresh(run: Reopens, read: Callable[[], T], torn: Callable[[T], bool]) -> T:
    """``read()``, read again with the file opened afresh while it looks ``torn`` and a writer may have torn it.

    A reader opens without the lock, and a writer's checkpoint copies HDF5's pages into the file
    one at a time (:mod:`.journal`): a read that overlaps one can meet new pages beside old ones
    (a metadata checksum, a row checksum or a Fletcher32 check that fails, a count past the rows,
    or an error from HDF5).  A writer that held the file when it was opened counts as well as one
    holding it now: its last commit may tear a read and the writer let go before the read ended.
    An error HDF5 raises on the last try, or with no writer about, is raised.
    """
    for attempt in range(READ_RETRIES):
        last = attempt + 1 == READ_RETRIES
        try:
            got = read()
        except READ_ERRORS:
            if last or not run.may_be_torn():
                raise
        else:
            if last or not torn(got) or not run.may_be_torn():
                return got
        time.sleep(0.02 * (attempt + 1))  # a commit under way: read again, afresh
        run.reopen()
    raise AssertionError("unreachable")


def metadata_checksum(f: h5py.File) -> int:
    """A checksum over every attribute in the file but the commit counters, and over the NeXus
    metadata fields of schema 3 (all fixed at creation)."""
    parts: list[bytes] = []

    def add(name: str, obj: Any) -> None:
        for key in sorted(obj.attrs):
            if key in MUTABLE_ATTRS:
                continue
            v = np.asarray(obj.attrs[key])
            if v.dtype.kind == "O":
                data = b"\x1f".join(x.encode("utf-8") if isinstance(x, str) else bytes(x) for x in v.ravel())
            else:
                data = v.tobytes()
            parts.append(f"{name}@{key}:{v.dtype.str}:".encode() + data)

    add("/", f)
    views = _views(f)
    for name in _objects(f):
        if name not in views:
            add(name, f[name])
    parts += field_parts(f)
    blob = np.frombuffer(b"\x1e".join(parts), dtype=np.uint8)
    return int(row_checksums([blob.reshape(1, -1)], 0)[0])


def _objects(f: h5py.File) -> list[str]:
    """Each object of the file once, by the first name met through hard links: the names
    ``visititems`` gives, in its order, found from the links alone.

    HDF5's object visit (``visit``, ``visititems``) reads each dataset's layout, and a virtual
    dataset's layout in the global heap, where one flipped bit hung it (measured); the link visit
    reads no object.
    """
    links: list[bytes] = []
    f.id.links.visit(links.append)  # H5Lvisit, in visit's order
    seen, names = {h5py.h5o.get_info(f.id).addr}, []  # the root group: no dataset, no layout
    for name in links:
        info = f.id.links.get_info(name)
        if info.type == h5py.h5l.TYPE_HARD and info.u not in seen:
            seen.add(info.u)
            names.append(name.decode("utf-8", "surrogateescape"))
    return names


def _views(f: h5py.File) -> set[str]:
    """The channels' NXlog ``value`` and ``raw_value`` of a schema-4 file, by name: views of
    ``raw/values`` and ``raw/counts`` (virtual datasets, :mod:`.frames`), which no reader opens.

    Their mappings live in HDF5's global heap, and HDF5 reads them as it opens the dataset (and
    in its object visit, hence :func:`_objects`): one flipped bit there can crash or hang the
    process (measured, as for variable-length text), so labcli reads the frames from the arrays
    themselves and leaves the views to NeXus readers.
    """
    raw = f.get("entry/raw")
    if not isinstance(raw, h5py.Group) or "values" not in raw:
        return set()
    return {f"entry/raw/{c}/{k}" for c in raw for k in ("value", "raw_value")}


def metadata_ok(f: h5py.File) -> bool:
    """Whether a file's metadata (schema 2 and later) match the checksum taken when it was created."""
    try:
        return int(home(f)["metadata_checksum"]) == metadata_checksum(f)
    except Exception:  # noqa: BLE001 - a damaged attribute can fail in any way
        return False


def check_openable(path: str, mode: str) -> None:
    """Refuse, in one sentence, a path that cannot be a run file open in ``mode``."""
    if not os.path.exists(path):
        raise StoreError(f"{path} does not exist; check the path.")
    if os.path.isdir(path):
        raise StoreError(f"{path} is a directory, not a run file.")
    what = space.kind_of(path)
    if what:
        raise StoreError(f"{path} is {what}, not a run file.")
    if not os.access(path, os.R_OK) or (mode == "a" and not os.access(path, os.W_OK)):
        raise StoreError(f"{path} cannot be {'read' if mode == 'r' else 'written'}: permission denied.")
    try:
        is_hdf5 = h5py.is_hdf5(path)
    except OSError:
        is_hdf5 = False
    if not is_hdf5:
        raise StoreError(f"{path} is not an HDF5 file; run files are written by 'labcli acquire' or 'labcli import'.")


def open_error(path: str, e: OSError) -> str:
    """The sentence for an HDF5 file that would not open."""
    if "unable to lock file" in str(e).lower():
        # A write lock is refused while anyone holds the file, a reader included.
        return f"{path} {space.BUSY}."
    return f"{path} is damaged or truncated and HDF5 cannot open it; use a backup copy."


def check_schema(f: h5py.File, path: str) -> int:
    """The file's schema version, refused in one sentence unless this labcli reads it."""
    where = home(f)  # the root up to schema 2, /entry/labcli from schema 3
    schema, version = where.get("schema"), where.get("schema_version")
    if schema is None or text(schema) != SCHEMA:
        found = "no schema attribute" if schema is None else f"schema {text(schema)!r}"
        raise StoreError(f"{path} is an HDF5 file but not a labcli run file ({found}, expected '{SCHEMA}').")
    try:
        version = int(version)
    except (TypeError, ValueError):
        raise StoreError(f"{path} has no valid schema_version attribute; the file is damaged.") from None
    if version > SCHEMA_VERSION:
        raise StoreError(
            f"{path} uses run-file schema version {version}, newer than this labcli reads "
            f"({SCHEMA_VERSION}); upgrade labcli."
        )
    if version < 1:
        raise StoreError(f"{path} has schema_version {version}, which no labcli wrote; the file is damaged.")
    return version


def h5open(path: str, mode: str) -> h5py.File:
    """The HDF5 file: a reader without the lock, a writer locked and journaled (:func:`open_writer`)."""
    if mode == "r":
        recover(path)  # a journal a killed writer left: replayed first, by whoever comes (when it may write)
        try:
            return h5py.File(path, "r", locking=False)
        except OSError as e:
            if "locking flag" not in str(e):
                raise
            return h5py.File(path, "r")  # already open in this process (as a writer): share it
    return open_writer(path)[0]


def open_writer(path: str) -> tuple[h5py.File, JournalFile]:
    """An existing run file open for writing: locked (as HDF5 locks), written through a :class:`JournalFile`."""
    fd = os.open(path, os.O_RDWR)
    try:
        lock(fd, path, space.BUSY)
        replay(fd, journal_path(path))
        io = JournalFile(fd, path)
        return h5py.File(io, "r+"), io
    except BaseException:
        os.close(fd)
        raise


@dataclass
class Tables:
    """The open tables of a schema-2 run (opened afresh when a reader reopens the file)."""

    records: Table
    columns: dict[str, Column]  # the record table's columns, its imported extras included
    frames: Frames
    split: Table
    models: Table
    sessions: Table


def open_tables(entry: h5py.Group, rt: RecordType, path: str) -> Tables:
    """The tables of a schema-2 run's ``/entry``, its record table's columns checked."""
    records = Table(entry[rt.collection])
    _check_columns(records, rt, path)
    return Tables(
        records,
        {c.name: c for c in record_columns(rt, _extra_columns(records, rt))},
        Frames(entry["raw"]),
        Table(entry["split"]),
        Table(entry["models"]),
        Table(entry["sessions"]),
    )


def _extra_columns(table: Table, rt: RecordType) -> list[Column]:
    """The columns an imported table brought (what the record type does not know), as stored."""
    known = {c.name for c in (*common_columns(rt.id_column), *rt.columns, *window_columns())}
    out = []
    for name in table.names:
        if name in known:
            continue
        ds = table.ds[name]
        kind = {"i": "int", "f": "float", "S": "text"}.get(ds.dtype.kind, "text")
        units = text(ds.attrs.get("units", ""))
        out.append(Column(name, units, kind=kind, width=ds.dtype.itemsize, optional=kind != "int"))
    return out


def _check_columns(table: Table, rt: RecordType, path: str) -> None:
    """Refuse, naming the dataset, a record table whose columns another program changed."""
    for c in (*common_columns(rt.id_column), *rt.columns, *window_columns()):
        where = f"/entry/{rt.collection}/{c.name}"
        if c.name not in table.ds and c.optional and c.name in getattr(rt, "added_columns", ()):
            continue  # a file from before the column was added: its records leave it empty
        if c.name not in table.ds:
            raise StoreError(
                f"{path} lacks the dataset {where}; the file was changed by another program or is damaged."
            )
        ds = table.ds[c.name]
        want = c.dtype
        if ds.shape[1:] != c.shape or ds.dtype.kind != want.kind or ds.dtype.itemsize != want.itemsize:
            got = f"shape {ds.shape} of {ds.dtype}"
            raise StoreError(
                f"{path}: the dataset {where} holds {got} where a run file keeps (n, "
                f"{', '.join(map(str, c.shape))}{',' if len(c.shape) == 1 else ''}) of {want}".replace("(n, )", "(n,)")
                + f" ({c.what or c.name}); the file was changed by another program."
            )
