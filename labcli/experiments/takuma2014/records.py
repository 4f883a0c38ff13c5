"""The McKibben rig's records: a force/angle trial (Section 3.2) and an object push (Section 4).

What each record holds in its group of the run file (SI: MPa gauge, rad, N, m, kg)::

    trials/000012/   @trial @plan_set @plan_mass_g @plan_direction_deg (the plan row)
        P0 (4,) MPa     baseline pressures P_L1, P_R1, P_L2, P_R2 (@channels)
        P  (4,) MPa     pressures under the load
        theta (2,) rad  joint deflections under the load; pot0 (2,) rad baseline angles (optional)
        F (2,) N        Fx, Fy at the contact point
        mass () kg, direction () rad   the pulley load (NaN when not a pulley load)
    pushes/000003/   @push @object @category
        P0, P (4,) MPa, R () m, d () m, phi () rad (NaN: unknown),
        true_stiffness () N/m (NaN unless simulated), theta and pot0 (optional)

The run file adds what every record has (times, settling, raw windows, extra columns).
Tables come out in the CSV exchange units (:mod:`.tables`): MPa, N, degrees, grams; degrees
and grams rounded to 12 significant digits, so table -> run file -> table is exact.
"""

from __future__ import annotations

import math
import os
from typing import Any, Mapping

from ...core.bounds import wrap_degrees_array
from ...core.experiment import Dataset, Stored
from ...core.report import records_line, settling_line, split_line
from ...core.store.h5 import missing, nan_if_empty, plain, scalar, text, to_edge, vector
from ...core.store import load_table
from ...core.store.records import BaseRecordType
from ...errors import ConfigError, StoreError
from .tables import BASELINE, LOADED, PUSH, REST, TRIAL

PRESSURE_NAMES = LOADED  # P_L1, P_R1, P_L2, P_R2
_PRESSURE_ATTRS = {"channels": ",".join(PRESSURE_NAMES)}


class _McKibbenRecords(BaseRecordType):
    """What trials and pushes share: four pressures before and under the load, the drift of the baseline."""

    def summarise(self, run: Any, ids: list[int], groups: list[Any]) -> dict[str, Any]:
        """How the baseline pressures moved over the run (recording order), from 2 records on."""
        import numpy as np

        if len(groups) < 2:
            return {}
        p0 = np.array([g["P0"][()] for g in groups])
        index = np.arange(len(groups), dtype=np.float64)
        drift = {}
        for c, name in enumerate(PRESSURE_NAMES):
            slope = np.polyfit(index, p0[:, c], 1)[0]
            drift[name] = {
                "first_MPa": float(p0[0, c]),
                "last_MPa": float(p0[-1, c]),
                "slope_kPa_per_trial": float(slope * 1e3),
                "max_deviation_kPa": float(np.max(np.abs(p0[:, c] - p0[0, c])) * 1e3),
            }
        return {"baseline_drift": drift, "baseline_leak": _leak(run, ids, groups, p0)}

    def inspect_lines(self, summary: dict[str, Any]) -> list[str]:
        return [records_line(summary), split_line(summary), settling_line(summary), *drift_lines(summary),
                *leak_lines(summary)]

    @staticmethod
    def _rest_posture(df: Any, groups: list[Any]) -> None:
        """The rest posture columns (deg) from each record's baseline angles ``pot0``, when any has them."""
        import numpy as np

        pot0 = [g["pot0"][()] if "pot0" in g else np.full(2, np.nan) for g in groups]
        if any(np.all(np.isfinite(p)) for p in pot0):
            rest = np.degrees(np.array(pot0, dtype=np.float64).reshape(-1, 2))
            for j, name in enumerate(REST):
                df[name] = to_edge(rest[:, j])

    @staticmethod
    def _rest_from_row(row: Mapping[str, Any]) -> dict[str, Any]:
        """``pot0_rad`` from a table row's rest posture (deg), when the row gives one."""
        a, b = (nan_if_empty(row.get(c)) for c in REST)
        return {} if math.isnan(a) or math.isnan(b) else {"pot0_rad": [math.radians(a), math.radians(b)]}

    @staticmethod
    def _pressures(record: Mapping[str, Any], label: str, loaded: str) -> list[Dataset]:
        p0 = vector(record, "P0_MPa", 4, "baseline pressures P_L1,P_R1,P_L2,P_R2 in MPa", label)
        p = vector(record, "P_MPa", 4, loaded, label)
        return [Dataset("P0", p0, "MPa", _PRESSURE_ATTRS), Dataset("P", p, "MPa", _PRESSURE_ATTRS)]


def drift_lines(s: dict[str, Any]) -> list[str]:
    """How the baseline pressures of a force or push run moved over the records."""
    rec = s["records"]
    drift = s["baseline_drift"]
    if not drift:
        return ["  baseline drift  needs at least 2 complete records"]
    lines = [f"  baseline drift over {s['complete']} {rec} (recording order):"]
    for name, d in drift.items():
        lines.append(f"    {name:<5} first {d['first_MPa']:.4f} MPa, last {d['last_MPa']:.4f} MPa, "
                     f"slope {d['slope_kPa_per_trial']:+.3f} kPa/{rec[:-1] if rec == 'trials' else 'push'}, "
                     f"max deviation {d['max_deviation_kPa']:.3f} kPa")
    return lines


def _baseline_times(run: Any, rid: int, group: Any) -> Any:
    """Device times (s) of a record's baseline window, None without one.

    Read from the record's group where the run file keeps it there (30 times faster than
    decoding the whole record), else through :meth:`RunFile.read`."""
    try:
        return group["baseline"]["time"][()]
    except (KeyError, TypeError):
        window = run.read(rid)["raw"].get("baseline")
        return None if window is None else window["t_s"]


def _leak(run: Any, ids: list[int], groups: list[Any], p0: Any) -> dict[str, Any] | None:
    """The baseline pressures' loss per minute of device time, from the records' baseline windows.

    The valves stay closed from the first baseline to the last, so a chamber that leaks
    loses pressure between baselines at its own rate; the slope of a straight line
    through (baseline window's mean device time, P0) is that rate.  The arm's posture
    after each unload differs a little (sleeve friction), which scatters the baselines
    by a fraction of a kPa but does not tilt the line.  None for records without raw
    windows (an imported table) or when the baselines span no time.
    """
    import numpy as np

    times = []
    for rid, g in zip(ids, groups):
        t_s = _baseline_times(run, rid, g)
        if t_s is None or len(t_s) == 0:
            return None
        times.append(float(np.mean(t_s)))
    t = np.asarray(times)
    if np.ptp(t) <= 0:
        return None
    loss = {name: float(-np.polyfit(t, p0[:, c], 1)[0] * 1e3 * 60) for c, name in enumerate(PRESSURE_NAMES)}
    return {"span_s": float(np.ptp(t)), "loss_kPa_per_min": loss}


def leak_lines(s: dict[str, Any]) -> list[str]:
    """How fast the baselines lost pressure per minute of device time (the closed chambers' leak)."""
    leak = s.get("baseline_leak")
    if not leak:
        return []
    rates = ", ".join(f"{name} {v:.2f}" for name, v in leak["loss_kPa_per_min"].items())
    return [f"  leak        baseline pressure lost over {leak['span_s'] / 60:.1f} min of device time, valves closed:",
            f"    {rates} kPa/min"]


class TrialRecords(_McKibbenRecords):
    """Force/angle trials of a ``force`` run: loaded pressures, deflections, the pulley load."""

    kind = "force"
    collection = "trials"
    id_column = "trial"
    noun = "trial"
    plural = "trials"
    splits = True
    table_spec = TRIAL

    def check(self, record: Mapping[str, Any], label: str, run: Any) -> Stored:
        """A trial (keys of ``TrialRecord`` in the run file's docs), checked before anything is written."""
        pressures = self._pressures(record, label, "loaded pressures P_L1,P_R1,P_L2,P_R2 in MPa")
        theta = vector(record, "theta_rad", 2, "joint deflections in rad", label)
        force = vector(record, "force_N", 2, "Fx, Fy in N", label)
        pot0 = (vector(record, "pot0_rad", 2, "baseline potentiometer angles in rad", label)
                if "pot0_rad" in record else None)
        mass = scalar(record, "mass_kg", label)
        direction = scalar(record, "direction_rad", label)
        plan = dict(record.get("plan") or {})
        if "set" in record and "set" not in plan:
            plan["set"] = record["set"]
        attrs = {f"plan_{k}": v if isinstance(v, str) else float(v) for k, v in plan.items()}
        datasets = [*pressures, Dataset("theta", theta, "rad")]
        if pot0 is not None:
            datasets.append(Dataset("pot0", pot0, "rad"))
        datasets += [Dataset("F", force, "N", {"components": "Fx,Fy"}), Dataset("mass", mass, "kg"),
                     Dataset("direction", direction, "rad")]
        return Stored(attrs, datasets)

    def read(self, g: Any) -> dict[str, Any]:
        rec: dict[str, Any] = {
            "trial": int(g.attrs["trial"]),
            "P0_MPa": g["P0"][()], "P_MPa": g["P"][()], "theta_rad": g["theta"][()], "force_N": g["F"][()],
            "mass_kg": float(g["mass"][()]), "direction_rad": float(g["direction"][()]),
            "plan": {k[5:]: plain(v) for k, v in g.attrs.items() if k.startswith("plan_")},
        }
        if "pot0" in g:
            rec["pot0_rad"] = g["pot0"][()]
        return rec

    def table(self, run: Any, ids: list[int], groups: list[Any]) -> Any:
        """The trial table (docs/table-formats.md): MPa, N, degrees and grams; ``set`` from the split."""
        import numpy as np
        import pandas as pd

        sets = run.set_of()
        cols: dict[str, Any] = {c: [] for c in TRIAL.names if c not in ("mass_g", "direction_deg", *REST)}
        mass, direction = [], []
        for t, g in zip(ids, groups):
            p0, p, theta, force = g["P0"][()], g["P"][()], g["theta"][()], g["F"][()]
            cols["trial"].append(t)
            cols["set"].append(sets.get(t, ""))
            for name, v in zip(BASELINE, p0):
                cols[name].append(float(v))
            for name, v in zip(LOADED, p):
                cols[name].append(float(v))
            cols["theta1_deg"].append(math.degrees(theta[0]))
            cols["theta2_deg"].append(math.degrees(theta[1]))
            cols["Fx_N"].append(float(force[0]))
            cols["Fy_N"].append(float(force[1]))
            mass.append(float(g["mass"][()]) * 1e3)
            direction.append(math.degrees(float(g["direction"][()])))
        df = pd.DataFrame(cols)
        df["trial"] = df["trial"].astype("int64")
        df["set"] = df["set"].astype(object)
        for c in ("theta1_deg", "theta2_deg"):
            df[c] = to_edge(df[c].to_numpy())
        if np.any(np.isfinite(mass)):
            df["mass_g"] = to_edge(mass)
        if np.any(np.isfinite(direction)):
            df["direction_deg"] = wrap_degrees_array(to_edge(direction))
        self._rest_posture(df, groups)
        return df

    def from_row(self, row: Mapping[str, Any], protocol: Any) -> dict[str, Any]:
        return {
            "trial": int(row["trial"]),
            "P0_MPa": [row[c] for c in BASELINE], "P_MPa": [row[c] for c in LOADED],
            "theta_rad": [math.radians(row["theta1_deg"]), math.radians(row["theta2_deg"])],
            "force_N": [row["Fx_N"], row["Fy_N"]],
            "mass_kg": nan_if_empty(row.get("mass_g")) * 1e-3,
            "direction_rad": math.radians(nan_if_empty(row.get("direction_deg"))),
            **self._rest_from_row(row),
        }

    def import_split(self, rows: list[dict[str, Any]]) -> tuple[list[int], list[int]]:
        """The ``set`` column of an imported trial table as the run's split."""
        fit, val = [], []
        for row in rows:
            s = "" if missing(row.get("set")) else str(row["set"])
            if s not in ("fit", "validation", ""):
                raise ConfigError(f"trial {int(row['trial'])}: set must be fit, validation or empty, got {s!r}.")
            (fit if s == "fit" else val if s == "validation" else []).append(int(row["trial"]))
        return fit, val


class PushRecords(_McKibbenRecords):
    """Object pushes of a ``push`` run: pressures before and with the object pushed in."""

    kind = "push"
    collection = "pushes"
    id_column = "push"
    noun = "push"
    plural = "pushes"
    table_spec = PUSH

    @property
    def known_columns(self) -> frozenset[str]:
        return frozenset((*PUSH.names, "true_stiffness_N_per_m"))

    def check(self, record: Mapping[str, Any], label: str, run: Any) -> Stored:
        """A push (keys of ``PushRecord`` in the run file's docs), checked before anything is written."""
        pressures = self._pressures(record, label, "pressures with the object pushed in, MPa")
        if "object" not in record:
            raise StoreError(f"{label} record lacks 'object' (the object name).")
        radius = scalar(record, "R_m", label)
        distance = scalar(record, "d_m", label)
        phi = scalar(record, "phi_rad", label)
        stiffness = scalar(record, "true_stiffness_N_per_m", label)
        theta = vector(record, "theta_rad", 2, "joint deflections in rad", label) if "theta_rad" in record else None
        pot0 = (vector(record, "pot0_rad", 2, "baseline potentiometer angles in rad", label)
                if "pot0_rad" in record else None)
        attrs = {"object": str(record["object"]), "category": str(record.get("category", "") or "")}
        datasets = [*pressures, Dataset("R", radius, "m"), Dataset("d", distance, "m"), Dataset("phi", phi, "rad"),
                    Dataset("true_stiffness", stiffness, "N/m")]
        if theta is not None:
            datasets.append(Dataset("theta", theta, "rad"))
        if pot0 is not None:
            datasets.append(Dataset("pot0", pot0, "rad"))
        return Stored(attrs, datasets)

    def read(self, g: Any) -> dict[str, Any]:
        optional = {key: g[name][()] for key, name in (("theta_rad", "theta"), ("pot0_rad", "pot0")) if name in g}
        return {
            **optional,
            "push": int(g.attrs["push"]), "object": text(g.attrs["object"]), "category": text(g.attrs["category"]),
            "R_m": float(g["R"][()]), "d_m": float(g["d"][()]), "phi_rad": float(g["phi"][()]),
            "true_stiffness_N_per_m": float(g["true_stiffness"][()]),
            "P0_MPa": g["P0"][()], "P_MPa": g["P"][()],
        }

    def table(self, run: Any, ids: list[int], groups: list[Any]) -> Any:
        """The push table (docs/table-formats.md): m, degrees, MPa; ``phi_deg`` NaN when unknown."""
        import numpy as np
        import pandas as pd

        cols: dict[str, Any] = {c: [] for c in PUSH.names if c not in REST}
        stiffness = []
        for t, g in zip(ids, groups):
            cols["push"].append(t)
            cols["object"].append(text(g.attrs["object"]))
            cols["R_m"].append(float(g["R"][()]))
            cols["d_m"].append(float(g["d"][()]))
            cols["phi_deg"].append(math.degrees(float(g["phi"][()])))
            for name, v in zip(BASELINE, g["P0"][()]):
                cols[name].append(float(v))
            for name, v in zip(LOADED, g["P"][()]):
                cols[name].append(float(v))
            cols["category"].append(text(g.attrs["category"]))
            stiffness.append(float(g["true_stiffness"][()]))
        df = pd.DataFrame(cols)
        df["push"] = df["push"].astype("int64")
        df["phi_deg"] = wrap_degrees_array(to_edge(df["phi_deg"].to_numpy()))
        self._rest_posture(df, groups)
        if np.any(np.isfinite(stiffness)):
            df["true_stiffness_N_per_m"] = stiffness
        return df

    def from_row(self, row: Mapping[str, Any], protocol: Any) -> dict[str, Any]:
        return {
            "push": int(row["push"]), "object": str(row["object"]),
            "R_m": float(row["R_m"]), "d_m": float(row["d_m"]),
            "phi_rad": math.radians(nan_if_empty(row.get("phi_deg"))),
            "category": "" if missing(row.get("category")) else str(row["category"]),
            "true_stiffness_N_per_m": nan_if_empty(row.get("true_stiffness_N_per_m")),
            "P0_MPa": [row[c] for c in BASELINE], "P_MPa": [row[c] for c in LOADED],
            **self._rest_from_row(row),
        }


RECORD_TYPES = {"force": TrialRecords(), "push": PushRecords()}


def load_trials(path: str | os.PathLike) -> Any:
    """The trial table (DataFrame) of a run file (``.h5``) or a trial CSV."""
    return load_table(path, RECORD_TYPES["force"])


def load_pushes(path: str | os.PathLike) -> Any:
    """The push table (DataFrame) of a run file (``.h5``) or a push CSV."""
    return load_table(path, RECORD_TYPES["push"])
