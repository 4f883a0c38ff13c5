"""Random bit flips over a run file: the checker process of ``tests/core/test_store_bitflip.py``.

``python tests/support/bitflip.py GOOD.h5 WORK.h5 SEED N`` flips one random bit of a copy of
GOOD.h5 N times (a fresh copy each time) and, for each, opens the copy and reads everything a
command reads (table, every record with its windows, split, models, session log, verify).
It prints one JSON line per flip: ``{"offset", "bit", "outcome", "detail"}`` where outcome is

* ``same``: everything read back equals the good file's, with no warning (the flip landed in
  bytes nothing reads);
* ``detected``: a LabcliError or a LabcliWarning said so (what was read is then only what
  checked out, and that must equal the good file's too);
* ``changed``: a value differs from the good file's without a word (a silent change);
* ``traceback``: any other exception.

Run in its own process so that a crash inside HDF5 shows as a missing line, not a lost test run.
"""

from __future__ import annotations

import json
import random
import shutil
import sys
import traceback
import warnings

import numpy as np


def snapshot(path: str) -> dict:
    """Everything a command reads from a run file, as comparable plain values."""
    from labcli.core.store import RunFile

    out: dict = {}
    with RunFile.open(path) as run:
        out["table"] = run.records.table().to_dict("list")
        for i in run.records.ids():
            out[f"record {i}"] = run.records.read(i)
        out["split"] = run.split.get()
        out["models"] = run.models.all()
        out["sessions"] = run.sessions.all()
        out["protocol"] = run.protocol_text
        out["attrs"] = run.attrs
        out["verify"] = run.verify()["ok"]
    return out


def equal(a, b) -> bool:
    from labcli.core.window import Window

    if isinstance(a, Window) and isinstance(b, Window):
        return all(equal(getattr(a, k), getattr(b, k)) for k in ("seq", "t_s", "counts", "si"))
    if isinstance(a, dict) and isinstance(b, dict):
        return a.keys() == b.keys() and all(equal(a[k], b[k]) for k in a)
    if isinstance(a, (list, tuple)) and isinstance(b, (list, tuple)):
        return len(a) == len(b) and all(equal(x, y) for x, y in zip(a, b, strict=False))
    if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        a, b = np.asarray(a), np.asarray(b)
        return a.shape == b.shape and a.dtype == b.dtype and bool(np.array_equal(a, b, equal_nan=a.dtype.kind == "f"))
    if isinstance(a, float) and isinstance(b, float) and a != a and b != b:
        return True
    return bool(a == b)


def subset_equal(got: dict, good: dict) -> bool:
    """What a damaged file gave is a part of the good file's (records left out, never changed)."""
    for key, v in got.items():
        if not key.startswith("record "):
            continue
        want = good.get(key)
        if want is None or not equal(
            {k: x for k, x in v.items() if k != "raw"}, {k: x for k, x in want.items() if k != "raw"}
        ):
            return False
        if not all(equal(w, want["raw"].get(name)) for name, w in v["raw"].items()):  # a window may be left out
            return False
    return True


def main(good_path: str, work: str, seed: int, n: int) -> None:
    from labcli.errors import LabcliError, LabcliWarning

    good = snapshot(good_path)
    size = len(open(good_path, "rb").read())
    rng = random.Random(seed)
    for _ in range(n):
        shutil.copyfile(good_path, work)
        offset, bit = rng.randrange(size), rng.randrange(8)
        with open(work, "r+b") as fh:
            fh.seek(offset)
            byte = fh.read(1)[0]
            fh.seek(offset)
            fh.write(bytes([byte ^ (1 << bit)]))
        detail = ""
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            try:
                got = snapshot(work)
            except LabcliError as e:
                outcome, detail = "detected", str(e)
            except Exception:  # noqa: BLE001 - what the test counts as a traceback
                outcome, detail = "traceback", traceback.format_exc(limit=3)
            else:
                said = [str(w.message) for w in caught if issubclass(w.category, LabcliWarning)]
                if said or not got["verify"]:
                    outcome = "detected" if subset_equal(got, good) else "changed"
                    detail = said[0] if said else "verify"
                else:
                    outcome = "same" if equal(got, good) else "changed"
        print(json.dumps({"offset": offset, "bit": bit, "outcome": outcome, "detail": detail[:300]}), flush=True)


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2], int(sys.argv[3]), int(sys.argv[4]))
