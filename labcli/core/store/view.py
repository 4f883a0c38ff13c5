"""The records of a run as columns, from either schema, checked before anything uses them.

:func:`from_v2` reads the record table (rows checked against their checksums, :mod:`.columns`);
:func:`from_v1` gathers the groups of a version-1 file (:mod:`.v1`).  Both give a
:class:`RecordColumns`: ids in recording order, every column as an array over them, and the
records found damaged with the reason, which include values outside the physical range the
record type declares for a column (:func:`out_of_bounds`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..paper import Column, RecordType
from .columns import Table, fill_value
from .layout import common_columns, extra_key, window_columns

MAX_ID = 999_999


@dataclass
class RecordColumns:
    """The good records of a run: ids, columns (text as str), and where each came from."""

    ids: list[int]
    cols: dict[str, np.ndarray]
    sources: list[Any]  # table row (schema 2) or the group's row (schema 1), per record
    damaged: list[tuple[str, str]] = field(default_factory=list)  # (what, why)
    incomplete: list[int] = field(default_factory=list)
    extras: list[str] = field(default_factory=list)

    def position(self, rid: int) -> int | None:
        if not hasattr(self, "_pos"):
            self._pos = {r: i for i, r in enumerate(self.ids)}
        return self._pos.get(int(rid))


def decode(values: np.ndarray) -> np.ndarray:
    """Fixed-length UTF-8 bytes as an object array of str."""
    if values.dtype.kind != "S":
        return values
    strings = getattr(np, "strings", None)
    decoded = strings.decode(values, "utf-8") if strings is not None else np.char.decode(values, "utf-8")
    return decoded.astype(object)


def _describe(c: Column, j: int | None) -> str:
    what = c.what or c.name
    if j is not None and c.components:
        return f"{what} ({c.components[j]})"
    return what


def out_of_bounds(columns: Sequence[Column], cols: dict[str, np.ndarray]) -> dict[int, str]:
    """Record index -> the first value outside its column's physical range (or not finite when required)."""
    bad: dict[int, str] = {}
    for c in columns:
        if c.kind not in ("float", "int") or c.name not in cols:
            continue
        v = np.asarray(cols[c.name], dtype=np.float64)
        n = v.shape[0]
        if n == 0:
            continue
        flat = v.reshape(n, -1)
        finite = np.isfinite(flat)
        problem = np.zeros(flat.shape, dtype=bool) if c.optional else ~finite
        if c.bounds is not None:
            lo, hi = c.bounds
            with np.errstate(invalid="ignore"):
                problem |= finite & ((flat < lo) | (flat > hi))
        for i, j in zip(*np.nonzero(problem), strict=False):
            if int(i) in bad:
                continue
            x = flat[i, j]
            where = _describe(c, int(j) if flat.shape[1] > 1 else None)
            units = f" {c.units}" if c.units not in ("", "1") else ""
            if not math.isfinite(x):
                bad[int(i)] = f"{where} is {x}, not a number it can hold"
            elif c.bounds is not None:
                lo, hi = c.bounds
                bad[int(i)] = f"{where} reads {x:.6g}{units}, outside the physically possible {lo:g} to {hi:g}{units}"
    return bad


def _keep(records: RecordColumns, keep: np.ndarray) -> None:
    records.ids = [i for i, k in zip(records.ids, keep, strict=False) if k]
    records.sources = [s for s, k in zip(records.sources, keep, strict=False) if k]
    records.cols = {name: v[keep] for name, v in records.cols.items()}


def check(records: RecordColumns, rt: RecordType, noun: str) -> RecordColumns:
    """Leave out (and name) records whose values cannot be right: out of range, bad ids, repeated ids."""
    n = len(records.ids)
    if not n:
        return records
    problems = out_of_bounds(rt.columns, records.cols)
    seen: dict[int, int] = {}
    for i, rid in enumerate(records.ids):
        if not 0 <= rid <= MAX_ID:
            problems.setdefault(i, f"its id {rid} is outside 0 to {MAX_ID}")
        elif rid in seen:
            problems.setdefault(i, f"{noun} {rid} is stored twice")
        seen.setdefault(rid, i)
    if problems:
        records.damaged += [(f"{noun} {records.ids[i]}", why) for i, why in sorted(problems.items())]
        _keep(records, np.array([i not in problems for i in range(n)]))
    return records


def from_v2(t: Table, rt: RecordType) -> RecordColumns:
    """The committed records of a version-2 record table, checked."""
    rows = t.read()
    ids = [int(i) for i in rows.cols[rt.id_column]]
    cols = {name: decode(v) for name, v in rows.cols.items()}
    damaged = [(_row_name(t, rt, r), why) for r, why in rows.damaged]
    known = {c.name for c in (*common_columns(rt.id_column), *rt.columns, *window_columns())}
    extras = [name for name in t.names if name not in known]
    stored = t.stored()
    tail = t.read(want=[rt.id_column], span=(t.committed, stored)) if stored > t.committed else None
    incomplete = sorted({int(i) for i in tail.cols[rt.id_column]} - set(ids)) if tail is not None else []
    return check(RecordColumns(ids, cols, [int(r) for r in rows.rows], damaged, incomplete, extras), rt, rt.noun)


def _row_name(t: Table, rt: RecordType, r: int) -> str:
    """A damaged row as messages name it: its position, and the record its id says it holds."""
    if r < 0:
        return f"the {rt.plural} table"
    try:
        rid = int(t.ds[rt.id_column][r])
    except (OSError, ValueError, RuntimeError, IndexError, KeyError):
        return f"row {r}"
    return f"row {r}, {rt.noun} {rid} by its id" if 0 <= rid <= MAX_ID else f"row {r}"


def from_v1(backend: Any, rt: RecordType) -> RecordColumns:
    """The complete records of a version-1 file, gathered into columns and checked."""
    ids, rows, damaged, incomplete, extras = backend.records()
    columns = [*common_columns(rt.id_column), *rt.columns, *window_columns()]
    cols: dict[str, np.ndarray] = {}
    for c in columns:
        values = [row.get(c.name) for row in rows]
        if c.kind == "text":
            cols[c.name] = np.array(["" if v is None else str(v) for v in values], dtype=object).reshape(len(rows))
        else:
            fill = fill_value(c)
            cols[c.name] = np.array(
                [np.full(c.shape, fill) if v is None else v for v in values], dtype=c.dtype
            ).reshape(len(rows), *c.shape)
    for name in extras:
        values = [row.get("extra", {}).get(name, math.nan) for row in rows]
        cols[extra_key(name)] = np.array(values, dtype=object)
    named = [(f"{rt.noun} {rid}", why) for rid, why in damaged]
    return check(RecordColumns(ids, cols, rows, named, incomplete, [extra_key(n) for n in extras]), rt, rt.noun)
