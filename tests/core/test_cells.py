"""An extra column's type: the whole-column check gives what the rules for one cell give."""

from __future__ import annotations

import math

import pandas as pd
from hypothesis import given, settings
from hypothesis import strategies as st

from labcli.core.cells import _is_canonical_float, _is_canonical_int, infer_extra_column


def one_cell_at_a_time(cells: list[str]) -> pd.Series:
    """infer_extra_column as the rules read: each cell matched, parsed and printed back by itself."""
    filled = [c for c in cells if c != ""]
    if not filled:
        return pd.Series([math.nan] * len(cells), dtype="float64")
    if len(filled) == len(cells) and all(_is_canonical_int(c) for c in filled):
        return pd.Series([int(c) for c in cells], dtype="int64")
    if all(_is_canonical_float(c) for c in filled):
        return pd.Series([float(c) if c else math.nan for c in cells], dtype="float64")
    return pd.Series(cells, dtype=object)


CELLS = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True).map(repr),
    st.floats(min_value=-1e6, max_value=1e6).map(lambda v: f"{v:.3f}"),
    st.integers(-(2**64), 2**64).map(str),
    st.sampled_from(
        [
            "",
            "-0",
            "+2",
            "007",
            " 5",
            "5 ",
            "1_000",
            "1e3",
            "1E+16",
            "1e+16",
            ".5",
            "1.",
            "-0.0",
            "nan",
            "inf",
            "\u0665",
            "9223372036854775807",
            "9223372036854775808",
            "-9223372036854775808",
            "0x10",
            "x",
        ]
    ),
)


@settings(max_examples=400, deadline=None)
@given(st.lists(CELLS, max_size=8), st.booleans())
def test_whole_columns_are_typed_as_cell_by_cell(cells: list[str], uniform: bool) -> None:
    if uniform and cells:  # a column of one kind of text, the common case
        cells = [cells[0]] * len(cells)
    pd.testing.assert_series_equal(infer_extra_column(cells), one_cell_at_a_time(cells))


def test_an_archive_column_of_reprs_reads_as_floats_and_of_ints_as_ints() -> None:
    floats = [repr(0.1 * k) for k in range(1000)]
    assert infer_extra_column(floats).tolist() == [0.1 * k for k in range(1000)]
    assert infer_extra_column([str(k) for k in range(-5, 5)]).dtype == "int64"
    assert infer_extra_column(["1.0", "", "2.5"]).isna().tolist() == [False, True, False]
    assert infer_extra_column(["1.0", "2.50"]).dtype == object  # 2.50 would not be written back as it came
