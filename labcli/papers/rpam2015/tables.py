"""The rPAM runs' CSV tables: one per experiment, in the run file's column order.

``labcli export`` writes them and ``labcli import --experiment stretch|joint`` reads them
back.  Pressures are measured gauge values in MPa: a vented actuator reads a little below
zero, so they are gauge pressures above vacuum (:mod:`labcli.core.bounds`), not the McKibben
sensors' span check.
"""

from __future__ import annotations

import os
from typing import TYPE_CHECKING

from ...core.tables import RowCheck, TableSpec, read_table, write_table
from ...errors import ConfigError

if TYPE_CHECKING:  # pragma: no cover
    import pandas as pd

STRETCH_POINTS = TableSpec(
    label="point",
    columns=(
        ("point", "id", "required"),
        ("mass_g", "payload", "required"),
        ("P_A", "gauge", "required"),
        ("P_B", "gauge", "required"),
        ("L_m", "length", "required"),
        ("lambda", "stretch-or-empty", "omit-if-empty"),
        ("set_mass_g", "payload-or-empty", "omit-if-empty"),
        ("set_P_A_kPa", "gauge-kPa-or-empty", "omit-if-empty"),
        ("set_P_B_kPa", "gauge-kPa-or-empty", "omit-if-empty"),
    ),
    id_column="point",
)

JOINT_POINTS = TableSpec(
    label="point",
    columns=(
        ("point", "id", "required"),
        ("P_A", "gauge", "required"),
        ("P_B", "gauge", "required"),
        ("alpha_deg", "angle", "required"),
        ("P_A0", "gauge-or-empty", "omit-if-empty"),
        ("P_B0", "gauge-or-empty", "omit-if-empty"),
        ("L_m", "length-or-empty", "omit-if-empty"),
        ("set_P_A_kPa", "gauge-kPa-or-empty", "omit-if-empty"),
        ("set_P_B_kPa", "gauge-kPa-or-empty", "omit-if-empty"),
    ),
    id_column="point",
    pairs=(("P_A0", "P_B0"),),
)

POINT_SPECS = {"stretch": STRETCH_POINTS, "joint": JOINT_POINTS}


def _spec(experiment: str) -> TableSpec:
    spec = POINT_SPECS.get(experiment)
    if spec is None:
        raise ConfigError(f"an rPAM point table is of experiment stretch or joint, not {experiment!r}.")
    return spec


def read_point_csv(
    path: str | os.PathLike, experiment: str, *, id_range: tuple[int, int] | None = None, check: RowCheck | None = None
) -> pd.DataFrame:
    """Read and check the point table of an rPAM experiment (``"stretch"`` or ``"joint"``).

    The columns are those ``labcli export`` writes for the run; pressures in MPa, ``L_m``
    in m, ``mass_g`` in g, ``alpha_deg`` in degrees, set values in g and kPa.
    """
    return read_table(path, _spec(experiment), id_range=id_range, check=check)


def write_point_csv(df: pd.DataFrame, path: str | os.PathLike, experiment: str) -> None:
    """Write an rPAM point table (stretch test or joint map) in the run file's column order."""
    write_table(df, path, _spec(experiment))
