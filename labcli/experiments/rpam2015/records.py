"""The rPAM runs' records: one point of the stretch test or of the joint map.

In the run file (SI: MPa gauge, rad, m, kg)::

    points/000007/   @point @experiment ("stretch" | "joint"), the set values as typed
                     @plan_mass_g @plan_P_A_kPa @plan_P_B_kPa
        P (2,) MPa   P_A, P_B (@channels)
        stretch:     mass () kg, L () m (actuator A's length), lambda () 1 (L / L0)
        joint map:   alpha () rad (deflection from the vented baseline), P0 (2,) MPa and
                     pot0 () rad of the baseline, L () m

The record a session commits (and ``RunFile.write`` takes): ``point`` (id), ``experiment``
(as the run's kind says), ``P_MPa`` (2,); stretch points ``mass_kg``, ``L_m``, ``lambda``;
joint-map points ``alpha_rad`` and optionally ``P0_MPa`` (2,), ``pot0_rad``, ``L_m``;
``plan`` (the set values: ``mass_g``, ``P_A_kPa``, ``P_B_kPa``); then ``settle``, ``raw``,
``started``, ``ended`` as every record.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Mapping

from ...core.experiment import Dataset, Stored
from ...core.protocol import loads_protocol
from ...core.report import ids_text, settling_line
from ...core.store.h5 import nan_if_empty, plain, scalar, to_edge, vector
from ...core.store.records import BaseRecordType
from ...core.tables import TableSpec
from .session import acquisition_protocol
from ...errors import LabcliError, StoreError
from .tables import POINT_SPECS

# key in the record -> (dataset, units)
_DATASETS = {"mass_kg": ("mass", "kg"), "L_m": ("L", "m"), "lambda": ("lambda", "1"),
             "alpha_rad": ("alpha", "rad"), "pot0_rad": ("pot0", "rad")}


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

    @property
    def qualifier(self) -> str:
        return f" of the {self.title}"

    @property
    def table_spec(self) -> TableSpec:
        return POINT_SPECS[self.experiment]

    def check(self, record: Mapping[str, Any], label: str, run: Any) -> Stored:
        if record.get("experiment", self.experiment) != self.experiment:
            raise StoreError(f"{label}: a {record['experiment']} point cannot go into {run.path}, "
                             f"a {run.kind} run.")
        p = vector(record, "P_MPa", 2, "pressures P_A, P_B in MPa", label)
        p0 = vector(record, "P0_MPa", 2, "baseline pressures P_A, P_B in MPa", label) if "P0_MPa" in record else None
        needed = ("mass_kg", "L_m", "lambda") if self.experiment == "stretch" else ("alpha_rad",)
        values = {}
        for key in needed:
            values[key] = scalar(record, key, label)
            if not math.isfinite(values[key]):
                raise StoreError(f"{label} record lacks a finite '{key}', which a {self.experiment} point needs.")
        for key in ("L_m", "pot0_rad"):
            if key not in values and key in record:
                values[key] = scalar(record, key, label)
        attrs = {"experiment": self.experiment}
        attrs.update({f"plan_{k}": v if isinstance(v, str) else float(v) for k, v in (record.get("plan") or {}).items()})
        datasets = [Dataset("P", p, "MPa", {"channels": "P_A,P_B"})]
        if p0 is not None:
            datasets.append(Dataset("P0", p0, "MPa", {"channels": "P_A,P_B"}))
        datasets += [Dataset(_DATASETS[key][0], v, _DATASETS[key][1]) for key, v in values.items()]
        return Stored(attrs, datasets)

    def read(self, g: Any) -> dict[str, Any]:
        rec: dict[str, Any] = {"point": int(g.attrs["point"]), "experiment": self.experiment, "P_MPa": g["P"][()]}
        if "P0" in g:
            rec["P0_MPa"] = g["P0"][()]
        for key, (name, _) in _DATASETS.items():
            if name in g:
                rec[key] = float(g[name][()])
        rec["plan"] = {k[5:]: plain(v) for k, v in g.attrs.items() if k.startswith("plan_")}
        return rec

    def table(self, run: Any, ids: list[int], groups: list[Any]) -> Any:
        """The table of an rPAM run (DataFrame): MPa and m, grams and degrees at the edge.

        Stretch test: ``point, mass_g, P_A, P_B, L_m, lambda``; joint map: ``point, P_A,
        P_B, alpha_deg, P_A0, P_B0, L_m`` (pressures in MPa, ``alpha_deg`` the deflection
        from the vented baseline); then the set values as ``set_mass_g``, ``set_P_A_kPa``,
        ``set_P_B_kPa``.  Rows in recording order.  ``labcli export`` writes this table and
        ``labcli import`` reads it back.
        """
        import pandas as pd

        cols: dict[str, list] = {"point": list(ids)}

        def get(g: Any, key: str, i: int | None = None) -> float:
            if key not in g:
                return math.nan
            v = g[key][()]
            return float(v if i is None else v[i])

        stretch = self.experiment == "stretch"
        if stretch:
            cols["mass_g"] = list(to_edge([get(g, "mass") * 1e3 for g in groups]))
        cols["P_A"] = [get(g, "P", 0) for g in groups]
        cols["P_B"] = [get(g, "P", 1) for g in groups]
        if stretch:
            cols["L_m"] = [get(g, "L") for g in groups]
            cols["lambda"] = [get(g, "lambda") for g in groups]
        else:
            cols["alpha_deg"] = list(to_edge([math.degrees(get(g, "alpha")) for g in groups]))
            cols["P_A0"] = [get(g, "P0", 0) for g in groups]
            cols["P_B0"] = [get(g, "P0", 1) for g in groups]
            cols["L_m"] = [get(g, "L") for g in groups]
        for key in ("mass_g", "P_A_kPa", "P_B_kPa"):
            vals = [float(g.attrs.get(f"plan_{key}", math.nan)) for g in groups]
            if any(math.isfinite(v) for v in vals):
                cols[f"set_{key}"] = vals
        df = pd.DataFrame(cols)
        df["point"] = df["point"].astype("int64")
        return df

    def from_row(self, row: Mapping[str, Any], protocol: Any) -> dict[str, Any]:
        """One row of a point table as the record the run file takes (SI)."""

        def value(key: str) -> float:
            return nan_if_empty(row.get(key))

        record: dict[str, Any] = {"point": int(row["point"]), "experiment": self.experiment,
                                  "P_MPa": [value("P_A"), value("P_B")]}
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

    def summarise(self, run: Any, ids: list[int], groups: list[Any]) -> dict[str, Any]:
        """The experiment, its grid's coverage and the ranges measured (``labcli inspect``).

        ``planned``/``missing_ids`` come from the protocol embedded in the run (None for an
        imported table, whose grid need not be the protocol's); ranges are [min, max] over
        the complete points (None when there is none): pressures in kPa, payloads in g,
        deflections in degrees.
        """
        import numpy as np

        table = self.table(run, ids, groups)

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
        lines = [f"  experiment  {r['title']}",
                 f"  points      {summary['complete']}{of} complete, {summary['incomplete']} incomplete{incomplete}"]
        if r["missing_ids"]:
            lines.append(f"  to record   {len(r['missing_ids'])} points ({ids_text(r['missing_ids'])}); "
                         "labcli acquire --resume records them")
        lines.append(f"  pressures   P_A {_range(r['P_A_kPa'], 'kPa')}, P_B {_range(r['P_B_kPa'], 'kPa')} (measured)")
        if r["experiment"] == "stretch":
            payloads = ", ".join(f"{m:g}" for m in r["payloads_g"])
            lines.append(f"  payloads    {payloads + ' g' if payloads else 'none'}; "
                         f"stretch lambda {_range(r['lambda'], '(L / L0)', '.3f')}")
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
