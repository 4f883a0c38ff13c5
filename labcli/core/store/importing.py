"""A run file built from a table: ``labcli import`` (data from MATLAB, LabVIEW, a spreadsheet).

The protocol's kind decides the record type (:mod:`labcli.core.registry`), which reads the
CSV (:meth:`~labcli.core.paper.RecordType.read_csv`) and turns the table into columns
(:meth:`~labcli.core.paper.RecordType.from_table`); columns labcli does not know are
kept as extra columns of the run's record table.
"""

from __future__ import annotations

import os
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from ...errors import ConfigError, StoreError
from ..files import check_output
from ..heap import kept_heap
from ..paper import Column
from ..protocol import load_protocol
from ..registry import import_protocol, record_type, untagged_run_kind
from ..words import count
from .h5 import h5_name, missing, nan_if_empty
from .layout import extra_column, extra_key, record_columns
from .records import ALL_COLUMNS
from .runfile import RunFile
from .split import Split
from .view import MAX_ID

NUL_PROBLEM = "holds a NUL character, which a run file cannot store; remove it"
CELL_BYTES = 16_384  # a text column is stored fixed-width, its type in a header HDF5 caps at 64 KB


def storable_cells(row: Mapping[str, Any]) -> Iterable[tuple[str, str]]:
    """(column, problem) for each cell of a table row that a run file cannot store.

    HDF5 keeps text as NUL-terminated strings: a NUL inside a text cell would cut it
    short (h5py refuses it outright).  Pass this to the table readers' ``check`` to
    have such cells reported by file, row and column.
    """
    for column, value in row.items():
        if isinstance(value, str) and "\x00" in value:
            yield str(column), NUL_PROBLEM
        elif isinstance(value, str) and len(value) > CELL_BYTES // 4 and len(value.encode("utf-8")) > CELL_BYTES:
            yield (
                str(column),
                f"holds {len(value.encode('utf-8'))} bytes of text, more than the {CELL_BYTES} a run file "
                "keeps in one cell; shorten it",
            )


def _any_nul(frame: Any) -> bool:
    """Whether any text cell of a table holds a NUL or is long (whole columns; the row check then names them).

    Each text column's distinct values are looked at, not its cells: a million rows of
    ``fit`` and ``validation`` are two strings to check, not a million to convert.
    """
    import pandas as pd

    for c in frame.columns:
        if pd.api.types.is_numeric_dtype(frame[c]) or pd.api.types.is_bool_dtype(frame[c]):
            continue
        distinct = pd.Series(pd.unique(frame[c]), dtype=object).astype(str)
        if distinct.str.contains("\x00", regex=False).any() or distinct.str.len().max() > CELL_BYTES // 4:
            return True
    return False


storable_cells.screen = _any_nul  # type: ignore[attr-defined]


def _extras(df: Any, names: Sequence[str]) -> tuple[list[Any], dict[str, Any]]:
    """The run-file columns and values of an imported table's columns labcli does not know."""
    columns: list[Column] = []
    values: dict[str, Any] = {}
    for name in names:
        raw = df[name].tolist()
        key = extra_key(str(name))
        c = extra_column(key, raw)
        columns.append(c)
        if c.kind == "text":
            values[key] = ["" if v is None or (isinstance(v, float) and np.isnan(v)) else str(v) for v in raw]
        elif c.kind == "int":
            values[key] = np.asarray(raw, dtype=np.int64)
        else:
            values[key] = np.asarray([nan_if_empty(v) for v in raw], dtype=np.float64)
    return columns, values


def _carried(df: Any) -> dict[str, Any]:
    """What every record carries, from the columns of an ``--all-columns`` export (times, how it was
    accepted, flags, settling), as the run file keeps it; empty cells read as not recorded."""
    out: dict[str, Any] = {}
    for c in ALL_COLUMNS:
        if c.name not in df.columns:
            continue
        raw = df[c.name].tolist()
        if c.kind == "text":
            out[c.name] = ["" if missing(v) else str(v) for v in raw]
        elif c.kind == "flag":
            out[c.name] = np.asarray([-1 if missing(v) else int(float(v)) for v in raw], dtype=np.int8)
        else:
            out[c.name] = np.asarray([nan_if_empty(v) for v in raw], dtype=np.float64)
    return out


# The record table's header keeps its column names in one attribute, whose bytes (names x the
# longest name) HDF5 holds to 64 KiB in the run file's format; the rest is the header's own room.
HEADER_ROOM = 60_000


def _check_header_room(rt: Any, extras: Sequence[Column], source: str) -> None:
    """Refuse, before any file is made, extra columns whose names the record table's header cannot hold."""
    names = [h5_name(c.name).encode("utf-8") for c in record_columns(rt, extras)]
    width = max(len(n) for n in names)
    if len(names) * width > HEADER_ROOM:
        fits = max(0, HEADER_ROOM // width - (len(names) - len(extras)))
        raise ConfigError(
            f"{source or 'the table'} has {len(extras)} columns labcli does not know, more than a run file's {rt.noun} "
            f"table can name ({fits} at the longest name's {width} bytes; {HEADER_ROOM} bytes of names in all); "
            "drop some or shorten their names, or keep them in a table beside the run."
        )


def _check_storable(df: Any, id_col: str) -> None:
    """Refuse, before any file is made, a table holding text a run file cannot store."""
    for c in df.columns:
        if "\x00" in str(c):
            raise ConfigError(
                f"the column name {str(c)!r} holds a NUL character, which a run file cannot store; rename the column."
            )
    if not _any_nul(df):
        return
    for c in df.columns:
        import pandas as pd

        if pd.api.types.is_numeric_dtype(df[c]) or pd.api.types.is_bool_dtype(df[c]):
            continue  # text columns are object or pandas' string dtype
        nul = df[c].map(lambda v: isinstance(v, str) and "\x00" in v).to_numpy(dtype=bool)
        if nul.any():
            rid = df[id_col].iloc[int(np.flatnonzero(nul)[0])]
            raise ConfigError(f"{id_col} {rid}, column {c}: {NUL_PROBLEM}.")


def import_table(
    df: Any, path: str | os.PathLike, *, protocol: Any, force: bool = False, source: str = "", operator: str = ""
) -> RunFile:
    """Build a run file without raw windows from a table (DataFrame) of ``protocol``'s records.

    ``protocol``: the protocol the run records with (its kind the run's, e.g. an rPAM
    protocol with its paper chosen).  A table naming fit and validation sets (a trial
    table's ``set`` column) gives the split (strategy ``imported``).  The records go in as
    one bulk commit (``run.records.append``) into a file built under a temporary name and
    put in place only when whole, so a failed or killed import leaves an existing file
    untouched (and the next start removes the temporary file).  Returns the run, open.
    """
    path = os.fspath(path)
    if os.path.lexists(path) and not force:
        raise StoreError(f"{path} already exists; use --force to overwrite it.")
    rt = record_type(str(getattr(protocol, "kind", "") or untagged_run_kind()))
    ids = df[rt.id_column]
    repeated = ids[ids.duplicated()]
    if len(repeated):
        raise ConfigError(f"{rt.id_column} {int(repeated.iloc[0])} appears twice in the table; ids must be unique.")
    _check_storable(df, rt.id_column)
    fit, val = rt.import_split(df)
    columns = {**rt.from_table(df, protocol), **_carried(df)}
    carried = {c.name for c in ALL_COLUMNS}
    extra_cols, extra_values = _extras(df, [c for c in df.columns if c not in rt.known_columns and c not in carried])
    _check_header_room(rt, extra_cols, source)
    run = RunFile.create(
        path,
        protocol=protocol,
        force=force,
        imported=True,
        source=source,
        operator=operator,
        extras=extra_cols,
        rows_hint=len(df),
        staged=True,
        command_line=None,
        exists_hint="use --force to overwrite it",
    )
    try:
        run.records.append({**columns, **extra_values})  # accepted: "imported", records.append's default
        if fit or val:
            run.split.set(fit, val, "imported")
        run.publish()
    except BaseException:
        run.discard()
        raise
    return run


@dataclass(frozen=True)
class Imported:
    """What ``labcli import`` did: records imported, their type, the split they named."""

    n: int
    record_type: Any
    split: Split | None
    captures: int = 1  # the protocol's captures_per_load: above 1, each row is a capture of a load

    def sentence(self, table: str, output: str) -> str:
        split = (
            ""
            if self.split is None
            else (f" (split: {len(self.split['fit'])} fit, {len(self.split['validation'])} validation)")
        )
        what = self.record_type.count(self.n) if self.captures == 1 else count(self.n, "capture")
        return f"Imported {what} from {table} into {output}{split}."


def import_csv(
    table: str, output: str, *, protocol: str, experiment: str | None = None, operator: str = "", force: bool = False
) -> Imported:
    """``labcli import``: read and check TABLE under ``protocol`` (its ``experiment``), build OUTPUT."""
    # A run file in OUTPUT's place is the import's business (replaced only with force, never while written).
    check_output(output, inputs=(table, protocol), replaces_runs=True)
    base = load_protocol(protocol)
    _, run_protocol = import_protocol(base, experiment, protocol)
    rt = record_type(run_protocol.kind)
    with kept_heap():  # the table's columns read, converted and written: arrays of 8-40 MB each
        df = rt.read_csv(table, id_range=(0, MAX_ID), check=storable_cells)
        with import_table(
            df, output, protocol=run_protocol, force=force, source=os.path.basename(table), operator=operator
        ) as run:
            split = run.split.get()
    return Imported(len(df), rt, split, run_protocol.air.captures_per_load)
