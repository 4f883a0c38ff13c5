"""A push plan: the pushes of the stiffness experiment fixed in advance, as the trial plan fixes loads.

``labcli acquire pushes.h5 --protocol takuma2014-stiffness --plan pushes-plan.csv`` runs the
pushes of a plan in its row order.  One row per push, in the units people measure and type
at the rig (the session's own questions ask in mm and deg)::

    push,object,R_mm,d_mm,phi_deg,category,stiffness_N_per_m
    1,pet-1,33,10,0,soft,
    2,pet-1,33,10,0,soft,
    3,can-al-1,33,15,,medium,

* ``push``: the push id (whole number, unique), under which the push is stored;
* ``object``: the object's name; an object's pushes are consecutive rows, and its radius,
  category and stiffness are the same on each;
* ``R_mm``: the object's radius R, mm; ``d_mm``: the push distance d, mm, within the
  protocol's ``push.distance_min_m`` to ``distance_max_m``;
* ``phi_deg`` (optional): the push direction phi in deg, counter-clockwise from +x; empty
  when unknown (it is then solved from the force);
* ``category`` (optional): the object's material class, for reference objects;
* ``stiffness_N_per_m`` (optional): the stiffness of a simulated object, which the simulated
  rig needs to push it; ignored on a real rig.

The plan is stored in the run file, so ``--resume`` continues it without ``--plan``.
"""

from __future__ import annotations

import math
import os
from collections.abc import Iterable
from typing import TYPE_CHECKING, Any

from ...core.tables import TableSpec, fmt_number, read_table, table_error
from .push_session import PlannedObject
from .session import ObjectSpec, PushSpec

if TYPE_CHECKING:  # pragma: no cover
    import pandas as pd

PUSH_PLAN = TableSpec(
    label="push plan",
    columns=(
        ("push", "id", "required"),
        ("object", "name", "required"),
        ("R_mm", "positive", "required"),
        ("d_mm", "positive", "required"),
        ("phi_deg", "float-or-empty", "optional"),
        ("category", "text", "optional"),
        ("stiffness_N_per_m", "positive-or-empty", "optional"),
    ),
    id_column="push",
)
PER_OBJECT = ("R_mm", "category", "stiffness_N_per_m")


def load_push_plan(path: str | os.PathLike, *, distance_range_m: tuple[float, float] | None = None) -> pd.DataFrame:
    """Read and check a push plan; every problem is named by file, row and column."""

    def limits(values: dict[str, Any]) -> Iterable[tuple[str, str]]:
        d = values.get("d_mm")
        if distance_range_m is not None and isinstance(d, float):
            lo, hi = (v * 1e3 for v in distance_range_m)
            if not lo <= d <= hi:
                yield (
                    "d_mm",
                    f"{fmt_number(d)} mm is outside the protocol's range {fmt_number(lo)} to {fmt_number(hi)} mm",
                )

    plan = read_table(path, PUSH_PLAN, check=limits)
    problems = list(_object_problems(plan, str(path)))
    if problems:
        raise table_error(str(path), problems)
    return plan


def _object_problems(plan: pd.DataFrame, label: str) -> Iterable[str]:
    """Each object's rows together, with the same radius, category and stiffness on each."""
    first: dict[str, dict[str, Any]] = {}
    previous = None
    for i, row in enumerate(plan.to_dict("records")):
        rownum = i + 2  # as a spreadsheet numbers rows, the header being row 1
        name = row["object"]
        if name in first and name != previous:
            yield f"{label}:row {rownum}, column object: {name}'s pushes must be consecutive rows (it also has row {first[name]['_row']})."
        elif name in first:
            for col in PER_OBJECT:
                if not _same(row[col], first[name][col]):
                    yield (
                        f"{label}:row {rownum}, column {col}: {_cell(row[col])} differs from {name}'s "
                        f"{_cell(first[name][col])} on row {first[name]['_row']}; an object has one {col}."
                    )
        else:
            first[name] = {**row, "_row": rownum}
        previous = name


def _same(a: Any, b: Any) -> bool:
    if isinstance(a, float) and isinstance(b, float) and math.isnan(a) and math.isnan(b):
        return True
    return a == b


def _cell(v: Any) -> str:
    if isinstance(v, float):
        return "empty" if math.isnan(v) else fmt_number(v)
    return repr(v) if v != "" else "empty"


def plan_objects(plan: pd.DataFrame) -> tuple[list[PlannedObject], list[int]]:
    """The objects of a plan with their pushes, and the push ids in the order they are run."""
    objects: list[PlannedObject] = []
    ids: list[int] = []
    for row in plan.to_dict("records"):
        phi = row.get("phi_deg")
        stiffness = row.get("stiffness_N_per_m")
        spec = PushSpec(float(row["d_mm"]) * 1e-3, None if _missing(phi) else math.radians(float(phi)))
        if objects and objects[-1].spec.name == row["object"]:
            objects[-1] = PlannedObject(objects[-1].spec, (*objects[-1].pushes, spec))
        else:
            obj = ObjectSpec(
                str(row["object"]),
                float(row["R_mm"]) * 1e-3,
                str(row.get("category") or ""),
                None if _missing(stiffness) else float(stiffness),
            )
            objects.append(PlannedObject(obj, (spec,)))
        ids.append(int(row["push"]))
    return objects, ids


def _missing(v: Any) -> bool:
    return v is None or (isinstance(v, float) and math.isnan(v)) or (isinstance(v, str) and not v.strip())
