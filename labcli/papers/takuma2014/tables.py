"""The McKibben rig's CSV exchange tables (``docs/table-formats.md``): trials, pushes, plans.

Plain data for :mod:`labcli.core.tables`, which reads and writes them: every cell
checked, every problem reported by file, row and column.  Pressures in MPa (gauge),
forces in N, angles in degrees, masses in grams.
"""

from __future__ import annotations

import os
from collections.abc import Iterable
from typing import TYPE_CHECKING, Any

from ...core.tables import PRESSURE_SPAN_MPA, RowCheck, TableSpec, fmt_number, read_table, write_table

if TYPE_CHECKING:  # pragma: no cover
    import pandas as pd

BASELINE = ("P_L10", "P_R10", "P_L20", "P_R20")
LOADED = ("P_L1", "P_R1", "P_L2", "P_R2")
# The rest posture: absolute joint angles at the record's baseline (absent: the arm rests at 0, 0).
REST = ("theta1_0_deg", "theta2_0_deg")
REST_POSTURE = tuple((c, "angle-or-empty", "omit-if-empty") for c in REST)

# Columns: (name, kind, presence); presence "required" | "optional" (added empty when
# absent) | "omit-if-empty" (optional, and left out of a written file when empty).
TRIAL = TableSpec(
    label="trial",
    columns=(
        ("trial", "id", "required"),
        ("set", "set", "optional"),
        *((c, "pressure", "required") for c in BASELINE + LOADED),
        ("theta1_deg", "angle", "required"),
        ("theta2_deg", "angle", "required"),
        ("Fx_N", "tip-force", "required"),
        ("Fy_N", "tip-force", "required"),
        ("mass_g", "mass-or-empty", "omit-if-empty"),
        ("direction_deg", "direction-or-empty", "omit-if-empty"),
        *REST_POSTURE,
    ),
    id_column="trial",
    pairs=(("mass_g", "direction_deg"), REST),
)

PUSH = TableSpec(
    label="push",
    columns=(
        ("push", "id", "required"),
        ("object", "name", "required"),
        ("R_m", "length", "required"),
        ("d_m", "distance", "required"),
        ("phi_deg", "direction-or-empty", "required"),
        *((c, "pressure", "required") for c in BASELINE + LOADED),
        ("category", "text", "omit-if-empty"),
        *REST_POSTURE,
    ),
    id_column="push",
    pairs=(REST,),
)

PLAN = TableSpec(
    label="plan",
    columns=(
        ("trial", "id", "required"),
        ("set", "set-required", "required"),
        ("mass_g", "mass", "required"),
        ("direction_deg", "direction", "required"),
    ),
    id_column="trial",
)


def read_trial_csv(
    path: str | os.PathLike,
    *,
    span_MPa: tuple[float, float] = PRESSURE_SPAN_MPA,
    id_range: tuple[int, int] | None = None,
    check: RowCheck | None = None,
) -> pd.DataFrame:
    """Read and check a trial table (``docs/table-formats.md``); every problem in one TableError.

    ``id_range`` (low, high) also checks the trial ids, e.g. against what a run file can hold;
    ``check(row) -> [(column, problem), ...]`` adds checks of its own (e.g.
    :func:`labcli.core.store.storable_cells`), reported by row and column like the others.
    """
    return read_table(path, TRIAL, span=span_MPa, id_range=id_range, check=check)


def read_push_csv(
    path: str | os.PathLike,
    *,
    span_MPa: tuple[float, float] = PRESSURE_SPAN_MPA,
    id_range: tuple[int, int] | None = None,
    check: RowCheck | None = None,
) -> pd.DataFrame:
    """Read and check a push table; ``phi_deg`` is NaN where the file leaves it empty."""
    return read_table(path, PUSH, span=span_MPa, id_range=id_range, check=check)


def load_plan(
    path: str | os.PathLike,
    *,
    mass_range_g: tuple[float, float] | None = None,
    direction_range_deg: tuple[float, float] | None = None,
) -> pd.DataFrame:
    """Read and check a plan (``trial, set, mass_g, direction_deg``), optionally against limits.

    Problems name the file, the row as a spreadsheet numbers it (header = row 1)
    and the column.
    """

    def limits(values: dict[str, Any]) -> Iterable[tuple[str, str]]:
        m, d = values.get("mass_g"), values.get("direction_deg")
        if mass_range_g is not None and isinstance(m, float):
            lo, hi = mass_range_g
            if not lo <= m <= hi:
                yield (
                    "mass_g",
                    (f"{fmt_number(m)} g is outside the protocol's range {fmt_number(lo)} to {fmt_number(hi)} g"),
                )
        if direction_range_deg is not None and isinstance(d, float):
            lo, hi = direction_range_deg
            if not lo <= d <= hi:
                yield (
                    "direction_deg",
                    (f"{fmt_number(d)} deg is outside the protocol's range {fmt_number(lo)} to {fmt_number(hi)} deg"),
                )

    return read_table(path, PLAN, check=limits)


def write_trial_csv(
    df: pd.DataFrame, path: str | os.PathLike, *, span_MPa: tuple[float, float] = PRESSURE_SPAN_MPA
) -> None:
    """Write a trial table: standard columns in ``docs/table-formats.md`` order, then extras."""
    write_table(df, path, TRIAL, span_MPa)


def write_push_csv(
    df: pd.DataFrame, path: str | os.PathLike, *, span_MPa: tuple[float, float] = PRESSURE_SPAN_MPA
) -> None:
    """Write a push table: standard columns in ``docs/table-formats.md`` order, then extras."""
    write_table(df, path, PUSH, span_MPa)


def write_plan_csv(df: pd.DataFrame, path: str | os.PathLike) -> None:
    """Write a plan (``trial, set, mass_g, direction_deg``)."""
    write_table(df, path, PLAN)
