"""A run file built from a table: ``labcli import`` (data from MATLAB, LabVIEW, a spreadsheet).

The protocol's kind decides the record type (:mod:`labcli.core.registry`), which reads the
CSV (:meth:`~labcli.core.experiment.RecordType.read_csv`) and turns each row into a record
(:meth:`~labcli.core.experiment.RecordType.from_row`); columns labcli does not know are
kept per record.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from typing import Any, Iterable, Mapping, Sequence

import numpy as np

from ...errors import ConfigError, StoreError
from ..protocol import load_protocol
from ..registry import import_protocol, record_type
from .h5 import nan_if_empty
from .runfile import MAX_ID, RunFile

NUL_PROBLEM = "holds a NUL character, which a run file cannot store; remove it"


def storable_cells(row: Mapping[str, Any]) -> Iterable[tuple[str, str]]:
    """(column, problem) for each cell of a table row that a run file cannot store.

    HDF5 keeps text as NUL-terminated strings: a NUL inside a text cell would cut it
    short (h5py refuses it outright).  Pass this to the table readers' ``check`` to
    have such cells reported by file, row and column.
    """
    for column, value in row.items():
        if isinstance(value, str) and "\x00" in value:
            yield str(column), NUL_PROBLEM


def _any_nul(frame: Any) -> bool:
    """Whether any text cell of a table holds a NUL (whole columns; the row check then names them)."""
    return any(frame[c].astype(str).str.contains("\x00", regex=False).any()
               for c in frame.columns if frame[c].dtype == object)


storable_cells.screen = _any_nul  # type: ignore[attr-defined]


def _extra_value(v: Any) -> Any:
    if isinstance(v, str):
        return v
    if isinstance(v, (int, np.integer)):
        return v
    return nan_if_empty(v)


def _check_storable(columns: Sequence[Any], rows: list[dict], id_col: str) -> None:
    """Refuse, before any file is made, a table holding text a run file cannot store."""
    for c in columns:
        if "\x00" in str(c):
            raise ConfigError(f"the column name {str(c)!r} holds a NUL character, which a run file cannot "
                              "store; rename the column.")
    for row in rows:
        for column, problem in storable_cells(row):
            raise ConfigError(f"{id_col} {row[id_col]}, column {column}: {problem}.")


def import_table(df: Any, path: str | os.PathLike, *, protocol: Any, force: bool = False, source: str = "",
                 operator: str = "") -> RunFile:
    """Build a run file without raw windows from a table (DataFrame) of ``protocol``'s records.

    ``protocol``: the protocol the run records with (its kind the run's, e.g. an rPAM
    protocol with its experiment chosen).  A table naming fit and validation sets (a trial
    table's ``set`` column) gives the split (strategy ``imported``).  The file is built
    beside ``path`` and moved into place only when whole, so a failed import leaves an
    existing file untouched.  Returns the run, open for reading.
    """
    path = os.fspath(path)
    if os.path.exists(path) and not force:
        raise StoreError(f"{path} already exists; use --force to overwrite it.")
    rt = record_type(str(getattr(protocol, "kind", "force")))
    rows = df.to_dict("records")
    extras = [c for c in df.columns if c not in rt.known_columns]
    seen: set[int] = set()
    for row in rows:
        rid = int(row[rt.id_column])
        if rid in seen:
            raise ConfigError(f"{rt.id_column} {rid} appears twice in the table; ids must be unique.")
        seen.add(rid)
    _check_storable(list(df.columns), rows, rt.id_column)
    fit, val = rt.import_split(rows)
    tmp = path + ".importing"
    run = RunFile.create(tmp, protocol=protocol, force=True, imported=True, source=source, operator=operator)
    run.sync_each_record = False  # the file only becomes the run once whole (os.replace below)
    try:
        for row in rows:
            record = rt.from_row(row, protocol)
            record.update(accepted="imported", ended="", extra={c: _extra_value(row[c]) for c in extras})
            run.write(record)
        if fit or val:
            run.set_split(fit, val, "imported")
        run.close()
        os.replace(tmp, path)
    except BaseException:
        run.close()
        os.unlink(tmp)
        raise
    return RunFile.open(path)


@dataclass(frozen=True)
class Imported:
    """What ``labcli import`` did: records imported, their type, the split they named."""

    n: int
    record_type: Any
    split: dict[str, Any] | None

    def sentence(self, table: str, output: str) -> str:
        split = "" if self.split is None else (f" (split: {len(self.split['fit'])} fit, "
                                               f"{len(self.split['validation'])} validation)")
        return f"Imported {self.record_type.count(self.n)} from {table} into {output}{split}."


def import_csv(table: str, output: str, *, protocol: str, experiment: str | None = None, operator: str = "",
               force: bool = False) -> Imported:
    """``labcli import``: read and check TABLE under ``protocol`` (its ``experiment``), build OUTPUT."""
    base = load_protocol(protocol)
    _, run_protocol = import_protocol(base, experiment, protocol)
    rt = record_type(run_protocol.kind)
    df = rt.read_csv(table, id_range=(0, MAX_ID), check=storable_cells)
    with import_table(df, output, protocol=run_protocol, force=force, source=os.path.basename(table),
                      operator=operator) as run:
        split = run.split()
    return Imported(len(df), rt, split)
