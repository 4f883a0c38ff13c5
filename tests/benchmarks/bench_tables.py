"""Trial tables at archive scale: reading, fit, validate and import of a CSV, against pandas in the same run.

Run:  python tests/benchmarks/bench_tables.py [--sizes 1e5,1e6] [--repeat 3] [--import-sizes 1e6]

Inputs, written once before any timing: a trial CSV of n rows cycled from 2000 trials of
:func:`labcli.papers.takuma2014.models.synthetic.paper_trials` (Eqs. 34-37 exact) with one
ADC count of fresh sensor noise, every row renumbered 0 .. n - 1 (the ids a run file holds);
the first 4/5 ``set = fit``, the rest ``validation``; written by pandas (``repr`` floats), about
240 bytes a row.

Each figure is one fresh Python process (so peak memory is that process's own high-water mark,
interpreter and imports included, and start-up is paid by both sides alike); the median of
``--repeat`` runs is kept, the two sides alternating so that a busy moment hits both:

* ``read``: ``read_trial_csv`` (the checked reader) against ``pandas.read_csv``;
* ``fit``: ``labcli fit t.csv -o m.json --json`` (the command, in process: its default posture
  form, the model file and the JSON printed) against ``pandas.read_csv`` plus ``TakumaModel.fit``
  (the four least-squares fits of Eqs. 34-37, the archive-scale baseline);
* ``validate``: ``labcli validate t.csv --model m.json`` (the report; it also fits the other form
  for its side-by-side table) against ``pandas.read_csv`` plus ``metrics.evaluate`` of the same
  model;
* ``import``: ``labcli import t.csv -o t.h5`` at ``--import-sizes`` (one bulk write into the run
  file), against ``read_trial_csv`` of the same table, so that the share of the time spent
  reading the table and writing the run file shows; and the run file's size per trial.

Printed: seconds and peak MiB per step beside the baseline and the ratios; peak memory as a
multiple of the CSV's size; the scaling exponent (log-log slope from the smallest to the
largest n) of time and of peak memory.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import resource
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")

POOL = 2000
STEPS = ("read", "fit", "validate")


def write_table(n: int, path: Path) -> None:
    import numpy as np

    from labcli.papers.takuma2014.models.synthetic import add_sensor_noise, paper_trials

    pool = paper_trials(POOL, seed=3, noise=False)
    out = pool.iloc[np.arange(n) % POOL].reset_index(drop=True)
    out["trial"] = np.arange(n)
    out = add_sensor_noise(out, seed=n, noise_counts=1.0)
    out["set"] = np.where(np.arange(n) < n * 4 // 5, "fit", "validation")
    columns = [
        "trial",
        "set",
        "P_L10",
        "P_R10",
        "P_L20",
        "P_R20",
        "P_L1",
        "P_R1",
        "P_L2",
        "P_R2",
        "theta1_deg",
        "theta2_deg",
        "Fx_N",
        "Fy_N",
    ]
    out[columns].to_csv(path, index=False)


# ------------------------------------------------------------------ one step in a fresh process


def child(step: str, side: str, csv: str, model: str, out: str) -> None:
    t0 = time.perf_counter()
    if side == "pandas":
        import pandas as pd

        df = pd.read_csv(csv)
        if step in ("fit", "validate"):
            from labcli.papers.takuma2014.models.takuma import TakumaModel

            if step == "fit":
                TakumaModel(geometry=_geometry(), protocol="takuma2014").fit(df)
            else:
                from labcli.papers.takuma2014.models.metrics import evaluate
                from labcli.papers.takuma2014.models.posture import load_force_model

                evaluate(load_force_model(model), df)
    elif step == "read":
        from labcli.papers.takuma2014.tables import read_trial_csv

        read_trial_csv(csv)
    else:
        from labcli.cli import cli

        args = {
            "fit": ["fit", csv, "-o", out, "--json"],
            "validate": ["validate", csv, "--model", model],
            "import": ["import", csv, "-o", out, "--protocol", "takuma2014", "--force"],
        }[step]
        import contextlib
        import io

        with contextlib.redirect_stdout(io.StringIO()):
            cli.main(args, standalone_mode=False)
    seconds = time.perf_counter() - t0
    peak = _high_water()
    print(json.dumps({"seconds": seconds, "peak": peak}))


def _high_water() -> int:
    """This process's peak resident bytes: VmHWM starts afresh at exec (ru_maxrss keeps the parent's peak)."""
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith("VmHWM:"):
            return int(line.split()[1]) * 1024
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024


def _geometry() -> dict:
    from labcli.core.protocol import load_protocol

    return dict(load_protocol("takuma2014").settings.rig)


def once(step: str, side: str, csv: Path, model: Path, out: Path) -> dict:
    res = subprocess.run(
        [sys.executable, __file__, "--child", step, side, str(csv), str(model), str(out)],
        capture_output=True,
        text=True,
        check=True,
    )
    return json.loads(res.stdout.strip().splitlines()[-1])


def paired(repeat: int, *sides: tuple) -> list[dict]:
    """Median seconds and peak of each side over ``repeat`` rounds, the sides alternating in each round."""
    runs: list[list[dict]] = [[] for _ in sides]
    for _ in range(repeat):
        for got, args in zip(runs, sides, strict=False):
            got.append(once(*args))
    return [{k: statistics.median(r[k] for r in got) for k in ("seconds", "peak")} for got in runs]


def slope(x: list[float], y: list[float]) -> float:
    return math.log(y[-1] / y[0]) / math.log(x[-1] / x[0]) if len(x) > 1 else math.nan


def mib(b: float) -> str:
    return f"{b / 2**20:.0f}"


# Over 80 lines: one benchmark from its options to its printed table, each step a row of it.
def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", default="1e5,1e6", help="rows of the trial CSV, comma-separated")
    ap.add_argument("--import-sizes", default="1e6", help="rows imported into a run file, comma-separated")
    ap.add_argument("--repeat", type=int, default=3, help="fresh processes per figure (the median is kept)")
    ap.add_argument("--json", default=None, help="also write the figures to this JSON file")
    ap.add_argument("--child", nargs=5, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.child:
        child(*args.child)
        return
    sizes = sorted(int(float(s)) for s in args.sizes.split(","))
    import_sizes = sorted(int(float(s)) for s in args.import_sizes.split(",") if s)
    work = Path(tempfile.mkdtemp(prefix="labcli_bench_tables_"))
    figures: dict = {"sizes": sizes, "steps": {}, "import": {}}
    print(
        f"{'n':>8} {'step':9} {'labcli s':>9} {'pandas s':>9} {'ratio':>6} "
        f"{'labcli MiB':>10} {'pandas MiB':>10} {'ratio':>6} {'CSV MiB':>8} {'peak/CSV':>8}"
    )
    for n in sizes:
        csv, model, out = work / f"t{n}.csv", work / f"m{n}.json", work / f"o{n}"
        write_table(n, csv)
        size = csv.stat().st_size
        for step in STEPS:
            mine, base = paired(
                args.repeat,
                (step, "labcli", csv, model, model if step == "fit" else out),
                (step, "pandas", csv, model, out),
            )
            figures["steps"].setdefault(step, []).append({"n": n, "csv_bytes": size, "labcli": mine, "pandas": base})
            print(
                f"{n:>8} {step:9} {mine['seconds']:>9.2f} {base['seconds']:>9.2f} "
                f"{mine['seconds'] / base['seconds']:>6.2f} {mib(mine['peak']):>10} {mib(base['peak']):>10} "
                f"{mine['peak'] / base['peak']:>6.2f} {mib(size):>8} {mine['peak'] / size:>8.2f}"
            )
    for step, rows in figures["steps"].items():
        ns = [r["n"] for r in rows]
        print(
            f"scaling exponent {step:9} time {slope(ns, [r['labcli']['seconds'] for r in rows]):.2f} "
            f"(pandas {slope(ns, [r['pandas']['seconds'] for r in rows]):.2f}), peak memory "
            f"{slope(ns, [r['labcli']['peak'] for r in rows]):.2f} "
            f"(pandas {slope(ns, [r['pandas']['peak'] for r in rows]):.2f})"
        )
    for n in import_sizes:
        csv, out = work / f"i{n}.csv", work / f"i{n}.h5"
        write_table(n, csv)
        whole, read = paired(args.repeat, ("import", "labcli", csv, csv, out), ("read", "labcli", csv, csv, out))
        per_trial = out.stat().st_size / n
        figures["import"][n] = {
            "import": whole,
            "read": read,
            "file_bytes_per_trial": per_trial,
            "csv_bytes_per_trial": csv.stat().st_size / n,
        }
        print(
            f"import {n:>8} rows: {whole['seconds']:.2f} s ({whole['seconds'] / n * 1e6:.0f} us/row), peak "
            f"{mib(whole['peak'])} MiB; of which reading the table {read['seconds']:.2f} s "
            f"({whole['seconds'] / read['seconds']:.2f}x the read); run file {per_trial:.0f} bytes per trial "
            f"(the CSV {csv.stat().st_size / n:.0f})"
        )
    if args.json:
        Path(args.json).write_text(json.dumps(figures, indent=1))
    shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    main()
