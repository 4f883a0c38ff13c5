"""The HDF5 run file: one file per run, every record committed whole and crash-safe.

Schema version 2 (:mod:`.layout` has the tree): the records of a run are the rows of one
table (``/entry/trials``, ``/entry/pushes``, ``/entry/points``), one dataset per column;
their raw windows are ranges of run-wide frame arrays (``/entry/raw``); splits, models and
the session log are tables too.  Version 1 files (a group per record, labcli 0.1) are read
as they are (:mod:`.v1`); the first write to one copies it into version 2 first.

**Commit.**  Adding anything (a record, a batch of imported records, a split, a model, the
session log's events) is one commit: the space it may need is reserved past the end of the
file (:mod:`.space`; a full disk or ``ulimit -f`` stops it here, before anything is
written), raw frames and rows are written after the committed ones at fresh chunk
boundaries, the file is flushed and fsynced, each table's ``@committed`` is set to its new
end (in place), and the file is flushed and fsynced again.  Two syncs suffice because the
new rows only count once ``@committed`` says so; what a kill or a power cut interrupts
before that is ignored, and the next commit writes over it.  Nothing committed is ever
written again (:mod:`.columns` says why that needs fresh chunks).

**Readers** (``RunFile.open(path)``) open without HDF5's file lock, read only committed
rows and check every row's checksum, so a run can be read while it is recorded; a torn read
(the writer mid-commit) is retried.  A record that fails its checksum or holds a value no
rig can produce is named in a :class:`~labcli.errors.LabcliWarning` and left out.

**Writers** hold HDF5's exclusive lock from open to close: a second writer (another
acquisition, an import or ``--force`` onto the file, ``fit`` recording its model, ``split``)
is refused in one sentence.  A new file is built under a temporary name and put in place
whole (:func:`~labcli.core.store.space.publish`).

Records and tables.  :meth:`RunFile.write` takes the record a session commits (a plain
dict, SI) and :meth:`RunFile.read` gives it back; :meth:`RunFile.append` takes many records
as columns at once (imports: a million rows in seconds); :meth:`RunFile.table` gives the CSV
exchange table, in the units people type, degrees and grams rounded to 12 significant
digits (:func:`~labcli.core.store.h5.to_edge`), which makes table -> run file -> table
exact.  What a record holds is its record type's business
(:class:`labcli.core.paper.RecordType`); the run file writes the columns every record
shares.  Text holding a NUL is refused before any file is made
(:func:`labcli.core.store.importing.storable_cells`).
"""

from __future__ import annotations

import contextlib
import math
import os
import time
import warnings
from collections.abc import Iterable, Iterator, Mapping
from types import SimpleNamespace
from typing import Any

import h5py
import numpy as np

from ...errors import DiskFull, LabcliError, LabcliWarning, StoreError
from ..files import RUN_FILE_SUFFIXES
from ..paper import Column, RecordType
from ..registry import record_type
from ..version import __version__
from . import logs, space
from . import split as _split
from .checksum import row_checksums
from .columns import Table, fixed
from .frames import Frames, StoredWindow, WindowWriter, chunk_frames, counts_out
from .h5 import WINDOW_GROUPS, calibration_arrays, plain, settle_attrs, text, window_arrays
from .layout import (
    SCHEMA,
    SCHEMA_VERSION,
    WINDOWS,
    common_columns,
    extra_column,
    initialise,
    now_iso,
    record_columns,
    session_columns,
    window_columns,
)
from .summary import summarise
from .v1 import V1Run
from .view import MAX_ID, Records, decode, from_v1, from_v2, out_of_bounds

# What to do about a run file that already exists where a new run would go.
RESUME_OR_FORCE = "continue it with --resume, or pass --force to overwrite it"
MUTABLE_ATTRS = ("committed", "committed_checksum", "metadata_checksum")
READ_RETRIES = 8  # torn reads while a writer commits: tries before the damage is believed


def metadata_checksum(f: h5py.File) -> int:
    """A checksum over every attribute in the file but the commit counters (fixed at creation)."""
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
    f.visititems(add)
    blob = np.frombuffer(b"\x1e".join(parts), dtype=np.uint8)
    return int(row_checksums([blob.reshape(1, -1)], 0)[0])


def _frames_per_window(protocol: Any) -> float:
    capture = getattr(getattr(protocol, "settling", None), "capture_s", None)
    rate = getattr(protocol, "rate_hz", None)
    try:
        return float(capture) * float(rate)
    except (TypeError, ValueError):
        return 256.0


def _row_chunk(rows_hint: int) -> int:
    """Rows per chunk: one for runs recorded a record at a time, about n/64 (<= 4096) for big imports."""
    return int(min(4096, max(1, rows_hint // 64)))


class RunFile:
    """An open run file.  Use as a context manager; writes are crash-safe per commit.

    >>> with RunFile.create("run.h5", protocol=proto, device_info=dev.info,
    ...                     port="sim://", operator="ada") as run:   # doctest: +SKIP
    ...     run.write(record)

    ``record_type`` is the run kind's (:class:`labcli.core.paper.RecordType`).
    """

    def __init__(self, h5: h5py.File, path: str, mode: str) -> None:
        self._f = h5
        self.path = path
        self._mode = mode
        self._tmp: str | None = None
        self._staged: tuple[bool, str] | None = None
        self._records: Records | None = None
        self._pending: list[dict[str, Any]] = []
        self._broken = False
        self._session: int | None = None  # the session-log number of the session writing now
        self._session_added: set[int] = set()
        root = h5.attrs
        self.version = int(root.get("schema_version", 1))
        if self.version == 1:
            kind = text(root.get("kind", "force"))
            self._channels = tuple(text(c) for c in root.get("channels", ()))
        else:
            self._entry = h5["entry"]
            kind = text(self._entry.attrs["kind"])
            self._channels = tuple(text(c) for c in self._entry.attrs.get("channels", ()))
        try:
            self.record_type: RecordType = record_type(kind)
        except LabcliError:
            raise StoreError(
                f"{path} is a run of kind '{kind}', which no installed paper reads; install the paper that recorded it."
            ) from None
        if self.version == 1:
            self._v1 = V1Run(h5, self.record_type)
        else:
            self._open_tables()

    def _open_tables(self) -> None:
        e, rt = self._entry, self.record_type
        self._table = Table(e[rt.collection])
        self._check_columns()
        self._frames = Frames(e["raw"])
        self._split_t, self._models_t, self._sessions_t = Table(e["split"]), Table(e["models"]), Table(e["sessions"])
        self._columns = {c.name: c for c in record_columns(rt, self._extra_columns())}

    def _extra_columns(self) -> list[Column]:
        rt = self.record_type
        known = {c.name for c in (*common_columns(rt.id_column), *rt.columns, *window_columns())}
        out = []
        for name in self._table.names:
            if name in known:
                continue
            ds = self._table.ds[name]
            kind = {"i": "int", "f": "float", "S": "text"}.get(ds.dtype.kind, "text")
            out.append(
                Column(
                    name, text(ds.attrs.get("units", "")), kind=kind, width=ds.dtype.itemsize, optional=kind != "int"
                )
            )
        return out

    def _check_columns(self) -> None:
        """Refuse, naming the dataset, a record table whose columns another program changed."""
        rt = self.record_type
        for c in (*common_columns(rt.id_column), *rt.columns, *window_columns()):
            where = f"/entry/{rt.collection}/{c.name}"
            if c.name not in self._table.ds:
                raise StoreError(
                    f"{self.path} lacks the dataset {where}; the file was changed by another program or is damaged."
                )
            ds = self._table.ds[c.name]
            want = c.dtype
            if ds.shape[1:] != c.shape or ds.dtype.kind != want.kind or ds.dtype.itemsize != want.itemsize:
                got = f"shape {ds.shape} of {ds.dtype}"
                raise StoreError(
                    f"{self.path}: the dataset {where} holds {got} where a run file keeps (n, "
                    f"{', '.join(map(str, c.shape))}{',' if len(c.shape) == 1 else ''}) of {want}".replace(
                        "(n, )", "(n,)"
                    )
                    + f" ({c.what or c.name}); the file was changed by another program."
                )

    # ----------------------------------------------------------- open / create

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
        space.check_new_file(path)
        if os.path.lexists(path) and not force:
            raise StoreError(f"{path} already exists; {exists_hint}.")
        if force and os.path.lexists(path) and space.writer_holds(path):
            raise StoreError(f"{path} {space.BUSY}; --force never replaces a run another program has open.")
        space.clean_partials(os.path.dirname(os.path.abspath(path)))
        space.ignore_file_size_signal()
        kind = kind or str(getattr(protocol, "kind", "force"))
        rt = record_type(kind)
        channels = [str(c) for c in (getattr(device_info, "channels", None) or getattr(protocol, "channels", ()))]
        cal = calibration or calibration_arrays(protocol, len(channels))
        tmp = space.partial_path(path, "import" if imported else "create")
        try:
            f = h5py.File(tmp, "w", fs_strategy="none")
        except OSError as e:
            raise StoreError(f"cannot create {path}: {e}.") from None
        try:
            space.reserve(f.id.get_vfd_handle(), 0, 1 << 20, path, "the new run", "no file was made")
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
                calibration=cal,
            )
            f.attrs["metadata_checksum"] = np.uint64(metadata_checksum(f))
            f.flush()
            os.fsync(f.id.get_vfd_handle())
            run = cls(f, path, "a")
        except BaseException:
            f.close()
            os.unlink(tmp)
            raise
        run._tmp = tmp
        run._staged = (force, exists_hint)
        if not staged:
            run.publish()
        return run

    def publish(self) -> None:
        """Put a file built with ``staged=True`` in place at its path (whole, or not at all)."""
        if self._staged is None:
            return
        force, hint = self._staged
        self._sync()
        try:
            space.publish(self._tmp, self.path, force=force, exists_hint=hint)
        except BaseException:
            self.discard()
            raise
        self._staged = self._tmp = None

    def discard(self) -> None:
        """Close a staged file without putting it in place, and remove it."""
        tmp = self._tmp
        self._staged = self._tmp = None
        if self._f.id.valid:
            self._f.close()
        if tmp:
            try:
                os.unlink(tmp)
            except OSError:
                pass

    @classmethod
    def open(cls, path: str | os.PathLike, mode: str = "r") -> RunFile:
        """Open an existing run file for reading (``"r"``) or adding to it (``"a"``).

        Reading takes no lock: a run being recorded can be read (what is committed so far).
        Adding takes the exclusive lock; a version-1 file is copied into version 2 first.
        """
        path = os.fspath(path)
        if mode not in ("r", "a"):
            raise ValueError(f"mode must be 'r' or 'a', got {mode!r}")
        cls._check_openable(path, mode)
        for attempt in range(READ_RETRIES):
            try:
                f = cls._h5open(path, mode)
                break
            except OSError as e:
                message = cls._open_error(path, mode, e)
                if mode == "r" and attempt + 1 < READ_RETRIES and space.writer_holds(path):
                    time.sleep(0.02 * (attempt + 1))  # the writer may be mid-commit
                    continue
                raise StoreError(message) from None
        try:
            version = cls._check_schema(f, path)
            if version == 1 and mode == "a":
                f.close()
                return cls._upgrade(path)
            run = cls(f, path, mode)
        except StoreError:
            f.close()
            raise
        except Exception:  # noqa: BLE001 - a damaged file can fail in any way
            f.close()
            raise StoreError(f"{path} is damaged or truncated and HDF5 cannot read it; use a backup copy.") from None
        if mode == "a":
            space.ignore_file_size_signal()
        for attempt in range(READ_RETRIES):
            if run._metadata_ok() or mode == "a" or attempt + 1 == READ_RETRIES or not space.writer_holds(path):
                break
            time.sleep(0.02 * (attempt + 1))  # the writer may be mid-commit: read afresh
            run._reopen()
        run._check_metadata()
        return run

    @staticmethod
    def _check_openable(path: str, mode: str) -> None:
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
            raise StoreError(
                f"{path} is not an HDF5 file; run files are written by 'labcli acquire' or 'labcli import'."
            )

    @staticmethod
    def _open_error(path: str, mode: str, e: OSError) -> str:
        if "unable to lock file" in str(e).lower():
            # A write lock is refused while anyone holds the file, a reader included.
            return f"{path} {space.BUSY}."
        return f"{path} is damaged or truncated and HDF5 cannot open it; use a backup copy."

    @staticmethod
    def _check_schema(f: h5py.File, path: str) -> int:
        schema, version = f.attrs.get("schema"), f.attrs.get("schema_version")
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

    @staticmethod
    def _h5open(path: str, mode: str) -> h5py.File:
        if mode == "r":
            try:
                return h5py.File(path, "r", locking=False)
            except OSError as e:
                if "locking flag" not in str(e):
                    raise
                return h5py.File(path, "r")  # already open in this process (as a writer): share it
        try:
            return h5py.File(path, "a")
        except OSError as e:
            msg = str(e).lower()
            # errno 11: another process holds the lock.  Any other lock failure means a file
            # system without locks (some network mounts), where HDF5 advises opening without.
            if "unable to lock file" in msg and "errno = 11" not in msg:
                return h5py.File(path, "a", locking=False)
            raise

    def _metadata_ok(self) -> bool:
        if self.version == 1:
            return True
        try:
            return int(self._f.attrs["metadata_checksum"]) == metadata_checksum(self._f)
        except Exception:  # noqa: BLE001 - a damaged attribute can fail in any way
            return False

    def _check_metadata(self) -> None:
        if not self._metadata_ok():
            self._warn(
                f"{self.path}: the run's metadata (the attributes of its groups and datasets) do not match "
                "their checksum; the file was changed after it was written, so check what it says."
            )

    def close(self) -> None:
        if self._staged is not None:
            self.discard()
            return
        if not self._f.id.valid:
            return
        if self._mode != "r" and not self._broken:
            if self._pending:
                self._commit([])
            self._sync()
            end = int(self._f.id.get_filesize())
            fd = self._f.id.get_vfd_handle()
            self._f.close()
            try:  # give back the space reserved past the end (a kill leaves it, harmlessly)
                if os.path.getsize(self.path) > end:
                    os.truncate(self.path, end)
            except OSError:
                pass
            del fd
            return
        self._f.close()

    def __enter__(self) -> RunFile:
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()

    def _sync(self) -> None:
        """Push everything written so far to the disk (flush, then fsync)."""
        self._f.flush()
        os.fsync(self._f.id.get_vfd_handle())

    def _warn(self, message: str) -> None:
        warnings.warn(LabcliWarning(message), stacklevel=3)

    # ----------------------------------------------------------- metadata

    @property
    def attrs(self) -> dict[str, Any]:
        """The run's metadata as plain Python values (the root's attributes in version 1)."""
        if self.version == 1:
            return self._v1.attrs()
        root = {k: plain(v) for k, v in self._f.attrs.items() if k not in MUTABLE_ATTRS}
        e = {k: plain(v) for k, v in self._entry.attrs.items()}
        out = {
            "schema": root.get("schema"),
            "schema_version": root.get("schema_version"),
            "labcli_version": e.get("program_version", ""),
            "started": e.get("start_time", ""),
            **e,
        }
        out["versions"] = {k: plain(v) for k, v in self._entry["versions"].attrs.items() if k != "NX_class"}
        out["file_name"], out["file_time"] = root.get("file_name", ""), root.get("file_time", "")
        out.pop("NX_class", None)
        out.pop("default", None)
        return out

    @property
    def kind(self) -> str:
        return self.record_type.kind

    @property
    def channels(self) -> tuple[str, ...]:
        return self._channels

    @property
    def protocol_text(self) -> str:
        """The protocol TOML embedded verbatim when the run was created."""
        if self.version == 1:
            return self._v1.protocol_text()
        try:
            return self._entry["protocol"][0].decode("utf-8")
        except (OSError, ValueError, KeyError, UnicodeDecodeError):
            raise StoreError(
                f"{self.path}: its copy of the protocol is damaged (it fails its checksum); use a backup copy."
            ) from None

    def calibration(self) -> dict[str, Any]:
        """Per-channel gain (SI/count), offset (SI) and units as stored."""
        if self.version == 1:
            return self._v1.calibration()
        raw = self._entry["raw"]
        gain = np.array([raw[c]["gain"][0] for c in self.channels])
        offset = np.array([raw[c]["offset"][0] for c in self.channels])
        units = tuple(text(raw[c]["value"].attrs["units"]) for c in self.channels)
        return {"channels": self.channels, "gain": gain, "offset": offset, "units": units}

    def plan_table(self):
        """The plan table stored at creation (DataFrame), or None."""
        import pandas as pd

        if self.version == 1:
            plan = self._v1.plan()
            return None if plan is None else pd.DataFrame(plan)
        if "plan" not in self._entry:
            return None
        t = Table(self._entry["plan"])
        rows = t.read()
        if rows.damaged:
            self._warn(
                f"{self.path}: its plan is damaged (row {rows.damaged[0][0]} fails its checksum); "
                "the rows that check out are used."
            )
        cols = {}
        for name in t.names:
            v = decode(rows.cols[name])
            cols[name] = [str(x) for x in v] if v.dtype == object else v.tolist()
        return pd.DataFrame(cols)

    # ----------------------------------------------------------- writing

    def _check_writable(self) -> None:
        if self._mode == "r":
            raise StoreError(f"{self.path} is open read-only; open it with mode 'a' to add records.")
        if self._broken:
            raise StoreError(f"{self.path} met a write error earlier; close it and open it again.")

    def _record_id(self, record: Mapping, what: str) -> tuple[int, str]:
        """The id of a ``what`` ("trial", "push", "point") record and its label for messages."""
        self._check_writable()
        if what not in record:
            raise StoreError(f"{what} record lacks '{what}' (the {what} id).")
        rid = int(record[what])
        label = f"{what} {rid}"
        if not 0 <= rid <= MAX_ID:
            raise StoreError(f"{label}: {what} ids must be between 0 and {MAX_ID}.")
        return rid, label

    def _kept(self) -> str:
        if self._staged is not None:  # built under a temporary name, removed when it fails
            return f"{self.path} is as it was" if os.path.lexists(self.path) else "no file was made"
        n = len(self.completed_ids())
        return f"the {self.record_type.count(n)} stored before {'is' if n == 1 else 'are'} intact"

    def _reserve(self, nbytes: int, doing: str) -> None:
        space.reserve(
            self._f.id.get_vfd_handle(), int(self._f.id.get_filesize()), int(nbytes), self.path, doing, self._kept()
        )

    def _commit(
        self,
        writes: list[tuple[Table, dict[str, Any], int]],
        frames: int = 0,
        doing: str = "the change",
        unwritten_fill: bool = False,
    ) -> list[tuple[int, int]]:
        """Write rows into tables in one commit (see the module docstring); their ``[start, stop)``.

        ``writes``: (table, column values, number of rows); the session log's waiting events
        join.  ``frames``: bytes of raw frames already written for it (for the reservation).
        ``unwritten_fill``: columns without values are left unwritten (:meth:`Table.prepared`).
        """
        writes = list(writes) + self._pending_writes()
        arrays = [(t, t.prepared(self._table_columns(t), values, n, unwritten_fill), n) for t, values, n in writes]
        self._reserve(sum(a.nbytes for _, arrs, _ in arrays for a in arrs) + frames, doing)
        with self._writing(doing):
            spans = [t.write(arrs, n) for t, arrs, n in arrays]
            self._sync()
            for (t, _, _), (_, stop) in zip(arrays, spans, strict=False):
                t.commit(stop)
            self._sync()
        self._pending.clear()
        return spans

    @contextlib.contextmanager
    def _writing(self, doing: str) -> Iterator[None]:
        """Turn a failed HDF5 write into one sentence, and keep HDF5 from flushing its half-written state later."""
        try:
            yield
        except DiskFull:
            raise
        except OSError as e:
            self._broken = True
            raise StoreError(
                f"{self.path} could not be written ({e.strerror or e}), so {doing} was not stored; {self._kept()}."
            ) from None

    def _table_columns(self, t: Table) -> dict[str, Column]:
        if t is self._table:
            return self._columns
        if t is self._sessions_t:
            return {c.name: c for c in session_columns(len(self.channels))}
        from .layout import MODEL_COLUMNS, SPLIT_COLUMNS

        return {c.name: c for c in (SPLIT_COLUMNS if t is self._split_t else MODEL_COLUMNS)}

    def _pending_writes(self) -> list[tuple[Table, dict[str, Any], int]]:
        if not self._pending:
            return []
        cols = {c.name: [e.get(c.name) for e in self._pending] for c in session_columns(len(self.channels))}
        values = {
            name: (None if all(v is None for v in vs) else [self._fill_none(name, v) for v in vs])
            for name, vs in cols.items()
        }
        return [(self._sessions_t, {k: v for k, v in values.items() if v is not None}, len(self._pending))]

    def _fill_none(self, name: str, v: Any) -> Any:
        if v is not None:
            return v
        c = {c.name: c for c in session_columns(len(self.channels))}[name]
        from .columns import fill_value

        return np.full(c.shape, fill_value(c)) if c.shape else (fill_value(c) if c.kind != "text" else "")

    def _texts_fit(self, values: Mapping[str, Any], label: str) -> None:
        for name, v in values.items():
            c = self._columns.get(name)
            if c is None or c.kind != "text" or v is None:
                continue
            size = len(str(v).encode("utf-8"))
            if size > c.width:
                raise StoreError(
                    f"{label} record: '{name}' is {size} bytes of text; a run file keeps at most "
                    f"{c.width} there, so shorten it."
                )

    def _row(self, record: Mapping, label: str, rid: int) -> dict[str, Any]:
        """Every column of one record but its windows' frames, checked before anything is written."""
        rt = self.record_type
        row = dict(rt.check(record, label, self))
        settle = record.get("settle") or {}
        windows = {WINDOW_GROUPS[k]: v for k, v in (settle.items()) if k in WINDOW_GROUPS}
        load = settle_attrs(windows.get("loaded"))
        accepted = str(record.get("accepted", load.get("accepted", "auto" if record.get("raw") else "imported")))
        if accepted not in ("auto", "timeout", "operator", "imported"):
            raise StoreError(
                f"{label} record: 'accepted' must be one of auto, timeout, operator, imported, got {accepted!r}."
            )
        row.update(
            {
                rt.id_column: rid,
                "started": str(record.get("started", "") or ""),
                "ended": str(record.get("ended", "") or now_iso()),
                "accepted": accepted,
                "flags": _joined_flags(record.get("flags"), label),
            }
        )
        for name in WINDOWS:
            s = settle_attrs(windows.get(name))
            row[f"{name}_settled"] = -1 if "settled" not in s else int(s["settled"])
            for key in (
                "settle_time_s",
                "waited_s",
                "pressure_spread_MPa",
                "angle_spread_rad",
                "criterion",
                "accepted",
            ):
                if key in s:
                    row[f"{name}_{key}"] = s[key]
        extra = record.get("extra") or {}
        unknown = [k for k in extra if k not in self._columns or k in row]
        if unknown:
            raise StoreError(f"{label} record: the run file has no column {unknown[0]!r} for it.")
        row.update(extra)
        self._texts_fit(row, label)
        bad = out_of_bounds(
            rt.columns,
            {c.name: np.asarray([row[c.name]]) for c in rt.columns if c.name in row and c.kind in ("float", "int")},
        )
        if bad:
            raise StoreError(f"{label} record: {bad[0]}.")
        return row

    def _windows(self, record: Mapping, label: str) -> list[tuple[str, Any]]:
        """The record's raw windows as (column prefix, StoredWindow or checked arrays)."""
        out: list[tuple[str, Any]] = []
        for key, raw in (record.get("raw") or {}).items():
            if key not in WINDOW_GROUPS:
                raise StoreError(f"{label} record: unknown window {key!r} in 'raw' (use baseline and load).")
            name = WINDOW_GROUPS[key]
            if any(name == w[0] for w in out):
                raise StoreError(f"{label} record: 'raw' gives the {name} window twice.")
            stored = raw.get("stored") if isinstance(raw, Mapping) else None
            if isinstance(stored, StoredWindow):
                if stored.run is not self:
                    raise StoreError(f"{label} record: its {name} window was written into another run file.")
                out.append((name, stored))
            else:
                out.append((name, window_arrays(raw, len(self.channels), label, name)))
        return out

    def write(self, record: Mapping) -> None:
        """Write one record of the run's kind whole; it counts only once it is committed.

        ``record``: what the run's record type takes (the session's ``Commit``, or an
        imported table row), plus what every record may carry: ``started``/``ended`` (ISO
        8601; ``ended`` defaults to now), ``settle`` (``{"baseline": ..., "load": ...}``),
        ``raw`` (the windows: arrays, or the :class:`StoredWindow` the engine streamed),
        ``accepted``, ``flags`` (a list of one-sentence notes), ``extra`` (imported columns).  Raises StoreError if
        the record is already complete in the file or is malformed (nothing is written
        then), DiskFull if there is no room for it (nothing is written then either).
        """
        rt = self.record_type
        rid, label = self._record_id(record, rt.id_column)
        self._to_v2(label)
        if rid in self._ids():
            raise StoreError(f"{label} is already complete in {self.path}; a stored record is never overwritten.")
        row = self._row(record, label, rid)
        windows = self._windows(record, label)
        frames = 0
        for name, w in windows:
            if not isinstance(w, StoredWindow):
                n = len(w["seq"])
                frames += n * 8 * (2 + 2 * len(self.channels))
                writer = self.begin_window(doing=label)
                writer.append(w["time"], w["seq"], w["counts"], w["values"])
                w = writer.finish()
            row.update({f"{name}_start": w.start, f"{name}_stop": w.stop, f"{name}_checksum": w.checksum})
        queued = len(self._pending)
        if self._session is not None:
            self._note_event("added", rid)  # committed with the record
        try:
            self._commit([(self._table, {k: [v] for k, v in row.items()}, 1)], frames, label)
        except BaseException:
            del self._pending[queued:]
            self._session_added.discard(rid)
            raise
        self._note_written([rid])

    def append(self, columns: Mapping[str, Any]) -> int:
        """Commit many records at once, given as columns (the bulk write of ``labcli import``).

        ``columns``: column name -> values over the records (sequence or array, first axis
        the records): the id column, the record type's columns (optional ones may be left
        out), and any of ``started``, ``ended``, ``accepted``, ``flags`` and the table's
        extra columns.  Checked whole first (ids new and unique, values of the right shape
        and in range, texts short enough); then one commit.  Returns the number of records.
        About a million trial rows take a few seconds (``tests/benchmarks/bench_store.py``).
        """
        rt = self.record_type
        self._check_writable()
        self._to_v2("the records")
        ids = np.asarray(columns[rt.id_column], dtype=np.int64).reshape(-1)
        n = ids.shape[0]
        values = self._bulk_values(columns, ids, n)
        self._commit([(self._table, values, n)], 0, f"the batch of {rt.count(n)}", unwritten_fill=True)
        self._note_written(ids.tolist())
        return n

    def _bulk_values(self, columns: Mapping[str, Any], ids: np.ndarray, n: int) -> dict[str, Any]:
        rt = self.record_type
        what = rt.id_column
        if n and (ids.min() < 0 or ids.max() > MAX_ID):
            bad = int(ids[(ids < 0) | (ids > MAX_ID)][0])
            raise StoreError(f"{what} {bad}: {what} ids must be between 0 and {MAX_ID}.")
        uniq, counts = np.unique(ids, return_counts=True)
        if (counts > 1).any():
            raise StoreError(f"{what} {int(uniq[counts > 1][0])} appears twice; ids must be unique.")
        already = sorted(set(uniq.tolist()) & self._ids())
        if already:
            raise StoreError(
                f"{what} {already[0]} is already complete in {self.path}; a stored record is never overwritten."
            )
        unknown = [k for k in columns if k not in self._columns]
        if unknown:
            raise StoreError(f"the run file has no column {unknown[0]!r}.")
        values: dict[str, Any] = {}
        for name, v in columns.items():
            c = self._columns[name]
            arr = fixed(c, v, n) if c.kind != "text" else np.asarray(v, dtype=object).reshape(n)
            if c.kind == "text":
                enc = [x if isinstance(x, bytes) else ("" if x is None else str(x)).encode("utf-8") for x in arr]
                longest = max((len(x) for x in enc), default=0)
                if longest > c.width:
                    i = next(i for i, x in enumerate(enc) if len(x) == longest)
                    raise StoreError(
                        f"{what} {int(ids[i])}: '{name}' is {longest} bytes of text; a run file keeps "
                        f"at most {c.width} there, so shorten it."
                    )
                arr = np.array(enc, dtype=c.dtype)
            values[name] = arr
        missing = [c.name for c in rt.columns if not c.optional and c.name not in values]
        if missing:
            raise StoreError(f"the records lack the column {missing[0]!r}.")
        bad = out_of_bounds(rt.columns, {c.name: values[c.name] for c in rt.columns if c.name in values})
        if bad:
            i = min(bad)
            raise StoreError(f"{what} {int(ids[i])}: {bad[i]}.")
        values.setdefault("ended", np.full(n, now_iso().encode(), dtype=self._columns["ended"].dtype))
        if "accepted" not in values:
            values["accepted"] = np.full(n, b"imported", dtype=self._columns["accepted"].dtype)
        return values

    def _note_written(self, ids: list[int]) -> None:
        self._records = None
        self._id_set.update(int(i) for i in ids)
        self._order.extend(int(i) for i in ids)

    def begin_window(self, doing: str = "a raw window") -> WindowWriter:
        """Start a raw window written as it arrives (the engine's Baseline and Capture).

        ``append(time, seq, counts, si)`` adds each block (whole chunks of frames go into the
        file and are flushed as they fill, not yet part of any record); ``finish()`` returns the
        :class:`StoredWindow` a record's ``raw`` then takes.  A window no record takes (a redo,
        a kill) stays unused: it lies past every committed window and the next one starts
        after it.
        """
        self._check_writable()
        self._to_v2(doing)
        return WindowWriter(
            self,
            self._frames,
            lambda nbytes: self._reserve(nbytes, doing),
            lambda: self._flush_frames(doing),
            lambda: self._writing(doing),
        )

    def _flush_frames(self, doing: str) -> None:
        """Push a window's frames written so far out of HDF5's caches (to the OS; the commit fsyncs)."""
        with self._writing(doing):
            self._f.flush()

    def frames(self, start: int, stop: int) -> dict[str, np.ndarray]:
        """Raw frames ``[start, stop)``: ``t_s``, ``seq``, ``counts``, ``si``; StoreError when any cannot be read."""
        if self.version == 1:
            raise StoreError(f"{self.path} keeps its raw windows per record (schema 1); use read().")
        w, whole = self._frames.read(start, stop)
        if not whole:
            raise StoreError(
                f"{self.path}: raw frames {start} to {stop} cannot all be read (damaged); "
                "labcli inspect --verify names the records they belong to."
            )
        w["counts"] = counts_out(w["counts"])
        return w

    def _to_v2(self, doing: str) -> None:
        if self.version == 1:
            raise StoreError(
                f"{self.path} is a version 1 run file open for reading; open it with mode 'a' "
                f"(which copies it into version 2) to add {doing}."
            )

    # ----------------------------------------------------------- reading records

    def _ids(self) -> set[int]:
        if not hasattr(self, "_id_set"):
            self._id_set = set(self.completed_ids())
        return self._id_set

    def records(self) -> Records:
        """The good records, as columns; damaged ones named in a warning (once) and left out."""
        if self._records is not None:
            return self._records
        for attempt in range(READ_RETRIES):
            try:
                rec = (
                    from_v1(self._v1, self.record_type) if self.version == 1 else from_v2(self._table, self.record_type)
                )
            except (OSError, KeyError, ValueError, RuntimeError, TypeError):
                rec = None
            busy = self._mode == "r" and (rec is None or rec.damaged) and space.writer_holds(self.path)
            if busy and attempt + 1 < READ_RETRIES:
                time.sleep(0.02 * (attempt + 1))  # a commit under way: read again, afresh
                self._reopen()
                continue
            break
        if rec is None:
            raise StoreError(f"{self.path} is damaged or truncated and HDF5 cannot read it; use a backup copy.")
        if rec.damaged:
            self._warn(self._damage_sentence(rec.damaged))
        if self.version == 1 and self._v1.unreadable_list:
            self._unreadable = True
        self._records = rec
        self._id_set = set(rec.ids)
        self._order = list(rec.ids)
        return rec

    def _reopen(self) -> None:
        self._f.close()
        self._f = self._h5open(self.path, "r")
        if self.version == 2:
            self._entry = self._f["entry"]
            self._open_tables()
        else:
            self._v1 = V1Run(self._f, self.record_type)

    def _damage_sentence(self, damaged: list[tuple[str, str]]) -> str:
        first = "; ".join(f"{what}: {why}" for what, why in damaged[:3])
        more = f" (and {len(damaged) - 3} more)" if len(damaged) > 3 else ""
        return (
            f"{self.path}: {len(damaged)} damaged {'record is' if len(damaged) == 1 else 'records are'} left out "
            f"({first}{more}); the file changed after it was written. "
            "`labcli inspect --verify` lists everything damaged."
        )

    def completed_ids(self) -> list[int]:
        """Ids of the complete records (trials, pushes, points: the run's kind), in recording order."""
        if self._records is None and hasattr(self, "_order"):
            return list(self._order)
        return list(self.records().ids)

    def incomplete_ids(self) -> list[int]:
        """Ids with only an interrupted write (a kill's leftovers), never counted."""
        done = self._ids()
        return sorted(i for i in self.records().incomplete if i not in done)

    def first_incomplete(self, plan_ids: Iterable[int]) -> int | None:
        """The first id of ``plan_ids`` not yet complete in the file (None: all done)."""
        done = self._ids()
        for i in plan_ids:
            if int(i) not in done:
                return int(i)
        return None

    def damaged(self) -> list[tuple[str, str]]:
        """(what, why) of every record left out as damaged."""
        return list(self.records().damaged)

    def _row_of(self, rid: int) -> tuple[Records, int]:
        rec = self.records()
        i = rec.position(int(rid))
        if i is None:
            raise StoreError(f"{self.record_type.noun} {rid} is not a complete record in {self.path}.")
        return rec, i

    def read(self, rid: int) -> dict:
        """One complete record back as the writer gave it (SI), with its windows as stored.

        A window whose frames fail their checksum is left out with a warning.
        """
        rec, i = self._row_of(rid)
        row = {name: v[i] for name, v in rec.cols.items()}
        raw, settle = {}, {}
        for name, key in (("baseline", "baseline"), ("loaded", "load")):
            w = self._window(rec, i, name)
            if w is not None:
                raw[key] = w
            s = self._settle(row, name)
            if s:
                settle[key] = s
        out = {
            **self.record_type.read(row),
            "started": str(row["started"]),
            "ended": str(row["ended"]),
            "accepted": str(row["accepted"]),
            "order": self._order_of(rec, i),
            "raw": raw,
            "settle": settle,
            "extra": {name: self._extra_value(row[name]) for name in rec.extras},
        }
        out["flags"] = split_flags(row.get("flags", ""))
        return out

    def _order_of(self, rec: Records, i: int) -> int:
        """Where record ``i`` of ``rec`` was recorded: its table row (schema 2), which a damaged
        record before it does not shift; its position among the good records (schema 1)."""
        return int(rec.sources[i]) if self.version >= 2 else i

    @staticmethod
    def _extra_value(v: Any) -> Any:
        if isinstance(v, (np.integer, np.floating, np.bool_)):
            return v.item()
        return v

    @staticmethod
    def _settle(row: Mapping[str, Any], name: str) -> dict[str, Any]:
        s: dict[str, Any] = {}
        settled = int(row.get(f"{name}_settled", -1))
        if settled >= 0:
            s["settled"] = bool(settled)
        for key in ("settle_time_s", "waited_s", "pressure_spread_MPa", "angle_spread_rad"):
            v = float(row.get(f"{name}_{key}", math.nan))
            if math.isfinite(v):
                s[key] = v
        for key in ("criterion", "accepted"):
            v = str(row.get(f"{name}_{key}", ""))
            if v:
                s[key] = v
        return s

    def _window(self, rec: Records, i: int, name: str) -> dict[str, np.ndarray] | None:
        if self.version == 1:
            return self._v1.window(rec.sources[i], name)
        a, b = int(rec.cols[f"{name}_start"][i]), int(rec.cols[f"{name}_stop"][i])
        if a < 0:
            return None
        what = f"{self.record_type.noun} {rec.ids[i]}"
        try:
            w, ok = self._frames.read(a, b)
            total, _ = self._frames.checksum(a, b)
        except StoreError:
            w, ok, total = None, False, None
        if w is None or not ok or total != int(rec.cols[f"{name}_checksum"][i]):
            self._warn(
                f"{self.path}: the {name} window of {what} is damaged (its frames fail their checksum) and is left out."
            )
            return None
        w["counts"] = counts_out(w["counts"])
        return w

    # ----------------------------------------------------------- tables

    def table(self, kind: RecordType | None = None) -> Any:
        """The CSV exchange table of the complete records (DataFrame), in recording order.

        The record type's columns, then the columns of an imported table labcli does not
        know.  ``kind``: another record type to read (a run holds only its own kind's records,
        so another kind gives an empty table).
        """
        rt = kind or self.record_type
        if rt.kind != self.record_type.kind:
            return rt.table(
                self,
                [],
                {c.name: np.empty((0, *c.shape), dtype=object if c.kind == "text" else c.dtype) for c in rt.columns},
            )
        rec = self.records()
        df = rt.table(self, list(rec.ids), rec.cols)
        for name in rec.extras:
            v = rec.cols[name]
            df[name] = [x.item() if isinstance(x, np.generic) else x for x in v] if v.dtype == object else v
        return df

    # ----------------------------------------------------------- split and models

    def set_split(
        self, fit_ids: Iterable[int], validation_ids: Iterable[int], strategy: str = "manual", seed: int | None = None
    ) -> None:
        """Store which complete records fit and which validate (the split in force from now on)."""
        self._check_writable()
        fit, val = _split.checked(self.path, self._split_ids(), fit_ids, validation_ids)
        self._to_v2("a split")
        self._commit_with_blob(
            self._split_t,
            lambda: logs.split_row(self._split_t.g, fit, val, str(strategy), seed),
            8 * (len(fit) + len(val)),
            "the split",
        )

    def _commit_with_blob(self, t: Table, make_row: Any, nbytes: int, doing: str) -> None:
        """Commit one row of ``t`` whose data (a split's ids, a model's JSON) ``make_row`` writes first.

        The room for both is reserved before the blob is written, so a full disk or ``ulimit -f``
        stops the change before HDF5 writes anything.
        """
        self._reserve(nbytes, doing)
        with self._writing(doing):
            row = make_row()
        self._commit([(t, {k: [v] for k, v in row.items()}, 1)], nbytes, doing)

    def _split_ids(self) -> list[int]:
        """The records a split may hold: the complete ones, if the record type splits at all."""
        return self.completed_ids() if self.record_type.splits else []

    def split_sizes(self) -> tuple[int, int]:
        """The fit and validation counts of the run's embedded protocol (its settings' ``default_split``)."""
        return _split.default_sizes(self.protocol_text, self.path)

    def assign_split(
        self, n_fit: int | None, n_validation: int | None, strategy: str = "sequential", seed: int | None = None
    ) -> dict[str, Any]:
        """Choose (see :func:`~labcli.core.store.split.choose_split`) and store a split; returns :meth:`split`.

        A count left None comes from the run's protocol (:meth:`split_sizes`).
        """
        if n_fit is None or n_validation is None:
            default_fit, default_validation = self.split_sizes()
            n_fit = default_fit if n_fit is None else n_fit
            n_validation = default_validation if n_validation is None else n_validation
        fit, val = _split.choose(self._split_ids(), n_fit, n_validation, strategy, seed, self.path)
        self.set_split(fit, val, strategy, (0 if seed is None else seed) if strategy == "random" else None)
        return self.split()

    def split(self) -> dict[str, Any] | None:
        """``{"fit": [...], "validation": [...], "strategy", "seed" (None), "created"}`` or None."""
        if self.version == 1:
            return self._v1.split()
        s, problems = logs.read_split(self._split_t)
        if problems:
            self._warn(f"{self.path}: {problems[0]}; the last split that checks out is used.")
        return s

    def set_of(self) -> dict[int, str]:
        """Record id -> "fit" / "validation" from the stored split (unassigned ids absent)."""
        return _split.set_of(self.split())

    def record_model(self, name: str, json_text: str) -> None:
        """Store a fitted model's parameters (JSON text) as ``name`` (the one in force from now on)."""
        self._check_writable()
        if not name or "/" in name or name.startswith(".") or len(name.encode()) > 64:
            raise StoreError(f"model name {name!r} must be non-empty, at most 64 bytes and contain no '/'.")
        self._to_v2("a model")
        self._commit_with_blob(
            self._models_t,
            lambda: logs.model_row(self._models_t.g, name, str(json_text), __version__),
            len(json_text.encode()),
            f"the model {name}",
        )

    def models(self) -> dict[str, str]:
        """Model name -> JSON text, as recorded (the last of each name)."""
        if self.version == 1:
            return self._v1.models()
        out, problems = logs.read_models(self._models_t)
        if problems:
            self._warn(f"{self.path}: {problems[0]}; it is left out.")
        return out

    def model_names(self) -> list[str]:
        """The names of the recorded models, sorted."""
        return sorted(self.models())

    # ----------------------------------------------------------- sessions

    # The session log: the run file's side of labcli.core.sessionlog.SessionLog, which the
    # engine reports to.  A record's "added" row is committed with the record itself, so the
    # log never claims a record the file lacks, nor misses one it holds; "redone" and
    # "skipped" rows ride on the next commit; "begin" and "end" are committed at once.

    def begin_session(self, info: Any) -> None:
        """A session starts writing to the run (before its first record); committed at once.

        ``info``: a :class:`labcli.core.sessionlog.SessionInfo` (started, port, baud, rig
        identity, operator, command line, resumed, other_rig).
        """
        import socket

        self._check_writable()
        self._to_v2("a session")
        sessions, _ = logs.read_sessions(self._sessions_t)
        number = max((s["number"] for s in sessions), default=0) + 1
        self._pending.append(logs.begin_event(number, info, socket.gethostname()))
        self._commit([], 0, "the session's start")
        self._session, self._session_added = number, set()

    def trial_added(self, rid: int) -> None:
        """Record ``rid`` was stored whole by this session (already logged by :meth:`write`)."""
        self._note_event("added", rid)

    def trial_redone(self, rid: int) -> None:
        """Record ``rid`` is redone before it is stored (logged with the next commit)."""
        self._note_event("redone", rid)

    def trial_skipped(self, rid: int) -> None:
        """Record ``rid`` was skipped by this session (logged with the next commit)."""
        self._note_event("skipped", rid)

    def _note_event(self, event: str, rid: int) -> None:
        number = self._session
        if number is None:
            raise StoreError(f"no session is open in {self.path}; begin one before noting {event} records.")
        if event == "added":
            if int(rid) in self._session_added:
                return
            self._session_added.add(int(rid))
        self._pending.append(logs.record_event(number, event, rid))

    def end(self, how: str) -> None:
        """The session ended: ``finished``, ``quit``, ``interrupted``, ``no input``, ``rig lost``,
        ``disk full`` or ``error``; committed at once.  A session with no end row ended without
        a word (a kill, a power cut)."""
        number = self._session
        if number is None:
            raise StoreError(f"no session is open in {self.path}; there is none to end.")
        self._pending.append(logs.end_event(number, how))
        self._commit([], 0, "the session's end")
        self._session = None

    def sessions(self) -> list[dict[str, Any]]:
        """Every session that recorded into the run, in order (see :mod:`.logs`); [] for schema 1."""
        if self.version == 1:
            return []
        out, problems = logs.read_sessions(self._sessions_t)
        if problems:
            self._warn(f"{self.path}: {problems[0]}; that event is left out of the session log.")
        return out

    def rig_identity(self) -> Any:
        """The rig of the run's latest session (a ``RigIdentity``), or None when no session is logged.

        (:func:`labcli.core.sessionlog.recorded_identity` falls back on the run's metadata.)
        """
        for s in reversed(self.sessions()):
            if s["started"]:
                cal = s["calibration"] or {"gain": [], "offset": []}
                keep = all(math.isfinite(x) for x in (*cal["gain"], *cal["offset"]))
                fields = {
                    "device": s["device"],
                    "firmware": s["firmware"],
                    "channels": tuple(s["channels"]),
                    "gain": tuple(cal["gain"]) if keep else (),
                    "offset": tuple(cal["offset"]) if keep else (),
                }
                return _rig_identity(fields)
        return None

    # ----------------------------------------------------------- summary

    def summary(self) -> dict[str, Any]:
        """What ``labcli inspect`` shows: metadata, completeness, split, settling, and what the
        record type adds (baseline drift, a paper's grid, ...)."""
        return summarise(self)

    def verify(self) -> dict[str, Any]:
        """Check every record, raw window, split, model and session event (``labcli inspect --verify``)."""
        from .verify import verify

        return verify(self)

    # ----------------------------------------------------------- schema 1

    @classmethod
    def _upgrade(cls, path: str) -> RunFile:
        """Copy a version-1 run into version 2 (in a new file put in its place), open for writing."""
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always", LabcliWarning)
            old = cls(h5py.File(path, "r", locking=False), path, "r")
            try:
                new = cls._copy_v1(old, path)
            finally:
                old.close()
        for w in caught:
            warnings.warn(w.message, stacklevel=3)
        try:
            new.publish()
        except BaseException:
            raise
        new._mode = "a"
        return new

    @classmethod
    def _copy_v1(cls, old: RunFile, path: str) -> RunFile:
        a = old.attrs
        rec = old.records()
        cal = old.calibration()
        proto = SimpleNamespace(
            name=a.get("protocol", ""),
            text=old.protocol_text,
            kind=old.kind,
            path=None,
            channels=old.channels,
            calibration=None,
        )
        extras = [extra_column(name, list(rec.cols[name])) for name in rec.extras]
        device = SimpleNamespace(
            device=a.get("device", ""), firmware=a.get("firmware", ""), channels=old.channels, port=a.get("port", "")
        )
        new = cls.create(
            path,
            protocol=proto,
            device_info=device,
            port=a.get("port", ""),
            operator=a.get("operator", ""),
            plan=old.plan_table(),
            force=True,
            imported=bool(a.get("imported", False)),
            source=a.get("source", ""),
            started=a.get("started", ""),
            kind=old.kind,
            command_line="",
            extras=extras,
            rows_hint=len(rec.ids),
            calibration=(cal["gain"], cal["offset"], list(cal["units"])),
            staged=True,
        )
        try:
            for rid in rec.ids:
                new.write(old.read(rid))
            s = old.split()
            if s is not None:
                new.set_split(s["fit"], s["validation"], s["strategy"], s["seed"])
            for name, json_text in old.models().items():
                new.record_model(name, json_text)
        except BaseException:
            new.discard()
            raise
        return new


def _joined_flags(flags: Any, label: str) -> str:
    """A record's flags (one sentence each, or one string) as the flags column keeps them: one per line."""
    if not flags:
        return ""
    items = [flags] if isinstance(flags, str) else list(flags)
    for k, flag in enumerate(items, 1):
        if not isinstance(flag, str):
            raise StoreError(f"{label} record: flag {k} is {type(flag).__name__}, not text; a flag is one sentence.")
        if "\n" in flag or "\r" in flag or not flag.strip():
            raise StoreError(
                f"{label} record: flag {k} is {'empty' if not flag.strip() else 'more than one line'}; "
                "a flag is one sentence."
            )
    return "\n".join(items)


def split_flags(value: Any) -> list[str]:
    """The flags column of one record back as the list of sentences the writer gave."""
    v = value.decode("utf-8") if isinstance(value, bytes) else str(value or "")
    return v.split("\n") if v else []


def _rig_identity(fields: dict[str, Any]) -> Any:
    """``labcli.core.sessionlog.RigIdentity(**fields)``; plain attributes where that seam is absent."""
    try:
        from ..sessionlog import RigIdentity  # type: ignore[import-not-found]
    except ImportError:
        return SimpleNamespace(**fields)
    return RigIdentity(**fields)


def load_table(path: str | os.PathLike, kind: RecordType) -> Any:
    """The table of ``kind``'s records from a run file (``.h5``, ``.hdf5``) or from a CSV table."""
    if os.fspath(path).lower().endswith(RUN_FILE_SUFFIXES):
        with RunFile.open(path) as run:
            return run.table(kind)
    return kind.read_csv(path)
