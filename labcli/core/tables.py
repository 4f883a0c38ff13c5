"""The CSV exchange tables: the machinery every paper's tables share.

A table is described by plain data (:class:`TableSpec`: its columns, what each holds,
which are required); a paper declares its own (the McKibben trial, push and plan
tables, the rPAM point tables) and reads and writes them with :func:`read_table` and
:func:`write_table`.

Reading checks every cell and reports every problem at once, one per line, as
``file:row N, column C: message``, under a first line that counts them.  Rows
are numbered as a spreadsheet shows them: the header is row 1, the first data
row is row 2.  Unknown extra columns are kept (as numbers when every cell is a
number written canonically, else as text) and written back after the standard
columns.

Writing formats floats with ``repr`` (the shortest text that reads back to the
same float), so export -> import -> export is byte-identical, and checks the
table with the same rules as reading, so a written file always loads.
Files are replaced atomically: an interrupted export leaves the old file.
"""

from __future__ import annotations

import csv
import io
import math
import os
import re
from collections.abc import Callable, Iterable, Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any

from ..errors import ConfigError
from .bounds import PRESSURE_SPAN_MPA, QUANTITIES, fmt_number, number_problem, wrap_degrees
from .cells import INT64_MAX as _INT64_MAX
from .cells import NUMBER as _NUMBER
from .cells import TableSpec, infer_extra_column
from .files import atomic_write, check_input, read_input

if TYPE_CHECKING:  # pragma: no cover
    import pandas as pd

MAX_LISTED = 200  # problems shown in one message; the count in line one is always complete


class TableError(ConfigError):
    """A table failed its checks; ``.problems`` lists every ``file:row N, column C: message``."""

    def __init__(self, message: str, problems: list[str]) -> None:
        super().__init__(message)
        self.problems = problems


# ---------------------------------------------------------------------------
# Cell parsing: (value, problem or None)
# ---------------------------------------------------------------------------


def _parse_number(s: str) -> tuple[float | None, str | None]:
    t = s.strip()
    if t == "":
        return None, "is empty; a number is required"
    if not _NUMBER.fullmatch(t):
        return None, f"{_quote(s)} is not a number"
    v = float(t)
    if not math.isfinite(v):
        return None, f"{_quote(s)} is too large to be a finite number"
    return v, None


def _parse_cell(kind: str, s: str, span: tuple[float, float]) -> tuple[Any, str | None]:
    if kind == "id":
        t = s.strip()
        if re.fullmatch(r"[+-]?[0-9]+", t):
            # int() directly: going through float would round ids above 2**53.
            whole = int(t)
            return (whole, None) if abs(whole) <= _INT64_MAX else (None, f"{_quote(s)} is too large for an integer id")
        x, err = _parse_number(s)
        if err or x is None:
            return None, (err or "").replace("a number", "an integer id")
        if x != int(x) or abs(x) > _INT64_MAX:
            return None, f"{_quote(s)} is not an integer id"
        return int(x), None
    if kind in ("set", "set-required"):
        t = s.strip()
        if t in ("fit", "validation") or (t == "" and kind == "set"):
            return t, None
        if kind == "set":
            return None, f"{_quote(s)} must be fit, validation or empty (unassigned)"
        return None, f"{_quote(s)} must be fit or validation"
    if kind == "name":
        if s.strip() == "":
            return None, "is empty; an object name is required"
        return s, None
    if kind == "text":
        return s, None
    base = kind.removesuffix("-or-empty")
    if base != kind and s.strip() == "":
        return math.nan, None
    v, err = _parse_number(s)
    if err or v is None:
        return None, err
    err = number_problem(base, v, span)
    if err:
        return None, err
    q = QUANTITIES.get(base)
    return (wrap_degrees(v) if q is not None and q.wrap else v), None


def _quote(s: str) -> str:
    return repr(s if len(s) <= 40 else s[:37] + "...")


_fmt = fmt_number


# ---------------------------------------------------------------------------
# Reading
# ---------------------------------------------------------------------------


def _table_kind(spec: TableSpec | None) -> str:
    return "a plan" if spec is not None and spec.label.endswith("plan") else "a table"


def _records(path: Path, label: str, spec: TableSpec | None = None) -> list[list[str]]:
    try:
        raw = read_input(path, _table_kind(spec), label=label)
    except FileNotFoundError:
        raise ConfigError(f"{label} does not exist; check the path.") from None
    except IsADirectoryError:
        raise ConfigError(f"{label} is a folder, not a CSV file.") from None
    except OSError as exc:
        raise ConfigError(f"{label} cannot be read ({exc.strerror or exc}).") from None
    try:
        text = raw.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise ConfigError(
            f"{label} is not UTF-8 text (bad byte at offset {exc.start}); save it as CSV UTF-8."
        ) from None
    return _records_from_text(text, label)


def _records_from_text(text: str, label: str) -> list[list[str]]:
    out: list[list[str]] = []
    reader = csv.reader(io.StringIO(text, newline=""), strict=True)
    try:
        for rec in reader:
            out.append(rec)
    except csv.Error as exc:
        raise ConfigError(
            f"{label}:row {len(out) + 1}: not valid CSV ({exc}); check the quoting on that row."
        ) from None
    return out


class _Problems(list):
    """Every problem of a table, as ``file:row N, column C: message.``, in the order found."""

    def __init__(self, label: str) -> None:
        super().__init__()
        self.label = label
        self.cells: list[tuple[int, str | None, str]] = []  # (spreadsheet row, column, message)

    def add(self, row: int, col: str | None, msg: str) -> None:
        where = f"{self.label}:row {row}" + (f", column {col}" if col is not None else "")
        self.append(f"{where}: {msg}.")
        self.cells.append((row, col, msg))


def _parse_records(
    records: list[list[str]],
    spec: TableSpec,
    label: str,
    span: tuple[float, float],
    extra_checks: Any = None,
) -> pd.DataFrame:
    problems = _Problems(label)
    hrow, header, data = _header(records, spec, label)
    keep, pairs = _check_header(header, data, spec, hrow, problems)
    columns, n = _parse_rows(data, header, keep, pairs, spec, span, extra_checks, problems)
    if problems:
        raise table_error(label, list(problems))
    return _frame(spec, header, keep, columns, n)


def _header(
    records: list[list[str]], spec: TableSpec, label: str
) -> tuple[int, list[str], list[tuple[int, list[str]]]]:
    """The header (the first non-blank record), its row number, and the non-blank data rows numbered."""
    start = 0
    while start < len(records) and not any(c.strip() for c in records[start]):
        start += 1
    if start == len(records):
        raise ConfigError(
            f"{label} has no header row; the first line must name the columns "
            f"({', '.join(c for c, _, p in spec.columns if p == 'required')})."
        )
    header = [h.strip() for h in records[start]]
    data = [(i + 1, rec) for i, rec in enumerate(records) if i > start and any(c.strip() for c in rec)]
    return start + 1, header, data


def _check_header(
    header: list[str], data: list[tuple[int, list[str]]], spec: TableSpec, hrow: int, problems: _Problems
) -> tuple[list[int], list[tuple[str, str]]]:
    """The header positions that carry a column, and the column pairs present; problems noted."""
    keep: list[int] = []
    seen: dict[str, int] = {}
    for j, name in enumerate(header):
        if name == "":
            # A trailing separator (common in spreadsheet exports) makes an unnamed,
            # empty column: harmless; an unnamed column with values is not.
            if any(j < len(rec) and rec[j].strip() for _, rec in data):
                problems.add(hrow, f"{j + 1}", "has values but no name in the header")
            continue
        if name in seen:
            problems.add(hrow, name, f"appears twice in the header (columns {seen[name] + 1} and {j + 1})")
            continue
        seen[name] = j
        keep.append(j)
    for c, _, presence in spec.columns:
        if presence == "required" and c not in seen:
            hint = ""
            if len(header) == 1 and (";" in header[0] or "\t" in header[0]):
                hint = " (the header is one column: is the file separated by ';' or tabs instead of commas?)"
            problems.add(hrow, c, f"required column is missing from the header{hint}")
    pairs = []
    for a, b in spec.pairs:
        if (a in seen) != (b in seen):
            have, lack = (a, b) if a in seen else (b, a)
            problems.add(hrow, lack, f"is missing from the header but {have} is there; give both columns or neither")
        elif a in seen:
            pairs.append((a, b))
    return keep, pairs


def _parse_rows(
    data: list[tuple[int, list[str]]],
    header: list[str],
    keep: list[int],
    pairs: list[tuple[str, str]],
    spec: TableSpec,
    span: tuple[float, float],
    extra_checks: Any,
    problems: _Problems,
) -> tuple[dict[str, list[Any]], int]:
    """The values of every good row, by column; every bad cell noted."""
    kinds = {c: k for c, k, _ in spec.columns}
    ncols = len(header)
    columns: dict[str, list[Any]] = {header[j]: [] for j in keep}
    ids: dict[int, int] = {}
    n = 0
    for rownum, rec in data:
        if len(rec) != ncols:
            # Trailing empty cells beyond the header are harmless; values are not.
            if len(rec) > ncols and not any(c.strip() for c in rec[ncols:]):
                rec = rec[:ncols]
            else:
                problems.add(rownum, None, f"has {len(rec)} values but the header has {ncols} columns")
                continue
        values, ok = _parse_row(rownum, rec, header, keep, kinds, pairs, span, problems)
        idv = values.get(spec.id_column)
        if isinstance(idv, int):
            if idv in ids:
                problems.add(rownum, spec.id_column, f"{spec.id_column} {idv} is already used on row {ids[idv]}")
                ok = False
            else:
                ids[idv] = rownum
        if extra_checks is not None:
            for col, msg in extra_checks(values):
                problems.add(rownum, col, msg)
                ok = False
        if ok:
            for name in columns:
                columns[name].append(values[name])
            n += 1
    return columns, n


def _parse_row(
    rownum: int,
    rec: list[str],
    header: list[str],
    keep: list[int],
    kinds: dict[str, str],
    pairs: list[tuple[str, str]],
    span: tuple[float, float],
    problems: _Problems,
) -> tuple[dict[str, Any], bool]:
    """One row's values by column name (None where a cell is bad) and whether all were good."""
    values: dict[str, Any] = {}
    ok = True
    for j in keep:
        name = header[j]
        cell = rec[j]
        if name in kinds:
            v, err = _parse_cell(kinds[name], cell, span)
            if err:
                problems.add(rownum, name, err)
                ok = False
            values[name] = v
        else:
            values[name] = cell
    for a, b in pairs:
        va, vb = values[a], values[b]
        if va is None or vb is None:
            continue
        if math.isnan(va) != math.isnan(vb):
            missing, given = (a, b) if math.isnan(va) else (b, a)
            problems.add(rownum, missing, f"is empty but {given} is given; give both or neither")
            ok = False
    return values, ok


def _frame(spec: TableSpec, header: list[str], keep: list[int], columns: dict[str, list[Any]], n: int) -> pd.DataFrame:
    """The table: the spec's columns in order (absent ones empty), then the extra columns."""
    import pandas as pd

    kinds = {c: k for c, k, _ in spec.columns}
    frame: dict[str, Any] = {}
    for c, kind, _ in spec.columns:
        if c in columns:
            frame[c] = _standard_series(kind, columns[c])
        elif kind in ("set", "text"):
            frame[c] = pd.Series([""] * n, dtype=object)
        else:
            frame[c] = pd.Series([math.nan] * n, dtype="float64")
    for j in keep:
        name = header[j]
        if name not in kinds:
            frame[name] = infer_extra_column(columns[name])
    return pd.DataFrame(frame)


def table_error(label: str, problems: list[str]) -> TableError:
    """The TableError listing ``problems`` (``file:row N, column C: message.``) under their count."""
    n = len(problems)
    shown = problems[:MAX_LISTED]
    more = [f"... and {n - MAX_LISTED} more."] if n > MAX_LISTED else []
    head = (
        f"{label} has {n} problem{'s' if n != 1 else ''} "
        "(rows counted as a spreadsheet shows them, the header included):"
    )
    return TableError("\n".join([head, *shown, *more]), problems)


def _standard_series(kind: str, values: list[Any]) -> pd.Series:
    import pandas as pd

    if kind == "id":
        return pd.Series(values, dtype="int64")
    if kind in ("set", "set-required", "name", "text"):
        return pd.Series(values, dtype=object)
    return pd.Series(values, dtype="float64")


def _read(path: str | os.PathLike, spec: TableSpec, span: tuple[float, float], extra_checks=None):
    label = str(path)
    return _parse_records(_records(Path(path), label, spec), spec, label, span, extra_checks)


RowCheck = Callable[[dict[str, Any]], Iterable[tuple[str, str]]]


def read_table(
    path: str | os.PathLike,
    spec: TableSpec,
    *,
    span: tuple[float, float] = PRESSURE_SPAN_MPA,
    id_range: tuple[int, int] | None = None,
    check: RowCheck | None = None,
) -> pd.DataFrame:
    """Read and check a table of ``spec``; every problem in one :class:`TableError`.

    ``span`` bounds the "pressure" cells (MPa); ``id_range`` (low, high) also checks the
    ids, e.g. against what a run file can hold; ``check(row) -> [(column, problem), ...]``
    adds checks of its own (e.g. :func:`labcli.core.store.storable_cells`), reported by
    row and column like the others.  A check may carry ``screen(frame) -> bool``, whether
    any row of the whole table may fail it, so that a large good table need not be
    checked row by row.

    The table is read whole columns at a time (:mod:`labcli.core.table_fast`); a table
    that does not read cleanly that way is read again cell by cell, which names every
    problem.
    """
    from .table_fast import read_fast

    try:
        check_input(path, _table_kind(spec))  # a FIFO or a device refused before any reader waits on it
    except OSError:
        pass  # a missing file or a folder: the cell-by-cell reader's sentences
    else:
        fast = read_fast(path, spec, span, _screen(spec, id_range, check))
        if fast is not None:
            return fast
    return _read(path, spec, span, _row_checks(spec, id_range, check))


def _screen(
    spec: TableSpec, id_range: tuple[int, int] | None, check: RowCheck | None
) -> Callable[[pd.DataFrame], bool] | None:
    """Whether any row of a parsed table may fail ``id_range`` or ``check`` (whole columns where it can)."""
    if id_range is None and check is None:
        return None
    own = getattr(check, "screen", None)

    def screen(frame: pd.DataFrame) -> bool:
        if id_range is not None and spec.id_column in frame.columns:
            ids = frame[spec.id_column]
            if ((ids < id_range[0]) | (ids > id_range[1])).any():
                return True
        if check is None:
            return False
        if own is not None:
            return bool(own(frame))
        return any(True for row in frame.to_dict("records") for _ in check(row))

    return screen


def _row_checks(spec: TableSpec, id_range: tuple[int, int] | None, check: RowCheck | None) -> RowCheck | None:
    if id_range is None and check is None:
        return None

    def checks(values: dict[str, Any]) -> Iterable[tuple[str, str]]:
        if id_range is not None:
            lo, hi = id_range
            v = values.get(spec.id_column)
            if isinstance(v, int) and not lo <= v <= hi:
                yield spec.id_column, f"{v} is outside the {spec.label} ids a run file holds, {lo} to {hi}"
        if check is not None:
            yield from check(values)

    return checks


# ---------------------------------------------------------------------------
# Writing
# ---------------------------------------------------------------------------


def _format(v: Any, kind: str | None) -> str:
    import numpy as np
    import pandas as pd

    if v is None or v is pd.NA or v is pd.NaT:
        return ""
    if isinstance(v, str):
        return v
    if isinstance(v, np.generic):
        v = v.item()
    if isinstance(v, bool):
        return str(v)
    if isinstance(v, float):
        if math.isnan(v):
            return ""
        if kind == "id" and v == int(v) and math.isfinite(v):
            return str(int(v))
        return repr(v)
    if isinstance(v, int):
        if kind is not None and kind not in ("id", "set", "set-required", "name", "text"):
            return repr(float(v))
        return str(v)
    return str(v)


def _format_frame(df: pd.DataFrame, spec: TableSpec) -> tuple[list[str], list[list[str]]]:
    # Each column taken once, in order (the first of a repeated name, as df[name] gave it): looking
    # each up by name costs more than the formatting of a small table.
    names = [str(c) for c in df.columns]
    series: dict[str, list[Any]] = {}
    for name, (_, s) in zip(names, df.items(), strict=True):
        if name not in series:
            series[name] = s.tolist()
    return _format_columns(series, len(df), spec, names)


def _format_columns(
    series: Mapping[str, list[Any]], n: int, spec: TableSpec, names: list[str] | None = None
) -> tuple[list[str], list[list[str]]]:
    """The header and rows of text a table of ``n`` rows is written as (``series``: column -> its
    values; ``names``: the columns in order, a repeated one repeated, when not ``series``' keys)."""
    kinds = {c: k for c, k, _ in spec.columns}
    presence = {c: p for c, _, p in spec.columns}
    header = [c for c in spec.names if c in series or presence[c] != "omit-if-empty"]
    header += [c for c in (list(series) if names is None else names) if c not in kinds]
    cols = [[_format(v, kinds.get(c)) for v in series[c]] if c in series else [""] * n for c in header]
    # Optional columns that are empty throughout stay out of the file.
    drop = {c for c, _, p in spec.columns if p == "omit-if-empty" and c in header and not any(cols[header.index(c)])}
    keep = [i for i, c in enumerate(header) if c not in drop]
    rows = [[cols[i][r] for i in keep] for r in range(n)]
    return [header[i] for i in keep], rows


def frame_problems(
    df: pd.DataFrame, spec: TableSpec, span: tuple[float, float] = PRESSURE_SPAN_MPA
) -> list[tuple[int, str | None, str]]:
    """What the reader of ``spec`` would refuse in ``df``: (row index in ``df``, column, why), in order.

    The bounds of every table in one place: ``labcli export`` asks this of a run before
    writing its table, and the store (through :func:`columns_problems`, the same rules) of a
    record before writing it, so that what is stored is what may be exported and imported again.
    """
    return _problems(*_format_frame(df, spec), spec, span)


def columns_problems(
    columns: Mapping[str, Any], spec: TableSpec, span: tuple[float, float] = PRESSURE_SPAN_MPA
) -> list[tuple[int, str | None, str]]:
    """:func:`frame_problems` of the table whose columns are ``columns`` (name -> array or list of
    its values, all of one length), without making the DataFrame.

    The store checks every record it writes, one row at a time, and a one-row DataFrame costs
    more than the row's whole check; the cells are formatted and read by the same functions.
    """
    series = {str(k): v.tolist() if hasattr(v, "tolist") else list(v) for k, v in columns.items()}
    n = len(next(iter(series.values()))) if series else 0
    return _problems(*_format_columns(series, n, spec), spec, span)


def _problems(
    header: list[str], rows: list[list[str]], spec: TableSpec, span: tuple[float, float]
) -> list[tuple[int, str | None, str]]:
    problems = _Problems("")
    hrow, names, data = _header([header, *rows], spec, "")
    keep, pairs = _check_header(names, data, spec, hrow, problems)
    _parse_rows(data, names, keep, pairs, spec, span, None, problems)
    return [(row - hrow - 1, col, msg) for row, col, msg in problems.cells]


def write_table(
    df: pd.DataFrame, path: str | os.PathLike, spec: TableSpec, span: tuple[float, float] = PRESSURE_SPAN_MPA
) -> None:
    """Write a table of ``spec``: its columns in order, then the extras; checked as it would be read."""
    label = str(path)
    names = [str(c) for c in df.columns]
    dup = sorted({c for c in names if names.count(c) > 1})
    if dup:
        raise ConfigError(f"Cannot write {label}: the {spec.label} table has column {dup[0]} twice.")
    missing = [c for c, _, p in spec.columns if p == "required" and c not in names]
    if missing:
        raise ConfigError(f"Cannot write {label}: the {spec.label} table has no column {', '.join(missing)}.")
    header, rows = _format_frame(df, spec)
    # Check with the reader's rules, then write the canonical form of what was read.
    checked = _parse_records([header, *rows], spec, label, span)
    header, rows = _format_frame(checked, spec)
    text = "".join(_csv_line(r) for r in [header, *rows])
    try:
        data = text.encode("utf-8")
    except UnicodeEncodeError as exc:
        raise ConfigError(
            f"Cannot write {label}: the table holds text that is not valid Unicode ({exc.reason})."
        ) from None
    atomic_write(Path(path), data)


def _csv_line(fields: list[str]) -> str:
    # csv.writer with a "\n" terminator leaves a lone "\r" unquoted, which readers
    # then take for a line break; quote every field holding a separator, quote or
    # line break ourselves.
    return ",".join('"' + f.replace('"', '""') + '"' if any(ch in f for ch in ',"\r\n') else f for f in fields) + "\n"
