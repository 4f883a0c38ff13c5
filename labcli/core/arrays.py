"""Column stacks and row-wise all/any of trial arrays, as numpy gives them, without its slow paths.

A trial table's quantities come in (n, k) arrays with k of 2 to 14 and n up to 10^6.  Along
such a short last axis numpy's general reductions (``np.all(x, axis=1)``) step row by row, and
``np.column_stack`` writes its output with a stride per element: at 10^6 trials each took
30-100 ms where one pass per column takes 3-25 ms, and a fit made dozens of them.  The results
here are the same arrays, element for element (same dtype, C order).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np


def stack_columns(parts: Sequence[Any]) -> np.ndarray:
    """``np.column_stack(parts)`` for 1-D arrays (one column each) and 2-D blocks (their columns)."""
    arrs = [np.asarray(p) for p in parts]
    if not arrs or any(a.ndim not in (1, 2) for a in arrs) or len({len(a) for a in arrs}) != 1:
        return np.column_stack(arrs)  # numpy's own answer, or its own error
    widths = [1 if a.ndim == 1 else a.shape[1] for a in arrs]
    out = np.empty((len(arrs[0]), sum(widths)), dtype=np.result_type(*arrs))
    k = 0
    for a, w in zip(arrs, widths, strict=True):
        if a.ndim == 1:
            out[:, k] = a
        else:
            out[:, k : k + w] = a
        k += w
    return out


def rows_all(x: Any) -> np.ndarray:
    """``np.all(x, axis=1)`` of a 2-D array: whether every column of each row is true."""
    return _rows(x, np.all, np.logical_and)


def rows_any(x: Any) -> np.ndarray:
    """``np.any(x, axis=1)`` of a 2-D array: whether some column of each row is true."""
    return _rows(x, np.any, np.logical_or)


def _rows(x: Any, whole: Any, combine: np.ufunc) -> np.ndarray:
    """``whole(x, axis=1)`` taken column by column with ``combine`` (numpy's axis reductions are
    slow on a few columns of many rows)."""
    x = np.asarray(x)
    if x.ndim != 2 or x.shape[1] == 0:
        return np.asarray(whole(x, axis=1))
    out = x[:, 0].astype(bool)
    for k in range(1, x.shape[1]):
        combine(out, x[:, k].astype(bool, copy=False), out=out)
    return out
