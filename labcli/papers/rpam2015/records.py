"""The rPAM runs' records: one point of the stretch test or of the joint map.

The columns of a point in its run's table (SI: MPa gauge, rad, m, kg)::

    points   experiment ("stretch" | "joint"), P (2,) MPa (P_A, P_B), the set values as
             typed: plan_mass_g, plan_P_A_kPa, plan_P_B_kPa
        stretch:     mass kg, L m (actuator A's length), lambda 1 (L / L0)
        joint map:   alpha rad (deflection from the vented baseline), P0 (2,) MPa and
                     pot0 rad of the baseline, L m
    (a column a point does not use holds NaN)

The record a session commits (and ``run.records.write`` takes): ``point`` (id), ``experiment``
(as the run's kind says), ``P_MPa`` (2,); stretch points ``mass_kg``, ``L_m``, ``lambda``;
joint-map points ``alpha_rad`` and optionally ``P0_MPa`` (2,), ``pot0_rad``, ``L_m``;
``plan`` (the set values: ``mass_g``, ``P_A_kPa``, ``P_B_kPa``); then ``settle``, ``raw``,
``started``, ``ended`` as every record.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, TypedDict

import numpy as np

from ...core.paper import Column
from ...core.protocol import loads_protocol
from ...core.record import Record
from ...core.report import ids_text, settling_line
from ...core.store.h5 import nan_if_empty, scalar, to_edge, vector
from ...core.store.record_type import BaseRecordType
from ...core.tables import TableSpec
from ...errors import LabcliError, StoreError
from .session import acquisition_protocol
from .tables import POINT_SPECS

# The stretch ratio L / L0 under its key "lambda", which a class body cannot spell.
_Stretch = TypedDict("_Stretch", {"lambda": float}, total=False)


class _PointOptional(Record, _Stretch, total=False):
    mass_kg: float  # stretch: the payload
    L_m: float  # actuator A's length (stretch; the joint map's when measured)
    P0_MPa: np.ndarray  # joint map: (2,) baseline pressures
    pot0_rad: float  # joint map: the baseline angle
    alpha_rad: float  # joint map: the deflection from the vented baseline
    plan: dict[str, float]  # the set values: mass_g, P_A_kPa, P_B_kPa


class PointRecord(_PointOptional):
    """A point of the stretch test or the joint map as a session commits it (SI)."""

    point: int
    experiment: str  # "stretch" or "joint", as the run's kind says
    P_MPa: np.ndarray  # (2,) P_A, P_B


# key in the record -> (column, units)
_DATASETS = {
    "mass_kg": ("mass", "kg"),
    "L_m": ("L", "m"),
    "lambda": ("lambda", "1"),
    "alpha_rad": ("alpha", "rad"),
    "pot0_rad": ("pot0", "rad"),
}
_PRESSURE_BOUNDS = (-1.0, 10.0)  # MPa gauge: far beyond any rPAM; a value outside marks a changed file
_BOUNDS = {
    "mass": (0.0, 1e4),
    "L": (-10.0, 10.0),
    "lambda": (-1e3, 1e3),
    "alpha": (-2 * math.pi, 2 * math.pi),
    "pot0": (-2 * math.pi, 2 * math.pi),
}
_WHAT = {
    "mass": "payload",
    "L": "actuator A's length",
    "lambda": "stretch L / L0",
    "alpha": "joint deflection",
    "pot0": "baseline potentiometer angle",
}
COLUMNS = (
    Column("experiment", "", kind="text", width=8, what="stretch test or joint map"),
    Column("P", "MPa", shape=(2,), components=("P_A", "P_B"), bounds=_PRESSURE_BOUNDS, what="pressures"),
    Column(
        "P0",
        "MPa",
        shape=(2,),
        components=("P_A", "P_B"),
        bounds=_PRESSURE_BOUNDS,
        optional=True,
        what="baseline pressures",
    ),
    *(Column(name, units, bounds=_BOUNDS[name], optional=True, what=_WHAT[name]) for name, units in _DATASETS.values()),
    Column("plan_mass_g", "g", bounds=(0.0, 1e7), optional=True, what="set payload"),
    Column("plan_P_A_kPa", "kPa", bounds=(-1e4, 1e4), optional=True, what="set P_A"),
    Column("plan_P_B_kPa", "kPa", bounds=(-1e4, 1e4), optional=True, what="set P_B"),
)


@dataclass(frozen=True)
class PointRecords(BaseRecordType):
    """Points of an rPAM run; ``experiment`` is the run's ("stretch" or "joint")."""

    kind: str
    experiment: str
    title: str  # "stretch test" | "joint map"
    collection: str = "points"
    id_column: str = "point"
    noun: str = "point"
    plural: str = "points"
    splits: bool = False
    columns: tuple[Column, ...] = COLUMNS

    @property
    def signal(self) -> str:
        return "L" if self.experiment == "stretch" else "alpha"

    @property
    def qualifier(self) -> str:
        return f" of the {self.title}"

    @property
    def table_spec(self) -> TableSpec:
        return POINT_SPECS[self.experiment]

    def check(self, record: Mapping[str, Any], label: str, run: Any) -> dict[str, Any]:
        if record.get("experiment", self.experiment) != self.experiment:
            raise StoreError(
                f"{label}: a {record['experiment']} point cannot go into {getattr(run, 'path', 'this run')}, "
                f"a {self.kind} run."
            )
        row: dict[str, Any] = {
            "experiment": self.experiment,
            "P": vector(record, "P_MPa", 2, "pressures P_A, P_B in MPa", label),
        }
        if "P0_MPa" in record:
            row["P0"] = vector(record, "P0_MPa", 2, "baseline pressures P_A, P_B in MPa", label)
        needed = ("mass_kg", "L_m", "lambda") if self.experiment == "stretch" else ("alpha_rad",)
        for key in needed:
            value = scalar(record, key, label)
            if not math.isfinite(value):
                raise StoreError(f"{label} record lacks a finite '{key}', which a {self.experiment} point needs.")
            row[_DATASETS[key][0]] = value
        for key in ("L_m", "pot0_rad"):
            if _DATASETS[key][0] not in row and key in record:
                row[_DATASETS[key][0]] = scalar(record, key, label)
        for k, v in (record.get("plan") or {}).items():
            if f"plan_{k}" not in {c.name for c in COLUMNS}:
                raise StoreError(
                    f"{label} record: its set values have {k!r}; a point's are mass_g, P_A_kPa and P_B_kPa."
                )
            row[f"plan_{k}"] = float(v)
        return row

    def read(self, row: Mapping[str, Any]) -> dict[str, Any]:
        rec: dict[str, Any] = {"point": int(row["point"]), "experiment": self.experiment, "P_MPa": np.asarray(row["P"])}
        if np.all(np.isfinite(row["P0"])):
            rec["P0_MPa"] = np.asarray(row["P0"])
        for key, (name, _) in _DATASETS.items():
            if math.isfinite(float(row[name])):
                rec[key] = float(row[name])
        rec["plan"] = {
            key: float(row[f"plan_{key}"])
            for key in ("mass_g", "P_A_kPa", "P_B_kPa")
            if math.isfinite(float(row[f"plan_{key}"]))
        }
        return rec

    def table(self, run: Any, ids: list[int], cols: Mapping[str, Any]) -> Any:
        """The table of an rPAM run (DataFrame): MPa and m, grams and degrees at the edge.

        Stretch test: ``point, mass_g, P_A, P_B, L_m, lambda``; joint map: ``point, P_A,
        P_B, alpha_deg, P_A0, P_B0, L_m`` (pressures in MPa, ``alpha_deg`` the deflection
        from the vented baseline); then the set values as ``set_mass_g``, ``set_P_A_kPa``,
        ``set_P_B_kPa``.  Rows in recording order.  ``labcli export`` writes this table and
        ``labcli import`` reads it back.
        """
        import pandas as pd

        return pd.DataFrame(self.table_columns(run, ids, cols))

    def table_columns(self, run: Any, ids: list[int], cols: Mapping[str, Any]) -> dict[str, Any]:
        """:meth:`table`'s columns (name -> values over ``ids``), the frame not made: what the store
        checks each point against the table's rules with (:func:`labcli.core.tables.columns_problems`)."""
        n = len(ids)

        def get(key: str, i: int | None = None) -> list[float]:
            v = np.asarray(cols[key], dtype=np.float64)
            return [float(x) for x in (v.reshape(n, -1)[:, i] if i is not None else v.reshape(n))]

        out: dict[str, Any] = {"point": np.asarray(ids, dtype=np.int64)}
        stretch = self.experiment == "stretch"
        if stretch:
            out["mass_g"] = list(to_edge([m * 1e3 for m in get("mass")]))
        out["P_A"], out["P_B"] = get("P", 0), get("P", 1)
        if stretch:
            out["L_m"], out["lambda"] = get("L"), get("lambda")
        else:
            out["alpha_deg"] = list(to_edge([math.degrees(a) for a in get("alpha")]))
            out["P_A0"], out["P_B0"] = get("P0", 0), get("P0", 1)
            out["L_m"] = get("L")
        for key in ("mass_g", "P_A_kPa", "P_B_kPa"):
            vals = get(f"plan_{key}")
            if any(math.isfinite(v) for v in vals):
                out[f"set_{key}"] = vals
        return out

    def from_row(self, row: Mapping[str, Any], protocol: Any) -> dict[str, Any]:
        """One row of a point table as the record the run file takes (SI)."""

        def value(key: str) -> float:
            return nan_if_empty(row.get(key))

        record: dict[str, Any] = {
            "point": int(row["point"]),
            "experiment": self.experiment,
            "P_MPa": [value("P_A"), value("P_B")],
        }
        keys = (("mass_g",) if self.experiment == "stretch" else ()) + ("P_A_kPa", "P_B_kPa")
        plan = {key: value(f"set_{key}") for key in keys}
        record["plan"] = {k: v for k, v in plan.items() if math.isfinite(v)}
        length = value("L_m")
        if self.experiment == "stretch":
            record["mass_kg"] = value("mass_g") * 1e-3
            record["L_m"] = length
            stretch = value("lambda")
            if not math.isfinite(stretch):
                # A table without lambda: the stretch of actuator A over its protocol's rest length.
                stretch = length / float(protocol.settings.L0_m)
            record["lambda"] = stretch
        else:
            record["alpha_rad"] = math.radians(value("alpha_deg"))
            p0 = [value("P_A0"), value("P_B0")]
            if all(math.isfinite(v) for v in p0):
                record["P0_MPa"] = p0
            if math.isfinite(length):
                record["L_m"] = length
        return record

    def summarise(self, run: Any, ids: list[int], cols: Mapping[str, Any]) -> dict[str, Any]:
        """The experiment, its grid's coverage and the ranges measured (``labcli inspect``).

        ``planned``/``missing_ids`` come from the protocol embedded in the run (None for an
        imported table, whose grid need not be the protocol's); ranges are [min, max] over
        the complete points (None when there is none): pressures in kPa, payloads in g,
        deflections in degrees.
        """
        table = self.table(run, ids, cols)

        def span(values: Any, scale: float = 1.0) -> list[float] | None:
            v = np.asarray(values, dtype=np.float64) * scale
            v = v[np.isfinite(v)]
            return [float(v.min()), float(v.max())] if v.size else None

        planned, missing_ids = self._coverage(run, ids)
        out: dict[str, Any] = {
            "experiment": self.experiment,
            "title": self.title,
            "planned": planned,
            "missing_ids": missing_ids,
            "P_A_kPa": span(table["P_A"], 1e3),
            "P_B_kPa": span(table["P_B"], 1e3),
        }
        if self.experiment == "stretch":
            out["payloads_g"] = sorted({float(m) for m in table["mass_g"] if math.isfinite(m)})
            out["lambda"] = span(table["lambda"])
        else:
            out["alpha_deg"] = span(table["alpha_deg"])
        return {"rpam": out}

    def _coverage(self, run: Any, ids: list[int]) -> tuple[int | None, list[int] | None]:
        """(points planned, ids not yet recorded) of the grid of the run's own protocol."""
        if run.attrs.get("imported", False):
            return None, None
        try:
            base = loads_protocol(run.protocol_text, source=f"{run.path} (embedded protocol)")
            grid = [p.point for p in acquisition_protocol(base, self.experiment).settings.points]
        except LabcliError:
            return None, None
        done = set(ids)
        return len(grid), [i for i in grid if i not in done]

    def inspect_lines(self, summary: dict[str, Any]) -> list[str]:
        """Points of the run's experiment against its grid, what they cover, how they settled."""
        r = summary["rpam"]
        incomplete = f" ({ids_text(summary['incomplete_ids'])})" if summary["incomplete"] else ""
        of = "" if r["planned"] is None else f" of {r['planned']} planned"
        lines = [
            f"  experiment  {r['title']}",
            f"  points      {summary['complete']}{of} complete, {summary['incomplete']} incomplete{incomplete}",
        ]
        if r["missing_ids"]:
            lines.append(
                f"  to record   {len(r['missing_ids'])} points ({ids_text(r['missing_ids'])}); "
                "labcli acquire --resume records them"
            )
        lines.append(f"  pressures   P_A {_range(r['P_A_kPa'], 'kPa')}, P_B {_range(r['P_B_kPa'], 'kPa')} (measured)")
        if r["experiment"] == "stretch":
            payloads = ", ".join(f"{m:g}" for m in r["payloads_g"])
            lines.append(
                f"  payloads    {payloads + ' g' if payloads else 'none'}; "
                f"stretch lambda {_range(r['lambda'], '(L / L0)', '.3f')}"
            )
        else:
            lines.append(f"  deflection  alpha {_range(r['alpha_deg'], 'deg', '+.1f')} from the vented baseline")
        return lines + [settling_line(summary)]


def _range(span: list[float] | None, unit: str, fmt: str = ".1f") -> str:
    if span is None:
        return "none"
    # "+ 0.0" turns a -0.0 (a vented sensor's noise, rounded) into 0.0.
    lo, hi = (float(f"{v:{fmt}}") + 0.0 for v in span)
    return f"{lo:{fmt}} to {hi:{fmt}} {unit}"


RECORD_TYPES = {
    "rpam-stretch": PointRecords("rpam-stretch", "stretch", "stretch test"),
    "rpam-joint": PointRecords("rpam-joint", "joint", "joint map"),
}
