"""The HDF5 run file: one file per run, every record committed whole and crash-safe.

A :class:`RunFile` is the file and its lifecycle (create, open, lock, close, publish,
discard) and its metadata; what it holds is reached through small facets, one concept each
(in the spirit of h5py's ``obj.attrs``):

=================  ========================================================================
``run.records``    the records: write one, append many, read back, the exchange table (:mod:`.records`)
``run.windows``    raw windows: streamed in as they arrive, read back checked (:mod:`.windows`)
``run.split``      which records fit and which validate (:mod:`.split`)
``run.models``     the fitted models, JSON text under a name (:mod:`.models`)
``run.sessions``   the session log: who recorded what, on which rig, how it ended (:mod:`.sessions`)
=================  ========================================================================

``run.summary()`` and ``run.verify()`` report on the whole file (:mod:`.summary`,
:mod:`.verify`).

Schema version 2 (:mod:`.layout` has the tree): the records of a run are the rows of one
table (``/entry/trials``, ``/entry/pushes``, ``/entry/points``), one dataset per column;
their raw windows are ranges of run-wide frame arrays (``/entry/raw``); splits, models and
the session log are tables too.  Version 1 files (a group per record, labcli 0.1) are read
as they are (:mod:`.v1`); opening one for writing copies it into version 2 first
(:mod:`.upgrade`).

**Commit.**  Every change is one commit through one write path (:mod:`.writer`): room
reserved, rows written past the committed ones, ``@committed`` moved, then one checkpoint
through the journal (:mod:`.journal`).  A kill or a power cut at any point leaves what was
committed before.

**Readers** (``RunFile.open(path)``) open without HDF5's file lock, read only committed
rows and check every row's checksum, so a run can be read while it is recorded; a torn read
(the writer mid-commit) is retried.  A record that fails its checksum or holds a value no
rig can produce is named in a :class:`~labcli.errors.LabcliWarning` and left out.

**Writers** hold HDF5's exclusive lock from open to close: a second writer (another
acquisition, an import or ``--force`` onto the file, ``fit`` recording its model, ``split``)
is refused in one sentence.  A new file is built under a temporary name and put in place
whole (:func:`~labcli.core.store.space.publish`).  Text holding a NUL is refused before any
file is made (:func:`labcli.core.store.importing.storable_cells`).
"""

from __future__ import annotations

import os
import time
import warnings
from collections.abc import Callable, Iterable
from typing import Any, TypeVar

import h5py
import numpy as np

from ...errors import LabcliError, LabcliWarning, StoreError
from ..files import RUN_FILE_SUFFIXES, is_run_file
from ..paper import Column, RecordType
from ..registry import record_type, untagged_run_kind
from . import space
from .columns import Rows, Table
from .frames import channel_units, chunk_frames
from .h5 import calibration_arrays, plain, text
from .journal import JournalFile, lock
from .layout import initialise
from .models import Models
from .nexus import PROTOCOL, home, read_metadata
from .notes import Notes
from .opening import (
    MUTABLE_ATTRS,
    READ_ERRORS,
    READ_RETRIES,
    Tables,
    check_openable,
    check_schema,
    h5open,
    metadata_checksum,
    metadata_ok,
    open_error,
    open_tables,
    open_writer,
    read_afresh,
)
from .records import Records
from .sessions import Sessions
from .split import Splits
from .summary import summarise
from .upgrade import upgrade
from .v1 import V1Run
from .view import decode
from .windows import Windows
from .writer import Writer

T = TypeVar("T")

# What to do about a run file that already exists where a new run would go.
RESUME_OR_FORCE = "continue it with --resume, or pass --force to overwrite it"


class RunFile:
    """An open run file.  Use as a context manager; writes are crash-safe per commit.

    >>> with RunFile.create("run.h5", protocol=proto, device_info=dev.info,
    ...                     port="sim://", operator="ada") as run:   # doctest: +SKIP
    ...     run.records.write(record)

    ``record_type`` is the run kind's (:class:`labcli.core.paper.RecordType`).  What the
    facets share (the open file ``h5``, its ``tables``, the ``writer``) is theirs to use.
    """

    records: Records
    windows: Windows
    split: Splits
    models: Models
    sessions: Sessions
    notes: Notes

    def __init__(self, h5: h5py.File, path: str, mode: str, io: JournalFile | None = None) -> None:
        self.h5 = h5
        self.path = path
        self.mode = mode
        self.io = io  # a writer's file, under HDF5 (:mod:`.journal`)
        self.held = False  # a reader's: whether a writer held the file when it was opened
        self._tmp: str | None = None
        self._staged: tuple[bool, str] | None = None
        root = home(h5)
        self.version = int(root.get("schema_version", 1))
        where = h5.attrs if self.version == 1 else root if self.version >= 3 else h5["entry"].attrs
        kind = text(where["kind"]) if "kind" in where else untagged_run_kind()
        self.channels: tuple[str, ...] = tuple(text(c) for c in where.get("channels", ()))
        try:
            self.record_type: RecordType = record_type(kind)
        except LabcliError:
            raise StoreError(
                f"{path} is a run of kind '{kind}', which no installed paper reads; install the paper that recorded it."
            ) from None
        self.v1: V1Run | None = V1Run(h5, self.record_type) if self.version == 1 else None
        self._tables: Tables | None = None if self.version == 1 else open_tables(h5["entry"], self.record_type, path)
        self.writer = Writer(path, mode, lambda: self.h5, self._kept, lambda: self.io)
        self.records = Records(self)
        self.windows = Windows(self)
        self.split = Splits(self)
        self.models = Models(self)
        self.sessions = Sessions(self)
        self.notes = Notes(self)
        self.writer.riders = self.sessions

    @property
    def tables(self) -> Tables:
        """The open tables (schema 2; a schema-1 file has none: :meth:`check_v2` first)."""
        if self._tables is None:
            raise StoreError(f"{self.path} is a version 1 run file; it keeps no tables.")
        return self._tables

    # ----------------------------------------------------------- create

    @classmethod
    def create(
        cls,
        path: str | os.PathLike,
        *,
        protocol: Any,
        device_info: Any = None,
        port: str = "",
        operator: str = "",
        plan: Any = None,
        force: bool = False,
        imported: bool = False,
        source: str = "",
        started: str | None = None,
        exists_hint: str = RESUME_OR_FORCE,
        kind: str | None = None,
        command_line: str | None = None,
        extras: Iterable[Column] = (),
        rows_hint: int = 0,
        calibration: tuple[Any, Any, list[str]] | None = None,
        staged: bool = False,
    ) -> RunFile:
        """Create a new run file for ``protocol`` (a :class:`labcli.core.protocol.Protocol`).

        ``kind``: the run kind (default: the protocol's); ``device_info``: the rig's
        ``DeviceInfo`` (device, firmware, channels); ``plan``: the plan table (DataFrame or
        dict of columns) or None; ``extras``: columns an imported table brings;
        ``rows_hint``: records about to be appended at once (sizes the table's chunks).
        An existing file is replaced only with ``force=True``, and never while another
        program has it open.  With ``staged=True`` the file is built under a temporary
        name and appears at ``path`` only at :meth:`publish`.
        """
        path = os.fspath(path)
        _check_new(path, force, exists_hint)
        kind = kind or str(getattr(protocol, "kind", "") or untagged_run_kind())
        rt = record_type(kind)
        channels = [str(c) for c in (getattr(device_info, "channels", ()) or getattr(protocol, "channels", ()))]
        tmp = space.partial_path(path, "import" if imported else "create")
        f, io = _new_file(tmp, path)
        try:
            space.reserve(io.fd, 0, 1 << 20, path, "the new run", "no file was made")
            initialise(
                f,
                path=path,
                protocol=protocol,
                rt=rt,
                kind=kind,
                channels=channels,
                device_info=device_info,
                port=port,
                operator=operator,
                plan=plan,
                imported=imported,
                source=source,
                started=started,
                command=command_line,
                chunk_rows=_row_chunk(rows_hint),
                chunk_frames=chunk_frames(_frames_per_window(protocol)),
                extras=list(extras),
                calibration=calibration or calibration_arrays(protocol, len(channels)),
            )
            home(f)["metadata_checksum"] = np.uint64(metadata_checksum(f))
            f.flush()
            io.checkpoint()
            run = cls(f, path, "a", io)
        except BaseException:
            f.close()
            io.close()
            os.unlink(tmp)
            raise
        run._tmp = tmp
        run._staged = (force, exists_hint)
        if not staged:
            run.publish()
        return run

    def publish(self) -> None:
        """Put a file built with ``staged=True`` in place at its path (whole, or not at all)."""
        if self._staged is None or self._tmp is None:
            return
        force, hint = self._staged
        self.writer.sync(publishing=True)
        try:
            space.publish(self._tmp, self.path, force=force, exists_hint=hint)
        except BaseException:
            self.discard()
            raise
        self._staged = self._tmp = None
        if self.io is not None:
            self.io.start_journal(self.path)

    def discard(self) -> None:
        """Close a staged file without putting it in place, and remove it."""
        tmp = self._tmp
        self._staged = self._tmp = None
        if self.h5.id.valid:
            self.h5.close()
        if self.io is not None:
            self.io.close()
            self.io = None
        if tmp:
            try:
                os.unlink(tmp)
            except OSError:
                pass

    # ----------------------------------------------------------- open / close

    @classmethod
    def open(cls, path: str | os.PathLike, mode: str = "r") -> RunFile:
        """Open an existing run file for reading (``"r"``) or adding to it (``"a"``).

        Reading takes no lock: a run being recorded can be read (what is committed so far).
        Adding takes the exclusive lock; a version-1 file is copied into version 2 first.
        """
        path = os.fspath(path)
        if mode not in ("r", "a"):
            raise ValueError(f"mode must be 'r' or 'a', got {mode!r}")
        check_openable(path, mode)
        for attempt in range(READ_RETRIES):
            held = mode == "r" and space.writer_holds(path)  # before HDF5 reads a byte (see read_afresh)
            try:
                run = _open_run(cls, path, mode, held)
                break
            except StoreError:
                if mode == "a" or attempt + 1 == READ_RETRIES or not (held or space.writer_holds(path)):
                    raise
            time.sleep(0.02 * (attempt + 1))  # a reader that met a commit under way: open afresh
        if mode == "a":
            space.ignore_file_size_signal()
        if not read_afresh(run, run._metadata_ok, lambda ok: not ok):
            run.warn(
                f"{path}: the run's metadata (the attributes of its groups and datasets) do not match "
                "their checksum; the file was changed after it was written, so check what it says."
            )
        return run

    def _metadata_ok(self) -> bool:
        try:
            return self.version == 1 or metadata_ok(self.h5)
        except Exception:  # noqa: BLE001 - a damaged attribute or header can fail in any way
            return False

    def may_be_torn(self) -> bool:
        """Whether a writer may have torn what this reader read: it held the file at the opening, or holds it now."""
        return self.mode == "r" and (self.held or space.writer_holds(self.path))

    def reopen(self) -> None:
        """Read the file afresh (a reader that met a commit under way)."""
        self.h5.close()
        self.held = space.writer_holds(self.path)
        self.h5 = h5open(self.path, "r")
        # Opened as __init__ opens it: every schema but the first keeps tables (schema 3 too).
        if self.version == 1:
            self.v1 = V1Run(self.h5, self.record_type)
        else:
            self._tables = open_tables(self.h5["entry"], self.record_type, self.path)

    def close(self) -> None:
        """Commit what waits (the session log's last events), give back the room reserved, close."""
        if self._staged is not None:
            self.discard()
            return
        if not self.h5.id.valid:
            return
        if self.mode == "r":
            self.h5.close()
            return
        io = self.io
        if self.writer.broken:  # what HDF5 writes as it closes is its half-written state: dropped
            self.h5.close()
            if io is not None:
                io.discard()
                io.close()
            return
        if self.sessions.waiting:
            self.writer.commit([])
        if self._tables is not None:  # the rows grown ahead of the writes, never written, given back
            with self.writer.writing("closing the run file"):
                for t in (self._tables.records, self._tables.split, self._tables.models, self._tables.sessions):
                    t.trim()
        self.writer.sync()
        self.h5.close()
        if io is None:
            return
        try:
            io.checkpoint()  # what HDF5 writes as it closes (the superblock's flags)
        except OSError:  # no room for it: the file stays as the last commit left it, whole
            io.discard()
        io.close(io.recorded_end())  # the room reserved past the end given back (a kill leaves it, harmlessly)

    def __enter__(self) -> RunFile:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # ----------------------------------------------------------- what the facets share

    def warn(self, message: str) -> None:
        """Say what was found wrong in the file (a :class:`~labcli.errors.LabcliWarning`)."""
        warnings.warn(LabcliWarning(message), stacklevel=3)

    def check_v2(self, doing: str) -> None:
        """Refuse to add ``doing`` to a version-1 file open for reading (writing upgrades it first)."""
        if self.version == 1:
            raise StoreError(
                f"{self.path} is a version 1 run file open for reading; open it with mode 'a' "
                f"(which copies it into version 2) to add {doing}."
            )

    def _kept(self) -> str:
        """What is safe when a write fails, for the sentence that says so."""
        if self._staged is not None:  # built under a temporary name, removed when it fails
            return f"{self.path} is as it was" if os.path.lexists(self.path) else "no file was made"
        n = len(self.records.ids())
        return f"the {self.record_type.count(n)} stored before {'is' if n == 1 else 'are'} intact"

    # ----------------------------------------------------------- metadata

    @property
    def attrs(self) -> dict[str, Any]:
        """The run's metadata as plain Python values (the root's attributes in version 1)."""
        if self.v1 is not None:
            return self.v1.attrs()
        root = {k: v for k, v in self._attrs_at("/").items() if k not in MUTABLE_ATTRS}
        e = {k: v for k, v in self._metadata().items() if k not in MUTABLE_ATTRS}
        out = {
            "schema": root.get("schema", e.get("schema")),
            "schema_version": root.get("schema_version", e.get("schema_version")),
            "labcli_version": e.get("program_version", ""),
            "started": e.get("start_time", ""),
            **e,
        }
        out["versions"] = {k: v for k, v in self._attrs_at("entry/versions").items() if k != "NX_class"}
        out["file_name"], out["file_time"] = root.get("file_name", ""), root.get("file_time", "")
        for key in ("NX_class", "default", "title"):
            out.pop(key, None)
        return out

    def _metadata(self) -> dict[str, Any]:
        """The run's metadata: ``/entry``'s attributes up to schema 2, its NeXus fields and
        ``/entry/labcli`` from schema 3; one sentence when HDF5 cannot read them."""
        if self.version < 3:
            return self._attrs_at("entry")
        try:
            return read_afresh(self, lambda: read_metadata(self.h5["entry"]), lambda _: False)
        except Exception:  # noqa: BLE001 - a damaged attribute or field can fail in any way
            raise StoreError(
                f"{self.path}: the run's metadata cannot be read (a damaged field or attribute of /entry); "
                "check the file with labcli inspect --verify and use a backup copy."
            ) from None

    def _attrs_at(self, where: str) -> dict[str, Any]:
        """The attributes of the group ``where`` as plain values; {} when the group is not there
        (a run without its ``versions``); one sentence when HDF5 cannot read them (a damaged header)."""

        def read() -> dict[str, Any]:
            if where != "/" and where not in self.h5:
                return {}
            return {k: plain(v) for k, v in self.h5[where].attrs.items()}

        try:  # a read torn by a writer's checkpoint is read again afresh (see read_afresh)
            return read_afresh(self, read, lambda _: False)
        except Exception:  # noqa: BLE001 - a damaged attribute or header can fail in any way
            raise StoreError(
                f"{self.path}: the run's metadata cannot be read (a damaged attribute of /{where.strip('/')}); "
                "check the file with labcli inspect --verify and use a backup copy."
            ) from None

    def read_checked(self, read: Callable[[], T], what: str, torn: Callable[[T], bool] = lambda _: False) -> T:
        """``read()`` through :func:`.opening.read_afresh`; one sentence naming ``what`` when HDF5 cannot read it."""
        try:
            return read_afresh(self, read, torn)
        except READ_ERRORS:
            raise StoreError(
                f"{self.path}: {what} cannot be read (damaged); check the file with labcli inspect --verify "
                "and use a backup copy."
            ) from None

    @property
    def kind(self) -> str:
        return self.record_type.kind

    @property
    def protocol_text(self) -> str:
        """The protocol TOML embedded verbatim when the run was created."""
        if self.v1 is not None:
            return self.v1.protocol_text()
        where = "entry/protocol" if self.version == 2 else f"entry/{PROTOCOL}"
        try:
            return read_afresh(self, lambda: self.h5[where][0].decode("utf-8"), lambda _: False)
        except (*READ_ERRORS, UnicodeDecodeError):
            raise StoreError(
                f"{self.path}: its copy of the protocol is damaged (it fails its checksum); use a backup copy."
            ) from None

    def calibration(self) -> dict[str, Any]:
        """Per-channel gain (SI/count), offset (SI) and units as stored."""
        if self.v1 is not None:
            return self.v1.calibration()
        return self.read_checked(lambda: _calibration(self.h5, self.version, self.channels), "its calibration")

    def plan_table(self) -> Any:
        """The plan table stored at creation (DataFrame), or None."""
        import pandas as pd

        if self.v1 is not None:
            plan = self.v1.plan()
            return None if plan is None else pd.DataFrame(plan)
        got = self.read_checked(
            lambda: _plan(self.h5), "its plan", lambda got: got is not None and bool(got[1].damaged)
        )
        if got is None:
            return None
        t, rows = got
        if rows.damaged:
            self.warn(
                f"{self.path}: its plan is damaged (row {rows.damaged[0][0]} fails its checksum); "
                "the rows that check out are used."
            )
        cols = {}
        for name in t.names:
            v = decode(rows.cols[name])
            cols[name] = [str(x) for x in v] if v.dtype == object else v.tolist()
        return pd.DataFrame(cols)

    # ----------------------------------------------------------- reports

    def summary(self) -> dict[str, Any]:
        """What ``labcli inspect`` shows: metadata, completeness, split, settling, and what the
        record type adds (baseline drift, a paper's grid, ...)."""
        return summarise(self)

    def verify(self) -> dict[str, Any]:
        """Check every record, raw window, split, model and session event (``labcli inspect --verify``)."""
        from .verify import verify

        return verify(self)


def _check_new(path: str, force: bool, exists_hint: str) -> None:
    """Refuse, in one sentence, a new run at ``path`` (a name, a folder, a file in the way), and
    clean the leftovers of builders that are gone."""
    space.check_new_file(path)
    if os.path.lexists(path) and not force:
        raise StoreError(f"{path} already exists; {exists_hint}.")
    if force and os.path.lexists(path) and space.writer_holds(path):
        raise StoreError(f"{path} {space.BUSY}; --force never replaces a run another program has open.")
    if force and os.path.isfile(path) and os.path.getsize(path) > 0 and not is_run_file(path):
        raise StoreError(
            f"Cannot replace {path}: it is not a run file, and --force replaces only a run file (an earlier "
            "output of acquire or import); choose another output name."
        )
    space.clean_partials(os.path.dirname(os.path.abspath(path)))
    space.ignore_file_size_signal()


def _new_file(tmp: str, path: str) -> tuple[h5py.File, JournalFile]:
    """A new HDF5 file at ``tmp`` (to be put in place at ``path``), locked by its builder."""
    try:
        fd = os.open(tmp, os.O_RDWR | os.O_CREAT | os.O_EXCL, 0o644)
    except OSError as e:
        raise StoreError(f"cannot create {path}: {e.strerror or e}.") from None
    io = JournalFile(fd, tmp, journaled=False)  # built whole before it is put in place: no journal yet
    try:
        lock(fd, tmp, space.BUSY)  # the builder is at work: clean_partials leaves it
        return h5py.File(io, "w", fs_strategy="none"), io
    except BaseException:
        io.close()
        os.unlink(tmp)
        raise


def _open_run(cls: type[RunFile], path: str, mode: str, held: bool) -> RunFile:
    """The file open with HDF5 and its tables found (``held``: a writer held it as it was opened)."""
    f, io = _open_h5(path, mode)

    def shut() -> None:
        f.close()
        if io is not None:
            io.close()

    try:
        version = check_schema(f, path)
        if version == 1 and mode == "a":
            shut()
            return upgrade(cls, path)
        run = cls(f, path, mode, io)
    except StoreError:
        shut()
        raise
    except Exception:  # noqa: BLE001 - a damaged file can fail in any way
        shut()
        raise StoreError(f"{path} is damaged or truncated and HDF5 cannot read it; use a backup copy.") from None
    run.held = held
    return run


def _open_h5(path: str, mode: str) -> tuple[h5py.File, JournalFile | None]:
    """Open with HDF5 (a reader that met a writer mid-commit is retried by :meth:`RunFile.open`);
    StoreError when it will not open."""
    try:
        return open_writer(path) if mode == "a" else (h5open(path, mode), None)
    except OSError as e:
        raise StoreError(open_error(path, e)) from None


def _calibration(h5: h5py.File, version: int, channels: tuple[str, ...]) -> dict[str, Any]:
    """Per-channel gain, offset and units as a schema-2 or later file keeps them."""
    raw = h5["entry/raw"]
    cal = raw if version == 2 else raw["calibration"]
    gain = np.array([cal[c]["gain"][0] for c in channels])
    offset = np.array([cal[c]["offset"][0] for c in channels])
    units = channel_units(raw, channels)
    return {"channels": channels, "gain": gain, "offset": offset, "units": units}


def _plan(h5: h5py.File) -> tuple[Table, Rows] | None:
    """The plan's table and what a read of it found, or None when the run keeps no plan."""
    if "plan" not in h5["entry"]:
        return None
    t = Table(h5["entry/plan"])
    return t, t.read()


def _frames_per_window(protocol: Any) -> float:
    capture = getattr(getattr(protocol, "settling", None), "capture_s", None)
    rate = getattr(protocol, "rate_hz", None)
    try:
        return float(capture) * float(rate)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        return 256.0


def _row_chunk(rows_hint: int) -> int:
    """Rows per chunk: one for runs recorded a record at a time, about n/64 (<= 4096) for big imports."""
    return int(min(4096, max(1, rows_hint // 64)))


def load_table(path: str | os.PathLike, kind: RecordType) -> Any:
    """The table of ``kind``'s records from a run file (``.h5``, ``.hdf5``) or from a CSV table."""
    if os.fspath(path).lower().endswith(RUN_FILE_SUFFIXES):
        with RunFile.open(path) as run:
            return run.records.table(kind)
    return kind.read_csv(path)
