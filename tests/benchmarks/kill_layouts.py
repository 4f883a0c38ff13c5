"""Run-file layouts under kill -9: schema v1 (a group per trial) against records as rows.

Run:  python tests/benchmarks/kill_layouts.py [--kills N] [--samples S] [--layouts v1,packed,aligned,v2]
                                              [--seed K] [--dir DIR]

Each layout gets the store's kill harness (``tests/core/test_kill.py``): a writer process adds
the trials of ``support.records.make_record`` (two raw windows of S frames each) with its
crash-safe commit, and is killed with SIGKILL at a random moment, N times in a row on the
same file; after every kill the file must open and every committed trial must be exactly what
the writer was given (values, texts, settling, both raw windows), and no trial committed before
a kill may be lost.

* ``v1``: labcli 0.1's layout (``tests/support/v1_writer.py``): a group per trial, its
  ``@complete`` written last, ``/index`` of references.
* ``packed``: the row layout as first sketched: one resizable chunked dataset per record field
  (64 rows a chunk) and per raw array (256 frames a chunk), gzip + shuffle + Fletcher32, rows
  and frames packed tightly; raw frames, then the row, flush + fsync, then ``@committed``
  bumped, flush + fsync.
* ``aligned``: the same, but a commit never writes into a chunk that holds committed data:
  record fields are chunked one row a chunk, and each raw window starts at a chunk boundary
  (the rest of the previous window's last chunk stays fill, which compresses to almost nothing).
* ``v2``: ``labcli.core.store.RunFile`` itself (once it writes schema version 2).

Besides the kills it measures, per layout and on the same disk, bytes per trial, ms per trial
(with the fsyncs) and *committed bytes rewritten*: over 40 commits, how often a commit wrote
again over file bytes that already held committed data chunks (read back from the file before
and after each commit).  HDF5 writes a compressed chunk whose size changed at a new address,
except when the chunk ends the file: then its old space is handed back and the new chunk is
written over it, in place.  A kill inside that write tears committed data.
"""

from __future__ import annotations

import argparse
import os
import random
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

HERE = Path(__file__).resolve()
ROOT = HERE.parents[2]
SUPPORT = ROOT / "tests" / "support"
sys.path[:0] = [str(ROOT), str(SUPPORT), str(ROOT / "tests")]

import h5py  # noqa: E402
import numpy as np  # noqa: E402
from records import CHANNELS, make_record, unwrap_s  # noqa: E402

from labcli.core.window import Window  # noqa: E402

N_TRIALS = 1_000_000
TEXT = {"plan_set": 16, "started": 32, "ended": 32, "accepted": 8, "settle_criterion": 128}
WINDOWS = (("baseline", "baseline"), ("load", "loaded"))
W_TEXT = {"criterion": 128, "accepted": 8}
W_FLOAT = ("settle_time_s", "waited_s", "pressure_spread_MPa", "angle_spread_rad")


# --------------------------------------------------------------------------- the row prototype


def _columns() -> dict[str, tuple[tuple[int, ...], Any]]:
    cols: dict[str, tuple[tuple[int, ...], Any]] = {
        "trial": ((), "i8"),
        "P0": ((4,), "f8"),
        "P": ((4,), "f8"),
        "theta": ((2,), "f8"),
        "pot0": ((2,), "f8"),
        "F": ((2,), "f8"),
        "mass": ((), "f8"),
        "direction": ((), "f8"),
        "plan_mass_g": ((), "f8"),
        "plan_direction_deg": ((), "f8"),
        "settle_time_s": ((), "f8"),
    }
    cols.update({k: ((), f"S{n}") for k, n in TEXT.items()})
    for _, w in WINDOWS:
        cols.update({f"{w}_start": ((), "i8"), f"{w}_stop": ((), "i8"), f"{w}_settled": ((), "i1")})
        cols.update({f"{w}_{k}": ((), "f8") for k in W_FLOAT})
        cols.update({f"{w}_{k}": ((), f"S{n}") for k, n in W_TEXT.items()})
    return cols


_OPTS = {"compression": "gzip", "compression_opts": 4, "shuffle": True, "fletcher32": True}


class RowWriter:
    """The row-layout prototype: records as rows, raw windows as run-wide frame arrays."""

    def __init__(self, path: str, aligned: bool, row_chunk: int, frame_chunk: int = 256) -> None:
        self.aligned = aligned
        new = not os.path.exists(path)
        if new:
            tmp = path + ".creating"
            with h5py.File(tmp, "w", fs_strategy="none") as f:
                t = f.create_group("entry/trials")
                t.attrs["committed"] = 0
                for name, (shape, dtype) in _columns().items():
                    t.create_dataset(
                        name,
                        shape=(0, *shape),
                        maxshape=(None, *shape),
                        dtype=dtype,
                        chunks=(row_chunk, *shape),
                        **_OPTS,
                    )
                r = f.create_group("entry/raw")
                r.create_dataset("time", shape=(0,), maxshape=(None,), dtype="f8", chunks=(frame_chunk,), **_OPTS)
                r.create_dataset("seq", shape=(0,), maxshape=(None,), dtype="u4", chunks=(frame_chunk,), **_OPTS)
                for c in CHANNELS:
                    for key in ("value", "raw_value"):
                        r.create_dataset(
                            f"{c}/{key}", shape=(0,), maxshape=(None,), dtype="f8", chunks=(frame_chunk,), **_OPTS
                        )
                f.flush()
                os.fsync(f.id.get_vfd_handle())
            os.replace(tmp, path)
        self.f = h5py.File(path, "a")
        self.t = self.f["entry/trials"]
        self.r = self.f["entry/raw"]
        self.chunk = frame_chunk
        n = int(self.t.attrs["committed"])
        self.done = set(int(i) for i in self.t["trial"][:n])

    def _append_frames(self, raw: dict) -> tuple[int, int]:
        n = len(raw.seq)
        end = self.r["time"].shape[0]
        start = -(-end // self.chunk) * self.chunk if self.aligned else end
        stop = start + n
        counts = np.asarray(raw.counts, dtype=np.float64)
        si = np.asarray(raw.si, dtype=np.float64)
        arrays = {"time": unwrap_s(raw.t_us), "seq": np.asarray(raw.seq, dtype=np.int64).astype(np.uint32)}
        for j, c in enumerate(CHANNELS):
            arrays[f"{c}/value"] = si[:, j]
            arrays[f"{c}/raw_value"] = counts[:, j]
        for name, a in arrays.items():
            d = self.r[name]
            d.resize((stop,))
            d[start:stop] = a
        return start, stop

    def write(self, rec: dict) -> None:
        row: dict[str, Any] = {
            "trial": rec["trial"],
            "P0": rec["P0_MPa"],
            "P": rec["P_MPa"],
            "theta": rec["theta_rad"],
            "pot0": rec["pot0_rad"],
            "F": rec["force_N"],
            "mass": rec["mass_kg"],
            "direction": rec["direction_rad"],
            "plan_set": rec["plan"]["set"],
            "plan_mass_g": rec["plan"]["mass_g"],
            "plan_direction_deg": rec["plan"]["direction_deg"],
            "started": rec["started"],
            "ended": rec["ended"],
        }
        load = rec["settle"]["load"]
        row.update(
            accepted="auto" if load["settled"] else "timeout",
            settle_time_s=load["settle_time_s"],
            settle_criterion=load["criterion"],
        )
        for key, w in WINDOWS:
            row[f"{w}_start"], row[f"{w}_stop"] = self._append_frames(rec["raw"][key])
            s = rec["settle"][key]
            row[f"{w}_settled"] = s["settled"]
            row.update({f"{w}_{k}": s[k] for k in W_FLOAT})
            row[f"{w}_criterion"] = s["criterion"]
            row[f"{w}_accepted"] = "auto" if s["settled"] else "timeout"
        self.f.flush()
        os.fsync(self.f.id.get_vfd_handle())
        n = self.t["trial"].shape[0]  # rows past @committed are a killed writer's leftovers: kept, skipped
        start = -(-n // self.t["trial"].chunks[0]) * self.t["trial"].chunks[0] if self.aligned else n
        for name, value in row.items():
            d = self.t[name]
            d.resize(start + 1, axis=0)
            d[start] = value.encode() if isinstance(value, str) else value
        self.f.flush()
        os.fsync(self.f.id.get_vfd_handle())
        self.t.attrs.modify("committed", start + 1)
        self.f.flush()
        os.fsync(self.f.id.get_vfd_handle())
        self.done.add(int(rec["trial"]))

    def close(self) -> None:
        self.f.close()


def read_rows(path: str) -> dict[int, dict]:
    """Committed trials of a row-layout file, as RunFile.read gives them (for the comparison)."""
    out = {}
    with h5py.File(path, "r", locking=False) as f:
        t, r = f["entry/trials"], f["entry/raw"]
        n = int(t.attrs["committed"])
        cols = {name: t[name][:n] for name in t}
        for i in range(n):
            raw, settle = {}, {}
            for key, w in WINDOWS:
                a, b = int(cols[f"{w}_start"][i]), int(cols[f"{w}_stop"][i])
                raw[key] = Window.of(
                    r["seq"][a:b],
                    np.stack([r[f"{c}/raw_value"][a:b] for c in CHANNELS], axis=1),
                    np.stack([r[f"{c}/value"][a:b] for c in CHANNELS], axis=1),
                    t_s=r["time"][a:b],
                )
                settle[key] = {
                    "settled": bool(cols[f"{w}_settled"][i]),
                    "criterion": cols[f"{w}_criterion"][i].decode(),
                    "accepted": cols[f"{w}_accepted"][i].decode(),
                    **{k: float(cols[f"{w}_{k}"][i]) for k in W_FLOAT},
                }
            out[int(cols["trial"][i])] = {
                "trial": int(cols["trial"][i]),
                "P0_MPa": cols["P0"][i],
                "P_MPa": cols["P"][i],
                "theta_rad": cols["theta"][i],
                "pot0_rad": cols["pot0"][i],
                "force_N": cols["F"][i],
                "mass_kg": float(cols["mass"][i]),
                "direction_rad": float(cols["direction"][i]),
                "started": cols["started"][i].decode(),
                "ended": cols["ended"][i].decode(),
                "accepted": cols["accepted"][i].decode(),
                "raw": raw,
                "settle": settle,
                "plan": {
                    "mass_g": float(cols["plan_mass_g"][i]),
                    "set": cols["plan_set"][i].decode(),
                    "direction_deg": float(cols["plan_direction_deg"][i]),
                },
            }
    return out


# --------------------------------------------------------------------------- one writer per layout


LAYOUTS = ("v1", "packed", "aligned", "v2")


def open_writer(layout: str, path: str) -> Any:
    if layout == "v1":
        import v1_writer

        if not os.path.exists(path):
            v1_writer.create(path)
        return v1_writer.Writer(path)
    if layout == "packed":
        return RowWriter(path, aligned=False, row_chunk=64)
    if layout == "aligned":
        return RowWriter(path, aligned=True, row_chunk=1)
    from records import FakeDevice, FakeProtocol

    from labcli.core.store import RunFile

    if os.path.exists(path):
        run = RunFile.open(path, "a")
    else:
        run = RunFile.create(path, protocol=FakeProtocol(), device_info=FakeDevice(), port="sim://", operator="kill")
    return V2Writer(run)


class V2Writer:
    """The run file as the campaign drives every layout: ``write(record)``, ``done``, ``f``, ``close()``."""

    def __init__(self, run: Any) -> None:
        self.run, self.f, self.done = run, run.h5, set(run.records.ids())

    def write(self, rec: dict) -> None:
        self.run.records.write(rec)

    def close(self) -> None:
        self.run.close()


def writer_main(layout: str, path: str, n_samples: int) -> None:
    w = open_writer(layout, path)
    print("ready", flush=True)
    i = 0
    while True:
        while i in w.done:
            i += 1
        w.write(make_record(i, n_samples))
        print(f"stored {i}", flush=True)


def committed(layout: str, path: str) -> dict[int, dict]:
    if layout in ("packed", "aligned"):
        return read_rows(path)
    from labcli.core.store import RunFile

    with RunFile.open(path) as run:
        return {i: run.records.read(i) for i in run.records.ids()}


def same(stored: dict, rec: dict) -> bool:
    from records import assert_record_stored

    try:
        assert_record_stored(stored, rec)
    except AssertionError:
        return False
    return True


# --------------------------------------------------------------------------- the campaign


def start(layout: str, path: str, n_samples: int) -> subprocess.Popen:
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(ROOT), str(SUPPORT), str(ROOT / "tests")]))
    p = subprocess.Popen(
        [sys.executable, str(HERE), "--writer", layout, path, str(n_samples)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        env=env,
    )
    line = p.stdout.readline()
    if line != b"ready\n":
        p.kill()
        p.wait()
        raise RuntimeError(f"{layout} writer did not start: {line!r} {p.stderr.read()[-2000:]!r}")
    return p


def campaign(layout: str, folder: Path, kills: int, n_samples: int, seed: int) -> dict[str, Any]:
    """``kills`` SIGKILLs at random moments into writers of one file; every file checked after each."""
    rng = random.Random(seed)
    path = str(folder / f"{layout}.h5")
    verified: dict[int, dict] = {}
    problems: list[str] = []
    landed_in_write = 0
    for _ in range(kills):
        p = start(layout, path, n_samples)
        assert p.stdout.readline().startswith(b"stored ")  # each writer commits one trial first
        time.sleep(rng.uniform(0.0, 0.25))
        p.send_signal(signal.SIGKILL)
        p.wait()
        try:
            got = committed(layout, path)
        except Exception as e:  # noqa: BLE001 - any failure to read back is what is counted
            problems.append(f"file does not read back: {type(e).__name__}: {e}")
            break
        lost = set(verified) - set(got)
        if lost:
            problems.append(f"committed trials lost: {sorted(lost)[:5]}")
        for i, stored in got.items():
            if not same(stored, make_record(i, n_samples)):
                problems.append(f"trial {i} differs from what was written")
        landed_in_write += len(got) > len(verified) + 1  # more than the one awaited: the kill hit a later trial
        verified = got
    return {"kills": kills, "trials": len(verified), "problems": problems}


def measure(layout: str, folder: Path, trials: int, n_samples: int) -> dict[str, Any]:
    """Bytes and ms per trial (one pass), and how often a commit rewrote committed data chunks (another)."""
    recs = [make_record(i, n_samples) for i in range(trials)]
    path = str(folder / f"m-{layout}.h5")
    w = open_writer(layout, path)
    t0 = time.perf_counter()
    for rec in recs:
        w.write(rec)
    elapsed = time.perf_counter() - t0
    w.close()
    size = os.path.getsize(path)
    path = str(folder / f"r-{layout}.h5")
    w = open_writer(layout, path)
    rewrites = torn_lost = torn_cases = 0
    checked = min(40, trials)
    for k, rec in enumerate(recs[:checked]):
        before = _data_regions(getattr(w, "f", None) or w._f)
        snapshot = Path(path).read_bytes()
        w.write(rec)
        after = Path(path).read_bytes()
        hit = [(a, b) for a, b in before if snapshot[a:b] != after[a:b]]
        rewrites += bool(hit)
        if hit:
            lost = _torn_write_loss(layout, folder, snapshot, after, hit, k, n_samples)
            torn_lost += lost
            torn_cases += lost > 0
    w.close()
    return {
        "bytes_per_trial": size / trials,
        "ms_per_trial": elapsed / trials * 1e3,
        "commits_rewriting_committed_data": rewrites,
        "commits_checked": checked,
        "torn_lost": torn_lost,
        "torn_cases": torn_cases,
    }


def _torn_write_loss(
    layout: str, folder: Path, before: bytes, after: bytes, hit: list[tuple[int, int]], k: int, n_samples: int
) -> int:
    """Committed trials lost when a kill tears the in-place rewrite after its first 4 KiB page.

    The torn file is the file after the commit with the old bytes back in every rewritten
    region beyond that region's first page (what the kernel leaves when SIGKILL arrives
    between the pages of one write call); its metadata is the new one.  The trials committed
    before this commit (0..k-1) must read back exactly.
    """
    torn = bytearray(after)
    for a, b in hit:
        cut = min(b, (a // 4096 + 1) * 4096)
        torn[cut:b] = before[cut:b]
    path = folder / f"torn-{layout}.h5"
    path.write_bytes(bytes(torn))
    try:
        got = committed(layout, str(path))
    except Exception:  # noqa: BLE001 - a file that no longer reads loses everything
        return k
    return sum(1 for i in range(k) if i not in got or not same(got[i], make_record(i, n_samples)))


def _data_regions(f: h5py.File) -> list[tuple[int, int]]:
    """(start, end) file offsets of every allocated data chunk or contiguous dataset, read-only."""
    regions: list[tuple[int, int]] = []

    def visit(name: str, obj: Any) -> None:
        if not isinstance(obj, h5py.Dataset) or name == "index":  # v1's index: empty slots filled in place
            return
        if obj.chunks is None:
            off = obj.id.get_offset()
            if off is not None:
                regions.append((off, off + obj.id.get_storage_size()))
            return
        for j in range(obj.id.get_num_chunks()):
            c = obj.id.get_chunk_info(j)
            regions.append((c.byte_offset, c.byte_offset + c.size))

    f.visititems(visit)
    return regions


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--kills", type=int, default=200)
    ap.add_argument("--samples", type=int, default=200, help="frames per raw window")
    ap.add_argument("--layouts", default="v1,packed,aligned")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--trials", type=int, default=100, help="trials for the size and speed figures")
    ap.add_argument("--dir", default=None)
    a = ap.parse_args()
    folder = Path(a.dir or tempfile.mkdtemp(prefix="kill-layouts-"))
    folder.mkdir(parents=True, exist_ok=True)
    print(f"kill -9 campaign: {a.kills} kills per layout, {a.samples} frames per window, seed {a.seed}, in {folder}")
    print(
        f"{'layout':8} {'kills':>6} {'trials':>7} {'problems':>9} {'B/trial':>9} {'ms/trial':>9} "
        f"{'commits rewriting committed data':>33} {'torn replays losing data':>25}"
    )
    for layout in a.layouts.split(","):
        m = measure(layout, folder, a.trials, a.samples)
        c = (
            campaign(layout, folder, a.kills, a.samples, a.seed)
            if a.kills
            else {"kills": 0, "trials": 0, "problems": []}
        )
        print(
            f"{layout:8} {c['kills']:6d} {c['trials']:7d} {len(c['problems']):9d} {m['bytes_per_trial']:9.0f} "
            f"{m['ms_per_trial']:9.2f} {m['commits_rewriting_committed_data']:>20d} of {m['commits_checked']:<9d} "
            f"{m['torn_cases']:>6d} ({m['torn_lost']} trials lost in all)",
            flush=True,
        )
        for prob in c["problems"][:5]:
            print(f"    {prob}")
    if not a.dir:
        shutil.rmtree(folder, ignore_errors=True)


if __name__ == "__main__":
    if len(sys.argv) > 1 and sys.argv[1] == "--writer":
        writer_main(sys.argv[2], sys.argv[3], int(sys.argv[4]))
    else:
        main()
