"""Peak memory of one trial with long capture windows: streamed into the file against gathered in memory.

Run:  python tests/benchmarks/bench_capture_memory.py [--windows 60,600,3600] [--rate 1000] [--dir DIR]
                                                       [--realism kind] [--seeds 1]

One force trial of takuma2014 (the reference rig's 6 channels) on the simulated rig (the kind
one, seed 1, by default: ``--realism``, ``--seeds``, rig_options.py) in virtual time, with every
capture window (the air supply's, the trial's baseline and its loaded window) ``--windows`` seconds long at ``--rate`` Hz (``tests/support/long_capture.py``):

* ``streamed``: ``labcli``'s engine, which streams a trial's windows into the run file in
  whole chunks as they arrive and keeps only their running statistics;
* ``in memory``: the same engine capturing as it did before (each window gathered whole,
  the trial's arrays written at the commit): the baseline, measured in the same run.

Each measurement runs in a fresh process, which first records a trial of 1 s windows; its
figure is the growth of the process's peak resident memory (``ru_maxrss``) over its resident
memory just before the measured trial, so the interpreter, the imported libraries and what
a first trial sets up are left out.  The two paths' run files must verify
clean and hold the same frames.

What the streamed path still gains with the window's length (about 1.4 bytes per frame) is
HDF5's own: freed chunk buffers it keeps on its internal free lists, which HDF5 caps (by
default at some tens of MiB in all) and gives back on ``H5garbage_collect``.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path[:0] = [str(ROOT), str(ROOT / "tests"), str(ROOT / "tests" / "support")]

from rig_options import add_rig_options, bench_parser  # noqa: E402

MiB = 1 << 20


def rss_bytes() -> int:
    with open("/proc/self/statm") as f:
        return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE")


def child(window_s: float, mode: str, rate: float, folder: str, seed: int = 1, realism: str = "kind") -> None:
    """One trial in this process; prints one JSON line."""
    from long_capture import record_trial

    from labcli.core.store import RunFile

    path = Path(folder) / f"{mode}-{window_s:g}.h5"
    # A trial of 1 s windows first, so what the first trial imports and sets up is not counted.
    record_trial(path, 1.0, in_memory=(mode == "in memory"), rate_hz=rate, seed=seed, realism=realism)
    path.unlink()
    before = rss_bytes()
    t = time.perf_counter()
    outcome = record_trial(path, window_s, in_memory=(mode == "in memory"), rate_hz=rate, seed=seed, realism=realism)
    wall = time.perf_counter() - t
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024
    with RunFile.open(path) as run:
        ok = run.verify()["ok"]
        rec = run.records.read(1)
    frames = sum(len(rec["raw"][w].seq) for w in ("baseline", "load"))
    print(
        json.dumps(
            {
                "status": outcome.status,
                "wall_s": wall,
                "before": before,
                "peak": peak,
                "ok": ok,
                "frames": frames,
                "bytes": path.stat().st_size,
                "checksums": [int(v) for k, v in sorted(run_checksums(path).items())],
            }
        )
    )
    path.unlink()


def run_checksums(path: Path) -> dict[str, int]:
    import h5py

    with h5py.File(path, "r") as f:
        t = f["entry/trials"]
        return {k: t[k][0] for k in ("baseline_checksum", "loaded_checksum")}


def measure(window_s: float, mode: str, rate: float, folder: str, seed: int = 1, realism: str = "kind") -> dict:
    rig = ["--seeds", str(seed), "--realism", realism]
    out = subprocess.run(
        [sys.executable, __file__, "--child", f"{window_s}", mode, "--rate", f"{rate}", "--dir", folder, *rig],
        capture_output=True,
        text=True,
        check=False,
    )
    if out.returncode != 0:
        raise SystemExit(f"{mode} {window_s:g} s failed:\n{out.stdout}{out.stderr}")
    return json.loads(out.stdout.strip().splitlines()[-1])


def label(s: float) -> str:
    return f"{s / 3600:g} h" if s >= 3600 else f"{s / 60:g} min" if s >= 60 else f"{s:g} s"


def main() -> None:
    ap = bench_parser(__doc__)
    add_rig_options(ap, realism="kind", seeds="1", one=True)
    ap.add_argument("--windows", default="60,600,3600", help="capture window lengths, s (comma-separated)")
    ap.add_argument("--rate", type=float, default=1000.0, help="frames per second")
    ap.add_argument("--dir", default=None, help="folder for the run files (default: a temporary one)")
    ap.add_argument("--child", nargs=2, metavar=("WINDOW_S", "MODE"), help=argparse.SUPPRESS)
    a = ap.parse_args()
    folder = a.dir or tempfile.mkdtemp(prefix="bench-capture-")
    if a.child:
        child(float(a.child[0]), a.child[1], a.rate, folder, a.seeds[0], a.realism)
        return
    windows = [float(w) for w in a.windows.split(",")]
    print(
        f"One force trial, 6 channels at {a.rate:g} Hz, every capture window as long as shown; "
        "peak resident memory over that before the trial (MiB), each in a fresh process."
    )
    print(
        f"{'window':>8} {'frames/trial':>13} {'in memory':>11} {'streamed':>10} {'ratio':>8} "
        f"{'B/frame in memory':>18} {'wall in memory / streamed':>26}"
    )
    results = []
    for w in windows:
        mem = measure(w, "in memory", a.rate, folder, a.seeds[0], a.realism)
        st = measure(w, "streamed", a.rate, folder, a.seeds[0], a.realism)
        for r in (mem, st):
            if r["status"] != "finished" or not r["ok"]:
                raise SystemExit(f"a {label(w)} trial did not finish clean: {r}")
        if mem["checksums"] != st["checksums"] or mem["frames"] != st["frames"]:
            raise SystemExit(f"the two paths stored different frames for {label(w)} windows")
        gm, gs = (r["peak"] - r["before"] for r in (mem, st))
        n = st["frames"]
        results.append((w, gm, gs))
        print(
            f"{label(w):>8} {n:>13,} {gm / MiB:>7.1f} MiB {gs / MiB:>6.1f} MiB {gm / max(gs, 1):>7.1f}x "
            f"{gm / n:>18.0f} {mem['wall_s']:>15.1f} s / {st['wall_s']:.1f} s"
        )
    if len(results) > 1:
        (w0, m0, s0), (w1, m1, s1) = results[0], results[-1]
        print(
            f"growth from {label(w0)} to {label(w1)} windows ({w1 / w0:g}x the frames): "
            f"in memory {m1 / max(m0, 1):.1f}x, streamed {s1 / max(s0, 1):.2f}x"
        )
    if not a.dir:
        os.rmdir(folder)


if __name__ == "__main__":
    main()
