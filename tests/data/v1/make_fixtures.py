"""How the version-1 fixtures here were made (labcli 0.1's sample runs, cut down); kept for the record.

``python tests/data/v1/make_fixtures.py SAMPLE_RUNS_DIR`` copies the first records of each sample
run of labcli 0.1 (schema version 1) with everything a run holds besides (metadata, protocol,
calibration, plan, split, models, the /index references), and adds to the force run an
interrupted trial and a second attempt beside it, as a kill left them.  The ``*.inspect.txt``,
``*.inspect.json`` and ``*.csv`` files beside them are what labcli 0.1 printed for them
(``labcli inspect``, ``labcli inspect --json``, ``labcli export``); the version-1 reader must
give the same.
"""

from __future__ import annotations

import sys
from pathlib import Path

import h5py

KEEP = {"force": ("trials", 5), "pushes": ("pushes", 4), "stretch": ("points", 4), "joint": ("points", 4)}


def cut(src: Path, dst: Path, collection: str, n: int) -> None:
    with h5py.File(src, "r") as f, h5py.File(dst, "w", fs_strategy="none") as g:
        for k, v in f.attrs.items():
            g.attrs[k] = v
        for name in f:
            if name in (collection, "index"):
                continue
            f.copy(f[name], g, name=name)
        c = g.create_group(collection)
        for k, v in f[collection].attrs.items():
            c.attrs[k] = v
        dcpl = h5py.h5p.create(h5py.h5p.DATASET_CREATE)
        dcpl.set_alloc_time(h5py.h5d.ALLOC_TIME_EARLY)
        index = g.create_dataset("index", shape=f["index"].shape, dtype=h5py.ref_dtype, dcpl=dcpl)
        for k, v in f["index"].attrs.items():
            index.attrs[k] = v
        kept = sorted(f[collection], key=lambda key: int(f[collection][key].attrs["order"]))[:n]
        for slot, key in enumerate(kept):
            f.copy(f[collection][key], c, name=key)
            index[slot] = c[key].ref
        if "split" in g and "fit" in g["split"]:
            ids = {int(f[collection][key].attrs["trial"]) for key in kept} if collection == "trials" else set()
            for name in ("fit", "validation"):
                data = [i for i in g["split"][name][()] if i in ids]
                units = g["split"][name].attrs["units"]
                del g["split"][name]
                g["split"].create_dataset(name, data=data, dtype="i8").attrs["units"] = units
        if collection == "trials":
            # A kill's leftovers: trial 6 interrupted; trial 4 interrupted once, then stored (000004.1).
            last = c[kept[-1]]
            for name, complete in (("000006", False),):
                h = c.create_group(name)
                h.attrs["NX_class"], h.attrs["complete"], h.attrs["trial"] = "NXcollection", complete, 6
                h.create_dataset("P0", data=last["P0"][()])
            key4 = next(k for k in kept if int(c[k].attrs["trial"]) == 4)
            c.move(key4, "000004.1")
            h = c.create_group("000004")
            h.attrs["NX_class"], h.attrs["complete"], h.attrs["trial"] = "NXcollection", False, 4


if __name__ == "__main__":
    here = Path(__file__).resolve().parent
    src = Path(sys.argv[1])
    for name, (collection, n) in KEEP.items():
        cut(src / f"{name}.h5", here / f"{name}.h5", collection, n)
