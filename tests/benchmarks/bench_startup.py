"""Start-up time of ``labcli --help`` against ``python -c pass``, in the same run.

    python tests/benchmarks/bench_startup.py [--repeat 20]

Prints the median wall time of each and their ratio.  The promise is that
``labcli --help`` stays well under half a second.
"""

from __future__ import annotations

import argparse
import statistics
import subprocess
import sys
import time


def median_wall(cmd: list[str], repeat: int) -> float:
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        subprocess.run(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, check=True)
        times.append(time.perf_counter() - t0)
    return statistics.median(times)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=20)
    args = parser.parse_args()
    base = median_wall([sys.executable, "-c", "pass"], args.repeat)
    help_ = median_wall([sys.executable, "-m", "labcli", "--help"], args.repeat)
    print(f"python -c pass : {base * 1000:7.1f} ms (median of {args.repeat})")
    print(f"labcli --help  : {help_ * 1000:7.1f} ms (median of {args.repeat})")
    print(f"ratio          : {help_ / base:7.2f} x; labcli's own share {1000 * (help_ - base):.1f} ms")


if __name__ == "__main__":
    main()
