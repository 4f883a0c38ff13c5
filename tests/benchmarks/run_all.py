"""Run every benchmark (quick by default) and print one Markdown table of the headline ratios.

Run:  python tests/benchmarks/run_all.py [--full] [--only models,demo,...] [--out table.md] [--log-dir DIR]

Each script runs in its own process, with arguments that shorten it (``--full``: the
scripts' own defaults), and its output is read for the figures below; every ratio is
between two things measured in the same run of that script on this machine.  The table is
what the README's Performance section shows; paste the output there.  A script that fails
or prints something unexpected gets a row saying so, and its output is kept in
``--log-dir`` (default: a temporary folder, printed at the end).
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import re
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

HERE = Path(__file__).resolve().parent


@dataclass
class Bench:
    name: str
    script: str
    quick: list[str]
    what: str
    baseline: str
    parse: Callable[[str, Path], tuple[str, str]]  # (stdout, json path) -> (headline, context)
    json: bool = False
    timeout_s: float = 900.0
    json_flag: str = "--json"  # how the script is asked for its figures file


def grab(pattern: str, text: str, flags: int = re.M) -> re.Match:
    m = re.search(pattern, text, flags)
    if not m:
        raise ValueError(f"no line matching {pattern!r}")
    return m


def p_reader(out: str, _: Path) -> tuple[str, str]:
    rows = re.findall(r"^\s*(\d+)\s+([\d,]+) fr/s\s+([\d,]+) fr/s\s+([\d.]+)x", out, re.M)
    if not rows:
        raise ValueError("no result row")
    head = "; ".join(f"{r[3]}x the baseline's speed at {int(r[0]) // 1024} KiB" for r in rows)
    return head, ", ".join(f"{r[2]} frames/s at {int(r[0]) // 1024} KiB" for r in rows)


def p_store(out: str, _: Path) -> tuple[str, str]:
    rows = re.findall(
        r"^\s*(\d+)\s+(\S+) smp/s\s+(\S+) smp/s\s+(\S+) smp/s\s+([\d.]+)\s+([\d.]+)\s+([\d.]+) ms", out, re.M
    )
    if not rows:
        raise ValueError("no result row")
    n, sync, _, _, vs_plain, vs_nosync, ms = rows[-1]
    size = grab(
        r"^file size per trial at (\d+) frames/window: run file ([\d.]+) KB, plain h5py ([\d.]+) KB "
        r"\(([\d.]+)x\), the frames' own bytes ([\d.]+) KB",
        out,
    )
    return (
        f"{float(vs_plain):.2f} of plain h5py's rate ({float(vs_nosync):.2f} of no-fsync); file size per trial "
        f"{size.group(4)}x plain h5py's",
        f"{float(sync):.3g} samples/s, {ms} ms/trial at {n} frames/window; {size.group(2)} KB per trial "
        f"(plain {size.group(3)} KB, the frames' own bytes {size.group(5)} KB, random counts) "
        f"at {size.group(1)} frames/window",
    )


def p_startup(out: str, _: Path) -> tuple[str, str]:
    m = grab(r"ratio\s*:\s*([\d.]+) x; labcli's own share ([\d.]+) ms", out)
    help_ms = grab(r"labcli --help\s*:\s*([\d.]+) ms", out).group(1)
    return f"{m.group(1)}x", f"{help_ms} ms, {m.group(2)} ms of it labcli's own"


def p_acquire(out: str, _: Path) -> tuple[str, str]:
    ratio = grab(r"run / baseline: ([\d.]+)", out).group(1)
    fast = grab(r"device time / run wall time: (\d+)x", out).group(1)
    wall = grab(r"108 trials: ([\d.]+) s wall", out).group(1)
    return f"{ratio}x the bare link; {fast}x faster than real time", f"{wall} s for 108 trials"


def p_link(out: str, _: Path) -> tuple[str, str]:
    ratio = grab(r"CPU per frame, labcli / raw read \+ numpy parser: ([\d.]+)", out).group(1)
    m = grab(r"^labcli Device\s+([\d.]+)\s+(\d+)\s+([\d.]+)\s+(\d+)\s+\d+\s+\d+\s+[\d.]+\s+([\d.]+)%", out)
    return (
        f"{ratio}x the baseline's CPU per frame; {m.group(4)} frames lost",
        f"{m.group(3)} frames/s, host CPU {m.group(5)} %",
    )


def p_sim(out: str, _: Path) -> tuple[str, str]:
    speed = grab(r"speed-up vs baseline:\s*([\d.]+) x", out).group(1)
    dev = grab(r"sim:// virtual clock:\s*(\d+) device s per wall s", out).group(1)
    return f"{speed}x faster", f"{dev} device s per wall s at 1 kHz"


def p_rpam(out: str, _: Path) -> tuple[str, str]:
    m = grab(r"grid (\d+) x \d+: scalar loop ([\d.]+) ms, vectorised ([\d.]+) ms, speed-up ([\d.]+)x", out)
    return f"{m.group(4)}x faster", f"{m.group(3)} ms for a {m.group(1)} x {m.group(1)} grid"


def p_accuracy(out: str, _: Path) -> tuple[str, str]:
    # The first block of the table is the default policy (project, pressure-only), one row per object.
    nums = r"\s+([\d.]+)\s+([\d.]+)\s+([\d.]+)\s+([\d.]+)\s+([\d.]+)\s+([\d.]+)\s*$"
    rows = re.findall(r"^(?:project\s+pressure-only|\s+)\s+(\S+)" + nums, out, re.M)[:6]
    if not rows:
        raise ValueError("no object rows")
    ratios = [float(r[1]) for r in rows]
    right = min(float(r[6]) for r in rows)
    seeds = grab(r"^seeds (\S+), (\d+) pushes", out)
    return (
        f"k / k_true {min(ratios):.3f} to {max(ratios):.3f}; categories right {100 * right:.0f} %",
        f"seeds {seeds.group(1)}, {seeds.group(2)} pushes per object (accuracy, not time)",
    )


def p_models(_: str, path: Path) -> tuple[str, str]:
    d = json.loads(path.read_text())
    last = d["rows"][-1]
    n = last["n"]
    s = d["slope_ge_1e4"]
    head = "; ".join(f"{k} {last[k] / last['lstsq']:.1f}x" for k in ("fit", "validate", "classify", "archive"))
    us = ", ".join(f"{k} {1e6 * last[k] / n:.2g}" for k in ("fit", "validate", "classify"))
    ctx = f"at n = {n:.0e}: {us} us/trial; growth exponent (n >= 1e4) " + ", ".join(
        f"{k} {s[k]:.2f}" for k in ("lstsq", "fit", "validate", "classify", "archive")
    )
    if d.get("peak_MB"):
        ctx += "; peak memory " + ", ".join(
            f"{k} {v:.0f} MB ({d['peak_over_input'][k]:.1f}x input)" for k, v in d["peak_MB"].items()
        )
    return head, ctx


def p_tables(_: str, path: Path) -> tuple[str, str]:
    """bench_tables.py's figures (--figures): each path's CPU ratio at the largest size, then wall, memory, growth."""
    d = json.loads(path.read_text())
    ratios = {k[: -len(" cpu ratio")]: v for k, v in d.items() if k.endswith(" cpu ratio")}
    n = max(float(k.split()[1]) for k in ratios)
    last = {k: v for k, v in ratios.items() if float(k.split()[1]) == n}
    head = "; ".join(f"{k.replace(f' {k.split()[1]}', '')} {v:.2f}x CPU" for k, v in last.items())
    ctx = f"at n = {n:.0e} against pandas + numpy / bare h5py (tests/benchmarks/baselines/), median of {d['rounds per figure']}: "
    ctx += ", ".join(
        f"{k.split()[0]} {k.split()[2]} wall {d[k + ' wall ratio']:.2f}x, memory {d[k + ' peak memory ratio']:.2f}x"
        for k in last
    )
    growth = {k: v for k, v in d.items() if "cpu growth exponent" in k}
    if growth:
        ctx += "; CPU growth exponents " + ", ".join(f"{k.split(' cpu')[0]} {v:.2f}" for k, v in growth.items())
    return head, ctx


def p_demo(_: str, path: Path) -> tuple[str, str]:
    d = json.loads(path.read_text())
    a, m = d["acquire"], d["demo"]
    return (
        f"acquire {a['over_import']:.0f}x, demo {m['over_import']:.0f}x the import; "
        f"acquire {a['device_over_wall']:.0f}x faster than real time",
        f"acquire {a['wall_s']:.1f} s, demo {m['wall_s']:.1f} s, import {d['import_s']:.2f} s "
        f"(median over seeds {d['seeds'][0]}-{d['seeds'][-1]})",
    )


def p_classify_report(_: str, path: Path) -> tuple[str, str]:
    """bench_classify_report.py's figures (--figures): CPU, wall and memory ratios at the largest size."""
    d = json.loads(path.read_text())
    names = [k[: -len(" cpu ratio")] for k in d if k.endswith(" cpu ratio")]
    k = names[-1]
    return (
        f"--json {d[k + ' cpu ratio']:.2f}x CPU, {d[k + ' wall ratio']:.2f}x wall, {d[k + ' peak memory ratio']:.2f}x memory",
        f"{k}: labcli {d[k + ' labcli cpu s']:.2f} s CPU, {d[k + ' labcli peak memory MiB']:.0f} MiB; baseline "
        f"{d[k + ' baseline cpu s']:.2f} s, {d[k + ' baseline peak memory MiB']:.0f} MiB (median of {d['rounds per figure']})",
    )


def p_firmware(out: str, _: Path) -> tuple[str, str]:
    if out.startswith("skipped"):
        return "skipped", out.strip()
    rows = {
        (m.group(1), m.group(2)): m
        for m in re.finditer(
            r"^\s*(\d+) (fresh|long)\s+(\d+)\s+[\d.]+\s+([\d.]+)\s+([\d.]+)\s+\d+\s+([\d.]+)\s+([\d.]+)\s+([\d.]+)",
            out,
            re.M,
        )
    }
    slow, fast = rows[("115200", "long")], rows[("1000000", "long")]
    speeds = [float(m.group(8)) for m in rows.values()]
    return (
        f"{slow.group(3)} Hz at 115200 ({slow.group(5)} of the baud limit), {fast.group(3)} Hz at 1000000 "
        f"({fast.group(7)} of the AVR limit), long lines",
        f"fresh lines {rows[('115200', 'fresh')].group(3)} / {rows[('1000000', 'fresh')].group(3)} Hz; "
        f"simavr {min(speeds):.1f}-{max(speeds):.1f}x real time",
    )


def p_capture_memory(out: str, _: Path) -> tuple[str, str]:
    rows = re.findall(r"^\s*([\d.]+ (?:s|min|h))\s+([\d,]+)\s+([\d.]+) MiB\s+([\d.]+) MiB\s+([\d.]+)x", out, re.M)
    if not rows:
        raise ValueError("no result row")
    window, frames, mem, streamed, ratio = rows[-1]
    growth = grab(r"^growth from .*: in memory ([\d.]+)x, streamed ([\d.]+)x", out)
    return (
        f"{ratio}x less peak memory at {window} windows ({streamed} MiB vs {mem} MiB)",
        f"{frames} frames per trial; from {rows[0][0]} to {window} windows peak memory grows "
        f"{growth.group(1)}x in memory, {growth.group(2)}x streamed",
    )


BENCHES = [
    Bench(
        "reader",
        "bench_reader.py",
        ["--frames", "50000", "--rounds", "3"],
        "stream reader, 6-channel frames parsed from 4 KiB and 64 KiB chunks (CPU, fresh processes)",
        "numpy: non-digits blanked, one fromstring per chunk, no checks",
        p_reader,
    ),
    Bench(
        "store",
        "bench_store.py",
        ["--trials", "20", "--samples", "400", "--repeat", "3"],
        "trials into the HDF5 run file, fsync per trial",
        "plain h5py append, never flushed",
        p_store,
    ),
    Bench("startup", "bench_startup.py", ["--repeat", "5"], "`labcli --help` start-up", "`python -c pass`", p_startup),
    Bench(
        "acquire",
        "bench_acquire.py",
        [],
        "unattended 108-trial run in-process (engine, settle, store)",
        "same frames through Device.read only",
        p_acquire,
    ),
    Bench(
        "link",
        "bench_link.py",
        ["--seconds", "5", "--rounds", "3"],
        "pty link at 1 kHz x 6 channels, host CPU per frame",
        "raw port.read + the numpy fromstring parser",
        p_link,
    ),
    Bench(
        "sim",
        "bench_sim.py",
        ["--frames", "20000", "--repeat", "2"],
        "simulated rig frame formatting, column-wise",
        "wire.format_frame per frame",
        p_sim,
    ),
    Bench(
        "rpam",
        "bench_rpam_solver.py",
        ["--grid", "11", "--repeat", "3"],
        "rPAM joint map (Eq. 6), one vectorised call",
        "equilibrium_angle per pressure pair",
        p_rpam,
    ),
    Bench(
        "accuracy",
        "classify_accuracy.py",
        ["--seeds", "1-2", "--pushes", "5"],
        "stiffness of the six simulated objects (default policy, pressure-only)",
        "true stiffness of the objects",
        p_accuracy,
    ),
    Bench(
        "models",
        "bench_models.py",
        ["--sizes", "1e2,1e3,1e4,1e5", "--repeat", "3", "--repeat-large", "2"],
        "fit / validate / classify (6 objects) / classify (n/10 objects), time over trials",
        "numpy lstsq on the fit's design shapes, same n",
        p_models,
        json=True,
    ),
    Bench(
        "classify-report",
        "bench_classify_report.py",
        ["--sizes", "1e4", "--repeat", "1"],
        "`labcli classify --json` on an archive of n pushes (n/10 objects), fresh processes: CPU, wall, peak RSS",
        "pandas read_csv + Eqs. 34-37 vectorised + groupby(object), to JSON (baselines/classify_groupby.py)",
        p_classify_report,
        json=True,
        json_flag="--figures",
    ),
    Bench(
        "firmware",
        "bench_firmware.py",
        ["--seconds", "2"],
        "highest frame rate with 0 lost, the firmware on simavr, 115200 and 1000000 baud",
        "baud limit (UART bytes/s over line length) and AVR limit (1 / sampling time per frame)",
        p_firmware,
    ),
    Bench(
        "tables",
        "bench_tables.py",
        ["--sizes", "1e4,1e5", "--repeat", "1"],
        "trial CSV: `labcli fit`, `validate`, `import`, contiguous and interleaved splits (fresh processes: CPU, wall, "
        "peak RSS)",
        "pandas read_csv + numpy lstsq of Eqs. 34-37 (+ their validation), read_csv + bare h5py (baselines/)",
        p_tables,
        json=True,
        json_flag="--figures",
    ),
    Bench(
        "capture-memory",
        "bench_capture_memory.py",
        ["--windows", "60,600"],
        "one trial with long capture windows (1 kHz x 6 channels) streamed into the run file, peak RSS growth",
        "the same engine gathering each window in memory, then writing the trial",
        p_capture_memory,
    ),
    Bench(
        "demo",
        "bench_demo.py",
        ["--seeds", "1", "--import-repeat", "5"],
        "`labcli demo` and `labcli acquire --unattended` as subprocesses, wall time",
        '`python -c "import labcli.core.engine, labcli.core.store, labcli.papers.takuma2014.models.takuma"`',
        p_demo,
        json=True,
    ),
]
# The archive-scale figures (--scale): tables and import at 10^6 rows, classify at 10^6 pushes.
SCALE_ARGS = {
    "tables": ["--sizes", "1e5,1e6", "--repeat", "3"],
    "classify-report": ["--sizes", "1e5,1e6", "--repeat", "3"],
}
FULL_ARGS = {
    "models": ["--sizes", "1e2,1e3,1e4,1e5,1e6"],
    "demo": ["--seeds", "1-3"],
    "tables": ["--sizes", "1e4,1e5,1e6", "--repeat", "5"],
    "classify-report": ["--sizes", "1e5", "--repeat", "5"],
    "capture-memory": ["--windows", "60,600,3600"],
}


def _cpu_model() -> str:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return " ".join(line.split(":", 1)[1].split())
    except OSError:
        pass
    return platform.processor() or "unknown CPU"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--full", action="store_true", help="the scripts' own (longer) settings instead of quick ones")
    ap.add_argument(
        "--scale",
        action="store_true",
        help="archive sizes for the tables and classify-report benchmarks (10^6 rows; about 15 minutes)",
    )
    ap.add_argument("--only", default="", help="comma-separated names: " + ",".join(b.name for b in BENCHES))
    ap.add_argument("--out", default=None, help="also write the Markdown table to this file")
    ap.add_argument("--log-dir", default=None, help="where each script's output is kept")
    args = ap.parse_args()
    chosen = [b for b in BENCHES if not args.only or b.name in args.only.split(",")]
    unknown = set(filter(None, args.only.split(","))) - {b.name for b in BENCHES}
    if unknown:
        raise SystemExit(f"unknown benchmark {sorted(unknown)[0]!r}; choose from {', '.join(b.name for b in BENCHES)}")
    logs = Path(args.log_dir or tempfile.mkdtemp(prefix="labcli_bench_"))
    logs.mkdir(parents=True, exist_ok=True)

    rows = []
    t_all = time.perf_counter()
    for b in chosen:
        extra = SCALE_ARGS.get(b.name) if args.scale else None
        cmd = [sys.executable, str(HERE / b.script)] + (extra or (FULL_ARGS.get(b.name, []) if args.full else b.quick))
        json_path = logs / f"{b.name}.json"
        if b.json:
            cmd += [b.json_flag, str(json_path)]
        print(f"running {b.name}: {' '.join(cmd[1:])}", file=sys.stderr, flush=True)
        t0 = time.perf_counter()
        try:
            proc = subprocess.run(
                cmd, cwd=HERE.parents[1], capture_output=True, text=True, timeout=b.timeout_s * (3 if extra else 1)
            )
            out, code = proc.stdout, proc.returncode
            (logs / f"{b.name}.log").write_text(out + proc.stderr)
        except subprocess.TimeoutExpired:
            out, code = "", f"timeout after {b.timeout_s:.0f} s"
        took = time.perf_counter() - t0
        if code != 0:
            head, ctx = f"FAILED ({code})", f"see {logs / (b.name + '.log')}"
        else:
            try:
                head, ctx = b.parse(out, json_path)
            except (ValueError, KeyError, OSError, json.JSONDecodeError) as e:
                head, ctx = "output not understood", f"{e}; see {logs / (b.name + '.log')}"
        rows.append((b, head, ctx, took))

    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    import numpy

    lines = [
        f"Measured {time.strftime('%Y-%m-%d')} with `python tests/benchmarks/run_all.py{' --full' if args.full else ''}"
        f"{' --scale' if args.scale else ''}` on {platform.system()} {platform.machine()} ({_cpu_model()}), "
        f"{os.cpu_count()} CPUs shared with other work (load {load:.1f}), "
        f"Python {platform.python_version()}, numpy {numpy.__version__}; "
        f"{'full' if args.full else 'quick'} settings{', archive sizes for tables and classify-report' if args.scale else ''}, "
        f"{time.perf_counter() - t_all:.0f} s in all.",
        "",
        "| benchmark | measures | baseline (same run) | headline | context |",
        "|---|---|---|---|---|",
    ]
    for b, head, ctx, _ in rows:
        lines.append(f"| `{b.script}` | {b.what} | {b.baseline} | {head} | {ctx} |")
    table = "\n".join(lines)
    print(table)
    if args.out:
        Path(args.out).write_text(table + "\n")
    print(f"\nscript outputs in {logs}", file=sys.stderr)
    if any(h.startswith(("FAILED", "output not")) for _, h, _, _ in rows):
        sys.exit(1)


if __name__ == "__main__":
    main()
