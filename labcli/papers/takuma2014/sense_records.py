"""The records of a ``sense`` run (``labcli sense --record``): every estimate and every event.

One record per estimate (a block of 0.1 s: its frames are the record's raw window) and one
per event (``load``, ``settled``, ``release``, ``push``: no window), numbered in the order they
came.  The columns (SI: rad, N, s)::

    item       "estimate" or the event's kind
    seq        the last frame of the block (of the block that revealed an event)
    t_device   s, the rig's clock: the block's end; an event's own time (a load's start)
    state      the estimator's state (estimates)
    theta, theta_se (2,) rad    theta1, theta2 and their standard errors
    F, F_se    (2,) N           Fx, Fy and their standard errors
    data       an event's data as JSON (a push's stiffness and category; a load's detection time)

The estimate's flags are the record's own ``flags`` (every record has them).  The table
(``labcli export``) has one row per record in the JSON lines' units: degrees and newtons,
each with its ``_se`` column.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping
from typing import Any

import numpy as np

from ...core.cells import TableSpec
from ...core.paper import Column
from ...core.report import records_line
from ...core.store.h5 import to_edge
from ...core.store.record_type import BaseRecordType
from ...errors import StoreError

WIDE = (-1e300, 1e300)  # an estimate far off is still an estimate; the bounds catch a changed file
ITEMS = ("estimate", "load", "settled", "release", "push")
QUANTITY_COLUMNS = (
    ("theta1_deg", "theta", 0, True),
    ("theta2_deg", "theta", 1, True),
    ("Fx_N", "F", 0, False),
    ("Fy_N", "F", 1, False),
)

SENSE_TABLE = TableSpec(
    label="sense",
    columns=(
        ("record", "id", "required"),
        ("item", "text", "required"),
        ("seq", "id", "required"),
        ("t_device_s", "float", "required"),
        ("state", "text", "optional"),
        *((c, "float-or-empty", "optional") for name, *_ in QUANTITY_COLUMNS for c in (name, name + "_se")),
        ("flags", "text", "optional"),
        ("data", "text", "optional"),
    ),
    id_column="record",
)


def _pair(record: Mapping[str, Any], key: str, label: str) -> np.ndarray:
    v = np.asarray(record.get(key, (math.nan, math.nan)), dtype=float).reshape(-1)
    if v.shape != (2,):
        raise StoreError(f"{label} record: {key} must hold 2 numbers, got {v.shape[0]}.")
    return v


def _finite(v: np.ndarray) -> np.ndarray:
    return np.where(np.isfinite(v), v, np.nan)


class SenseRecords(BaseRecordType):
    """Estimates and events of a live session (module docstring)."""

    kind = "sense"
    collection = "estimates"
    id_column = "record"
    noun = "estimate or event"
    plural = "estimates and events"
    signal = "F"
    table_spec = SENSE_TABLE
    columns = (
        Column("item", "", kind="text", width=16, what="estimate, or the event's kind"),
        Column("seq", "1", kind="int", what="the block's last frame"),
        Column("t_device", "s", bounds=(-1e12, 1e12), what="the rig's clock"),
        Column("state", "", kind="text", width=16, optional=True, what="the estimator's state"),
        Column("theta", "rad", shape=(2,), components=("theta1", "theta2"), bounds=WIDE, optional=True, what="joint angles"),
        Column("theta_se", "rad", shape=(2,), components=("theta1", "theta2"), bounds=WIDE, optional=True, what="their standard errors"),
        Column("F", "N", shape=(2,), components=("Fx", "Fy"), bounds=WIDE, optional=True, what="tip force"),
        Column("F_se", "N", shape=(2,), components=("Fx", "Fy"), bounds=WIDE, optional=True, what="its standard errors"),
        Column("data", "", kind="text", width=400, optional=True, what="an event's data, JSON"),
    )  # fmt: skip

    def count(self, n: int) -> str:
        return f"{n} {'record' if n == 1 else 'records'} (estimates and events)"

    def check(self, record: Mapping[str, Any], label: str, run: Any) -> dict[str, Any]:
        item = str(record.get("item", ""))
        if item not in ITEMS:
            raise StoreError(f"{label} record: item must be one of {', '.join(ITEMS)}, got {item!r}.")
        data = record.get("data") or {}
        text = json.dumps(data, separators=(",", ":"), allow_nan=False) if data else ""
        if len(text.encode()) > 400:
            raise StoreError(f"{label} record: its data take more than 400 bytes of JSON.")
        return {
            "item": item,
            "seq": int(record.get("seq", -1)),
            "t_device": float(record["t_device_s"]),
            "state": str(record.get("state", "")),
            "theta": _pair(record, "theta_rad", label),
            "theta_se": _pair(record, "theta_se_rad", label),
            "F": _pair(record, "force_N", label),
            "F_se": _pair(record, "force_se_N", label),
            "data": text,
        }

    def read(self, row: Mapping[str, Any]) -> dict[str, Any]:
        return {
            "record": int(row["record"]),
            "item": str(row["item"]),
            "seq": int(row["seq"]),
            "t_device_s": float(row["t_device"]),
            "state": str(row["state"]),
            "theta_rad": np.asarray(row["theta"]),
            "theta_se_rad": np.asarray(row["theta_se"]),
            "force_N": np.asarray(row["F"]),
            "force_se_N": np.asarray(row["F_se"]),
            "data": json.loads(row["data"]) if row["data"] else {},
        }

    def table(self, run: Any, ids: list[int], cols: Mapping[str, Any]) -> Any:
        import pandas as pd

        n = len(ids)
        df = pd.DataFrame({"record": np.asarray(ids, dtype=np.int64)})
        df["item"] = [str(x) for x in cols["item"]]
        df["seq"] = np.asarray(cols["seq"], dtype=np.int64)
        df["t_device_s"] = np.asarray(cols["t_device"], dtype=np.float64)
        df["state"] = [str(x) for x in cols["state"]]
        for name, col, j, angle in QUANTITY_COLUMNS:
            # What the JSON lines publish as null (an infinite standard error) is an empty cell.
            v = _finite(np.asarray(cols[col], dtype=np.float64).reshape(n, 2)[:, j])
            se = _finite(np.asarray(cols[col + "_se"], dtype=np.float64).reshape(n, 2)[:, j])
            df[name] = to_edge(np.degrees(v)) if angle else v
            df[name + "_se"] = to_edge(np.degrees(se)) if angle else se
        flags = cols.get("flags")
        df["flags"] = [str(x).replace("\n", ";") for x in flags] if flags is not None else ""
        df["data"] = [str(x) for x in cols["data"]]
        return df

    def from_row(self, row: Mapping[str, Any], protocol: Any) -> dict[str, Any]:
        def pair(a: str, b: str, angle: bool) -> list[float]:
            v = [float(row.get(a, math.nan)), float(row.get(b, math.nan))]
            return [math.radians(x) for x in v] if angle else v

        return {
            "record": int(row["record"]),
            "item": row["item"],
            "seq": int(row["seq"]),
            "t_device_s": float(row["t_device_s"]),
            "state": row.get("state", ""),
            "theta_rad": pair("theta1_deg", "theta2_deg", True),
            "theta_se_rad": pair("theta1_deg_se", "theta2_deg_se", True),
            "force_N": pair("Fx_N", "Fy_N", False),
            "force_se_N": pair("Fx_N_se", "Fy_N_se", False),
            "data": json.loads(row["data"]) if row.get("data") else {},
            "flags": [f for f in str(row.get("flags", "")).split(";") if f],
        }

    def summarise(self, run: Any, ids: list[int], cols: Mapping[str, Any]) -> dict[str, Any]:
        items = [str(x) for x in cols.get("item", [])]
        t = np.asarray(cols.get("t_device", []), dtype=np.float64)
        events = {k: items.count(k) for k in ITEMS[1:] if k in items}
        span = float(np.ptp(t)) if t.size else 0.0
        return {"sense": {"estimates": items.count("estimate"), "events": events, "span_s": span}}

    def inspect_lines(self, summary: dict[str, Any]) -> list[str]:
        s = summary.get("sense") or {}
        events = ", ".join(f"{n} {k}" for k, n in (s.get("events") or {}).items()) or "no events"
        return [
            records_line(summary),
            f"  session     {s.get('estimates', 0)} estimates over {s.get('span_s', 0.0):.1f} s of the rig's clock; "
            f"{events}",
        ]
