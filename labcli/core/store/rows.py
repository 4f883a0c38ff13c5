"""Records to rows and back: what the record table of a run file holds for each record.

A record (what a session commits, or an imported table row) becomes one row of the run's
record table: the id, the record type's columns (:meth:`labcli.core.paper.RecordType.check`),
what every record carries (times, how it was accepted, flags, how each window settled) and
an imported table's extra columns.  Everything is checked here, before anything is written:
a record that cannot be stored is refused in one sentence naming it.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any, cast

import numpy as np

from ...errors import StoreError
from ..files import stored_text
from ..paper import Column, RecordType
from ..record import ACCEPTED, Settle
from ..timestamps import utc_now
from .columns import fill_value, fixed
from .h5 import settle_attrs
from .layout import WINDOWS
from .view import MAX_ID, out_of_bounds
from .windows import WINDOW_GROUPS

SETTLE_NUMBERS = ("settle_time_s", "waited_s", "pressure_spread_MPa", "angle_spread_rad")
SETTLE_TEXTS = ("criterion", "accepted")


def record_id(record: Mapping[str, Any], what: str) -> tuple[int, str]:
    """The id of a ``what`` ("trial", "push", "point") record and its label for messages."""
    if what not in record:
        raise StoreError(f"{what} record lacks '{what}' (the {what} id).")
    rid = int(record[what])
    label = f"{what} {rid}"
    if not 0 <= rid <= MAX_ID:
        raise StoreError(f"{label}: {what} ids must be between 0 and {MAX_ID}.")
    return rid, label


def record_row(
    rt: RecordType,
    columns: Mapping[str, Column],
    record: Mapping[str, Any],
    label: str,
    rid: int,
    run: Any,
    table_check: bool = True,
) -> dict[str, Any]:
    """Every column of one record but its windows' frames, checked before anything is written.

    ``table_check``: False when the caller checks a batch's rows against the table at once
    (:func:`exportable`)."""
    row = dict(rt.check(record, label, run))
    settle = record.get("settle") or {}
    windows = {WINDOW_GROUPS[k]: v for k, v in settle.items() if k in WINDOW_GROUPS}
    load = settle_attrs(windows.get("loaded"))
    accepted = str(record.get("accepted", load.get("accepted", "auto" if record.get("raw") else "imported")))
    if accepted not in ACCEPTED:
        raise StoreError(f"{label} record: 'accepted' must be one of {', '.join(ACCEPTED)}, got {accepted!r}.")
    row.update(
        {
            rt.id_column: rid,
            "started": str(record.get("started", "") or ""),
            "ended": str(record.get("ended", "") or utc_now()),
            "accepted": accepted,
            "flags": joined_flags(record.get("flags"), label),
        }
    )
    for name in WINDOWS:
        s: Mapping[str, Any] = settle_attrs(windows.get(name))
        row[f"{name}_settled"] = -1 if "settled" not in s else int(s["settled"])
        for key in (*SETTLE_NUMBERS, *SETTLE_TEXTS):
            if key in s:
                row[f"{name}_{key}"] = s[key]
    extra = record.get("extra") or {}
    unknown = [k for k in extra if k not in columns or k in row]
    if unknown:
        raise StoreError(f"{label} record: the run file has no column {unknown[0]!r} for it.")
    row.update(extra)
    _texts_fit(columns, row, label)
    if not _plainly_in_bounds(rt.columns, row):  # the sentence from the same check as a read's
        bad = out_of_bounds(
            rt.columns,
            {c.name: np.asarray([row[c.name]]) for c in rt.columns if c.name in row and c.kind in ("float", "int")},
        )
        if bad:
            raise StoreError(f"{label} record: {bad[0]}.")
    if table_check:
        exportable(rt, [row], [rid], [label], run)
    return row


def _plainly_in_bounds(cols: Sequence[Column], row: Mapping[str, Any]) -> bool:
    """Whether one row's numbers pass :func:`~.view.out_of_bounds` (finite where required, within
    bounds where finite), judged value by value: for one row, a tenth of the time of the arrays."""
    for c in cols:
        if c.kind not in ("float", "int") or c.name not in row:
            continue
        v = row[c.name]
        values = np.ravel(v).tolist() if isinstance(v, (np.ndarray, list, tuple)) else [v]
        for x in values:
            try:
                x = float(x)
            except (TypeError, ValueError):
                return False  # not a number: the array check says what it is
            if not math.isfinite(x):
                if not c.optional:
                    return False
            elif c.bounds is not None and not c.bounds[0] <= x <= c.bounds[1]:
                return False
    return True


def exportable(
    rt: RecordType, rows: Sequence[Mapping[str, Any]], ids: Sequence[int], labels: Sequence[str], run: Any
) -> None:
    """StoreError unless the records' rows of the exchange table pass that table's own bounds.

    The run file's column bounds are wide (they catch a changed file); the table's are the
    physics of the bench.  A record outside them would be stored and then refused by
    ``labcli export``, so it is refused here, before anything is written.  A batch (the
    estimates ``labcli sense --record`` commits each second) is checked as one table.
    """
    from ..tables import columns_problems, frame_problems

    spec = getattr(rt, "table_spec", None)
    if spec is None or not getattr(rt, "table_checked", True) or not rows:
        return
    cols = {
        c.name: np.asarray(
            [r[c.name] if c.name in r else np.full(c.shape, fill_value(c), dtype=object) for r in rows],
            dtype=object if c.kind == "text" or any(c.name not in r for r in rows) else None,
        )
        for c in rt.columns
    }
    # The table's columns without the DataFrame when the record type gives them (the same cells,
    # checked by the same reader; a one-row frame costs more than the rest of the check).
    columns = getattr(rt, "table_columns", None)
    if columns is not None:
        problems = columns_problems(columns(run, list(ids), cols), spec)
    else:
        problems = frame_problems(rt.table(run, list(ids), cols), spec)
    if problems:
        at, col, msg = problems[0]
        where = f"column {col}: " if col else ""
        raise StoreError(
            f"{labels[at]} was not stored: {where}{msg}, which a {spec.label} table cannot hold "
            "(the rig or its link is not measuring)."
        )


def _texts_fit(columns: Mapping[str, Column], values: Mapping[str, Any], label: str) -> None:
    for name, v in values.items():
        c = columns.get(name)
        if c is None or c.kind != "text" or v is None:
            continue
        size = len(stored_text(str(v)).encode("utf-8"))
        if size > c.width:
            raise StoreError(
                f"{label} record: '{name}' is {size} bytes of text; a run file keeps at most "
                f"{c.width} there, so shorten it."
            )


def joined_flags(flags: Any, label: str) -> str:
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


def settle_of(row: Mapping[str, Any], name: str) -> Settle:
    """How window ``name`` ("baseline", "loaded") of a stored row settled; {} when not recorded."""
    s: dict[str, Any] = {}
    settled = int(row.get(f"{name}_settled", -1))
    if settled >= 0:
        s["settled"] = bool(settled)
    for key in SETTLE_NUMBERS:
        v = float(row.get(f"{name}_{key}", math.nan))
        if math.isfinite(v):
            s[key] = v
    for key in SETTLE_TEXTS:
        t = str(row.get(f"{name}_{key}", ""))
        if t:
            s[key] = t
    return cast(Settle, s)  # the keys above are Settle's


def bulk_values(
    rt: RecordType, columns: Mapping[str, Column], given: Mapping[str, Any], ids: np.ndarray, done: set[int], path: str
) -> dict[str, Any]:
    """Many records given as columns (``labcli import``), checked whole and made ready to write.

    ``done``: the ids already complete in the file (refused: a stored record is never overwritten).
    """
    what = rt.id_column
    n = ids.shape[0]
    _check_ids(what, ids, done, path)
    unknown = [k for k in given if k not in columns]
    if unknown:
        raise StoreError(f"the run file has no column {unknown[0]!r}.")
    values: dict[str, Any] = {}
    for name, v in given.items():
        c = columns[name]
        values[name] = _texts(c, v, n, ids, what) if c.kind == "text" else fixed(c, v, n)
    missing = [c.name for c in rt.columns if not c.optional and c.name not in values]
    if missing:
        raise StoreError(f"the records lack the column {missing[0]!r}.")
    bad = out_of_bounds(rt.columns, {c.name: values[c.name] for c in rt.columns if c.name in values})
    if bad:
        i = min(bad)
        raise StoreError(f"{what} {int(ids[i])}: {bad[i]}.")
    values.setdefault("ended", np.full(n, utc_now().encode(), dtype=columns["ended"].dtype))
    if "accepted" not in values:
        values["accepted"] = np.full(n, b"imported", dtype=columns["accepted"].dtype)
    return values


def _check_ids(what: str, ids: np.ndarray, done: set[int], path: str) -> None:
    if len(ids) and (ids.min() < 0 or ids.max() > MAX_ID):
        bad = int(ids[(ids < 0) | (ids > MAX_ID)][0])
        raise StoreError(f"{what} {bad}: {what} ids must be between 0 and {MAX_ID}.")
    # A sort, not np.unique: numpy 2 hashes, several times slower on a million ids.  Sorted, the
    # first repeated (or stored) id is the smallest, as a check id by id in order would name it.
    ordered = np.sort(ids)
    twice = ordered[1:][ordered[1:] == ordered[:-1]]
    if len(twice):
        raise StoreError(f"{what} {int(twice[0])} appears twice; ids must be unique.")
    if done:
        already = ordered[np.isin(ordered, np.fromiter(done, dtype=np.int64, count=len(done)))]
        if len(already):
            raise StoreError(
                f"{what} {int(already[0])} is already complete in {path}; a stored record is never overwritten."
            )


def _texts(c: Column, v: Any, n: int, ids: np.ndarray, what: str) -> np.ndarray:
    """A text column's values as the fixed-width bytes it stores, refused when one is too long."""
    arr = np.asarray(v, dtype=object).reshape(n)
    enc = [x if isinstance(x, bytes) else stored_text("" if x is None else str(x)).encode("utf-8") for x in arr]
    longest = max((len(x) for x in enc), default=0)
    if longest > c.width:
        i = next(i for i, x in enumerate(enc) if len(x) == longest)
        raise StoreError(
            f"{what} {int(ids[i])}: '{c.name}' is {longest} bytes of text; a run file keeps "
            f"at most {c.width} there, so shorten it."
        )
    return np.array(enc, dtype=c.dtype)
