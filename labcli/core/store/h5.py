"""HDF5 plumbing of the run file: datasets with units, text, columns, raw windows, settling.

Record types (the papers' :class:`labcli.core.paper.RecordType`) check their
records with :func:`vector` and :func:`scalar` and read values back with :func:`text`
and :func:`plain`; the run file (:mod:`labcli.core.store.runfile`) writes everything
with the helpers below, so every dataset carries its ``units`` attribute.
"""

from __future__ import annotations

import datetime as _dt
import math
from collections.abc import Mapping, Sequence
from typing import Any, TypedDict

import h5py
import numpy as np

from ...errors import StoreError

ACCEPTED = ("auto", "timeout", "operator", "imported")
EDGE_DIGITS = 12
# A record's raw windows: key in the record -> group name in the file.
WINDOW_GROUPS = {"baseline": "baseline", "load": "loaded", "loaded": "loaded"}


class RawWindow(TypedDict, total=False):
    """One capture window as received (``labcli.papers.takuma2014.session.Window.as_dict()``).

    ``seq`` (n,) frame counters, ``t_us`` (n,) device clock (wraps at 2**32),
    ``counts`` (n, k) values as sent, ``si`` (n, k) calibrated SI values;
    ``t_s`` (n,) unwrapped device time in s, optional (derived from ``t_us``).
    """

    seq: Any
    t_us: Any
    counts: Any
    si: Any
    t_s: Any


class SettleInfo(TypedDict, total=False):
    """How a window's equilibrium was reached (``labcli.core.settle.SettleReport.as_dict()``)."""

    settled: bool  # False: timed out and accepted
    settle_time_s: float
    waited_s: float
    pressure_spread_MPa: float
    angle_spread_rad: float
    criterion: str
    accepted: str  # overrides the auto/timeout reading of ``settled`` (e.g. "operator")


def utc_now() -> str:
    """The current time as ISO 8601 UTC with a Z suffix, to the second."""
    return _dt.datetime.now(_dt.timezone.utc).replace(microsecond=0).isoformat().replace("+00:00", "Z")


def to_edge(values: Any) -> np.ndarray:
    """Round converted table values (deg, g) to 12 significant digits.

    A value typed in degrees or grams, stored in rad or kg and converted back,
    lands within a few ulp of what was typed; rounding at the edge makes
    table -> run file -> table exact while keeping far more digits than any sensor.
    """
    arr = np.asarray(values, dtype=np.float64)
    return np.array([float(f"{v:.{EDGE_DIGITS}g}") for v in arr.ravel()], dtype=np.float64).reshape(arr.shape)


def text(v: Any) -> str:
    if isinstance(v, bytes):
        return v.decode("utf-8")
    return str(v)


def plain(v: Any) -> Any:
    """HDF5 attribute value -> plain Python value."""
    if isinstance(v, bytes):
        return v.decode("utf-8")
    if isinstance(v, np.ndarray):
        return [plain(x) for x in v.tolist()]
    if isinstance(v, np.bool_):
        return bool(v)
    if isinstance(v, np.integer):
        return int(v)
    if isinstance(v, np.floating):
        return float(v)
    return v


def vector(record: Mapping, key: str, n: int, what: str, label: str, *, finite: bool = True) -> np.ndarray:
    if key not in record:
        raise StoreError(f"{label} record lacks '{key}' ({what}).")
    try:
        arr = np.asarray(record[key], dtype=np.float64)
    except (TypeError, ValueError):
        raise StoreError(f"{label} record: '{key}' must be numbers ({what}).") from None
    if arr.shape != (n,):
        raise StoreError(f"{label} record: '{key}' must hold {n} values ({what}), got shape {arr.shape}.")
    if finite and not np.all(np.isfinite(arr)):
        raise StoreError(f"{label} record: '{key}' holds a value that is not finite ({what}).")
    return arr


def scalar(record: Mapping, key: str, label: str, *, default: float = math.nan) -> float:
    v = record.get(key, default)
    if v is None:
        return math.nan
    try:
        return float(v)
    except (TypeError, ValueError):
        raise StoreError(f"{label} record: '{key}' must be a number, got {v!r}.") from None


# Raw windows of a few hundred samples a channel are most of a run's data; byte-shuffled
# gzip shrinks the large ones about fourfold at a cost far below the fsync each trial pays.
# Below about a thousand values a chunk index costs more than it saves: those stay contiguous.
_RAW_COMPRESSION = {"compression": "gzip", "compression_opts": 4, "shuffle": True}
_RAW_MIN_VALUES = 1000


def dataset(g: h5py.Group, key: str, data: Any, units: str, *, raw: bool = False, **attrs: Any) -> h5py.Dataset:
    arr = np.asarray(data)
    opts = _RAW_COMPRESSION if raw and arr.size >= _RAW_MIN_VALUES else {}
    ds = g.create_dataset(key, data=arr, **opts)
    ds.attrs["units"] = units
    for k, v in attrs.items():
        ds.attrs[k] = v
    return ds


def text_dataset(g: h5py.Group, key: str, value: str, **attrs: Any) -> h5py.Dataset:
    ds = g.create_dataset(key, data=value, dtype=h5py.string_dtype("utf-8"))
    ds.attrs["units"] = ""
    for k, v in attrs.items():
        ds.attrs[k] = v
    return ds


def column_units(name: str, ids: Sequence[str] = ()) -> str:
    """The units of a table column named in the exchange style (``mass_g``, ``Fx_N``); ids are "1"."""
    for suffix, units in (
        ("_g", "g"),
        ("_deg", "deg"),
        ("_N_per_m", "N/m"),
        ("_N", "N"),
        ("_m", "m"),
        ("_MPa", "MPa"),
        ("_s", "s"),
    ):
        if name.endswith(suffix):
            return units
    if name in ids:
        return "1"
    return ""


def write_columns(g: h5py.Group, columns: Mapping[str, Any], order: Sequence[str], ids: Sequence[str] = ()) -> None:
    """Store table columns as one dataset each (text or float64/int64); ``ids`` name id columns."""
    g.attrs["columns"] = list(order)
    for name in order:
        values = list(columns[name])
        if values and all(isinstance(v, (int, np.integer)) and not isinstance(v, bool) for v in values):
            dataset(g, name, np.asarray(values, dtype=np.int64), column_units(name, ids))
            continue
        if not any(isinstance(v, str) for v in values):
            try:
                arr = np.asarray([math.nan if v is None else float(v) for v in values], dtype=np.float64)
            except (TypeError, ValueError):
                pass
            else:
                dataset(g, name, arr, column_units(name, ids))
                continue
        texts = ["" if v is None or (isinstance(v, float) and math.isnan(v)) else str(v) for v in values]
        ds = g.create_dataset(name, data=np.array(texts, dtype=object), dtype=h5py.string_dtype("utf-8"))
        ds.attrs["units"] = ""


def read_columns(g: h5py.Group) -> dict[str, list]:
    out: dict[str, list] = {}
    for name in [text(c) for c in g.attrs.get("columns", list(g))]:
        ds = g[name]
        if h5py.check_string_dtype(ds.dtype) is not None:
            out[name] = [text(v) for v in ds[()]]
        else:
            out[name] = ds[()].tolist()
    return out


def unwrap_us(t_us: np.ndarray) -> np.ndarray:
    """Device time in s from a 32-bit microsecond clock that wraps."""
    t = np.asarray(t_us, dtype=np.int64)
    if t.size == 0:
        return np.zeros(0, dtype=np.float64)
    steps = np.diff(t)
    wraps = np.concatenate([[0], np.cumsum(steps < 0)])
    return (t + wraps * (1 << 32)) * 1e-6


def window_arrays(raw: Mapping, k: int, label: str, which: str) -> dict[str, np.ndarray]:
    missing = [key for key in ("seq", "counts", "si") if key not in raw]
    if "t_s" not in raw and "t_us" not in raw:
        missing.append("t_us")
    if missing:
        raise StoreError(f"{label} record: the {which} window lacks {', '.join(missing)}.")
    seq = np.asarray(raw["seq"])
    n = seq.shape[0] if seq.ndim == 1 else -1
    counts = np.asarray(raw["counts"])
    si = np.asarray(raw["si"], dtype=np.float64)
    time = np.asarray(raw["t_s"], dtype=np.float64) if "t_s" in raw else unwrap_us(raw["t_us"])
    if n < 0 or counts.shape != (n, k) or si.shape != (n, k) or time.shape != (n,):
        raise StoreError(
            f"{label} record: the {which} window must hold n frames of {k} channels "
            f"(seq (n,), counts (n,{k}), si (n,{k})), got seq {seq.shape}, counts {counts.shape}, si {si.shape}."
        )
    counts_f = counts.astype(np.float64)
    counts_out: np.ndarray
    if (
        np.all(np.isfinite(counts_f))
        and np.all(counts_f == np.rint(counts_f))
        and (counts_f.size == 0 or np.abs(counts_f).max() < 2**31)
    ):
        counts_out = counts_f.astype(np.int32)
    else:
        counts_out = counts_f  # decimals as sent: kept exactly rather than rounded
    return {
        "time": time,
        "counts": counts_out,
        "values": si,
        "seq": (seq.astype(np.int64) % (1 << 32)).astype(np.uint32),
    }


def settle_attrs(info: Mapping | None) -> dict[str, Any]:
    if not info:
        return {}
    out: dict[str, Any] = {}
    for key in ("settle_time_s", "waited_s", "pressure_spread_MPa", "angle_spread_rad"):
        if key in info and info[key] is not None:
            out[key] = float(info[key])
    if "criterion" in info:
        out["criterion"] = str(info["criterion"])
    if "settled" in info:
        out["settled"] = bool(info["settled"])
    accepted = info.get("accepted")
    if accepted is None and "settled" in info:
        accepted = "auto" if info["settled"] else "timeout"
    if accepted is not None:
        if accepted not in ACCEPTED:
            raise StoreError(f"settle 'accepted' must be one of {', '.join(ACCEPTED)}, got {accepted!r}.")
        out["accepted"] = accepted
    return out


Window = tuple[str, dict[str, np.ndarray], dict[str, Any]]  # group name, arrays, settle attributes


def checked_common(record: Mapping, k: int, label: str) -> tuple[dict[str, Any], list[Window]]:
    """The record's settle attributes and raw windows, checked and converted before anything touches the file."""
    settle = record.get("settle") or {}
    load = settle_attrs(settle.get("load") or settle.get("loaded"))
    accepted = str(record.get("accepted", load.get("accepted", "auto" if record.get("raw") else "imported")))
    if accepted not in ACCEPTED:
        raise StoreError(f"{label} record: 'accepted' must be one of {', '.join(ACCEPTED)}, got {accepted!r}.")
    attrs = {
        "settle_time_s": float(load.get("settle_time_s", math.nan)),
        "settle_criterion": str(load.get("criterion", "")),
        "accepted": accepted,
    }
    windows: list[Window] = []
    for key, raw_w in (record.get("raw") or {}).items():
        if key not in WINDOW_GROUPS:
            raise StoreError(f"{label} record: unknown window {key!r} in 'raw' (use baseline and load).")
        name = WINDOW_GROUPS[key]
        if any(name == w[0] for w in windows):
            raise StoreError(f"{label} record: 'raw' gives the {name} window twice.")
        windows.append((name, window_arrays(raw_w, k, label, name), settle_attrs(settle.get(key) or settle.get(name))))
    return attrs, windows


def calibration_arrays(protocol: Any, k: int) -> tuple[np.ndarray, np.ndarray, list[str]]:
    """Per-channel gain and offset of the protocol's (linear) calibration."""
    cal = getattr(protocol, "calibration", None)
    units = [str(u) for u in getattr(cal, "units", ())] if cal is not None else []
    if len(units) != k:
        units = [""] * k
    if cal is None or not hasattr(cal, "to_si"):
        return np.full(k, math.nan), np.full(k, math.nan), units
    probe = np.array([[0.0] * k, [1000.0] * k])
    si = np.asarray(cal.to_si(probe), dtype=np.float64)
    return (si[1] - si[0]) / 1000.0, si[0].copy(), units


def nan_if_empty(v: Any) -> float:
    """A table cell as a float; empty (None or blank text) is NaN."""
    if v is None or (isinstance(v, str) and v.strip() == ""):
        return math.nan
    return float(v)


def missing(v: Any) -> bool:
    """True for a table cell with nothing in it (None, NaN, empty text)."""
    return v is None or (isinstance(v, float) and math.isnan(v)) or (isinstance(v, str) and v == "")
