"""A run's table written in the format its file name asks for: CSV, parquet, Excel or MATLAB.

=========  ====================================================================================
``.csv``   the exchange table, and beside it ``OUTPUT.json``, its Frictionless description
           (:mod:`.table_meta`); ``labcli import`` reads it back
``.parquet``  the same table, units and provenance in the file's key-value metadata (pyarrow:
           ``pip install 'labcli[parquet]'``)
``.xlsx``  an Excel workbook: the table on its first sheet under a row of units, and a
           "provenance" sheet saying where the rows came from (openpyxl:
           ``pip install 'labcli[xlsx]'``)
``.mat``   a MATLAB file (scipy): a struct named as the table (``trials``, ``pushes``,
           ``points``) with a field per column, ``units`` and ``provenance`` structs beside
           it; ``load('run.mat')`` in MATLAB or Octave, ``scipy.io.loadmat`` in Python
=========  ====================================================================================

Every format holds the same values (text as text, numbers as float64 or int64, missing
numbers as NaN); the DataFrame's ``attrs`` give the units and the provenance.
"""

from __future__ import annotations

import io
import os
import re
from collections.abc import Callable, Mapping
from typing import Any

from ..errors import ConfigError
from . import table_meta
from .cells import TableSpec
from .files import atomic_write

XLSX_INSTALL = "pip install 'labcli[xlsx]'"
EXTENSIONS = {".csv": "csv", ".parquet": "parquet", ".pq": "parquet", ".xlsx": "xlsx", ".mat": "mat"}
FORMATS = ("csv", "parquet", "xlsx", "mat")


def format_of(output: str, fmt: str | None) -> str:
    """The format to write ``output`` in: ``fmt`` when given, else its extension's (ConfigError when unknown)."""
    if fmt is not None:
        return fmt
    ext = os.path.splitext(output)[1].lower()
    if ext not in EXTENSIONS:
        what = f"the extension {ext}, which names no format labcli writes" if ext else "no extension to name its format"
        raise ConfigError(f"{output} has {what}; end it in .csv, .parquet, .xlsx or .mat, or give --format.")
    return EXTENSIONS[ext]


def check_exportable(df: Any, spec: TableSpec, run: str) -> None:
    """ConfigError, naming the run and the record, when a record breaks the table's bounds.

    The store refuses such a record (:func:`labcli.core.tables.frame_problems`); a run written
    before it did may still hold one, and the message must name that run, not a table
    that has not been written.
    """
    from .tables import frame_problems

    problems = frame_problems(df[[c for c in df.columns if c in spec.names]], spec)
    if problems:
        i, col, msg = problems[0]
        rid = df[spec.id_column].iloc[i] if 0 <= i < len(df) else "?"
        more = f" ({len(problems)} values in all)" if len(problems) > 1 else ""
        raise ConfigError(
            f"{run}: {spec.id_column} {rid}, column {col}: {msg}{more}, which a {spec.label} table cannot hold, "
            f"so the run cannot be exported; that reading is not physical: record the {spec.label} again."
        )


def write(
    df: Any, spec: TableSpec, name: str, output: str, fmt: str, csv_writer: Callable[[Any, str], None]
) -> list[str]:
    """Write ``df`` (attrs: units, provenance) as ``output`` in ``fmt``; the files written.

    ``name``: the table's name (``trials``: the sheet, the MATLAB struct); ``csv_writer``: the
    record type's CSV writer (:meth:`~labcli.core.paper.RecordType.write_csv`).
    """
    if fmt == "csv":
        csv_writer(df, output)
        return [output, table_meta.write_sidecar(df, spec, output)]
    if fmt == "parquet":
        table_meta.write_parquet(df, output)
    elif fmt == "xlsx":
        write_xlsx(df, name, output)
    elif fmt == "mat":
        write_mat(df, name, output)
    else:
        raise ConfigError(f"labcli writes tables as {', '.join(FORMATS)}, not {fmt!r}.")
    return [output]


# ------------------------------------------------------------------ Excel


def _cell(v: Any) -> Any:
    """A value as a spreadsheet cell: numbers as numbers, NaN as an empty cell, numpy scalars as Python's."""
    if hasattr(v, "item"):
        v = v.item()
    if isinstance(v, float) and v != v:
        return None
    return v


def write_xlsx(df: Any, name: str, output: str) -> None:
    """``df`` as a workbook: the table (names, then units, then one row per record) and its provenance."""
    try:
        from openpyxl import Workbook
        from openpyxl.styles import Font
    except ImportError:
        raise ConfigError(
            f"writing .xlsx needs openpyxl, which is not installed; install it with {XLSX_INSTALL}."
        ) from None
    units = df.attrs.get("units", {})
    wb = Workbook()
    ws = wb.active
    ws.title = name[:31]
    ws.append([str(c) for c in df.columns])
    ws.append([units.get(str(c), "") for c in df.columns])
    for cell in ws[1]:
        cell.font = Font(bold=True)
    for cell in ws[2]:
        cell.font = Font(italic=True)
    ws.freeze_panes = "A3"  # names and units stay in view
    for row in df.itertuples(index=False, name=None):
        ws.append([_cell(v) for v in row])
    prov = wb.create_sheet("provenance")
    prov.append(["key", "value"])
    for key, value in _flat(df.attrs.get("provenance", {})).items():
        prov.append([key, value])
    buf = io.BytesIO()
    wb.save(buf)
    atomic_write(output, buf.getvalue())


def _flat(d: Mapping[str, Any], prefix: str = "") -> dict[str, str]:
    """Nested provenance as one key per line (``versions.numpy``), values as text."""
    out: dict[str, str] = {}
    for k, v in d.items():
        if isinstance(v, Mapping):
            out.update(_flat(v, f"{prefix}{k}."))
        else:
            out[f"{prefix}{k}"] = (
                ", ".join(map(str, v)) if isinstance(v, (list, tuple)) else ("" if v is None else str(v))
            )
    return out


# ------------------------------------------------------------------ MATLAB

_MATLAB_NAME = re.compile(r"[A-Za-z][A-Za-z0-9_]{0,62}")


def matlab_name(name: str) -> str:
    """``name`` as a MATLAB field name (letters, digits, underscores; a letter first; at most 63)."""
    if _MATLAB_NAME.fullmatch(name):
        return name
    fixed = re.sub(r"[^A-Za-z0-9_]", "_", name)
    return ("x" + fixed if not fixed[:1].isalpha() else fixed)[:63]


def _mat_value(values: Any) -> Any:
    import numpy as np

    a = np.asarray(values)
    if a.dtype.kind in "iufb":
        return a.astype(np.float64) if a.dtype.kind == "b" else a
    return np.array(["" if v is None or (isinstance(v, float) and v != v) else str(v) for v in a], dtype=object)


def write_mat(df: Any, name: str, output: str) -> None:
    """``df`` as a MATLAB (v5) file: a struct of columns, and ``units`` and ``provenance`` structs."""
    import scipy.io

    names = [matlab_name(str(c)) for c in df.columns]
    twice = sorted({n for n in names if names.count(n) > 1})
    if twice:
        raise ConfigError(
            f"two columns become the MATLAB name {twice[0]}; rename one of them before exporting to .mat."
        )
    units = df.attrs.get("units", {})
    table = {n: _mat_value(df[c].to_numpy()) for n, c in zip(names, df.columns, strict=True)}
    contents = {
        matlab_name(name): table,
        "units": {n: units.get(str(c), "") for n, c in zip(names, df.columns, strict=True)},
        "columns": _mat_value([str(c) for c in df.columns]),  # a cell array: each name as written
        "provenance": {matlab_name(k): v for k, v in _flat(df.attrs.get("provenance", {})).items()},
    }
    buf = io.BytesIO()
    scipy.io.savemat(buf, contents, long_field_names=True, do_compression=True, oned_as="column")
    atomic_write(output, buf.getvalue())
