"""What a table says about itself: the unit of each column and where its rows came from.

``load_trials`` / ``load_pushes`` put both in the DataFrame's ``attrs``
(``attrs["units"]``: column -> unit, ``attrs["provenance"]``: run uid, protocol, device,
labcli version, source file, ... as far as the run file records them).  ``labcli export``
writes them beside a CSV as a sidecar ``<table>.csv.json`` in the Frictionless Table
Schema style (a tabular data resource: ``path``, ``schema.fields`` with ``name``, ``type``
and ``unit``, ``schema.primaryKey``, and the provenance under ``labcli``), so the CSV itself
stays the plain exchange table (header row, column names unchanged), and into a parquet
file's own key-value metadata.  A CSV read back finds its sidecar and gets the same attrs.
"""

from __future__ import annotations

import json
import os
from collections.abc import Mapping
from typing import Any

from ..errors import ConfigError, LabcliError
from .bounds import QUANTITIES
from .cells import TableSpec
from .files import read_input

SIDECAR_SUFFIX = ".json"  # t.csv -> t.csv.json
PARQUET_INSTALL = "pip install 'labcli[parquet]'"
# What a run file records about where its rows came from (v1 names; a later schema adds, never renames).
PROVENANCE_KEYS = (
    "run_uid",
    "uid",
    "protocol",
    "kind",
    "device",
    "firmware",
    "port",
    "operator",
    "started",
    "labcli_version",
    "versions",
    "command_line",
    "host",
    "imported",
    "source",
    "schema",
    "schema_version",
)


def unit_of(kind: str) -> str:
    """The unit a column of ``kind`` is written in ("" for ids, text and ratios)."""
    base = kind.removesuffix("-or-empty")
    if base == "pressure":
        return "MPa"
    q = QUANTITIES.get(base)
    return q.unit if q is not None else ""


def units(spec: TableSpec, columns: Any) -> dict[str, str]:
    """column -> unit for the spec's columns among ``columns`` (extras have no known unit: left out)."""
    present = set(columns)
    return {c: u for c, kind, _ in spec.columns if c in present and (u := unit_of(kind))}


def provenance(attrs: Mapping[str, Any], path: str | os.PathLike) -> dict[str, Any]:
    """The run's recorded origin (whatever of :data:`PROVENANCE_KEYS` it holds) and the file read."""
    out: dict[str, Any] = {"file": os.path.basename(os.fspath(path))}
    for key in PROVENANCE_KEYS:
        if key in attrs:
            out[key] = _plain(attrs[key])
    return out


def run_provenance(run: Any, path: str | os.PathLike) -> dict[str, Any]:
    """:func:`provenance` of an open run file, with its raw frames that belong to no record
    (``unused_frames``: frames per reason, :mod:`labcli.core.store.unused`) when it has any."""
    from .store.unused import counts

    out = provenance(run.attrs, path)
    unused = counts(run.windows.unused())
    if unused:
        out["unused_frames"] = unused
    return out


def _plain(v: Any) -> Any:
    """A JSON value from an HDF5 attribute (numpy scalars, arrays, bytes)."""
    if hasattr(v, "tolist"):
        v = v.tolist()
    if isinstance(v, bytes):
        return v.decode("utf-8", "replace")
    if isinstance(v, (list, tuple)):
        return [_plain(x) for x in v]
    return v


def describe(df: Any, spec: TableSpec, prov: Mapping[str, Any]) -> Any:
    """``df`` with ``attrs["units"]`` and ``attrs["provenance"]`` set; returned for chaining."""
    df.attrs["units"] = units(spec, df.columns)
    df.attrs["provenance"] = dict(prov)
    return df


# ------------------------------------------------------------------ the CSV sidecar


def _field_type(dtype: Any) -> str:
    kind = getattr(dtype, "kind", "O")
    return {"i": "integer", "u": "integer", "f": "number", "b": "boolean"}.get(kind, "string")


def sidecar(df: Any, spec: TableSpec, csv_path: str | os.PathLike, header: list[str] | None = None) -> dict[str, Any]:
    """The Frictionless tabular-data-resource description of ``df`` written as ``csv_path``.

    ``header``: the columns as the CSV has them (the writer puts the spec's columns first and
    leaves out empty optional ones); the fields follow it, as Frictionless checks them by position.
    """
    unit = df.attrs.get("units", {})
    names = [str(c) for c in df.columns]
    kinds = {c: kind for c, kind, _ in spec.columns}
    fields = []
    for name in names if header is None else header:
        if name in kinds:
            kind = kinds[name].removesuffix("-or-empty")
            typ = (
                "integer" if kind == "id" else "string" if kind in ("set", "set-required", "name", "text") else "number"
            )
        else:
            typ = _field_type(df[df.columns[names.index(name)]].dtype) if name in names else "string"
        field: dict[str, Any] = {"name": name, "type": typ}
        if unit.get(name):
            field["unit"] = unit[name]
        fields.append(field)
    return {
        "profile": "tabular-data-resource",
        "name": os.path.splitext(os.path.basename(os.fspath(csv_path)))[0].lower() or "table",
        "path": os.path.basename(os.fspath(csv_path)),
        "format": "csv",
        "encoding": "utf-8",
        "schema": {"fields": fields, "primaryKey": spec.id_column, "missingValues": [""]},
        "labcli": {"table": spec.label, "provenance": df.attrs.get("provenance", {})},
    }


def write_sidecar(df: Any, spec: TableSpec, csv_path: str | os.PathLike) -> str:
    """Write ``<csv_path>.json`` beside the CSV; returns its path."""
    from .files import atomic_write

    path = os.fspath(csv_path) + SIDECAR_SUFFIX
    meta = sidecar(df, spec, csv_path, header=csv_header(csv_path))
    atomic_write(path, (json.dumps(meta, indent=1) + "\n").encode("utf-8"))
    return path


def csv_header(csv_path: str | os.PathLike) -> list[str]:
    """The column names of a CSV file, as its first line has them."""
    import csv

    with open(csv_path, encoding="utf-8", newline="") as fh:
        return next(csv.reader(fh), [])


def read_sidecar(csv_path: str | os.PathLike) -> dict[str, Any] | None:
    """The provenance and units a CSV's sidecar gives (None without a readable one beside it)."""
    path = os.fspath(csv_path) + SIDECAR_SUFFIX
    try:
        meta = json.loads(read_input(path, "a table").decode("utf-8"))
        fields = meta["schema"]["fields"]
        return {
            "units": {f["name"]: f["unit"] for f in fields if f.get("unit")},
            "provenance": dict(meta.get("labcli", {}).get("provenance", {})),
        }
    except (OSError, ValueError, KeyError, TypeError, AttributeError, RecursionError, LabcliError):
        return None


# ------------------------------------------------------------------ parquet


def write_parquet(df: Any, path: str | os.PathLike) -> None:
    """``df`` as a parquet file, units and provenance in its key-value metadata (``labcli``)."""
    try:
        import pyarrow as pa
        import pyarrow.parquet as pq
    except ImportError:
        raise ConfigError(
            f"writing parquet needs pyarrow, which is not installed; install it with {PARQUET_INSTALL}."
        ) from None
    from .files import atomic_write

    table = pa.Table.from_pandas(df, preserve_index=False)
    meta = dict(table.schema.metadata or {})
    meta[b"labcli"] = json.dumps(
        {"units": df.attrs.get("units", {}), "provenance": df.attrs.get("provenance", {})}
    ).encode()
    table = table.replace_schema_metadata(meta)
    sink = pa.BufferOutputStream()
    pq.write_table(table, sink)
    atomic_write(path, sink.getvalue().to_pybytes())


def read_parquet(path: str | os.PathLike) -> Any:
    """A parquet table written by :func:`write_parquet`, its attrs restored."""
    import pandas as pd
    import pyarrow.parquet as pq

    table = pq.read_table(path)
    df = table.to_pandas()
    for c in df.columns:  # text as the CSV reader gives it (object), not pandas' string dtype
        if isinstance(df[c].dtype, pd.StringDtype):
            df[c] = df[c].astype(object)
    meta = (table.schema.metadata or {}).get(b"labcli")
    df.attrs = json.loads(meta) if meta else {}
    return df


# ------------------------------------------------------------------ load_trials / load_pushes


def read_run(path: str | os.PathLike, *, all_columns: bool = False) -> Any:
    """The record table of a run file of any kind (trials, pushes, an rPAM stand's records, a
    sensing session's estimates) as a DataFrame; ``attrs``: ``kind``, ``units``, ``provenance``.

    ``all_columns``: also what every record carries (when it began and was stored, how it was
    accepted, its flags, how each window settled), as ``labcli export --all-columns`` writes.
    """
    from .store import RunFile

    with RunFile.open(path) as run:
        records = run.record_type
        df = run.records.table(all_columns=all_columns)
        prov = run_provenance(run, path)
        kind = run.kind
    df = describe(df, records.table_spec, prov)
    df.attrs["kind"] = kind
    return df


def load_described(path: str | os.PathLike, kind: Any) -> Any:
    """The table of ``kind`` (a record type) from a run file or a CSV, with units and provenance in ``attrs``.

    From a run file the provenance is what the run records; from a CSV, what its sidecar
    says of the run it was exported from (``run_file``: that run's name), when there is one.
    """
    from .files import RUN_FILE_SUFFIXES
    from .store import RunFile

    name = os.path.basename(os.fspath(path))
    if os.fspath(path).lower().endswith(RUN_FILE_SUFFIXES):
        with RunFile.open(path) as run:
            df = run.records.table(kind)
            prov = run_provenance(run, path)
    else:
        df = kind.read_csv(path)
        prov = dict((read_sidecar(path) or {}).get("provenance", {}))
        if "file" in prov:
            prov["run_file"] = prov.pop("file")
        prov["file"] = name
    return describe(df, kind.table_spec, prov)
