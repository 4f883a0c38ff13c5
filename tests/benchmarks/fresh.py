"""Commands timed as fresh processes, labcli beside its baseline, interleaved; medians and the noise.

Every figure of ``bench_tables.py`` and ``bench_classify_report.py`` comes from here:

* one run is one fresh Python process (the interpreter, the imports and the work: what a
  person waits for), stdout to /dev/null;
* CPU time is the child's user + system time (``resource.getrusage(RUSAGE_CHILDREN)`` before
  and after: every thread it ran, none of the machine's other work), the figure the ratios
  are taken on, because wall time on a shared machine measures the neighbours too;
* peak memory is the child's own high-water mark (VmHWM, read by the child as it exits:
  ``ru_maxrss`` of a child starts from the parent's peak);
* labcli and its baseline alternate, round after round, the order flipping every round, so a
  busy moment lands on both; each figure is the median of the rounds, and the spread of the
  per-round CPU ratios is printed beside it as the noise;
* each side runs once untimed before the rounds, so both read cached bytecode and a warm page
  cache (``PYTHONDONTWRITEBYTECODE`` is dropped for the children: see ``UNSET``).
"""

from __future__ import annotations

import json
import os
import resource
import statistics
import subprocess
import sys
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

# Both sides run numpy's BLAS on one thread: idle-spinning BLAS threads on a loaded machine
# made least-squares timings jump tenfold between runs (tests/benchmarks/README.md).
ENV = {"OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1", "COLUMNS": "100"}
# Both sides read their modules' cached bytecode, as any installed package does: numpy and pandas
# come compiled, and labcli's own caches on its first run (the untimed warm-up).  A shell with
# PYTHONDONTWRITEBYTECODE set would make labcli compile its 20,000 lines in every process, 0.4 s
# of CPU no user pays twice.
UNSET = ("PYTHONDONTWRITEBYTECODE",)

# The child reports its own VmHWM at exit, then runs the script (or ``-m module``) it was given.
_WRAPPER = """
import atexit, runpy, sys
def _peak():
    for line in open("/proc/self/status"):
        if line.startswith("VmHWM:"):
            sys.stderr.write("\\nFRESH_PEAK_KB " + line.split()[1] + "\\n")
atexit.register(_peak)
if sys.argv[1] == "-m":
    sys.argv = sys.argv[2:]
    runpy.run_module(sys.argv[0], run_name="__main__", alter_sys=True)
else:
    sys.argv = sys.argv[1:]
    runpy.run_path(sys.argv[0], run_name="__main__")
"""


@dataclass(frozen=True)
class Run:
    """One fresh process: wall seconds, CPU seconds (user + system, all threads), peak resident MiB."""

    wall_s: float
    cpu_s: float
    peak_mib: float


def fresh(argv: Sequence[str], cwd: str | os.PathLike | None = None) -> Run:
    """Run ``python <argv>`` (a script and its arguments, or ``-m module ...``) in a fresh process and measure it."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    with open(os.devnull, "w") as null:
        proc = subprocess.run(
            [sys.executable, "-c", _WRAPPER, *map(str, argv)],
            stdout=null,
            stderr=subprocess.PIPE,
            text=True,
            env={**{k: v for k, v in os.environ.items() if k not in UNSET}, **ENV},
            cwd=cwd,
        )
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    peaks = [line for line in proc.stderr.splitlines() if line.startswith("FRESH_PEAK_KB ")]
    if proc.returncode != 0 or not peaks:
        raise SystemExit(f"python {' '.join(map(str, argv))} failed ({proc.returncode}):\n{proc.stderr[-3000:]}")
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return Run(wall, cpu, int(peaks[-1].split()[1]) / 1024)


KEYS = ("wall_s", "cpu_s", "peak_mib")


@dataclass
class Pair:
    """The rounds of one comparison: labcli's runs and the baseline's, round by round."""

    name: str
    mine: list[Run] = field(default_factory=list)
    base: list[Run] = field(default_factory=list)

    def median(self, side: str, key: str) -> float:
        return statistics.median(getattr(r, key) for r in (self.mine if side == "labcli" else self.base))

    def ratio(self, key: str) -> float:
        """labcli's median over the baseline's median."""
        return self.median("labcli", key) / self.median("baseline", key)

    def spread(self, key: str) -> tuple[float, float]:
        """The smallest and largest ratio of one round's two runs: how much the machine moved the figure."""
        per_round = [getattr(a, key) / getattr(b, key) for a, b in zip(self.mine, self.base, strict=True)]
        return min(per_round), max(per_round)

    def figures(self) -> dict[str, float]:
        """Flat {name: value} with the units in the names (for the docs' figure files)."""
        out: dict[str, float] = {}
        for key, (what, unit) in zip(KEYS, (("wall", "s"), ("cpu", "s"), ("peak memory", "MiB")), strict=True):
            out[f"{self.name} labcli {what} {unit}"] = round(self.median("labcli", key), 3)
            out[f"{self.name} baseline {what} {unit}"] = round(self.median("baseline", key), 3)
            out[f"{self.name} {what} ratio"] = round(self.ratio(key), 3)
        lo, hi = self.spread("cpu_s")
        out[f"{self.name} cpu ratio lowest round"] = round(lo, 3)
        out[f"{self.name} cpu ratio highest round"] = round(hi, 3)
        return out


def interleaved(
    name: str, repeat: int, mine: Sequence[str], base: Sequence[str], cwd: str | os.PathLike | None = None
) -> Pair:
    """``repeat`` rounds of labcli (``mine``) and its baseline (``base``), the order flipping every round.

    Each side runs once untimed first: bytecode written, files in the page cache, for both alike.
    """
    pair = Pair(name)
    fresh(mine, cwd)
    fresh(base, cwd)
    for k in range(repeat):
        if k % 2 == 0:
            pair.mine.append(fresh(mine, cwd))
            pair.base.append(fresh(base, cwd))
        else:
            pair.base.append(fresh(base, cwd))
            pair.mine.append(fresh(mine, cwd))
    return pair


HEADER = (
    f"{'path':34} {'labcli CPU s':>12} {'base CPU s':>10} {'CPU x':>6} {'(rounds)':>13} "
    f"{'labcli wall s':>13} {'base wall s':>11} {'wall x':>6} {'labcli MiB':>10} {'base MiB':>8} {'mem x':>6}"
)


def row(pair: Pair) -> str:
    """One printed line: each of labcli's medians beside the baseline's of the same run, and the ratios."""
    lo, hi = pair.spread("cpu_s")
    return (
        f"{pair.name:34} {pair.median('labcli', 'cpu_s'):>12.2f} {pair.median('baseline', 'cpu_s'):>10.2f} "
        f"{pair.ratio('cpu_s'):>6.2f} {f'{lo:.2f}-{hi:.2f}':>13} "
        f"{pair.median('labcli', 'wall_s'):>13.2f} {pair.median('baseline', 'wall_s'):>11.2f} "
        f"{pair.ratio('wall_s'):>6.2f} {pair.median('labcli', 'peak_mib'):>10.0f} "
        f"{pair.median('baseline', 'peak_mib'):>8.0f} {pair.ratio('peak_mib'):>6.2f}"
    )


def command_line(script: str, argv: Sequence[str]) -> str:
    """The command that reruns ``script`` with ``argv``, less its ``--figures FILE`` (for a figure file)."""
    out: list[str] = []
    skip = False
    for x in argv:
        if not skip and x != "--figures" and not x.startswith("--figures="):
            out.append(x)
        skip = x == "--figures"
    return " ".join(["python", f"tests/benchmarks/{script}", *out])


def write_figures(path: str | os.PathLike, figures: Mapping[str, float | int | str]) -> None:
    """The figures as one flat JSON object, {name: value}, units in the names."""
    Path(path).parent.mkdir(parents=True, exist_ok=True)
    Path(path).write_text(json.dumps(dict(figures), indent=1, sort_keys=False) + "\n")


def machine() -> dict[str, float | int | str]:
    """What the figures were measured on (a line of context for the figure file)."""
    import platform

    import numpy

    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    return {
        "measured on": f"{platform.system()} {platform.machine()}, {os.cpu_count()} CPUs",
        "load average at start": round(load, 2),
        "python": platform.python_version(),
        "numpy": numpy.__version__,
        "date": time.strftime("%Y-%m-%d"),
    }
