"""A table's description (plain data) and what the text of its cells is.

Shared by the cell-by-cell reader (:mod:`labcli.core.tables`) and the whole-column one
(:mod:`labcli.core.table_fast`), so that both read an extra column the same way.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from typing import TYPE_CHECKING

if TYPE_CHECKING:  # pragma: no cover
    import pandas as pd

NUMBER = re.compile(r"[+-]?(?:[0-9]+(?:\.[0-9]*)?|\.[0-9]+)(?:[eE][+-]?[0-9]+)?")
INT64_MAX = 2**63 - 1


# ---------------------------------------------------------------------------
# Table descriptions (plain data): (column, kind, presence)
#   kind: "id" (integer) | "set" (fit, validation or empty) | "set-required" | "name"
#         (non-empty text) | "text" | "pressure" (gauge MPa in the sensor span) | a
#         quantity of labcli.core.bounds ("angle", "tip-force", "mass", ...: unit and physical
#         range) | "float", "positive", "nonnegative" (any finite number, with that sign:
#         for a table whose quantities have no entry there yet); a numeric kind ending in
#         "-or-empty" also takes an empty cell (NaN).
#   presence: "required" | "optional" (added empty when absent) |
#             "omit-if-empty" (optional, and left out of a written file when empty)
# ---------------------------------------------------------------------------


@dataclass(frozen=True)
class TableSpec:
    label: str  # "trial", "push", "plan": used in messages
    columns: tuple[tuple[str, str, str], ...]
    id_column: str
    pairs: tuple[tuple[str, str], ...] = ()  # given together or not at all

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(c[0] for c in self.columns)


def infer_extra_column(cells: list[str]) -> pd.Series:
    """Numbers only when every cell reads back to exactly its own text (nothing lost); empty: NaN.

    Whole columns at a time: ``str(int(c)) == c`` and ``repr(float(c)) == c`` hold exactly for
    the cells the per-cell rules accept (:func:`_is_canonical_int`, :func:`_is_canonical_float`),
    and mapped over a column they cost a tenth of a regex per cell (10^5 pushes with four extra
    columns: a second of ``classify``).
    """
    import pandas as pd

    filled = [c for c in cells if c != ""]
    if not filled:
        # No value says what the column is; missing numbers, as pandas reads it.
        return pd.Series([math.nan] * len(cells), dtype="float64")
    if len(filled) == len(cells):
        ints = _canonical_ints(filled)
        if ints is not None:
            return pd.Series(ints, dtype="int64")
    values = _canonical_floats(filled)
    if values is not None:
        if len(filled) < len(cells):
            it = iter(values)
            values = [next(it) if c else math.nan for c in cells]
        return pd.Series(values, dtype="float64")
    return pd.Series(cells, dtype=object)


def _canonical_ints(cells: list[str]) -> list[int] | None:
    """The cells as ints when every one is an integer's own decimal text within int64, else None."""
    try:  # fails at the first cell that is no integer; anything int() reads otherwise fails the comparison
        values = list(map(int, cells))
    except (TypeError, ValueError):
        return None
    if list(map(str, values)) != cells or max(map(abs, values)) > INT64_MAX:
        return None
    return values


def _canonical_floats(cells: list[str]) -> list[float] | None:
    """The cells as floats when every one is a finite float's own repr, else None."""
    try:
        values = list(map(float, cells))
    except (TypeError, ValueError):
        return None
    # A list's text is its items' reprs joined by ", ", and no cell float() reads holds ", ": one
    # comparison of two long strings instead of a repr and a comparison per cell.
    if not all(map(math.isfinite, values)) or str(values)[1:-1] != ", ".join(cells):
        return None
    return values


def _is_canonical_int(s: str) -> bool:
    """The rule for one cell (the whole-column check above holds exactly where this does)."""
    if not re.fullmatch(r"-?[0-9]+", s):
        return False
    v = int(s)
    return str(v) == s and abs(v) <= INT64_MAX


def _is_canonical_float(s: str) -> bool:
    """The rule for one cell (the whole-column check above holds exactly where this does)."""
    if not NUMBER.fullmatch(s):
        return False
    v = float(s)
    return math.isfinite(v) and repr(v) == s
