"""The reader of run files of schema version 1 (labcli 0.1): one HDF5 group per record.

Layout of version 1 (nothing writes it any more)::

    /  @schema "labcli-run" @schema_version 1 @kind @protocol @device @firmware @port
       @channels @operator @started @imported @source
      protocol (scalar text) · calibration/ gain, offset · plan/ one dataset per column
      trials/000012/ (pushes/, points/)   one group per record: @trial @order @started @ended
          @settle_time_s @settle_criterion @accepted @complete, the record type's datasets and
          attributes (named as the columns of version 2), extra/, and the raw windows
          baseline/ and loaded/ (time, counts, values, seq, settling attributes)
      index   references to the record groups in recording order
      split/  fit, validation @strategy @seed @created · models/<name> JSON text

A record counts once its ``@complete`` is True; a record is found by name and, should a
crash have damaged its collection's list, through ``/index``.  The reader gives the same
columns as a version-2 record table (:mod:`.layout`), so everything above it reads both.
A record whose group cannot be read, or whose datasets have another shape or type than
its record type's columns, is damaged: named and left out, never a traceback.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

import h5py
import numpy as np

from ..paper import Column, RecordType
from ..window import Window
from .h5 import plain, read_columns, text
from .layout import WINDOWS

if TYPE_CHECKING:
    from .split import Split


def _value(g: h5py.Group, c: Column) -> tuple[Any, str | None]:
    """Column ``c`` of a v1 record group: (value, problem)."""
    if c.name in g and isinstance(g[c.name], h5py.Dataset):
        ds = g[c.name]
        if ds.shape != c.shape:
            return None, f"its dataset {c.name} has shape {ds.shape}, not {c.shape}"
        if c.kind == "text":
            if h5py.check_string_dtype(ds.dtype) is None:
                return None, f"its dataset {c.name} holds {ds.dtype} where text belongs"
            return text(ds[()]), None
        if ds.dtype.kind not in "fiub":
            return None, f"its dataset {c.name} holds {ds.dtype} where numbers belong"
        return np.asarray(ds[()], dtype=np.float64 if c.kind == "float" else np.int64), None
    if c.name in g.attrs:
        v = plain(g.attrs[c.name])
        if c.kind == "text":
            return str(v), None
        if isinstance(v, str) or np.shape(v) != c.shape:
            return None, f"its attribute {c.name} is {v!r}, not {'a number' if not c.shape else c.shape}"
        return np.asarray(v, dtype=np.float64 if c.kind == "float" else np.int64), None
    if c.optional:
        return None, None
    return None, f"it lacks {c.name}"


class V1Run:
    """The records, windows, split and models of an open version-1 run file."""

    version = 1

    def __init__(self, f: h5py.File, rt: RecordType) -> None:
        self.f = f
        self.rt = rt
        self.unreadable_list = False

    # ------------------------------------------------------------ metadata
    def attrs(self) -> dict[str, Any]:
        return {k: plain(v) for k, v in self.f.attrs.items()}

    def protocol_text(self) -> str:
        return text(self.f["protocol"][()]) if "protocol" in self.f else ""

    def calibration(self) -> dict[str, Any]:
        g = self.f["calibration"]
        units = tuple(text(g["offset"].attrs["units"]).split(","))
        channels = tuple(text(c) for c in self.f.attrs.get("channels", ()))
        return {"channels": channels, "gain": g["gain"][()], "offset": g["offset"][()], "units": units}

    def plan(self) -> dict[str, list] | None:
        return read_columns(self.f["plan"]) if "plan" in self.f else None

    # ------------------------------------------------------------ records
    def _groups(self) -> tuple[list[tuple[int, int, h5py.Group]], set[int]]:
        """(order, id, group) of the complete records, and ids with only incomplete groups."""
        rt = self.rt
        complete: dict[int, tuple[int, h5py.Group]] = {}
        incomplete: set[int] = set()

        def visit(get, fallback: int | None = None) -> None:
            try:
                g = get()
                rid = int(g.attrs[rt.id_column])
                ok = bool(g.attrs.get("complete", False))
                order = int(g.attrs["order"]) if ok else -1
            except Exception:  # a crash's leftovers may be unreadable in any way: never complete
                if fallback is not None:
                    incomplete.add(fallback)
                return
            if ok:
                complete.setdefault(rid, (order, g))
            else:
                incomplete.add(rid)

        try:
            parent = self.f[rt.collection] if rt.collection in self.f else None
            keys = list(parent) if parent is not None else []
        except Exception:
            self.unreadable_list = True
            parent, keys = None, []
        for key in keys:
            try:
                fallback = int(key.split(".")[0])
            except ValueError:
                continue
            visit(lambda key=key: parent[key], fallback)  # type: ignore[index]  # keys come from parent
        try:
            refs = self.f["index"][()] if "index" in self.f else []
        except Exception:
            refs = []
        for ref in refs:
            if not ref:
                break
            visit(lambda ref=ref: self.f[ref])
        rows = sorted((order, rid, g) for rid, (order, g) in complete.items())
        return rows, incomplete - set(complete)

    def records(self) -> tuple[list[int], list[dict[str, Any]], list[tuple[int, str]], list[int], list[str]]:
        """(ids, rows, damaged (id, why), incomplete ids, extra column names) in recording order."""
        found, incomplete = self._groups()
        ids: list[int] = []
        rows: list[dict[str, Any]] = []
        damaged: list[tuple[int, str]] = []
        extras: dict[str, None] = {}
        for _, rid, g in found:
            try:
                row, problem = self._row(g)
            except Exception:  # noqa: BLE001 - a damaged group can fail in any way
                row, problem = {}, "its group cannot be read"
            if problem:
                damaged.append((rid, problem))
                continue
            ids.append(rid)
            rows.append(row)
            for name in row.get("extra", {}):
                extras.setdefault(name, None)
        return ids, rows, damaged, sorted(incomplete), list(extras)

    def _row(self, g: h5py.Group) -> tuple[dict[str, Any], str | None]:
        rt = self.rt
        a = g.attrs
        row: dict[str, Any] = {
            rt.id_column: int(a[rt.id_column]),
            "started": text(a.get("started", "")),
            "ended": text(a.get("ended", "")),
            "accepted": text(a.get("accepted", "")),
            "flags": "",
        }
        for c in rt.columns:
            value, problem = _value(g, c)
            if problem:
                return row, problem
            if value is not None:
                row[c.name] = value
        for name in WINDOWS:
            w = g[name] if name in g else None
            s = {k: plain(v) for k, v in w.attrs.items()} if w is not None else {}
            if name == "loaded":
                s.setdefault("settle_time_s", float(a.get("settle_time_s", math.nan)))
                if text(a.get("settle_criterion", "")):
                    s.setdefault("criterion", text(a.get("settle_criterion", "")))
            row[f"{name}_start"] = row[f"{name}_stop"] = -1
            row[f"{name}_settled"] = -1 if "settled" not in s else int(bool(s["settled"]))
            for key in ("settle_time_s", "waited_s", "pressure_spread_MPa", "angle_spread_rad"):
                if key in s:
                    row[f"{name}_{key}"] = float(s[key])
            for key in ("criterion", "accepted"):
                if key in s:
                    row[f"{name}_{key}"] = str(s[key])
        if "extra" in g:
            e = g["extra"]
            extra = {}
            for name in [text(c) for c in e.attrs.get("columns", list(e))]:
                v = e[name][()]
                extra[name] = text(v) if isinstance(v, (bytes, str)) else v.item()
            row["extra"] = extra
        row["_group"] = g
        return row, None

    def window(self, row: dict[str, Any], name: str) -> Window | None:
        """The ``name`` window ("baseline", "loaded") of a record's group, read into memory."""
        g = row["_group"]
        if name not in g:
            return None
        w = g[name]
        return Window.of(w["seq"][()], w["counts"][()], w["values"][()], t_s=w["time"][()])

    # ------------------------------------------------------------ split and models
    def split(self) -> Split | None:
        if "split" not in self.f or "fit" not in self.f["split"]:
            return None
        g = self.f["split"]
        seed = int(g.attrs.get("seed", -1))
        return {
            "fit": [int(i) for i in g["fit"][()]],
            "validation": [int(i) for i in g["validation"][()]],
            "strategy": text(g.attrs.get("strategy", "")),
            "seed": None if seed < 0 else seed,
            "created": text(g.attrs.get("created", "")),
        }

    def models(self) -> dict[str, str]:
        if "models" not in self.f:
            return {}
        return {name: text(ds[()]) for name, ds in self.f["models"].items()}
