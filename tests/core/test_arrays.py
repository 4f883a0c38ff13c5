"""labcli.core.arrays gives numpy's own answers, element for element, dtype and layout included."""

from __future__ import annotations

import numpy as np
import pytest

from labcli.core.arrays import rows_all, rows_any, stack_columns


@pytest.mark.parametrize("seed", range(12))
def test_stacked_columns_are_numpys_column_stack(seed):
    rng = np.random.default_rng(seed)
    n = int(rng.integers(0, 50))
    parts = []
    for _ in range(int(rng.integers(1, 5))):
        kind = rng.integers(0, 4)
        if kind == 0:
            parts.append(rng.normal(size=n))
        elif kind == 1:
            parts.append(rng.normal(size=(n, int(rng.integers(0, 4)))))
        elif kind == 2:
            parts.append(rng.integers(-5, 5, size=n))
        else:
            parts.append(rng.random(n) < 0.5)
    got, want = stack_columns(parts), np.column_stack(parts)
    assert got.dtype == want.dtype and got.shape == want.shape and got.flags.c_contiguous
    assert np.array_equal(got, want, equal_nan=got.dtype.kind == "f")


def test_unequal_lengths_are_refused_as_numpy_refuses_them():
    with pytest.raises(ValueError):
        stack_columns([np.zeros(3), np.zeros(4)])
    with pytest.raises(ValueError):
        stack_columns([])


@pytest.mark.parametrize("seed", range(12))
def test_row_wise_all_and_any_are_numpys(seed):
    rng = np.random.default_rng(seed)
    shape = (int(rng.integers(0, 40)), int(rng.integers(0, 6)))
    x = rng.normal(size=shape)
    x[rng.random(shape) < 0.2] = np.nan
    for m in (np.isfinite(x), x > 0, np.where(np.isfinite(x), x, 0.0)):  # bools, and numbers' truth
        assert np.array_equal(rows_all(m), np.all(m, axis=1))
        assert np.array_equal(rows_any(m), np.any(m, axis=1))
        assert rows_all(m).dtype == bool and rows_any(m).dtype == bool
