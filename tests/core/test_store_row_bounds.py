"""A record's numbers are judged value by value before it is written, as the arrays' check judges them.

The store refuses a record holding a value no rig can produce (out of its column's physical
bounds, or not finite where it must be) before anything is written.  One row is judged value by
value (:func:`labcli.core.store.rows._plainly_in_bounds`); only a row that fails is handed to the
arrays' check (:func:`labcli.core.store.view.out_of_bounds`) for its sentence.  Both must give the
same verdict on every row, including the edges of each range, NaN, infinities and optional columns.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from labcli.core.registry import record_type
from labcli.core.store.rows import _plainly_in_bounds
from labcli.core.store.view import out_of_bounds


def verdict_of_arrays(cols, row) -> bool:
    arrays = {c.name: np.asarray([row[c.name]]) for c in cols if c.name in row and c.kind in ("float", "int")}
    return not out_of_bounds(cols, arrays)


def special_values(c) -> list[float]:
    out = [math.nan, math.inf, -math.inf, 0.0]
    if c.bounds is not None:
        lo, hi = c.bounds
        out += [lo, hi, np.nextafter(lo, -math.inf), np.nextafter(hi, math.inf), (lo + hi) / 2]
    return out


@pytest.mark.parametrize("kind", ["force", "push"])
def test_value_by_value_agrees_with_the_arrays_check_on_every_column_edge(kind) -> None:
    rt = record_type(kind)
    numeric = [c for c in rt.columns if c.kind in ("float", "int")]
    assert numeric and any(c.bounds for c in numeric) and any(not c.optional for c in numeric)
    rng = np.random.default_rng(5)

    def good(c):
        lo, hi = c.bounds if c.bounds is not None else (-1.0, 1.0)
        v = rng.uniform(max(lo, -1e3), min(hi, 1e3), size=c.shape or None)
        return v.astype(np.int64) if c.kind == "int" else v

    base = {c.name: good(c) for c in numeric}
    assert _plainly_in_bounds(rt.columns, base) and verdict_of_arrays(rt.columns, base)
    seen = {True: 0, False: 0}
    for c in numeric:
        for x in special_values(c):
            row = dict(base)
            if c.shape:
                v = np.array(base[c.name], dtype=np.float64)
                v[rng.integers(0, v.size)] = x
                row[c.name] = v
            else:
                row[c.name] = x
            fast, slow = _plainly_in_bounds(rt.columns, row), verdict_of_arrays(rt.columns, row)
            assert fast == slow, (c.name, x, fast, slow)
            seen[fast] += 1
    assert seen[True] and seen[False]  # both verdicts were reached


def test_a_value_that_is_no_number_goes_to_the_arrays_check() -> None:
    rt = record_type("force")
    c = next(c for c in rt.columns if c.kind == "float" and not c.shape)
    assert not _plainly_in_bounds(rt.columns, {c.name: "twelve"})
