"""The HDF5 run file: one file per run, every record written whole and crash-safe.

Layout (schema ``labcli-run``, version 1).  SI inside: pressures MPa gauge,
angles rad, forces N, lengths m, masses kg, times s.  Every dataset carries a
``units`` attribute (``""`` for text, ``"1"`` for ids and counters); every
group an ``NX_class`` attribute in the NeXus style::

    /                               NX_class=NXentry
      @schema           "labcli-run"
      @schema_version   1
      @labcli_version   "0.1.0"
      @kind             the run kind ("force", "push", "rpam-stretch", ...): its experiment's
                        record type says what one record holds (labcli.core.registry)
      @protocol         protocol name, e.g. "takuma2014"
      @device @firmware from the rig's ID? reply ("" for imported runs)
      @port             serial port or URL ("" for imported runs)
      @channels         channel names, in data-line order
      @operator         who ran it
      @started          ISO 8601 UTC, e.g. "2024-05-01T09:30:00Z"
      @imported         True when built from a CSV table (no raw windows)
      @source           the imported CSV's file name ("" otherwise)
      protocol          the protocol TOML, verbatim (string; @name @kind @path)
      calibration/      NXcollection: gain (k,) SI/count, offset (k,) SI, @units per channel
      plan/             NXcollection, only when a plan was given: one dataset per plan
                        column (trial, set, mass_g, direction_deg, ...), table units
      trials/ (pushes/, points/, ...)   NXcollection named by the record type
        000012/         NXcollection, one record (id zero-padded to 6 digits)
          @trial        the id, under the record type's id column
          @order (recording order, 0-based) @started @ended (ISO 8601 UTC)
          @settle_time_s @settle_criterion @accepted ("auto" | "timeout" | "operator"
                        | "imported") for the loaded window ("operator": accepted over a warning)
          @flags        what the session's checks found, one sentence each (only when any)
          ...           what the record type stores (labcli.experiments.<paper>.records)
          extra/        columns of an imported table that labcli does not know
          baseline/     NXlog, the unloaded window; loaded/ NXlog, the loaded window:
            time (n,) s float64     device time, unwrapped
            counts (n,k) int32      values as sent (float64 if the device sends decimals)
            values (n,k) float64    calibrated SI values, @units "MPa,...,rad"
            seq (n,) uint32         frame counter as sent
            @settled @settle_time_s @waited_s @pressure_spread_MPa
            @angle_spread_rad @criterion @accepted
          @complete     True, written last (see below)
        000012.1/       a later attempt at record 12, when a kill left 000012
                        unfinished (which stays, ignored)
      index (16384,)    object references to the record groups in recording order,
                        written in place (storage allocated at creation): a second
                        way to every complete record if a crash damages a link list
      split/            NXcollection: fit (m,) and validation (v,) record ids
                        @strategy ("sequential" | "random" | "plan" | "imported" | ...)
                        @seed (-1 when none) @created (:mod:`.split`)
      models/           NXcollection: one string dataset of JSON per fitted model, @created
                        (:mod:`.models`)

Crash safety.  A record group is created with ``@complete = False``; its
datasets and attributes are written, the file is flushed and fsynced, and only
then is ``@complete`` set to True (in place) and the file flushed and fsynced
again.  Readers count only complete groups.  An incomplete one (a crash's
leftover) is never removed: the next attempt at its id is written beside it as
``000012.1``, because a removal frees blocks at the end of the file and HDF5
shrinks the file at the next flush, which a kill at that moment turns into a
file that no longer opens.  Nothing is ever deleted during a session.  The root's
groups all exist from creation, so the root's link list never changes afterwards;
each record's reference goes into ``/index`` before the first fsync.  The file uses
HDF5's default format bounds (not ``libver='latest'``, not SWMR: after a kill -9 those
refuse to open without ``h5clear``) with the file-space strategy "none", so space freed
during a session is never reused and structures already on disk are never
overwritten by new data.  A new file is built as ``RUN.h5.creating`` and
renamed once its metadata is on disk, so a kill during creation leaves no
half-made run and ``force=True`` keeps the old file until the new one exists.

Records and tables.  :meth:`RunFile.write` takes the record a session commits (a plain
dict, SI) and :meth:`RunFile.read` gives it back; :meth:`RunFile.table` gives the CSV
exchange table, in the units people type, degrees and grams rounded to 12 significant
digits (:func:`~labcli.core.store.h5.to_edge`), which makes table -> run file -> table
exact.  What a record holds is its record type's business
(:class:`labcli.core.experiment.RecordType`); the run file writes the parts every record
shares.  HDF5 strings end at a NUL, so text holding one is refused before any file is
made (:func:`labcli.core.store.importing.storable_cells`) rather than stored cut short.
"""

from __future__ import annotations

import functools
import math
import os
from typing import Any, Iterable, Mapping

import h5py
import numpy as np

from ...errors import LabcliError, StoreError
from ..experiment import RecordType
from ..files import RUN_FILE_SUFFIXES
from ..registry import record_type
from ..version import __version__
from . import models as _models
from . import split as _split
from .h5 import (
    Window,
    calibration_arrays,
    checked_common,
    column_units,
    dataset,
    plain,
    read_columns,
    text,
    text_dataset,
    utc_now,
    write_columns,
)
from .summary import summarise

SCHEMA = "labcli-run"
SCHEMA_VERSION = 1
MAX_ID = 999_999
INDEX_SLOTS = 16_384  # records reachable through /index; later ones by name only
# What to do about a run file that already exists where a new run would go.
RESUME_OR_FORCE = "continue it with --resume, or pass --force to overwrite it"


class RunFile:
    """An open run file.  Use as a context manager; writes are crash-safe per record.

    >>> with RunFile.create("run.h5", protocol=proto, device_info=dev.info,
    ...                     port="sim://", operator="ada") as run:   # doctest: +SKIP
    ...     run.write(record)

    ``record_type`` is the run kind's (:class:`labcli.core.experiment.RecordType`).
    """

    def __init__(self, h5: h5py.File, path: str) -> None:
        self._f = h5
        self.path = path
        self._channels = tuple(text(c) for c in h5.attrs.get("channels", ()))
        kind = self.kind
        try:
            self.record_type: RecordType = record_type(kind)
        except LabcliError:
            raise StoreError(f"{path} is a run of kind '{kind}', which no installed experiment reads; "
                             "install the experiment that recorded it.") from None
        # fsync each record (crash safety); a file built whole under a temporary
        # name (import) turns it off and is synced once when closed.
        self.sync_each_record = True
        # (collection, id) -> (recording order, object reference) of every complete
        # record.  Scanned once: the file is locked, so only this object adds records.
        self._unreadable: set[str] = set()  # collections whose link list the scan could not read
        complete, self._incomplete = self._scan()
        self._index: dict[tuple[str, int], tuple[int, Any]] = {
            (c, rid): (order, ref) for c, order, rid, ref in complete
        }
        self._order = max((order for order, _ in self._index.values()), default=-1) + 1

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
    ) -> "RunFile":
        """Create a new run file for ``protocol`` (a :class:`labcli.core.protocol.Protocol`).

        ``kind``: the run kind (default: the protocol's); ``device_info``: the rig's
        ``DeviceInfo`` (device, firmware, channels); ``plan``: the plan table (DataFrame or
        dict of columns) or None.
        An existing file is overwritten only with ``force=True``.
        """
        path = os.fspath(path)
        if os.path.exists(path) and not force:
            raise StoreError(f"{path} already exists; {exists_hint}.")
        parent = os.path.dirname(os.path.abspath(path))
        if not os.path.isdir(parent):
            raise StoreError(f"cannot create {path}: the directory {parent} does not exist.")
        kind = kind or str(getattr(protocol, "kind", "force"))
        channels = [str(c) for c in (getattr(device_info, "channels", None) or getattr(protocol, "channels", ()))]
        # Built under a temporary name and renamed when whole: a kill during
        # creation leaves no half-made run, and --force keeps the old file until then.
        tmp = path + ".creating"
        try:
            # fs_strategy "none": freed space is never reused (see the module docstring).
            f = h5py.File(tmp, "w", fs_strategy="none")
        except OSError as e:
            raise StoreError(f"cannot create {path}: {e}.") from None
        try:
            cls._initialise(f, protocol=protocol, device_info=device_info, port=port, operator=operator,
                            plan=plan, imported=imported, source=source, started=started, kind=kind,
                            channels=channels)
            f.flush()
            os.fsync(f.id.get_vfd_handle())
        except BaseException:
            f.close()
            os.unlink(tmp)
            raise
        f.close()
        os.replace(tmp, path)
        return cls.open(path, "a")

    @staticmethod
    def _initialise(f: h5py.File, *, protocol: Any, device_info: Any, port: str, operator: str, plan: Any,
                    imported: bool, source: str, started: str | None, kind: str, channels: list[str]) -> None:
        rt = record_type(kind)
        a = f.attrs
        a["NX_class"] = "NXentry"
        a["schema"] = SCHEMA
        a["schema_version"] = SCHEMA_VERSION
        a["labcli_version"] = __version__
        a["kind"] = kind
        a["protocol"] = str(getattr(protocol, "name", ""))
        a["device"] = str(getattr(device_info, "device", "") or "")
        a["firmware"] = str(getattr(device_info, "firmware", "") or "")
        a["port"] = str(port or getattr(device_info, "port", "") or "")
        a["channels"] = channels
        a["operator"] = str(operator or "")
        a["started"] = started or utc_now()
        a["imported"] = bool(imported)
        a["source"] = str(source)
        text_dataset(f, "protocol", str(getattr(protocol, "text", "")),
                      name=str(getattr(protocol, "name", "")), kind=kind,
                      path=str(getattr(protocol, "path", "") or ""))
        gain, offset, units = calibration_arrays(protocol, len(channels))
        cal = f.create_group("calibration")
        cal.attrs["NX_class"] = "NXcollection"
        cal.attrs["channels"] = channels
        dataset(cal, "gain", gain, ",".join(f"{u}/count" if u else "1/count" for u in units))
        dataset(cal, "offset", offset, ",".join(units))
        if plan is not None:
            cols = plan.to_dict("list") if hasattr(plan, "to_dict") else dict(plan)
            g = f.create_group("plan")
            g.attrs["NX_class"] = "NXcollection"
            write_columns(g, cols, list(cols), ids=(rt.id_column,))
        # Every group the run will need exists from the start: the root's link
        # list is never changed again, so no later crash can damage it.
        for name in (rt.collection, "split", "models"):
            f.create_group(name).attrs["NX_class"] = "NXcollection"
        dcpl = h5py.h5p.create(h5py.h5p.DATASET_CREATE)
        dcpl.set_alloc_time(h5py.h5d.ALLOC_TIME_EARLY)
        index = f.create_dataset("index", shape=(INDEX_SLOTS,), dtype=h5py.ref_dtype, dcpl=dcpl)
        index.attrs["units"] = ""

    @classmethod
    def open(cls, path: str | os.PathLike, mode: str = "r") -> "RunFile":
        """Open an existing run file for reading (``"r"``) or resuming (``"a"``)."""
        path = os.fspath(path)
        if mode not in ("r", "a"):
            raise ValueError(f"mode must be 'r' or 'a', got {mode!r}")
        if not os.path.exists(path):
            raise StoreError(f"{path} does not exist; check the path.")
        if os.path.isdir(path):
            raise StoreError(f"{path} is a directory, not a run file.")
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
        try:
            f = cls._h5open(path, mode)
        except OSError as e:
            if "unable to lock file" in str(e).lower():
                if mode == "r":
                    # A read lock is refused only while a writer holds the file.
                    raise StoreError(
                        f"{path} is open for writing in another process; wait for that run to end and try again."
                    ) from None
                # A write lock is refused while anyone holds the file, a reader included.
                raise StoreError(
                    f"{path} is open in another program (a viewer, or a run still recording); "
                    "close it there and try again."
                ) from None
            raise StoreError(f"{path} is damaged or truncated and HDF5 cannot open it; use a backup copy.") from None
        try:
            schema = f.attrs.get("schema")
            version = f.attrs.get("schema_version")
        except (OSError, KeyError, RuntimeError):
            f.close()
            raise StoreError(f"{path} is damaged or truncated and HDF5 cannot open it; use a backup copy.") from None
        if schema is None or text(schema) != SCHEMA:
            f.close()
            found = "no schema attribute" if schema is None else f"schema {text(schema)!r}"
            raise StoreError(f"{path} is an HDF5 file but not a labcli run file ({found}, expected '{SCHEMA}').")
        try:
            version = int(version)
        except (TypeError, ValueError):
            f.close()
            raise StoreError(f"{path} has no valid schema_version attribute; the file is damaged.") from None
        if version > SCHEMA_VERSION:
            f.close()
            raise StoreError(
                f"{path} uses run-file schema version {version}, newer than this labcli reads "
                f"({SCHEMA_VERSION}); upgrade labcli."
            )
        try:
            return cls(f, path)
        except StoreError:
            f.close()
            raise
        except (OSError, KeyError, RuntimeError):
            f.close()
            raise StoreError(f"{path} is damaged or truncated and HDF5 cannot read it; use a backup copy.") from None

    @staticmethod
    def _h5open(path: str, mode: str) -> h5py.File:
        try:
            return h5py.File(path, mode)
        except OSError as e:
            msg = str(e).lower()
            # errno 11: another process holds the lock.  Any other lock failure
            # means a file system without locks (some network mounts), where
            # HDF5 advises opening without them.
            if "unable to lock file" in msg and "errno = 11" not in msg:
                return h5py.File(path, mode, locking=False)
            raise

    def close(self) -> None:
        if self._f.id.valid:
            if self._f.mode != "r":
                self._commit()
            self._f.close()

    def __enter__(self) -> "RunFile":
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()

    def _commit(self) -> None:
        """Push everything written so far to the disk (flush, then fsync)."""
        self._f.flush()
        os.fsync(self._f.id.get_vfd_handle())

    # ----------------------------------------------------------- metadata

    @property
    def attrs(self) -> dict[str, Any]:
        """The run's root attributes as plain Python values."""
        return {k: plain(v) for k, v in self._f.attrs.items()}

    @property
    def kind(self) -> str:
        return text(self._f.attrs.get("kind", "force"))

    @property
    def channels(self) -> tuple[str, ...]:
        return self._channels

    @property
    def protocol_text(self) -> str:
        """The protocol TOML embedded verbatim when the run was created."""
        if "protocol" not in self._f:
            return ""
        return text(self._f["protocol"][()])

    def calibration(self) -> dict[str, Any]:
        """Per-channel gain (SI/count), offset (SI) and units as stored."""
        g = self._f["calibration"]
        units = text(g["offset"].attrs["units"]).split(",")
        return {"channels": self.channels, "gain": g["gain"][()], "offset": g["offset"][()], "units": tuple(units)}

    def plan_table(self):
        """The plan table stored at creation (DataFrame), or None."""
        import pandas as pd

        if "plan" not in self._f:
            return None
        return pd.DataFrame(read_columns(self._f["plan"]))

    # ----------------------------------------------------------- writing

    def _check_writable(self) -> None:
        if self._f.mode == "r":
            raise StoreError(f"{self.path} is open read-only; open it with mode 'a' to add records.")

    def _new_group(self, collection: str, rid: int, label: str) -> h5py.Group:
        if (collection, rid) in self._index:
            raise StoreError(f"{label} is already complete in {self.path}; a stored record is never overwritten.")
        # The scan at opening read every link list; nothing but this object changes them since.
        if collection in self._unreadable:
            raise StoreError(
                f"the list of {collection} in {self.path} is damaged, so no record can be added; its complete "
                "records can still be read: copy them to a new file with 'labcli export' and 'labcli import'."
            )
        if collection not in self._f:
            self._f.create_group(collection).attrs["NX_class"] = "NXcollection"
        parent = self._f[collection]
        base = f"{rid:06d}"
        # Leftovers of interrupted writes stay where they are, ignored, and the
        # new attempt takes the next free name (000012, 000012.1, ...).  Removing
        # them frees blocks at the end of the file; HDF5 then shrinks the file at
        # the next flush, and a kill at that moment left a file that no longer
        # opens ("truncated file"), as the kill tests showed.
        name = base
        n = 0
        while name in parent:
            n += 1
            name = f"{base}.{n}"
        g = parent.create_group(name)
        g.attrs["NX_class"] = "NXcollection"
        g.attrs["complete"] = False  # first attribute; set True in place once all else is on disk
        return g

    @functools.cached_property
    def _values_units(self) -> str:
        """The units of a window's calibrated values, one per channel (read once, on the first write)."""
        return text(self._f["calibration/offset"].attrs["units"])

    @functools.cached_property
    def _index_dataset(self) -> h5py.Dataset | None:
        return self._f.get("index")

    def _write_common(self, g: h5py.Group, record: Mapping, attrs: Mapping[str, Any],
                      windows: list[Window]) -> None:
        g.attrs["order"] = self._order
        g.attrs["started"] = str(record.get("started", "") or "")
        g.attrs["ended"] = str(record.get("ended", "") or utc_now())
        for key, v in attrs.items():
            g.attrs[key] = v
        if record.get("flags"):
            # What the session's checks found (a stream off its rate, a trial accepted over a
            # warning): one sentence each, kept with the record.
            g.attrs["flags"] = [str(f) for f in record["flags"]]
        extra = record.get("extra") or {}
        ids = (self.record_type.id_column,)
        if extra:
            e = g.create_group("extra")
            e.attrs["NX_class"] = "NXcollection"
            e.attrs["columns"] = list(extra)
            for name, v in extra.items():
                if isinstance(v, str):
                    text_dataset(e, name, v)
                elif isinstance(v, (int, np.integer)) and not isinstance(v, bool):
                    dataset(e, name, np.int64(v), column_units(name, ids))
                else:
                    dataset(e, name, math.nan if v is None else float(v), column_units(name, ids))
        for name, arrays, settle in windows:
            w = g.create_group(name)
            w.attrs["NX_class"] = "NXlog"
            w.attrs["channels"] = list(self.channels)
            dataset(w, "time", arrays["time"], "s", raw=True)
            dataset(w, "counts", arrays["counts"], "counts", raw=True)
            dataset(w, "values", arrays["values"], self._values_units, raw=True)
            dataset(w, "seq", arrays["seq"], "1", raw=True)
            for sk, sv in settle.items():
                w.attrs[sk] = sv

    def _finish(self, g: h5py.Group, collection: str, rid: int) -> None:
        index = self._index_dataset
        if index is not None and self._order < index.shape[0]:
            # A write in place into storage allocated at creation: no HDF5
            # structure changes, so the record stays reachable even if a later
            # crash damages the group's list of links.
            index[self._order] = g.ref
        if self.sync_each_record:
            self._commit()
        g.attrs.modify("complete", True)
        if self.sync_each_record:
            self._commit()
        self._index[(collection, rid)] = (self._order, g.ref)
        self._incomplete.discard((collection, rid))
        self._order += 1

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

    def write(self, record: Mapping) -> None:
        """Write one record of the run's kind whole; it counts only once it is on disk.

        ``record``: what the run's record type takes (the session's ``Commit``, or an
        imported table row), plus what every record may carry: ``started``/``ended`` (ISO
        8601 UTC; ``ended`` defaults to the write time), ``settle`` (``{"baseline": ...,
        "load": ...}``), ``raw`` (the windows), ``accepted``, ``extra`` (other table
        columns).  Raises StoreError if the record is already complete in the file or is
        malformed (nothing is written then).
        """
        rt = self.record_type
        rid, label = self._record_id(record, rt.id_column)
        stored = rt.check(record, label, self)
        common = checked_common(record, len(self.channels), label)
        g = self._new_group(rt.collection, rid, label)
        g.attrs[rt.id_column] = rid
        for key, value in stored.attrs.items():
            g.attrs[key] = value
        for d in stored.datasets:
            dataset(g, d.name, d.value, d.units, **d.attrs)
        self._write_common(g, record, *common)
        self._finish(g, rt.collection, rid)

    # ----------------------------------------------------------- reading records

    def _identify(self, g: h5py.Group) -> tuple[str, int, bool, int]:
        """(collection, id, complete, order) of a record group; raises if it cannot be read."""
        a = g.attrs
        rt = self.record_type
        if rt.id_column not in a:
            raise KeyError("no id")
        ok = bool(a.get("complete", False))
        return rt.collection, int(a[rt.id_column]), ok, int(a["order"]) if ok else -1

    def _scan(self) -> tuple[list[tuple[str, int, int, Any]], set[tuple[str, int]]]:
        """Complete records as (collection, order, id, reference), and (collection, id) only incomplete.

        Records are found by name under their collection (/trials, /pushes, ...) and,
        independently, through /index (object references written in place), so that damage to
        a group's link list after a crash loses no complete record.
        """
        complete: dict[tuple[str, int], tuple[int, Any]] = {}
        incomplete: set[tuple[str, int]] = set()

        def visit(get_group, fallback: tuple[str, int] | None = None) -> None:
            try:
                g = get_group()
                collection, rid, ok, order = self._identify(g)
            except Exception:  # a crash's leftovers may be unreadable in any way: never complete
                if fallback is not None:
                    incomplete.add(fallback)
                return
            if ok:
                complete.setdefault((collection, rid), (order, g.ref))
            else:
                incomplete.add((collection, rid))

        for collection in (self.record_type.collection,):
            try:
                parent = self._f[collection] if collection in self._f else None
                keys = list(parent) if parent is not None else []
            except Exception:
                self._unreadable.add(collection)
                keys = []
            for key in keys:
                try:
                    fallback = (collection, int(key.split(".")[0]))
                except ValueError:
                    continue
                visit(lambda parent=parent, key=key: parent[key], fallback)
        try:
            refs = self._f["index"][()] if "index" in self._f else []
        except Exception:
            refs = []
        for ref in refs:
            if not ref:
                break  # slots are filled in recording order
            visit(lambda ref=ref: self._f[ref])
        rows = sorted(((c, order, rid, ref) for (c, rid), (order, ref) in complete.items()), key=lambda r: r[:3])
        return rows, incomplete - set(complete)

    def _complete(self, collection: str | None = None) -> list[tuple[int, int, Any]]:
        """(order, id, object reference) of the complete records, in recording order."""
        c = collection or self.record_type.collection
        return sorted(((order, rid, ref) for (cc, rid), (order, ref) in self._index.items() if cc == c),
                      key=lambda row: row[:2])

    def completed_ids(self) -> list[int]:
        """Ids of the complete records (trials, pushes, points: the run's kind), in recording order."""
        return [rid for _, rid, _ in self._complete()]

    def incomplete_ids(self) -> list[int]:
        """Ids with only groups left incomplete by an interrupted write (never counted)."""
        return sorted(rid for _, rid in self._incomplete)

    def first_incomplete(self, plan_ids: Iterable[int]) -> int | None:
        """The first id of ``plan_ids`` not yet complete in the file (None: all done)."""
        done = set(self.completed_ids())
        for i in plan_ids:
            if int(i) not in done:
                return int(i)
        return None

    def _complete_groups(self, collection: str) -> tuple[list[int], list[h5py.Group]]:
        complete = self._complete(collection)
        return [rid for _, rid, _ in complete], [self._f[ref] for _, _, ref in complete]

    def _complete_group(self, collection: str, rid: int) -> h5py.Group:
        entry = self._index.get((collection, rid))
        if entry is None:
            raise StoreError(f"{self.record_type.noun} {rid} is not a complete record in {self.path}.")
        return self._f[entry[1]]

    @staticmethod
    def _read_windows(g: h5py.Group) -> tuple[dict, dict]:
        raw, settle = {}, {}
        for name, key in (("baseline", "baseline"), ("loaded", "load")):
            if name not in g:
                continue
            w = g[name]
            raw[key] = {"t_s": w["time"][()], "counts": w["counts"][()], "si": w["values"][()], "seq": w["seq"][()]}
            s = {k: plain(v) for k, v in w.attrs.items() if k not in ("NX_class", "channels")}
            if s:
                settle[key] = s
        return raw, settle

    @staticmethod
    def _read_extra(g: h5py.Group) -> dict:
        if "extra" not in g:
            return {}
        e = g["extra"]
        out = {}
        for name in [text(c) for c in e.attrs.get("columns", list(e))]:
            v = e[name][()]
            out[name] = text(v) if isinstance(v, (bytes, str)) else v.item()
        return out

    def read(self, rid: int) -> dict:
        """One complete record back as the writer gave it (SI), with its windows as stored."""
        g = self._complete_group(self.record_type.collection, int(rid))
        raw, settle = self._read_windows(g)
        return {
            **self.record_type.read(g),
            "started": text(g.attrs["started"]), "ended": text(g.attrs["ended"]),
            "accepted": text(g.attrs["accepted"]), "order": int(g.attrs["order"]),
            "raw": raw, "settle": settle, "extra": self._read_extra(g),
        }

    # ----------------------------------------------------------- tables

    def table(self, kind: RecordType | None = None) -> Any:
        """The CSV exchange table of the complete records (DataFrame), in recording order.

        The record type's columns, then the columns of an imported table labcli does not
        know.  ``kind``: another record type to read (its collection is empty unless the
        run is of that kind).
        """
        rt = kind or self.record_type
        ids, groups = self._complete_groups(rt.collection)
        df = rt.table(self, ids, groups)
        self._add_extras(df, groups)
        return df

    def _add_extras(self, df: Any, groups: list[h5py.Group]) -> None:
        """Append the imported columns labcli does not know, in first-seen order; NaN where a record lacks one."""
        extras = [self._read_extra(g) for g in groups]
        for name in dict.fromkeys(name for e in extras for name in e):
            df[name] = [e.get(name, math.nan) for e in extras]

    # ----------------------------------------------------------- split and models

    def set_split(self, fit_ids: Iterable[int], validation_ids: Iterable[int], strategy: str = "manual",
                  seed: int | None = None) -> None:
        """Store which complete records fit and which validate (replaces an earlier split)."""
        self._check_writable()
        _split.store(self._f, self.path, self._split_ids(), fit_ids, validation_ids, strategy, seed)
        self._commit()

    def _split_ids(self) -> list[int]:
        """The records a split may hold: the complete ones, if the record type splits at all."""
        return self.completed_ids() if self.record_type.splits else []

    def split_sizes(self) -> tuple[int, int]:
        """The fit and validation counts of the run's embedded protocol (its settings' ``default_split``)."""
        return _split.default_sizes(self.protocol_text, self.path)

    def assign_split(self, n_fit: int | None, n_validation: int | None, strategy: str = "sequential",
                     seed: int | None = None) -> dict[str, Any]:
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
        return _split.read(self._f)

    def set_of(self) -> dict[int, str]:
        """Record id -> "fit" / "validation" from the stored split (unassigned ids absent)."""
        return _split.set_of(self.split())

    def record_model(self, name: str, json_text: str) -> None:
        """Store a fitted model's parameters (JSON text) under ``/models/<name>``, replacing one of that name."""
        self._check_writable()
        _models.store(self._f, name, json_text)
        self._commit()

    def models(self) -> dict[str, str]:
        """Model name -> JSON text, as recorded."""
        return _models.read(self._f)

    def model_names(self) -> list[str]:
        """The names of the recorded models, sorted."""
        return _models.names(self._f)

    # ----------------------------------------------------------- summary

    def summary(self) -> dict[str, Any]:
        """What ``labcli inspect`` shows: metadata, completeness, split, settling, and what the
        record type adds (baseline drift, an experiment's grid, ...)."""
        return summarise(self)

    def complete_groups(self) -> tuple[list[int], list[h5py.Group]]:
        """Ids and groups of the complete records, in recording order."""
        return self._complete_groups(self.record_type.collection)


def load_table(path: str | os.PathLike, kind: RecordType) -> Any:
    """The table of ``kind``'s records from a run file (``.h5``, ``.hdf5``) or from a CSV table."""
    if os.fspath(path).lower().endswith(RUN_FILE_SUFFIXES):
        with RunFile.open(path) as run:
            return run.table(kind)
    return kind.read_csv(path)
