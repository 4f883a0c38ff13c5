"""The layout of a run file (schema version :data:`SCHEMA_VERSION`): what a new run holds and where.

::

    /                           NXroot  @default "entry"  @file_name @file_time @creator
                                @HDF5_Version @h5py_version  (@schema and @schema_version: entry/labcli)
      entry/                    NXentry  @default (the record table)  @kind @protocol @run_uid
                                @start_time @program_name @program_version @command_line @host_name
                                @operator @device @firmware @port @channels @imported @source
        versions/               @python @numpy @h5py @hdf5 @labcli (that wrote the file)
        protocol (1,)           the protocol TOML, verbatim  @name @kind @file_name
        plan/                   the plan table (when there was a plan)
        trials/ (pushes/, points/)  NXdata  @signal @axes: the records, one row each
        raw/                    every raw frame: time, seq, values and counts (frames x channels),
                                and per channel an NXlog (its value and raw_value: views of those)
          unused/               ranges of frames no record takes, and why (redone, interrupted, ...)
        split/                  every split assigned, the last one in force; ids (m,), their
                                checksum and its version (2, whole-array; a log without the
                                column holds version 1)
        models/                 every model recorded, the last of each name in force; json (bytes)
        sessions/               the session log: one row per event (begin, added, redone, skipped, end)

Every dataset is chunked with gzip and Fletcher32 (raw windows at gzip level 4 with byte
shuffle; tables and split ids at level 1, shuffled where they hold whole numbers: see
:data:`.columns.TABLE_FILTERS`; a table's numbers in chunks of at most 64 bytes, as a table
written a row a commit has them, and checksum columns, Fletcher32 alone: :func:`.columns.table_filters`) and has a ``units`` attribute (one unit: per-channel units live in
separate datasets); every group has an
``NX_class``.  Times are ISO 8601 with microseconds and a UTC offset.  No path of the
writer's machine is stored: files are named by their file name only, and the command line
keeps only the file names of the paths in it.

The tables (:mod:`.columns`) are append-only and committed by ``@committed``; the raw frames
(:mod:`.frames`) are referenced by the rows.  This module only builds a new file; the run
file (:mod:`.runfile`) reads and adds to it.
"""

from __future__ import annotations

import os
import platform
import shlex
import socket
import sys
import uuid
from collections.abc import Mapping, Sequence
from typing import Any

import h5py
import numpy as np

from ..files import stored_text
from ..paper import Column, RecordType
from ..timestamps import utc_now
from ..version import __version__
from .columns import FILTERS, TABLE_FILTERS, Table, per_channel
from .frames import create as create_frames
from .h5 import put
from .nexus import default_plot, write_metadata

SCHEMA = "labcli-run"
SCHEMA_VERSION = 4
WINDOWS = ("baseline", "loaded")  # a record's raw windows: group names of schema 1, column prefixes here
TIME_WIDTH = 40
FLAGS_WIDTH = 1024  # bytes of the flags column: a few one-sentence notes per record


def text_column(name: str, width: int, what: str = "") -> Column:
    return Column(name, "", kind="text", width=width, optional=True, what=what)


def common_columns(id_column: str) -> list[Column]:
    """What every record has, before its record type's columns."""
    return [
        Column(id_column, "1", kind="int", what=f"{id_column} id"),
        text_column("started", TIME_WIDTH, "when the record began (ISO 8601)"),
        text_column("ended", TIME_WIDTH, "when the record was stored (ISO 8601)"),
        text_column("accepted", 8, "how it was accepted: auto, timeout, operator or imported"),
        text_column("flags", FLAGS_WIDTH, "what was noticed about the record, one sentence per line"),
    ]


def window_columns() -> list[Column]:
    """Per raw window: its frames in /entry/raw, their checksum, and how its equilibrium was reached."""
    cols = []
    for w in WINDOWS:
        cols += [
            Column(f"{w}_start", "1", kind="int", what=f"first frame of the {w} window in raw/"),
            Column(f"{w}_stop", "1", kind="int", what=f"frame after the last of the {w} window"),
            Column(f"{w}_checksum", "1", kind="uint", what=f"checksum of the {w} window's frames"),
            Column(f"{w}_settled", "1", kind="flag", what="1 settled, 0 timed out, -1 not recorded"),
            Column(f"{w}_settle_time_s", "s", optional=True, what="time to equilibrium"),
            Column(f"{w}_waited_s", "s", optional=True, what="time waited in all"),
            Column(f"{w}_pressure_spread_MPa", "MPa", optional=True, what="pressure spread at equilibrium"),
            Column(f"{w}_angle_spread_rad", "rad", optional=True, what="angle spread at equilibrium"),
            text_column(f"{w}_criterion", 192, "the equilibrium criterion"),
            text_column(f"{w}_accepted", 8, "auto, timeout or operator"),
        ]
    return cols


def record_columns(rt: RecordType, extras: Sequence[Column] = ()) -> list[Column]:
    """Every column of a record table, in order: common, imported extras, the record type's, windows."""
    return [*common_columns(rt.id_column), *extras, *rt.columns, *window_columns()]


EXTRA_PREFIX = "extra:"  # an imported table's own columns, in a namespace of their own


def extra_key(name: str) -> str:
    """The record table's name for an imported table's column ``name``: never one of the run
    file's own columns (``P``, ``flags``, ...), never an HDF5 path (``.``, ``a/``)."""
    return EXTRA_PREFIX + name.replace("%", "%25").replace("/", "%2F")


def extra_name(key: str) -> str:
    """The imported column's own name, back from :func:`extra_key` (older runs kept it as it was)."""
    if not key.startswith(EXTRA_PREFIX):
        return key
    return key[len(EXTRA_PREFIX) :].replace("%2F", "/").replace("%25", "%")


def extra_column(name: str, values: Sequence[Any]) -> Column:
    """The column for an imported table's column labcli does not know, from its values."""
    from .h5 import column_units

    present = [v for v in values if v is not None and not (isinstance(v, float) and np.isnan(v))]
    if present and all(isinstance(v, (int, np.integer)) and not isinstance(v, bool) for v in values):
        return Column(name, column_units(name), kind="int", what="imported column")
    if not any(isinstance(v, str) for v in present):
        return Column(name, column_units(name), optional=True, what="imported column")
    width = max([len(str(v).encode("utf-8")) for v in present] + [1])
    return text_column(name, width, "imported column")


SPLIT_COLUMNS = [
    text_column("strategy", 32),
    Column("seed", "1", kind="int"),
    text_column("created", TIME_WIDTH),
    Column("fit_start", "1", kind="int"),
    Column("fit_stop", "1", kind="int"),
    Column("validation_start", "1", kind="int"),
    Column("validation_stop", "1", kind="int"),
    Column("ids_checksum", "1", kind="uint"),
    Column("ids_checksum_version", "1", kind="int", what="1: the ids' words folded in turn; 2: each, then summed"),
]
# raw/unused: ranges of raw frames no record takes, and why (:mod:`.unused`).
UNUSED = "unused"
UNUSED_COLUMNS = [
    Column("start", "1", kind="int", what="first frame of the range in raw/"),
    Column("stop", "1", kind="int", what="frame after the last of the range"),
    text_column("why", 16, "redone, skipped, retaken, interrupted or unknown"),
    Column("record", "1", kind="int", what="the record the frames were taken for; -1: not known"),
    Column("session", "1", kind="int", what="the session that marked them; -1: none"),
    text_column("time", TIME_WIDTH, "when they were marked (ISO 8601)"),
]
MODEL_COLUMNS = [
    text_column("name", 64),
    text_column("created", TIME_WIDTH),
    text_column("labcli_version", 32),
    Column("json_start", "1", kind="int"),
    Column("json_stop", "1", kind="int"),
    Column("json_checksum", "1", kind="uint"),
]


def session_columns(k: int, units: Sequence[str] = ()) -> list[Column]:
    """The session log: one row per event; ``k`` channels (of ``units``) for the calibration in force."""
    return [
        Column("session", "1", kind="int", what="session number, from 1"),
        text_column("event", 16, "begin, added, redone, skipped or end"),
        text_column("time", TIME_WIDTH),
        Column("record", "1", kind="int", what="the record an added/redone/skipped event is about"),
        text_column("port", 256),
        Column("baud", "1", kind="int"),
        text_column("device", 64),
        text_column("firmware", 64),
        text_column("channels", 256),
        Column("gain", per_channel(units, "/count"), shape=(k,), optional=True, what="calibration gain per channel"),
        Column("offset", per_channel(units), shape=(k,), optional=True, what="calibration offset per channel"),
        text_column("command_line", 1024),
        text_column("host_name", 128),
        text_column("operator", 128),
        Column("resumed", "1", kind="flag", what="1 when the session resumed the run, else 0"),
        Column("other_rig", "1", kind="flag", what="1 when resumed on another rig (--allow-other-rig)"),
        text_column("how", 16, "finished, quit, interrupted, rig lost, no input, ..."),
        text_column("note", 512),
    ]


def blob(
    parent: h5py.Group, name: str, dtype: str, chunk: int, units: str, what: str, filters: Mapping[str, Any] = FILTERS
) -> h5py.Dataset:
    ds = parent.create_dataset(name, shape=(0,), maxshape=(None,), dtype=dtype, chunks=(chunk,), **filters)
    put(ds, "units", units)
    put(ds, "long_name", what)
    return ds


def versions() -> dict[str, str]:
    return {
        "python": platform.python_version(),
        "numpy": np.__version__,
        "h5py": h5py.version.version,
        "hdf5": h5py.version.hdf5_version,
        "labcli": __version__,
    }


def command_line(argv: Sequence[str] | None = None) -> str:
    """The command that is running, its paths cut to their file names (no directories of this machine)."""
    argv = list(sys.argv if argv is None else argv)
    if not argv:
        return ""
    words = ["labcli"] if os.path.basename(argv[0]) in ("labcli", "__main__.py", "-m") else [os.path.basename(argv[0])]
    for a in argv[1:]:
        words.append(os.path.basename(a) if os.path.isabs(a) or os.sep in a and os.path.exists(a) else a)
    return stored_text(shlex.join(words))


def plan_columns(plan: Mapping[str, Sequence[Any]], id_column: str) -> tuple[list[Column], dict[str, Any]]:
    """Columns and values of a plan table (text, whole numbers or numbers, as the values are)."""
    from .h5 import column_units

    cols: list[Column] = []
    values: dict[str, Any] = {}
    for name, vals in plan.items():
        vals = list(vals)
        if vals and all(isinstance(v, (int, np.integer)) and not isinstance(v, bool) for v in vals):
            cols.append(Column(name, column_units(name, (id_column,)), kind="int"))
            values[name] = np.asarray(vals, dtype=np.int64)
            continue
        if not any(isinstance(v, str) for v in vals):
            try:
                values[name] = np.asarray([np.nan if v is None else float(v) for v in vals], dtype=np.float64)
            except (TypeError, ValueError):
                pass
            else:
                cols.append(Column(name, column_units(name, (id_column,)), optional=True))
                continue
        texts = ["" if v is None or (isinstance(v, float) and np.isnan(v)) else str(v) for v in vals]
        cols.append(text_column(name, max([len(t.encode("utf-8")) for t in texts] + [1])))
        values[name] = texts
    return cols, values


def _plan_table(e: h5py.Group, plan: Any, id_column: str) -> None:
    """The plan table (a DataFrame or a dict of columns), written and committed whole."""
    cols = plan.to_dict("list") if hasattr(plan, "to_dict") else dict(plan)
    pc, values = plan_columns(cols, id_column)
    n = len(next(iter(values.values()), []))
    t = Table.create(e, "plan", pc, chunk_rows=max(1, n))
    t.commit(t.write(t.prepared({c.name: c for c in pc}, values, n), n)[1])


def _record_table(e: h5py.Group, rt: RecordType, extras: Sequence[Column], chunk_rows: int) -> None:
    """The empty record table: a collection of columns (NXdata would ask a plot of each of them)."""
    Table.create(e, rt.collection, record_columns(rt, extras), chunk_rows)


def _root(f: h5py.File, path: str) -> None:
    """The root's attributes: NXroot's own terms (the file, its time, what wrote it)."""
    root = {
        "NX_class": "NXroot",
        "default": "entry",
        "file_name": stored_text(os.path.basename(path)),
        "file_time": utc_now(),
        "creator": "labcli",
        "creator_version": __version__,
        "HDF5_Version": h5py.version.hdf5_version,
        "h5py_version": h5py.version.version,
    }
    for key, value in root.items():
        put(f, key, value)


def initialise(
    f: h5py.File,
    *,
    path: str,
    protocol: Any,
    rt: RecordType,
    kind: str,
    channels: Sequence[str],
    device_info: Any,
    port: str,
    operator: str,
    plan: Any,
    imported: bool,
    source: str,
    started: str | None,
    command: str | None,
    chunk_rows: int,
    chunk_frames: int,
    extras: Sequence[Column],
    calibration: tuple[np.ndarray, np.ndarray, list[str]],
) -> None:
    """Build the structure of a new run in ``f`` (empty tables, metadata, protocol, plan)."""
    _root(f, path)
    e = f.create_group("entry")
    put(e, "NX_class", "NXentry")
    name = str(getattr(protocol, "name", ""))
    meta = {
        "title": f"{kind} run, protocol {name}" if name else f"{kind} run",
        "run_uid": str(uuid.uuid4()),
        "start_time": started or utc_now(),
        "program_name": "labcli",
        "program_version": __version__,
        "command_line": command_line() if command is None else command,
        "operator": str(operator or ""),
        "device": str(getattr(device_info, "device", "") or ""),
    }
    own = {
        "schema": SCHEMA,
        "schema_version": np.int64(SCHEMA_VERSION),
        "kind": kind,
        "protocol": name,
        "host_name": socket.gethostname(),
        "firmware": str(getattr(device_info, "firmware", "") or ""),
        "port": str(port or getattr(device_info, "port", "") or ""),
        "source": os.path.basename(str(source)),
        "channels": [stored_text(c) for c in channels],
        "imported": np.int8(bool(imported)),  # 0 or 1: HDF5 keeps a bool as an enum type other tools warn about
    }
    proto_path = getattr(protocol, "path", None)
    protocol_attrs = {
        "name": name,
        "kind": kind,
        "file_name": os.path.basename(str(proto_path)) if proto_path else "",
    }
    write_metadata(e, meta, own, str(getattr(protocol, "text", "")), protocol_attrs)
    v = e.create_group("versions")
    put(v, "NX_class", "NXcollection")
    for key, value in versions().items():
        put(v, key, value)
    if plan is not None:
        _plan_table(e, plan, rt.id_column)
    _record_table(e, rt, extras, chunk_rows)
    gain, offset, units = calibration
    raw = create_frames(e, channels, units, gain, offset, chunk_frames)
    Table.create(raw, UNUSED, UNUSED_COLUMNS, 16)
    default_plot(e)
    s = Table.create(e, "split", SPLIT_COLUMNS, 1)
    # The split's ids are a table's whole numbers (filters as its columns'), chunked as the records
    # are: an imported archive's split of 10^6 ids took 4,000 chunks of 256.
    ids_filters = {**TABLE_FILTERS, "shuffle": True}
    blob(s.g, "ids", "<i8", max(256, chunk_rows), "1", "fit ids, then validation ids, of each split", ids_filters)
    m = Table.create(e, "models", MODEL_COLUMNS, 1)
    blob(m.g, "json", "u1", 4096, "1", "each model's JSON as UTF-8 bytes")
    Table.create(e, "sessions", session_columns(len(channels), units), 1)
