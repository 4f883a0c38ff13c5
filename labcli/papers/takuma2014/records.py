"""The McKibben rig's records: a force/angle trial (Section 3.2) and an object push (Section 4).

The columns each record holds in its run's table (SI: MPa gauge, rad, N, m, kg)::

    trials   P0 (4,) MPa    baseline pressures P_L1, P_R1, P_L2, P_R2
             P  (4,) MPa    pressures under the load
             theta (2,) rad joint deflections under the load; pot0 (2,) rad baseline angles
             F (2,) N       Fx, Fy at the contact point
             mass kg, direction rad   the pulley load (NaN when not a pulley load)
             plan_set, plan_mass_g, plan_direction_deg   the plan row it followed
             relief_vent   the side the friction relief vented before the baseline (L, R; empty: none)
    pushes   P0, P (4,) MPa, R m, d m, phi rad (NaN: unknown), true_stiffness N/m (NaN unless
             simulated), theta and pot0 (2,) rad (NaN when not measured), object, category

The run file adds what every record has (id, times, settling, raw windows, extra columns).
Tables come out in the CSV exchange units (:mod:`.tables`): MPa, N, degrees, grams; degrees
and grams rounded to 12 significant digits, so table -> run file -> table is exact.
"""

from __future__ import annotations

import math
import os
from collections.abc import Mapping
from typing import Any

import numpy as np

from ...core.air import RELIEF_SIDES as VENTED_SIDES
from ...core.arrays import rows_all, stack_columns
from ...core.bounds import wrap_degrees_array
from ...core.files import RUN_FILE_SUFFIXES
from ...core.paper import Column
from ...core.record import Record
from ...core.report import records_line, settling_line, split_line
from ...core.store import load_table
from ...core.store.h5 import missing, nan_if_empty, scalar, to_edge, vector
from ...core.store.record_type import BaseRecordType
from ...errors import ConfigError, StoreError
from .sense_records import SenseRecords
from .tables import BASELINE, LOADED, PUSH, REST, TRIAL

PRESSURE_NAMES = LOADED  # P_L1, P_R1, P_L2, P_R2
RELIEF_SIDES = ("", *VENTED_SIDES)  # a trial's relief_vent: no relief, or the side vented before its baseline
TWO_PI = 2 * math.pi
# Physical ranges of what a record can hold; a value read back outside one marks the record
# damaged.  Wide on purpose: they catch a changed file, not an unusual experiment.
PRESSURE_BOUNDS = (-1.0, 10.0)  # MPa gauge: no pneumatic rig of this kind goes near 10 MPa
ANGLE_BOUNDS = (-TWO_PI, TWO_PI)  # rad: a joint cannot turn more than a full turn either way
FORCE_BOUNDS = (-1e5, 1e5)  # N
LENGTH_BOUNDS = (-10.0, 10.0)  # m
DEG_BOUNDS = (-1e4, 1e4)  # deg, a direction typed in a plan


class _TrialOptional(Record, total=False):
    set: str  # the plan's set (fit, validation)
    pot0_rad: np.ndarray  # (2,) baseline potentiometer angles
    plan: dict[str, Any]  # the plan row it followed: set, mass_g, direction_deg
    relief_vent: str  # the side the friction relief vented before the baseline: L or R


class TrialRecord(_TrialOptional):
    """A force/angle trial as a session commits it (SI), beside what every record carries."""

    trial: int
    P0_MPa: np.ndarray  # (4,) baseline pressures P_L1, P_R1, P_L2, P_R2
    P_MPa: np.ndarray  # (4,) pressures under the load
    theta_rad: np.ndarray  # (2,) joint deflections under the load
    force_N: np.ndarray  # (2,) Fx, Fy at the contact point
    mass_kg: float  # the pulley load (NaN when not a pulley load)
    direction_rad: float


class _PushOptional(Record, total=False):
    true_stiffness_N_per_m: float  # the simulated object's (absent at a real rig)


class PushRecord(_PushOptional):
    """An object push (Section 4) as a session commits it (SI), beside what every record carries."""

    push: int
    object: str
    category: str
    R_m: float  # the object's radius
    d_m: float  # how far it was pushed
    phi_rad: float  # the push direction (NaN: unknown)
    P0_MPa: np.ndarray  # (4,)
    P_MPa: np.ndarray  # (4,)
    pot0_rad: np.ndarray  # (2,)
    theta_rad: np.ndarray  # (2,)


def _pressure(name: str, what: str, optional: bool = False) -> Column:
    return Column(
        name, "MPa", shape=(4,), components=PRESSURE_NAMES, bounds=PRESSURE_BOUNDS, optional=optional, what=what
    )


def _angles(name: str, what: str, optional: bool = False) -> Column:
    return Column(
        name, "rad", shape=(2,), components=("theta1", "theta2"), bounds=ANGLE_BOUNDS, optional=optional, what=what
    )


class _McKibbenRecords(BaseRecordType):
    """What trials and pushes share: four pressures before and under the load, the drift of the baseline."""

    signal = "P"

    def summarise(self, run: Any, ids: list[int], cols: Mapping[str, Any]) -> dict[str, Any]:
        """How the baseline pressures moved over the run (recording order), from 2 records on."""
        if len(ids) < 2:
            return {}
        p0 = np.asarray(cols["P0"], dtype=np.float64)
        index = np.arange(len(ids), dtype=np.float64)
        drift = {}
        for c, name in enumerate(PRESSURE_NAMES):
            slope = np.polyfit(index, p0[:, c], 1)[0]
            drift[name] = {
                "first_MPa": float(p0[0, c]),
                "last_MPa": float(p0[-1, c]),
                "slope_kPa_per_trial": float(slope * 1e3),
                "max_deviation_kPa": float(np.max(np.abs(p0[:, c] - p0[0, c])) * 1e3),
            }
        return {"baseline_drift": drift, "baseline_leak": _leak(run, ids, cols, p0)}

    def inspect_lines(self, summary: dict[str, Any]) -> list[str]:
        return [
            records_line(summary),
            split_line(summary),
            settling_line(summary),
            *drift_lines(summary),
            *leak_lines(summary),
        ]

    @staticmethod
    def _rest_posture(df: Any, cols: Mapping[str, Any], n: int) -> None:
        """The rest posture columns (deg) from each record's baseline angles ``pot0``, when any has them
        (``df`` a frame or the dict of columns it is made from)."""
        if "pot0" not in cols:
            return
        rest = np.degrees(np.asarray(cols["pot0"], dtype=np.float64).reshape(n, 2))
        if np.any(rows_all(np.isfinite(rest))):
            for j, name in enumerate(REST):
                df[name] = to_edge(rest[:, j])

    @staticmethod
    def _rest_from_row(row: Mapping[str, Any]) -> dict[str, Any]:
        """``pot0_rad`` from a table row's rest posture (deg), when the row gives one."""
        a, b = (nan_if_empty(row.get(c)) for c in REST)
        return {} if math.isnan(a) or math.isnan(b) else {"pot0_rad": [math.radians(a), math.radians(b)]}

    @staticmethod
    def _rest_columns(table: Any, n: int) -> dict[str, Any]:
        """``pot0`` (rad, NaN where a row gives no rest posture) from a table's rest columns, if it has them."""
        if not all(c in table for c in REST):
            return {}
        parts = [_numbers(table, c, n) for c in REST]
        if not any(np.isfinite(p).any() for p in parts):  # an archive without rest postures: the fill throughout
            return {}
        rest = stack_columns(parts)
        rest[~rows_all(np.isfinite(rest))] = np.nan
        return {"pot0": np.radians(rest)}

    @staticmethod
    def _pressures(record: Mapping[str, Any], label: str, loaded: str) -> dict[str, Any]:
        p0 = vector(record, "P0_MPa", 4, "baseline pressures P_L1,P_R1,P_L2,P_R2 in MPa", label)
        p = vector(record, "P_MPa", 4, loaded, label)
        return {"P0": p0, "P": p}


def drift_lines(s: dict[str, Any]) -> list[str]:
    """How the baseline pressures of a force or push run moved over the records."""
    rec = s["records"]
    drift = s["baseline_drift"]
    if not drift:
        return ["  baseline drift  needs at least 2 complete records"]
    lines = [f"  baseline drift over {s['complete']} {rec} (recording order):"]
    for name, d in drift.items():
        lines.append(
            f"    {name:<5} first {d['first_MPa']:.4f} MPa, last {d['last_MPa']:.4f} MPa, "
            f"slope {d['slope_kPa_per_trial']:+.3f} kPa/{'push' if rec == 'pushes' else rec[:-1]}, "
            f"max deviation {d['max_deviation_kPa']:.3f} kPa"
        )
    return lines


def _finite(values: Any) -> bool:
    return bool(np.all(np.isfinite(values)))


def _baseline_times(run: Any, rid: int, i: int, cols: Mapping[str, Any]) -> Any:
    """Device times (s) of a record's baseline window, None without one.

    Read as a range of the run's raw frames where the run file keeps them so (schema 2: no
    need to decode the whole record), else through ``run.records.read``."""
    if getattr(run, "version", 1) >= 2 and "baseline_start" in cols:
        a, b = int(cols["baseline_start"][i]), int(cols["baseline_stop"][i])
        return None if a < 0 else run.windows.frames(a, b).t_s
    window = run.records.read(rid)["raw"].get("baseline")
    return None if window is None else window.t_s


def _leak(run: Any, ids: list[int], cols: Mapping[str, Any], p0: Any) -> dict[str, Any] | None:
    """The baseline pressures' loss per minute of device time, from the records' baseline windows.

    The valves stay closed from the first baseline to the last, so a chamber that leaks
    loses pressure between baselines at its own rate; the slope of a straight line
    through (baseline window's mean device time, P0) is that rate.  The arm's posture
    after each unload differs a little (sleeve friction), which scatters the baselines
    by a fraction of a kPa but does not tilt the line.  None for records without raw
    windows (an imported table) or when the baselines span no time.
    """
    import numpy as np

    from ...errors import StoreError

    times = []
    for i, rid in enumerate(ids):
        try:
            t_s = _baseline_times(run, rid, i, cols)
        except StoreError:  # a damaged window: no leak figure rather than one from fill
            return None
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
    return [
        f"  leak        baseline pressure lost over {leak['span_s'] / 60:.1f} min of device time, valves closed:",
        f"    {rates} kPa/min",
    ]


def check_relief_sides(table: Any) -> None:
    """Refuse, in one sentence naming the trial, a trial table (imported, or read by fit and validate)
    whose ``relief_vent`` holds another side than L, R or empty: the labels read the play's states
    from it (models/labels.py), and would take another as no relief."""
    import pandas as pd

    if "relief_vent" not in table:
        return
    codes, names = pd.factorize(table["relief_vent"], use_na_sentinel=True)
    for k, s in enumerate(names):
        if not missing(s) and str(s) not in RELIEF_SIDES:
            t = table["trial"].to_numpy()[int(np.flatnonzero(codes == k)[0])]
            raise ConfigError(f"trial {int(t)}: relief_vent must be L, R or empty, got {str(s)!r}.")


class TrialRecords(_McKibbenRecords):
    """Force/angle trials of a ``force`` run: loaded pressures, deflections, the pulley load."""

    kind = "force"
    collection = "trials"
    id_column = "trial"
    noun = "trial"
    plural = "trials"
    splits = True
    table_spec = TRIAL
    columns = (
        _pressure("P0", "baseline pressures"),
        _pressure("P", "pressures under the load"),
        _angles("theta", "joint deflections under the load"),
        _angles("pot0", "baseline potentiometer angles", optional=True),
        Column("F", "N", shape=(2,), components=("Fx", "Fy"), bounds=FORCE_BOUNDS, what="force at the contact point"),
        Column("mass", "kg", bounds=(0.0, 1e4), optional=True, what="pulley mass"),
        Column("direction", "rad", bounds=(-1e3, 1e3), optional=True, what="pulley direction"),
        Column("plan_set", "", kind="text", width=16, optional=True, what="the plan's set"),
        Column("plan_mass_g", "g", bounds=(0.0, 1e7), optional=True, what="the plan's mass"),
        Column("plan_direction_deg", "deg", bounds=DEG_BOUNDS, optional=True, what="the plan's direction"),
        Column("relief_vent", "", kind="text", width=1, optional=True, what="the side the relief vented"),
    )
    added_columns = frozenset({"relief_vent"})  # runs from before it have none

    def check(self, record: Mapping[str, Any], label: str, run: Any) -> dict[str, Any]:
        """A trial (:class:`TrialRecord`), checked before anything is written."""
        row = self._pressures(record, label, "loaded pressures P_L1,P_R1,P_L2,P_R2 in MPa")
        row["theta"] = vector(record, "theta_rad", 2, "joint deflections in rad", label)
        row["F"] = vector(record, "force_N", 2, "Fx, Fy in N", label)
        if "pot0_rad" in record:
            row["pot0"] = vector(record, "pot0_rad", 2, "baseline potentiometer angles in rad", label)
        row["mass"] = scalar(record, "mass_kg", label)
        row["direction"] = scalar(record, "direction_rad", label)
        plan = dict(record.get("plan") or {})
        if "set" in record and "set" not in plan:
            plan["set"] = record["set"]
        unknown = [k for k in plan if k not in ("set", "mass_g", "direction_deg")]
        if unknown:
            raise StoreError(
                f"{label} record: its plan row has {unknown[0]!r}; a trial's plan gives set, mass_g and direction_deg."
            )
        for key, v in plan.items():
            row[f"plan_{key}"] = str(v) if key == "set" else scalar(plan, key, label)
        vent = record.get("relief_vent", "")
        if vent not in RELIEF_SIDES:
            raise StoreError(f"{label} record: relief_vent must be L, R or empty, got {vent!r}.")
        if vent:
            row["relief_vent"] = vent
        return row

    def read(self, row: Mapping[str, Any]) -> dict[str, Any]:
        rec: dict[str, Any] = {
            "trial": int(row["trial"]),
            "P0_MPa": np.asarray(row["P0"]),
            "P_MPa": np.asarray(row["P"]),
            "theta_rad": np.asarray(row["theta"]),
            "force_N": np.asarray(row["F"]),
            "mass_kg": float(row["mass"]),
            "direction_rad": float(row["direction"]),
            "plan": _plan(row, {"set": "plan_set", "mass_g": "plan_mass_g", "direction_deg": "plan_direction_deg"}),
        }
        if _finite(row["pot0"]):
            rec["pot0_rad"] = np.asarray(row["pot0"])
        if row.get("relief_vent"):
            rec["relief_vent"] = str(row["relief_vent"])
        return rec

    def table(self, run: Any, ids: list[int], cols: Mapping[str, Any]) -> Any:
        """The trial table (docs/table-formats.md): MPa, N, degrees and grams; ``set`` from the split."""
        import pandas as pd

        data = self.table_columns(run, ids, cols)
        data["set"] = pd.Series(data["set"], dtype=object)
        return pd.DataFrame(data)

    def table_columns(self, run: Any, ids: list[int], cols: Mapping[str, Any]) -> dict[str, Any]:
        """:meth:`table`'s columns (name -> values over ``ids``), the frame not made: what the store
        checks each trial against the table's rules with (:func:`labcli.core.tables.columns_problems`)."""
        sets = run.split.set_of()
        n = len(ids)
        p0 = np.asarray(cols["P0"], dtype=np.float64).reshape(n, 4)
        p = np.asarray(cols["P"], dtype=np.float64).reshape(n, 4)
        theta = np.asarray(cols["theta"], dtype=np.float64).reshape(n, 2)
        force = np.asarray(cols["F"], dtype=np.float64).reshape(n, 2)
        # The columns gathered first, the frame made once: a column set on a frame copies its
        # blocks, and the store makes this table of one row for every trial it writes.
        data: dict[str, Any] = {"trial": np.asarray(ids, dtype=np.int64), "set": [sets.get(t, "") for t in ids]}
        for j, name in enumerate(BASELINE):
            data[name] = p0[:, j]
        for j, name in enumerate(LOADED):
            data[name] = p[:, j]
        data["theta1_deg"] = to_edge(np.degrees(theta[:, 0]))
        data["theta2_deg"] = to_edge(np.degrees(theta[:, 1]))
        data["Fx_N"] = force[:, 0]
        data["Fy_N"] = force[:, 1]
        mass = np.asarray(cols["mass"], dtype=np.float64) * 1e3
        direction = np.degrees(np.asarray(cols["direction"], dtype=np.float64))
        if np.any(np.isfinite(mass)):
            data["mass_g"] = to_edge(mass)
        if np.any(np.isfinite(direction)):
            data["direction_deg"] = wrap_degrees_array(to_edge(direction))
        self._rest_posture(data, cols, n)
        vent = [str(v) for v in cols.get("relief_vent", ())]
        if any(vent):  # a column of its own beside the exchange table's, as an imported one is
            data["relief_vent"] = vent
        return data

    def from_row(self, row: Mapping[str, Any], protocol: Any) -> dict[str, Any]:
        return {
            "trial": int(row["trial"]),
            "P0_MPa": [row[c] for c in BASELINE],
            "P_MPa": [row[c] for c in LOADED],
            "theta_rad": [math.radians(row["theta1_deg"]), math.radians(row["theta2_deg"])],
            "force_N": [row["Fx_N"], row["Fy_N"]],
            "mass_kg": nan_if_empty(row.get("mass_g")) * 1e-3,
            "direction_rad": math.radians(nan_if_empty(row.get("direction_deg"))),
            **self._rest_from_row(row),
        }

    def from_table(self, table: Any, protocol: Any) -> dict[str, Any]:
        """The trial table's rows as columns, all at once (what :meth:`from_row` gives row by row)."""
        n = len(table)
        check_relief_sides(table)
        theta = _rows(table, ["theta1_deg", "theta2_deg"])
        cols = {
            "trial": table["trial"].to_numpy(dtype=np.int64),
            "P0": _rows(table, BASELINE),
            "P": _rows(table, LOADED),
            "theta": np.radians(theta, out=theta),
            "F": _rows(table, ["Fx_N", "Fy_N"]),
            "mass": _numbers(table, "mass_g", n) * 1e-3,
            "direction": np.radians(_numbers(table, "direction_deg", n)),
            **self._rest_columns(table, n),
        }
        return cols

    def import_split(self, table: Any) -> tuple[list[int], list[int]]:
        """The ``set`` column of an imported trial table as the run's split."""
        import pandas as pd

        if "set" not in table:
            return [], []
        # Few distinct set names: each checked once, every row by its code (-1: a missing value).
        codes, names = pd.factorize(table["set"], use_na_sentinel=True)
        names = ["" if missing(s) else str(s) for s in names]
        trials = table["trial"].to_numpy()
        for k, s in enumerate(names):
            if s not in ("fit", "validation", ""):
                t = trials[int(np.flatnonzero(codes == k)[0])]
                raise ConfigError(f"trial {int(t)}: set must be fit, validation or empty, got {s!r}.")
        # By code, not by a million names compared as objects.
        fit = np.isin(codes, [k for k, s in enumerate(names) if s == "fit"])
        val = np.isin(codes, [k for k, s in enumerate(names) if s == "validation"])
        return trials[fit].astype(int).tolist(), trials[val].astype(int).tolist()


def _rows(table: Any, names: Any) -> np.ndarray:
    """Columns of numbers as one array of rows, C-ordered as a run file stores them (a DataFrame's
    ``to_numpy`` of several columns is Fortran-ordered: its row checksums and its write each copied it)."""
    return stack_columns([table[c].to_numpy(dtype=np.float64) for c in names])


def _numbers(table: Any, name: str, n: int) -> np.ndarray:
    """An optional column of numbers (empty cells NaN; NaN throughout when the table lacks it)."""
    import pandas as pd

    if name not in table:
        return np.full(n, np.nan)
    if table[name].dtype == np.float64:  # as the table reader gives it: numbers already, no empty text to find
        return table[name].to_numpy(dtype=np.float64)
    return pd.to_numeric(table[name].replace("", np.nan), errors="coerce").to_numpy(dtype=np.float64)


def _plan(row: Mapping[str, Any], keys: Mapping[str, str]) -> dict[str, Any]:
    """The plan row a record followed, from its ``plan_*`` columns (missing values left out)."""
    out: dict[str, Any] = {}
    for key, column in keys.items():
        if column not in row:
            continue
        v = row[column]
        if isinstance(v, str):
            if v:
                out[key] = v
        elif math.isfinite(float(v)):
            out[key] = float(v)
    return out


class PushRecords(_McKibbenRecords):
    """Object pushes of a ``push`` run: pressures before and with the object pushed in."""

    kind = "push"
    collection = "pushes"
    id_column = "push"
    noun = "push"
    plural = "pushes"
    table_spec = PUSH
    columns = (
        _pressure("P0", "baseline pressures"),
        _pressure("P", "pressures with the object pushed in"),
        Column("R", "m", bounds=(0.0, 10.0), what="object radius"),
        Column("d", "m", bounds=LENGTH_BOUNDS, what="push distance"),
        Column("phi", "rad", bounds=(-1e3, 1e3), optional=True, what="push direction"),
        Column("true_stiffness", "N/m", bounds=(0.0, 1e12), optional=True, what="true stiffness (simulated objects)"),
        _angles("theta", "joint deflections", optional=True),
        _angles("pot0", "baseline potentiometer angles", optional=True),
        Column("object", "", kind="text", width=64, what="object name"),
        Column("category", "", kind="text", width=32, optional=True, what="object category"),
    )

    @property
    def known_columns(self) -> frozenset[str]:
        return frozenset((*PUSH.names, "true_stiffness_N_per_m"))

    def check(self, record: Mapping[str, Any], label: str, run: Any) -> dict[str, Any]:
        """A push (keys of ``PushRecord`` in the run file's docs), checked before anything is written."""
        row = self._pressures(record, label, "pressures with the object pushed in, MPa")
        if "object" not in record:
            raise StoreError(f"{label} record lacks 'object' (the object name).")
        row.update(
            R=scalar(record, "R_m", label),
            d=scalar(record, "d_m", label),
            phi=scalar(record, "phi_rad", label),
            true_stiffness=scalar(record, "true_stiffness_N_per_m", label),
            object=str(record["object"]),
            category=str(record.get("category", "") or ""),
        )
        if "theta_rad" in record:
            row["theta"] = vector(record, "theta_rad", 2, "joint deflections in rad", label)
        if "pot0_rad" in record:
            row["pot0"] = vector(record, "pot0_rad", 2, "baseline potentiometer angles in rad", label)
        return row

    def read(self, row: Mapping[str, Any]) -> dict[str, Any]:
        optional = {
            key: np.asarray(row[name])
            for key, name in (("theta_rad", "theta"), ("pot0_rad", "pot0"))
            if _finite(row[name])
        }
        return {
            **optional,
            "push": int(row["push"]),
            "object": str(row["object"]),
            "category": str(row["category"]),
            "R_m": float(row["R"]),
            "d_m": float(row["d"]),
            "phi_rad": float(row["phi"]),
            "true_stiffness_N_per_m": float(row["true_stiffness"]),
            "P0_MPa": np.asarray(row["P0"]),
            "P_MPa": np.asarray(row["P"]),
        }

    def table(self, run: Any, ids: list[int], cols: Mapping[str, Any]) -> Any:
        """The push table (docs/table-formats.md): m, degrees, MPa; ``phi_deg`` NaN when unknown."""
        import pandas as pd

        data = self.table_columns(run, ids, cols)
        for name in ("object", "category"):
            data[name] = pd.Series(data[name], dtype=object)
        return pd.DataFrame(data)

    def table_columns(self, run: Any, ids: list[int], cols: Mapping[str, Any]) -> dict[str, Any]:
        """:meth:`table`'s columns (name -> values over ``ids``), the frame not made (the store's check)."""
        n = len(ids)
        p0 = np.asarray(cols["P0"], dtype=np.float64).reshape(n, 4)
        p = np.asarray(cols["P"], dtype=np.float64).reshape(n, 4)
        data: dict[str, Any] = {
            "push": np.asarray(ids, dtype=np.int64),
            "object": [str(x) for x in cols["object"]],
            "R_m": np.asarray(cols["R"], dtype=np.float64),
            "d_m": np.asarray(cols["d"], dtype=np.float64),
            "phi_deg": wrap_degrees_array(to_edge(np.degrees(np.asarray(cols["phi"], dtype=np.float64)))),
        }
        for j, name in enumerate(BASELINE):
            data[name] = p0[:, j]
        for j, name in enumerate(LOADED):
            data[name] = p[:, j]
        data["category"] = [str(x) for x in cols["category"]]
        stiffness = np.asarray(cols["true_stiffness"], dtype=np.float64)
        if np.any(np.isfinite(stiffness)):
            data["true_stiffness_N_per_m"] = stiffness
        self._rest_posture(data, cols, n)
        return data

    def from_row(self, row: Mapping[str, Any], protocol: Any) -> dict[str, Any]:
        return {
            "push": int(row["push"]),
            "object": str(row["object"]),
            "R_m": float(row["R_m"]),
            "d_m": float(row["d_m"]),
            "phi_rad": math.radians(nan_if_empty(row.get("phi_deg"))),
            "category": "" if missing(row.get("category")) else str(row["category"]),
            "true_stiffness_N_per_m": nan_if_empty(row.get("true_stiffness_N_per_m")),
            "P0_MPa": [row[c] for c in BASELINE],
            "P_MPa": [row[c] for c in LOADED],
            **self._rest_from_row(row),
        }


RECORD_TYPES = {"force": TrialRecords(), "push": PushRecords(), "sense": SenseRecords()}


def load_trials(path: str | os.PathLike) -> Any:
    """The trial table (DataFrame) of a run file (``.h5``) or a trial CSV (checked against its units)."""
    return _checked(path, load_table(path, RECORD_TYPES["force"]))


def load_pushes(path: str | os.PathLike) -> Any:
    """The push table (DataFrame) of a run file (``.h5``) or a push CSV (checked against its units)."""
    return _checked(path, load_table(path, RECORD_TYPES["push"]))


def _checked(path: str | os.PathLike, table: Any) -> Any:
    """A CSV's table read against its units (:mod:`.units`): a run file was written in SI by labcli."""
    if os.fspath(path).lower().endswith(RUN_FILE_SUFFIXES):
        return table
    from .units import check_units

    return check_units(table, os.fspath(path))
