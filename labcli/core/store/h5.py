"""HDF5 plumbing of the run file: values checked and read back, units, settling, calibration.

Record types (the papers' :class:`labcli.core.paper.RecordType`) check their
records with :func:`vector` and :func:`scalar` and read values back with :func:`text`
and :func:`plain`; the run file (:mod:`labcli.core.store.runfile`) writes everything
with the helpers below, so every dataset carries its ``units`` attribute.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any, cast

import h5py
import numpy as np

from ...errors import StoreError
from ..record import ACCEPTED, Settle

EDGE_DIGITS = 12
NEXUS_SUFFIXES = ("_set", "_errors", "_weights", "_mask")  # a field's companions in NeXus


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


def put(obj: Any, key: str, value: Any) -> None:
    """Set attribute ``key`` of ``obj``; a text, or a list of texts, as fixed-length UTF-8.

    h5py keeps a Python ``str`` as a variable-length string, whose bytes live in the file's
    global heap: a heap's length field damaged by one flipped bit makes HDF5 read past its
    buffer (a crash inside the library, no exception to catch).  A fixed-length text lives in
    the object's header, where a damaged byte is a wrong value the metadata checksum finds.
    """
    if isinstance(value, (str, bytes)):
        data = value.encode("utf-8") if isinstance(value, str) else value
        obj.attrs.create(key, np.bytes_(data), dtype=h5py.string_dtype("utf-8", max(1, len(data))))
    elif isinstance(value, (list, tuple)) and all(isinstance(v, (str, bytes)) for v in value):
        items = [v.encode("utf-8") if isinstance(v, str) else v for v in value]
        width = max([1, *map(len, items)])
        obj.attrs.create(key, np.array(items, dtype=f"S{width}"), dtype=h5py.string_dtype("utf-8", width))
    else:
        obj.attrs[key] = value


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


def h5_name(name: str) -> str:
    """The dataset name of column ``name`` (see :mod:`.columns`)."""
    return f"{name}_" if name.endswith(NEXUS_SUFFIXES) else name


def column_name(stored: str) -> str:
    """The column a dataset ``stored`` holds: :func:`h5_name` undone."""
    return stored[:-1] if stored.endswith(tuple(f"{s}_" for s in NEXUS_SUFFIXES)) else stored


def read_columns(g: h5py.Group) -> dict[str, list]:
    out: dict[str, list] = {}
    for name in [text(c) for c in g.attrs.get("columns", list(g))]:
        ds = g[name]
        if h5py.check_string_dtype(ds.dtype) is not None:
            out[column_name(name)] = [text(v) for v in ds[()]]
        else:
            out[column_name(name)] = ds[()].tolist()
    return out


def settle_attrs(info: Mapping[str, Any] | None) -> Settle:
    """How a window settled (a record's ``settle`` entry), checked and in the types the file keeps."""
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
    return cast(Settle, out)  # the keys above are Settle's


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
