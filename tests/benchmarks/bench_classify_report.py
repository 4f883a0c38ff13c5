"""``labcli classify`` on an archive of n pushes: peak memory and time of the report, against pandas.

Input: the six demo objects pushed ten times each on the simulated rig, tiled to n pushes on
n / 10 objects (an archive: every copy of the pool named apart), written as a push CSV, and
a force model fitted on the shipped plan's weight trials through the same rig.

Each command runs as a fresh subprocess; its peak resident memory is its own VmHWM read at
exit, its time the wall time.  Measured side by side, same run, same CSV:

* baseline: ``pandas.read_csv`` of the push CSV, ``groupby("object")`` mean and standard
  deviation of every numeric column, written as JSON (what any script would do first);
* ``classify --json``: every push's and every object's results, streamed to /dev/null;
* ``classify``: the human report (a summary per object; pushes are not listed at this size).

The ratio is classify / baseline; the target is --json within 3x at 10^6 pushes.  The
CSV reading is the tables' (labcli.core.tables); the report stage is measured apart, in
process, with tracemalloc: the streamed JSON against building the whole report as one dict.

    python tests/benchmarks/bench_classify_report.py [--sizes 1e5,1e6] [--keep DIR]
"""

from __future__ import annotations

import argparse
import gc
import json
import os
import subprocess
import sys
import tempfile
import time
import tracemalloc
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np  # noqa: E402

BASELINE = """
import sys, pandas as pd
df = pd.read_csv(sys.argv[1])
num = df.select_dtypes("number").columns.drop("push")
out = df.groupby("object")[list(num)].agg(["mean", "std"])
out.to_json(sys.argv[2])
"""


# Each command runs under this wrapper, which prints the process's own peak RSS (VmHWM) at exit.
# ru_maxrss of a child is no use here: a forked child inherits the parent's high-water mark.
PEAK = """
import atexit, runpy, sys
def peak():
    for line in open("/proc/self/status"):
        if line.startswith("VmHWM:"):
            sys.stderr.write("PEAK_KB " + line.split()[1] + "\\n")
atexit.register(peak)
code = sys.argv[1]
sys.argv = sys.argv[1:]
if code == "-m":
    sys.argv = sys.argv[1:]
    runpy.run_module("labcli", run_name="__main__")
else:
    exec(compile(code, "<baseline>", "exec"))
"""


def measure(args: list[str]) -> tuple[float, float]:
    """(wall seconds, peak RSS in MB) of a fresh Python running ``args``; stdout to /dev/null."""
    t0 = time.perf_counter()
    with open(os.devnull, "w") as null:
        p = subprocess.run(
            [sys.executable, "-c", PEAK, *args],
            stdout=null,
            stderr=subprocess.PIPE,
            text=True,
            env=dict(os.environ, COLUMNS="80"),
        )
    dt = time.perf_counter() - t0
    peaks = [line for line in p.stderr.splitlines() if line.startswith("PEAK_KB ")]
    if p.returncode != 0 or not peaks:
        raise SystemExit(f"{' '.join(args)} failed: {p.stderr}")
    return dt, int(peaks[-1].split()[1]) / 1024


def inputs(folder: Path, n: int) -> tuple[Path, Path]:
    from labcli.core.protocol import load_protocol
    from labcli.papers.takuma2014.models.takuma import TakumaModel
    from labcli.papers.takuma2014.protocol import load_plan
    from labcli.papers.takuma2014.sim.drive import simulate_pushes, simulate_weight_trials
    from labcli.papers.takuma2014.sim.objects import DEMO_OBJECTS
    from labcli.papers.takuma2014.sim.rig import SimRig
    from labcli.papers.takuma2014.tables import write_push_csv

    force, push = load_protocol("takuma2014"), load_protocol("takuma2014-stiffness")
    rig = SimRig(seed=1)
    model_path = folder / "force.model.json"
    if not model_path.exists():
        trials = simulate_weight_trials(rig, load_plan(force), calibration=force.calibration)
        TakumaModel(geometry=force.settings.rig, protocol=force.name).fit(trials).save(model_path)
    pool = simulate_pushes(rig, DEMO_OBJECTS, calibration=push.calibration, pushes_per_object=10)
    idx = np.arange(n) % len(pool)
    table = pool.iloc[idx].reset_index(drop=True)
    table["push"] = np.arange(1, n + 1)
    table["object"] = table["object"] + "#" + (np.arange(n) // len(pool)).astype(str)
    csv = folder / f"pushes-{n}.csv"
    write_push_csv(table, csv)
    return csv, model_path


def report_stage(csv: Path, model_path: Path) -> tuple[float, float]:
    """Peak traced MB above the classification of the streamed JSON and of the whole-dict report."""
    from labcli.papers.takuma2014.models.classify import classify_file, report_to_dict, write_report_json

    rep = classify_file(csv, model_path, method="bands")
    out = []
    for fn in (lambda: write_report_json(rep, open(os.devnull, "w")), lambda: json.dumps(report_to_dict(rep))):
        gc.collect()
        tracemalloc.start()
        base = tracemalloc.get_traced_memory()[0]
        fn()
        out.append((tracemalloc.get_traced_memory()[1] - base) / 1e6)
        tracemalloc.stop()
    return out[0], out[1]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--sizes", default="1e5", help="comma-separated push counts (default 1e5; archive scale: 1e6)")
    ap.add_argument("--keep", type=Path, default=None, help="folder for the CSVs (default: a temporary one)")
    ap.add_argument("--no-stage", action="store_true", help="skip the in-process report-stage measurement")
    args = ap.parse_args()
    folder = args.keep or Path(tempfile.mkdtemp(prefix="bench-classify-"))
    folder.mkdir(parents=True, exist_ok=True)
    rows = []
    for n in (int(float(s)) for s in args.sizes.split(",")):
        csv, model = inputs(folder, n)
        base_t, base_m = measure([BASELINE, str(csv), str(folder / "groupby.json")])
        js_t, js_m = measure(
            ["-m", "labcli", "classify", str(csv), "--model", str(model), "--method", "bands", "--json"]
        )
        hu_t, hu_m = measure(["-m", "labcli", "classify", str(csv), "--model", str(model), "--method", "bands"])
        row = {
            "n": n,
            "csv_MB": csv.stat().st_size / 1e6,
            "baseline_s": base_t,
            "baseline_MB": base_m,
            "json_s": js_t,
            "json_MB": js_m,
            "report_s": hu_t,
            "report_MB": hu_m,
        }
        if not args.no_stage:
            row["stage_stream_MB"], row["stage_dict_MB"] = report_stage(csv, model)
        rows.append(row)
        print(
            f"n = {n:>9,} pushes ({row['csv_MB']:.0f} MB CSV): baseline {base_t:6.2f} s {base_m:7.0f} MB | "
            f"classify --json {js_t:6.2f} s {js_m:7.0f} MB ({js_m / base_m:.2f}x memory, {js_t / base_t:.1f}x time)"
            f" | classify {hu_t:6.2f} s {hu_m:7.0f} MB ({hu_m / base_m:.2f}x memory, {hu_t / base_t:.1f}x time)"
        )
        if "stage_stream_MB" in row:
            print(
                f"    report stage alone (tracemalloc): streamed JSON {row['stage_stream_MB']:.1f} MB, "
                f"whole report as one dict {row['stage_dict_MB']:.1f} MB"
            )
        csv.unlink()
    print(json.dumps(rows))


if __name__ == "__main__":
    main()
