"""Wall time of ``labcli demo`` and of an unattended 108-trial ``labcli acquire``, as subprocesses.

Run:  python tests/benchmarks/bench_demo.py [--seeds 1-3] [--realism kind] [--import-repeat 10]
                                            [--skip-demo] [--skip-acquire]

Each run is a fresh process in a fresh temporary folder, exactly as a user types it:

* ``labcli demo OUT --seed S``: 108 force trials acquired unattended through the ``sim://``
  serial protocol (virtual clock), split, fit, validation with Figure 7, 60 pushes,
  classification with Figure 9, the summary;
* ``labcli acquire RUN.h5 --port 'sim://?seed=S&clock=virtual&realism=R' --unattended``: the 108
  trials of the shipped takuma2014 plan, each written crash-safe, on the rig of ``--realism``
  (rig_options.py; kind by default, the rig docs/performance.md's figures were measured on).
  ``labcli demo`` takes no realism: it runs the simulator's default rig whatever ``--realism`` says.

Baseline, measured in the same run: ``python -c "import labcli.core.engine, labcli.core.store,
labcli.papers.takuma2014.models.takuma"``, the start-up every one of those commands pays before its first
frame (interpreter, numpy, h5py, the toolkit).  Reported: the median wall time of each
over the seeds, its ratio to the baseline, the demo's own stage times (from its
summary.json), and for each acquisition the device time it covered (the last loaded
window's end on the rig's clock, read from the run file) over its wall time: how much
faster than real time the simulated rig runs the protocol.
"""

from __future__ import annotations

import json
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from rig_options import add_rig_options, bench_parser

ROOT = Path(__file__).resolve().parents[2]
LABCLI = [sys.executable, "-m", "labcli"]
IMPORTS = "import labcli.core.engine, labcli.core.store, labcli.papers.takuma2014.models.takuma"


def wall(cmd: list[str], cwd: str) -> float:
    t0 = time.perf_counter()
    proc = subprocess.run(cmd, cwd=cwd, capture_output=True, text=True)
    t = time.perf_counter() - t0
    if proc.returncode != 0:
        raise SystemExit(f"{' '.join(cmd)} failed with exit code {proc.returncode}: {proc.stderr.strip()[-500:]}")
    return t


def device_seconds(path: Path) -> float:
    """End of the last loaded window on the rig's clock (s): how long the run kept the rig busy."""
    import h5py
    import numpy as np

    end = 0.0
    with h5py.File(path, "r") as f:
        raw = f.get("entry/raw")
        if raw is not None:  # schema 2: every window's frames in run-wide datasets, device time in each channel's
            times = [raw[name]["time"] for name in raw if isinstance(raw[name], h5py.Group) and "time" in raw[name]]
            return float(np.nanmax(times[0][()])) if times and times[0].shape[0] else 0.0  # gaps are NaN fill
        for group in ("trials", "pushes"):  # schema 1: a group per record
            for rec in f.get(group, {}).values():
                if "loaded/time" in rec and len(rec["loaded/time"]):
                    end = max(end, float(rec["loaded/time"][-1]))
    return end


def main() -> None:
    ap = bench_parser(__doc__)
    add_rig_options(ap, realism="kind", seeds="1-3")  # one run of each command per seed
    ap.add_argument("--import-repeat", type=int, default=10, help="runs of the import baseline (median kept)")
    ap.add_argument("--skip-demo", action="store_true")
    ap.add_argument("--skip-acquire", action="store_true")
    ap.add_argument("--json", default=None, help="also write the figures to this JSON file (for run_all.py)")
    args = ap.parse_args()
    seeds = args.seeds

    with tempfile.TemporaryDirectory(prefix="bench_demo_") as tmp:
        base = statistics.median(wall([sys.executable, "-c", IMPORTS], tmp) for _ in range(args.import_repeat))
        print(f'baseline: python -c "{IMPORTS}": {base:.3f} s (median of {args.import_repeat})')

        results: dict[str, list[tuple[float, float]]] = {}
        stages: list[dict[str, float]] = []
        for seed in seeds:
            if not args.skip_acquire:
                folder = Path(tempfile.mkdtemp(dir=tmp))
                t = wall(
                    LABCLI
                    + [
                        "acquire",
                        "run.h5",
                        "--port",
                        f"sim://?seed={seed}&clock=virtual&realism={args.realism}",
                        "--unattended",
                    ],
                    str(folder),
                )
                results.setdefault("acquire", []).append((t, device_seconds(folder / "run.h5")))
                print(
                    f"seed {seed}: labcli acquire --unattended (108 trials): {t:.2f} s wall, "
                    f"{results['acquire'][-1][1]:.0f} s of device time",
                    flush=True,
                )
            if not args.skip_demo:
                folder = Path(tempfile.mkdtemp(dir=tmp))
                t = wall(LABCLI + ["demo", "out", "--seed", str(seed)], str(folder))
                out = folder / "out"
                dev = device_seconds(out / "force.h5") + device_seconds(out / "pushes.h5")
                results.setdefault("demo", []).append((t, dev))
                stages.append(json.loads((out / "summary.json").read_text())["timings_s"])
                print(f"seed {seed}: labcli demo: {t:.2f} s wall, {dev:.0f} s of device time", flush=True)

    print()
    print(f"{'command':<28} {'median wall s':>13} {'/ import baseline':>18} {'device s':>9} {'device / wall':>14}")
    summary: dict = {"import_s": base, "seeds": seeds}
    for name, label in (("acquire", "labcli acquire --unattended"), ("demo", "labcli demo")):
        if name not in results:
            continue
        t = statistics.median(r[0] for r in results[name])
        dev = statistics.median(r[1] for r in results[name])
        summary[name] = {"wall_s": t, "over_import": t / base, "device_s": dev, "device_over_wall": dev / t}
        print(f"{label:<28} {t:>13.2f} {t / base:>18.1f} {dev:>9.0f} {dev / t:>13.0f}x")
    if stages:
        keys = [k for k in stages[0] if k != "total"]
        print(
            "demo stages (median s, in-process): "
            + ", ".join(f"{k} {statistics.median(s[k] for s in stages):.2f}" for k in keys)
            + f"; total {statistics.median(s['total'] for s in stages):.2f}"
        )
        summary["demo_stages_s"] = {k: statistics.median(s[k] for s in stages) for k in stages[0]}
    if args.json:
        Path(args.json).write_text(json.dumps(summary, indent=1))


if __name__ == "__main__":
    main()
