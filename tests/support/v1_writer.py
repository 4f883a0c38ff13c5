"""Run files of schema version 1, written as labcli 0.1 wrote them (the library writes only v2 now).

Kept for three things: fixtures of the version-1 reader (records complete, incomplete and
superseded, a damaged trial list, the /index fallback), the kill comparison of the two
layouts (``tests/benchmarks/kill_layouts.py``), and files whose datasets a test rewrites
with a wrong shape or type.  Force trials only (the records of
:func:`support.records.make_record`); push and rPAM runs of version 1 are the committed
``sample_runs/*.h5``.

``python tests/support/v1_writer.py RUN.h5 N_TRIALS N_SAMPLES`` is the kill harness's writer
for this layout: it writes trials 0..N-1, resuming a file that exists, and prints "ready"
once the file is open and "stored N" after each trial.
"""

from __future__ import annotations

import math
import os
import sys
from collections.abc import Mapping
from typing import Any

import h5py
import numpy as np

CHANNELS = ("P_L1", "P_R1", "P_L2", "P_R2", "POT1", "POT2")
VALUE_UNITS = "MPa,MPa,MPa,MPa,rad,rad"
INDEX_SLOTS = 16_384
_RAW = {"compression": "gzip", "compression_opts": 4, "shuffle": True}


def _dataset(g: h5py.Group, key: str, data: Any, units: str, raw: bool = False, **attrs: Any) -> None:
    arr = np.asarray(data)
    ds = g.create_dataset(key, data=arr, **(_RAW if raw and arr.size >= 1000 else {}))
    ds.attrs["units"] = units
    for k, v in attrs.items():
        ds.attrs[k] = v


def _unwrap(t_us: Any) -> np.ndarray:
    t = np.asarray(t_us, dtype=np.int64)
    return (t + np.concatenate([[0], np.cumsum(np.diff(t) < 0)]) * (1 << 32)) * 1e-6


def create(
    path: str,
    *,
    protocol_text: str = 'name = "bench"\nkind = "force"\n',
    protocol: str = "bench",
    kind: str = "force",
    operator: str = "v1",
    plan: Mapping[str, list] | None = None,
) -> None:
    """A new, empty version-1 run of force trials (the reference rig's channels and calibration)."""
    tmp = path + ".creating"
    with h5py.File(tmp, "w", fs_strategy="none") as f:
        a = f.attrs
        a["NX_class"] = "NXentry"
        a["schema"], a["schema_version"], a["labcli_version"] = "labcli-run", 1, "0.1.0"
        a["kind"], a["protocol"] = kind, protocol
        a["device"], a["firmware"], a["port"] = "mckibben-2dof", "1.0", "sim://?seed=1"
        a["channels"] = list(CHANNELS)
        a["operator"], a["started"], a["imported"], a["source"] = operator, "2024-05-01T09:00:00Z", False, ""
        ds = f.create_dataset("protocol", data=protocol_text, dtype=h5py.string_dtype("utf-8"))
        ds.attrs.update({"units": "", "name": protocol, "kind": kind, "path": "/home/someone/" + protocol + ".toml"})
        cal = f.create_group("calibration")
        cal.attrs["NX_class"], cal.attrs["channels"] = "NXcollection", list(CHANNELS)
        gain = np.array([5 / 16380] * 4 + [math.radians(340 / 4095)] * 2)
        offset = np.array([-0.25] * 4 + [-2048 * math.radians(340 / 4095)] * 2)
        _dataset(cal, "gain", gain, "MPa/count,MPa/count,MPa/count,MPa/count,rad/count,rad/count")
        _dataset(cal, "offset", offset, VALUE_UNITS)
        if plan is not None:
            g = f.create_group("plan")
            g.attrs["NX_class"], g.attrs["columns"] = "NXcollection", list(plan)
            for name, values in plan.items():
                if all(isinstance(v, str) for v in values):
                    g.create_dataset(name, data=np.array(values, dtype=object), dtype=h5py.string_dtype("utf-8")).attrs[
                        "units"
                    ] = ""
                else:
                    _dataset(g, name, np.asarray(values), "1" if name == "trial" else "")
        for name in ("trials", "split", "models"):
            f.create_group(name).attrs["NX_class"] = "NXcollection"
        dcpl = h5py.h5p.create(h5py.h5p.DATASET_CREATE)
        dcpl.set_alloc_time(h5py.h5d.ALLOC_TIME_EARLY)
        f.create_dataset("index", shape=(INDEX_SLOTS,), dtype=h5py.ref_dtype, dcpl=dcpl).attrs["units"] = ""
        f.flush()
        os.fsync(f.id.get_vfd_handle())
    os.replace(tmp, path)


def _settle(info: Mapping | None) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for key in ("settle_time_s", "waited_s", "pressure_spread_MPa", "angle_spread_rad"):
        if info and info.get(key) is not None:
            out[key] = float(info[key])
    if info and "criterion" in info:
        out["criterion"] = str(info["criterion"])
    if info and "settled" in info:
        out["settled"] = bool(info["settled"])
        out["accepted"] = "auto" if info["settled"] else "timeout"
    return out


class Writer:
    """An open version-1 run, adding force trials as labcli 0.1 did (crash-safe per trial)."""

    def __init__(self, path: str) -> None:
        self.f = h5py.File(path, "a")
        self.done = {int(g.attrs["trial"]) for g in self._groups() if g.attrs.get("complete", False)}
        refs = self.f["index"][()]
        self.order = sum(1 for r in refs if r)

    def _groups(self):
        for key in self.f["trials"]:
            try:
                g = self.f["trials"][key]
                if "trial" in g.attrs:
                    yield g
            except Exception:
                continue

    def close(self) -> None:
        self.f.flush()
        os.fsync(self.f.id.get_vfd_handle())
        self.f.close()

    def __enter__(self) -> Writer:
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()

    def _sync(self) -> None:
        self.f.flush()
        os.fsync(self.f.id.get_vfd_handle())

    def write(self, rec: Mapping[str, Any], *, complete: bool = True) -> h5py.Group:
        """Write trial ``rec`` (the keys of :func:`support.records.make_record`) as one v1 group."""
        parent = self.f["trials"]
        name = base = f"{int(rec['trial']):06d}"
        n = 0
        while name in parent:
            n += 1
            name = f"{base}.{n}"
        g = parent.create_group(name)
        g.attrs["NX_class"] = "NXcollection"
        g.attrs["complete"] = False
        g.attrs["trial"] = int(rec["trial"])
        for k, v in (rec.get("plan") or {}).items():
            g.attrs[f"plan_{k}"] = v if isinstance(v, str) else float(v)
        chan = {"channels": "P_L1,P_R1,P_L2,P_R2"}
        _dataset(g, "P0", rec["P0_MPa"], "MPa", **chan)
        _dataset(g, "P", rec["P_MPa"], "MPa", **chan)
        _dataset(g, "theta", rec["theta_rad"], "rad")
        if "pot0_rad" in rec:
            _dataset(g, "pot0", rec["pot0_rad"], "rad")
        _dataset(g, "F", rec["force_N"], "N", components="Fx,Fy")
        _dataset(g, "mass", float(rec["mass_kg"]), "kg")
        _dataset(g, "direction", float(rec["direction_rad"]), "rad")
        g.attrs["order"] = self.order
        g.attrs["started"], g.attrs["ended"] = str(rec.get("started", "")), str(rec.get("ended", ""))
        load = _settle((rec.get("settle") or {}).get("load"))
        g.attrs["settle_time_s"] = float(load.get("settle_time_s", math.nan))
        g.attrs["settle_criterion"] = str(load.get("criterion", ""))
        g.attrs["accepted"] = str(rec.get("accepted", load.get("accepted", "auto" if rec.get("raw") else "imported")))
        for key, gname in (("baseline", "baseline"), ("load", "loaded")):
            raw = (rec.get("raw") or {}).get(key)
            if raw is None:
                continue
            w = g.create_group(gname)
            w.attrs["NX_class"], w.attrs["channels"] = "NXlog", list(CHANNELS)
            counts = np.asarray(raw.counts, dtype=np.float64)
            if np.all(counts == np.rint(counts)):
                counts = counts.astype(np.int32)
            _dataset(w, "time", _unwrap(raw.t_us), "s", raw=True)
            _dataset(w, "counts", counts, "counts", raw=True)
            _dataset(w, "values", np.asarray(raw.si, dtype=np.float64), VALUE_UNITS, raw=True)
            _dataset(w, "seq", (np.asarray(raw.seq, dtype=np.int64) % (1 << 32)).astype(np.uint32), "1", raw=True)
            for k, v in _settle((rec.get("settle") or {}).get(key)).items():
                w.attrs[k] = v
        if complete:
            self.f["index"][self.order] = g.ref
            self._sync()
            g.attrs.modify("complete", True)
            self._sync()
            self.done.add(int(rec["trial"]))
            self.order += 1
        return g

    def set_split(self, fit: list[int], validation: list[int], strategy: str = "sequential") -> None:
        g = self.f["split"]
        g.attrs["strategy"], g.attrs["seed"], g.attrs["created"] = strategy, -1, "2024-05-01T10:00:00Z"
        for name, ids in (("fit", fit), ("validation", validation)):
            if name in g:
                del g[name]
            _dataset(g, name, np.asarray(ids, dtype=np.int64), "1")
        self._sync()

    def record_model(self, name: str, text: str) -> None:
        ds = self.f["models"].create_dataset(name, data=text, dtype=h5py.string_dtype("utf-8"))
        ds.attrs["units"], ds.attrs["created"] = "", "2024-05-01T10:00:00Z"
        self._sync()


def write_run(path: str, records: list[Mapping[str, Any]], **kw: Any) -> None:
    """A whole version-1 run of ``records`` (force trials)."""
    create(path, **kw)
    with Writer(path) as w:
        for rec in records:
            w.write(rec)


def writer_process(path: str, n_trials: int, n_samples: int) -> None:
    from records import make_record  # tests/support on sys.path (this file's folder)

    if not os.path.exists(path):
        create(path)
    with Writer(path) as w:
        print("ready", flush=True)
        for i in range(n_trials):
            if i in w.done:
                continue
            w.write(make_record(i, n_samples))
            print(f"stored {i}", flush=True)


if __name__ == "__main__":
    writer_process(sys.argv[1], int(sys.argv[2]), int(sys.argv[3]))
