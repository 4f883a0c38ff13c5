"""Raw samples per second into a run file, crash safety on, against a plain h5py append loop.

Run:  python tests/benchmarks/bench_store.py [--trials N] [--samples S[,S...]] [--repeat R] [--dir DIR]

Each trial carries two windows (baseline and loaded) of S frames of the
reference rig's 6 channels: ``time`` float64, ``counts`` int32, ``values``
float64 and ``seq`` uint32 per frame, as the run file stores them.

* ``store (fsync)``: ``run.records.write`` of each trial, its two windows given in memory:
  the frames and the trial's row written, ``@committed`` moved, one checkpoint (flush, then
  one record appended to the journal and synced; the run file itself synced every few
  commits and at close, :mod:`labcli.core.store.journal`).  Every row times the trials'
  writes alone; creating and closing the run file (once a run) is printed apart.
* ``store (no fsync)``: the same writes with ``os.fsync`` and ``os.fdatasync`` made no-ops
  for the run (the flushes stay), to separate the cost of durability from the cost of the
  layout.  RunFile has no switch for it (every commit syncs, by design): the benchmark counts
  the calls, and prints them, so a row that says "no fsync" cannot quietly be the fsync path
  (tests/benchmarks/test_bench_options.py holds each option to what it changes).
* ``bare h5py, same filters, one fsync per trial``: the independent baseline of the write path
  (the same four arrays, the run file's gzip 4, shuffle, Fletcher32 and chunk length, each
  trial appended and then flushed and fsynced once); the run file is quoted as a ratio to it.
* ``bare h5py, no fsync``: the same baseline with ``os.fsync`` made a no-op, as the run file's
  "no fsync" row: their ratio is the layout's and the crash safety's cost apart from the disk's
  syncs, which on a shared disk vary from run to run far more than the writes do.
* ``plain h5py``: the baseline a first version usually is: four resizable
  datasets in one file, each window appended with ``resize`` and a slice
  write, never flushed until the file is closed (closing is timed).  It does
  not survive a kill -9 (an HDF5 file closed by a kill mid-write may not open again).

Samples are frames x channels.  Best of R interleaved runs for each; the ratios are
measured in the same run on the same disk.  Last, the file size per trial of the run file
(compressed, checksummed) and of the plain file (neither), beside the frames' own bytes.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import math
import os
import shutil
import sys
import tempfile
import time
from collections.abc import Callable, Iterator
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

import h5py  # noqa: E402
import numpy as np  # noqa: E402

from labcli.core.store import RunFile  # noqa: E402
from labcli.core.window import Window  # noqa: E402

CHANNELS = ("P_L1", "P_R1", "P_L2", "P_R2", "POT1", "POT2")


class _Protocol:
    name = "bench"
    kind = "force"
    text = 'name = "bench"\nkind = "force"\n'
    channels = CHANNELS

    class calibration:  # noqa: N801 - stands in for labcli.core.calibration.Calibration
        units = ("MPa",) * 4 + ("rad",) * 2

        @staticmethod
        def to_si(counts):
            c = np.asarray(counts, dtype=np.float64)
            return np.hstack([(c[:, :4] * 5.0 / 4095 - 1.0) / 4.0, np.radians((c[:, 4:] - 2048) * 340 / 4095)])


def protocol_for(frames_per_window: int) -> _Protocol:
    """The bench protocol capturing windows of this many frames (the run file picks its chunk length from it)."""
    p = _Protocol()
    p.rate_hz = 1000.0  # type: ignore[attr-defined]
    p.settling = type("settling", (), {"capture_s": frames_per_window / 1000.0})()  # type: ignore[attr-defined]
    return p


class _Device:
    device, firmware, channels, port = "bench", "1.0", CHANNELS, "bench://"


def make_records(n_trials: int, n: int, seed: int = 0) -> list[dict]:
    rng = np.random.default_rng(seed)
    out = []
    for i in range(n_trials):
        raw = {}
        for w, key in enumerate(("baseline", "load")):
            counts = rng.integers(0, 4096, size=(n, 6), dtype=np.int64)
            seq = np.arange(n, dtype=np.int64) + (2 * i + w) * n
            raw[key] = Window.of(seq, counts, _Protocol.calibration.to_si(counts), t_us=seq * 5000)
        out.append(
            {
                "trial": i,
                "P0_MPa": rng.uniform(0.1, 0.3, 4),
                "P_MPa": rng.uniform(0.1, 0.3, 4),
                "theta_rad": rng.uniform(-0.3, 0.3, 2),
                "force_N": rng.uniform(-2, 2, 2),
                "mass_kg": 0.2,
                "direction_rad": 0.5,
                "raw": raw,
                "settle": {"load": {"settled": True, "settle_time_s": 2.0, "criterion": "bench"}},
            }
        )
    return out


@contextlib.contextmanager
def fsyncs(enabled: bool) -> Iterator[list[int]]:
    """Count the calls of ``os.fsync`` (and ``os.fdatasync``) in the block; ``enabled=False`` makes them no-ops."""
    calls = [0]
    real = {name: getattr(os, name) for name in ("fsync", "fdatasync") if hasattr(os, name)}

    def counted(name: str) -> Callable[[int], None]:
        def sync(fd: int) -> None:
            calls[0] += 1
            if enabled:
                real[name](fd)

        return sync

    for name in real:
        setattr(os, name, counted(name))
    try:
        yield calls
    finally:
        for name, fn in real.items():
            setattr(os, name, fn)


def run_store(path: str, records: list[dict], sync: bool, opened: list[float] | None = None) -> tuple[float, int]:
    """Seconds to write ``records`` into a new run file, and the fsyncs made (skipped when not ``sync``).

    The seconds are the trials' commits alone: creating the file (its layout, metadata and
    first checkpoint) and closing it are a run's, not a trial's, and are added to ``opened``."""
    with fsyncs(sync) as calls:
        t0 = time.perf_counter()
        n = len(next(iter(records[0]["raw"].values())).seq)
        with RunFile.create(path, protocol=protocol_for(n), device_info=_Device(), force=True) as run:
            t1 = time.perf_counter()
            for rec in records:
                run.records.write(rec)
            seconds = time.perf_counter() - t1
            t2 = time.perf_counter()
        if opened is not None:
            opened.append(t1 - t0 + time.perf_counter() - t2)
    return seconds, calls[0]


def run_plain(path: str, records: list[dict]) -> float:
    t0 = time.perf_counter()
    with h5py.File(path, "w") as f:
        time_ds = f.create_dataset("time", shape=(0,), maxshape=(None,), dtype="f8", chunks=(4096,))
        counts_ds = f.create_dataset("counts", shape=(0, 6), maxshape=(None, 6), dtype="i4", chunks=(4096, 6))
        values_ds = f.create_dataset("values", shape=(0, 6), maxshape=(None, 6), dtype="f8", chunks=(4096, 6))
        seq_ds = f.create_dataset("seq", shape=(0,), maxshape=(None,), dtype="u4", chunks=(4096,))
        end = 0
        for rec in records:
            for w in rec["raw"].values():
                n = len(w.seq)
                for ds in (time_ds, counts_ds, values_ds, seq_ds):
                    ds.resize(end + n, axis=0)
                time_ds[end : end + n] = w.t_us * 1e-6
                counts_ds[end : end + n] = w.counts.astype(np.int32)
                values_ds[end : end + n] = w.si
                seq_ds[end : end + n] = w.seq.astype(np.uint32)
                end += n
    return time.perf_counter() - t0


# The run file's own filters, written out here so that the baseline imports nothing of labcli.
FILTERS = {"compression": "gzip", "compression_opts": 4, "shuffle": True, "fletcher32": True}


def run_durable(path: str, records: list[dict], chunk: int) -> float:
    """Bare h5py as a careful user writes a crash-safe log: the same four arrays as ``plain``, with
    the run file's filters and chunk length, each trial's two windows appended, then one flush and
    one fsync per trial.  What a trial's durability costs at the least, with no layout of labcli's."""
    with h5py.File(path, "w") as f:
        shapes = {"time": ((), "f8"), "counts": ((6,), "i4"), "values": ((6,), "f8"), "seq": ((), "u4")}
        ds = {
            k: f.create_dataset(k, shape=(0, *s), maxshape=(None, *s), dtype=t, chunks=(chunk, *s), **FILTERS)
            for k, (s, t) in shapes.items()
        }
        t0 = time.perf_counter()  # the trials alone, as for the run file
        end = 0
        for rec in records:
            for w in rec["raw"].values():
                n = len(w.seq)
                for d in ds.values():
                    d.resize(end + n, axis=0)
                ds["time"][end : end + n] = w.t_us * 1e-6
                ds["counts"][end : end + n] = w.counts.astype(np.int32)
                ds["values"][end : end + n] = w.si
                ds["seq"][end : end + n] = w.seq.astype(np.uint32)
                end += n
            f.flush()
            os.fsync(f.id.get_vfd_handle())
        seconds = time.perf_counter() - t0
    return seconds


def chunk_of(frames_per_window: int) -> int:
    """The run file's chunk length for windows of this many frames (a power of two, 64 to 4096)."""
    return int(min(4096, max(64, 2 ** math.ceil(math.log2(max(1, frames_per_window))))))


def measure(folder: str, records: list[dict], repeat: int) -> dict[str, float]:
    """Best seconds of each way over ``repeat`` interleaved rounds, and the fsyncs each store run made."""
    best = dict.fromkeys(("sync", "nosync", "plain", "durable", "durable_nosync", "opened"), math.inf)
    chunk = chunk_of(len(next(iter(records[0]["raw"].values())).seq))
    made = {"sync": 0, "nosync": 0}
    for _ in range(repeat):  # interleaved, so that a busy moment on the machine hits all three alike
        for key, sync in (("sync", True), ("nosync", False)):
            opened: list[float] = []
            seconds, calls = run_store(os.path.join(folder, f"{key}.h5"), records, sync, opened)
            if sync:
                best["opened"] = min(best["opened"], opened[0])
            best[key] = min(best[key], seconds)
            made[key] = calls if sync else 0  # the no-fsync run's calls were skipped
        best["plain"] = min(best["plain"], run_plain(os.path.join(folder, "plain.h5"), records))
        best["durable"] = min(best["durable"], run_durable(os.path.join(folder, "durable.h5"), records, chunk))
        with fsyncs(False):
            seconds = run_durable(os.path.join(folder, "durable-nosync.h5"), records, chunk)
        best["durable_nosync"] = min(best["durable_nosync"], seconds)
    return {**best, **{f"fsyncs_{k}": v for k, v in made.items()}}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--trials", type=int, default=60)
    ap.add_argument("--samples", default="400,4000", help="frames per window, comma-separated")
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--dir", default=None, help="where to write (default: a temporary folder)")
    ap.add_argument("--figures", default=None, help="write the figures to this JSON file ({name: value})")
    ap.add_argument(
        "--processes",
        type=int,
        default=0,
        help="run the benchmark in this many fresh processes, one after another, and report each figure's median",
    )
    args = ap.parse_args()
    if args.processes:
        in_processes(args)
        return
    figures: dict[str, float | int | str] = {"trials": args.trials, "best of": args.repeat}
    figures["load average at start"] = round(os.getloadavg()[0], 2)  # 1-minute: how busy the machine was
    folder = args.dir or tempfile.mkdtemp(prefix="bench_store_")
    os.makedirs(folder, exist_ok=True)
    print(
        f"h5py {h5py.__version__}, HDF5 {h5py.version.hdf5_version}; {args.trials} trials x 2 windows x 6 channels; "
        f"best of {args.repeat}; files in {folder}"
    )
    print(
        f"{'frames/window':>13} {'store fsync':>17} {'store no fsync':>17} {'plain h5py':>17} "
        f"{'fsync/plain':>12} {'fsync/no-fsync':>15} {'ms/trial (fsync)':>17} {'fsyncs/trial made':>20}"
    )
    sizes: list[tuple[int, float, float]] = []
    try:
        for n in (int(s) for s in args.samples.split(",")):
            t = measure(folder, make_records(args.trials, n), args.repeat)
            samples = args.trials * 2 * n * len(CHANNELS)
            rate = [samples / t[k] for k in ("sync", "nosync", "plain")]
            print(
                f"{n:>13} {rate[0]:>11.3g} smp/s {rate[1]:>11.3g} smp/s {rate[2]:>11.3g} smp/s "
                f"{rate[0] / rate[2]:>12.3f} {rate[0] / rate[1]:>15.3f} {t['sync'] / args.trials * 1e3:>14.1f} ms "
                f"{t['fsyncs_sync'] / args.trials:>8.1f} vs {t['fsyncs_nosync'] / args.trials:.1f}"
            )
            sizes.append(
                (n, *(os.path.getsize(os.path.join(folder, f)) / args.trials for f in ("sync.h5", "plain.h5")))
            )
            print(
                f"{'':>13} bare h5py, same filters and chunks, one fsync per trial: "
                f"{t['durable'] / args.trials * 1e3:.2f} ms/trial; the run file takes "
                f"{t['sync'] / t['durable']:.2f}x its time (creating and closing the run file, once a run: "
                f"{t['opened'] * 1e3:.0f} ms)"
            )
            print(
                f"{'':>13} with os.fsync a no-op in both: bare h5py {t['durable_nosync'] / args.trials * 1e3:.2f} "
                f"ms/trial; the run file takes {t['nosync'] / t['durable_nosync']:.2f}x its time"
            )
            figures[f"{n} frames durable h5py no fsync ms per trial"] = round(
                t["durable_nosync"] / args.trials * 1e3, 3
            )
            figures[f"{n} frames no fsync over durable h5py no fsync"] = round(t["nosync"] / t["durable_nosync"], 3)
            figures[f"{n} frames create and close ms"] = round(t["opened"] * 1e3, 1)
            figures[f"{n} frames durable h5py ms per trial"] = round(t["durable"] / args.trials * 1e3, 3)
            figures[f"{n} frames fsync over durable h5py"] = round(t["sync"] / t["durable"], 3)
            for key, what in (("sync", "fsync"), ("nosync", "no fsync"), ("plain", "plain h5py")):
                figures[f"{n} frames {what} ms per trial"] = round(t[key] / args.trials * 1e3, 3)
            figures[f"{n} frames fsyncs per trial"] = t["fsyncs_sync"] / args.trials
            figures[f"{n} frames no fsync fsyncs per trial"] = t["fsyncs_nosync"] / args.trials
            figures[f"{n} frames fsync over no fsync"] = round(t["sync"] / t["nosync"], 3)
        for n, run_b, plain_b in sizes:
            # The frames' own bytes: time f8, seq u4, counts i4 x 6, values f8 x 6, two windows a trial.
            data_b = 2 * n * (8 + 4 + 4 * len(CHANNELS) + 8 * len(CHANNELS))
            print(
                f"file size per trial at {n} frames/window: run file {run_b / 1e3:.1f} KB, plain h5py "
                f"{plain_b / 1e3:.1f} KB ({run_b / plain_b:.2f}x), the frames' own bytes {data_b / 1e3:.1f} KB"
            )
    finally:
        if args.dir is None:
            shutil.rmtree(folder, ignore_errors=True)
    print("A 200 Hz rig produces 1200 samples/s (6 channels).")
    figures["load average at end"] = round(os.getloadavg()[0], 2)
    print(
        f"load average (1 min) {figures['load average at start']} at the start, {figures['load average at end']} at the end"
    )
    if args.figures:
        Path(args.figures).write_text(json.dumps(figures, indent=1) + "\n")


def in_processes(args: argparse.Namespace) -> None:
    """``--processes N``: N fresh processes of this script (each interleaving every way over its own
    ``--repeat`` rounds); each figure is the median over the processes, the ratios taken within each."""
    import statistics
    import subprocess

    runs: list[dict] = []
    with tempfile.TemporaryDirectory() as tmp:
        for i in range(args.processes):
            out = Path(tmp) / f"figures-{i}.json"
            cmd = [sys.executable, __file__, "--trials", str(args.trials), "--samples", args.samples]
            cmd += ["--repeat", str(args.repeat), "--figures", str(out)] + (["--dir", args.dir] if args.dir else [])
            print(subprocess.run(cmd, check=True, capture_output=True, text=True).stdout, end="")
            runs.append(json.loads(out.read_text()))
    figures: dict[str, float | int | str] = {"trials": args.trials, "best of": args.repeat, "processes": len(runs)}
    for key in runs[0]:
        if key not in figures:
            figures[key] = round(statistics.median(float(r[key]) for r in runs), 3)
    ratios = ", ".join(
        f"{n}: {[r[f'{n} frames fsync over durable h5py'] for r in runs]}" for n in args.samples.split(",")
    )
    print(f"median of {len(runs)} fresh processes; the run file over bare h5py in each, by frames/window: {ratios}")
    for n in args.samples.split(","):
        print(
            f"{n} frames/window: the run file takes {figures[f'{n} frames fsync over durable h5py']}x bare h5py's time"
        )
    if args.figures:
        Path(args.figures).write_text(json.dumps(figures, indent=1) + "\n")


if __name__ == "__main__":
    main()
