"""Joint-map solve (Eq. 6 over a Pa x Pb grid): one vectorised call against a scalar loop.

    python tests/benchmarks/bench_rpam_solver.py [--grid 21] [--repeat 5]

Both solve the same grid of the shipped rpam2015 protocol at the paper's optimum links; the
baseline calls ``equilibrium_angle`` (grid bracket + scipy brentq) once per pressure pair.
Prints the median wall time of each, their ratio, and the largest angle difference.
"""

from __future__ import annotations

import argparse
import statistics
import time

import numpy as np

from labcli.papers.rpam2015.models import rpam
from labcli.papers.rpam2015.protocol import load_rpam


def median_time(fn, repeat: int) -> float:
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--grid", type=int, default=21)
    parser.add_argument("--repeat", type=int, default=5)
    args = parser.parse_args()
    settings = load_rpam("rpam2015").settings
    act, geom = settings.actuator, settings.geometry
    P = np.linspace(0.041, 0.138, args.grid)

    def vectorised():
        return rpam.joint_map(P, P, geom, act).alpha_rad

    def scalar():
        out = np.full((len(P), len(P)), np.nan)
        for i, pa in enumerate(P):
            for j, pb in enumerate(P):
                try:
                    out[i, j] = rpam.equilibrium_angle(pa, pb, geom, act)
                except rpam.ModelError:
                    pass
        return out

    diff = np.nanmax(np.abs(vectorised() - scalar()))
    t_vec = median_time(vectorised, args.repeat)
    t_sca = median_time(scalar, args.repeat)
    print(
        f"grid {args.grid} x {args.grid}: scalar loop {t_sca * 1e3:.1f} ms, vectorised {t_vec * 1e3:.1f} ms, "
        f"speed-up {t_sca / t_vec:.1f}x, max angle difference {np.degrees(diff):.2e} deg"
    )


if __name__ == "__main__":
    main()
