"""Fit, validate and classify from 10^2 to 10^6 trials, against a bare numpy lstsq of the same size.

Run:  python tests/benchmarks/bench_models.py [--sizes 1e2,1e3,1e4,1e5,1e6] [--repeat 5] [--repeat-large 2]
                                         [--no-memory] [--realism kind] [--seeds 1]

Inputs, built once before any timing:

* trial tables: a pool of 2000 trials from :func:`labcli.papers.takuma2014.models.synthetic.paper_trials`
  (Eqs. 34-37 solved exactly with the paper's coefficients), tiled to n rows and read
  through the 12-bit sensors again (:func:`add_sensor_noise`, 1 count), so every row
  differs and the equations hold to sensor noise; all rows ``set = fit`` for the fit, a
  copy with ``set = validation`` for the validation;
* push tables: the six demo objects pushed ten times each on the simulated rig
  (:func:`labcli.papers.takuma2014.sim.drive.simulate_pushes`), tiled to n pushes with 1 count of fresh
  pressure noise, classified with a model fitted on the rig's 90 weight trials.  Two
  shapes: the six objects pushed n / 6 times each (``classify``), and an archive of n / 10
  objects pushed ten times each, every copy of the pool named apart (``archive``).  The rig is the kind one
  (``--realism``, rig_options.py), the one docs/performance.md's figures were measured on.

Timed at each n (best of ``--repeat``, ``--repeat-large`` from 10^5 on):

* ``fit``: ``TakumaModel.fit`` (Eqs. 34-37, four least-squares fits with statistics);
* ``validate``: ``metrics.evaluate`` pressure-only (predict and the accuracy measures; the
  figure is not drawn);
* ``classify``: ``classify_pushes`` with the protocol's bands (predict, Eqs. 38-42 per push,
  per-object statistics, categories; no figure), six objects;
* ``archive``: the same on n / 10 objects (cost per object as well as per push);
* baseline: ``numpy.linalg.lstsq`` on random design matrices of the fit's shapes
  (n x 2, n x 4, n x 6, n x 6), the bare arithmetic any fit of Eqs. 34-37 needs.

Printed per n: seconds, microseconds per trial and the ratio to the baseline; then the
growth exponent of each (log-log slope of time against n over n >= 10^4, where fixed
costs no longer dominate, and over the whole range), and the peak traced memory
(tracemalloc) of each step at the largest n as a multiple of the table's own size.
"""

from __future__ import annotations

import gc
import json
import os
import resource
import sys
import time
import tracemalloc
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))
# One BLAS thread for the fit and the baseline alike: on a busy machine idle-spinning BLAS
# threads make the baseline jump by tens; set OPENBLAS_NUM_THREADS to measure otherwise.
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")

import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402

from labcli.core.protocol import load_protocol  # noqa: E402
from labcli.papers.takuma2014.models.classify import classify_pushes  # noqa: E402
from labcli.papers.takuma2014.models.metrics import evaluate  # noqa: E402
from labcli.papers.takuma2014.models.synthetic import PAPER_GEOMETRY, add_sensor_noise, paper_trials  # noqa: E402
from labcli.papers.takuma2014.models.takuma import TakumaModel  # noqa: E402
from labcli.papers.takuma2014.protocol import load_plan  # noqa: E402
from labcli.papers.takuma2014.sim.drive import simulate_pushes, simulate_weight_trials  # noqa: E402
from labcli.papers.takuma2014.sim.nonideal import NonIdeal  # noqa: E402
from labcli.papers.takuma2014.sim.objects import DEMO_OBJECTS  # noqa: E402
from labcli.papers.takuma2014.sim.rig import SimRig  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
from rig_options import add_rig_options, bench_parser  # noqa: E402

POOL = 2000
PRESSURES = ("P_L10", "P_R10", "P_L20", "P_R20", "P_L1", "P_R1", "P_L2", "P_R2")


def tile(pool: pd.DataFrame, n: int, id_col: str, seed: int) -> pd.DataFrame:
    """n rows cycled from the pool, renumbered, with one ADC count of fresh sensor noise."""
    idx = np.arange(n) % len(pool)
    out = pool.iloc[idx].reset_index(drop=True)
    out[id_col] = np.arange(1, n + 1)
    return add_sensor_noise(out, seed=seed, noise_counts=1.0)


def best(fn, repeat: int) -> float:
    t = float("inf")
    for _ in range(repeat):
        gc.collect()
        t0 = time.perf_counter()
        fn()
        t = min(t, time.perf_counter() - t0)
    return t


def peak_traced(fn) -> int:
    """Peak bytes allocated (Python and numpy) while fn runs, above what was live before."""
    gc.collect()
    tracemalloc.start()
    tracemalloc.reset_peak()
    base = tracemalloc.get_traced_memory()[0]
    fn()
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    return peak - base


def slope(ns: list[int], ts: list[float]) -> float:
    if len(ns) < 2:
        return float("nan")
    return float(np.polyfit(np.log10(ns), np.log10(ts), 1)[0])


# Over 80 lines: one benchmark from its options to its printed table, each step a column of it.
def main() -> None:
    ap = bench_parser(__doc__)
    ap.add_argument("--sizes", default="1e2,1e3,1e4,1e5,1e6", help="numbers of trials, comma-separated")
    add_rig_options(ap, realism="kind", seeds="1", one=True)  # the push pool's rig
    ap.add_argument("--repeat", type=int, default=5, help="repeats below 10^5 trials (best is kept)")
    ap.add_argument("--repeat-large", type=int, default=2, help="repeats from 10^5 trials on")
    ap.add_argument("--no-memory", action="store_true", help="skip the tracemalloc pass at the largest n")
    ap.add_argument("--json", default=None, help="also write the figures to this JSON file (for run_all.py)")
    args = ap.parse_args()
    sizes = sorted(int(float(s)) for s in args.sizes.split(","))

    t_setup = time.perf_counter()
    trial_pool = paper_trials(POOL, seed=3, noise=False)
    geometry = dict(PAPER_GEOMETRY)
    force, push = load_protocol("takuma2014"), load_protocol("takuma2014-stiffness")
    bands = push.settings.push.stiffness_bands_N_per_m
    rig = SimRig(seed=args.seeds[0], nonideal=NonIdeal(realism=args.realism))
    push_model = TakumaModel(geometry=force.settings.rig, protocol=force.name).fit(
        simulate_weight_trials(rig, load_plan(force), calibration=force.calibration)
    )
    push_pool = simulate_pushes(rig, DEMO_OBJECTS, calibration=push.calibration, pushes_per_object=10)
    print(
        f"inputs: {POOL}-trial pool (Eqs. 34-37 exact), {len(push_pool)}-push pool from the simulated rig, "
        f"built in {time.perf_counter() - t_setup:.1f} s"
    )

    rng = np.random.default_rng(0)
    rows = []
    for n in sizes:
        fit_table = tile(trial_pool, n, "trial", seed=n)
        fit_table["set"] = "fit"
        val_table = fit_table.copy()
        val_table["set"] = "validation"
        pushes = tile(push_pool, n, "push", seed=n + 1)
        archive = pushes.copy()
        archive["object"] = archive["object"] + "#" + (np.arange(n) // len(push_pool)).astype(str)
        model = TakumaModel(geometry=geometry, protocol="takuma2014").fit(fit_table)
        designs = [(rng.standard_normal((n, p)), rng.standard_normal(n)) for p in (2, 4, 6, 6)]
        repeat = args.repeat if n < 100_000 else args.repeat_large

        def bare() -> None:
            for X, y in designs:
                np.linalg.lstsq(X, y, rcond=None)

        t_base = best(bare, repeat)
        t_fit = best(lambda: TakumaModel(geometry=geometry, protocol="takuma2014").fit(fit_table), repeat)
        t_val = best(lambda: evaluate(model, val_table, mode="pressure-only"), repeat)
        t_cls = best(lambda: classify_pushes(pushes, push_model, bands=bands, method="bands"), repeat)
        t_arc = best(lambda: classify_pushes(archive, push_model, bands=bands, method="bands"), repeat)
        rows.append(
            {
                "n": n,
                "repeat": repeat,
                "lstsq": t_base,
                "fit": t_fit,
                "validate": t_val,
                "classify": t_cls,
                "archive": t_arc,
            }
        )
        print(
            f"n = {n:>8,}: lstsq {t_base * 1e3:9.2f} ms, fit {t_fit * 1e3:9.2f} ms, "
            f"validate {t_val * 1e3:9.2f} ms, classify {t_cls * 1e3:9.2f} ms, archive {t_arc * 1e3:9.2f} ms "
            f"(best of {repeat})",
            flush=True,
        )
        if n != sizes[-1]:
            del fit_table, val_table, pushes, archive, designs

    steps = ("lstsq", "fit", "validate", "classify", "archive")
    print()
    print(
        f"{'n':>9} | "
        + " | ".join(f"{s + ' s':>11} {'us/trial':>8}" for s in steps)
        + " | "
        + " | ".join(f"{s + '/lstsq':>14}" for s in steps[1:])
    )
    for r in rows:
        print(
            f"{r['n']:>9,} | "
            + " | ".join(f"{r[s]:>11.4g} {1e6 * r[s] / r['n']:>8.3g}" for s in steps)
            + " | "
            + " | ".join(f"{r[s] / r['lstsq']:>14.3g}" for s in steps[1:])
        )
    ns = [r["n"] for r in rows]
    big = [i for i, n in enumerate(ns) if n >= 10_000]
    print()
    print("growth exponent (log-log slope of time against n; 1 = linear):")
    summary: dict = {"rows": rows, "slope_ge_1e4": {}, "slope_all": {}, "peak_MB": {}, "peak_over_input": {}}
    for s in steps:
        ts = [r[s] for r in rows]
        summary["slope_ge_1e4"][s] = slope([ns[i] for i in big], [ts[i] for i in big])
        summary["slope_all"][s] = slope(ns, ts)
        print(f"  {s:<9} n >= 1e4: {summary['slope_ge_1e4'][s]:5.2f}   all n: {summary['slope_all'][s]:5.2f}")

    if not args.no_memory:
        n = sizes[-1]
        table_bytes = int(fit_table.memory_usage(deep=True).sum())
        push_bytes = int(pushes.memory_usage(deep=True).sum())
        print()
        print(
            f"peak traced memory at n = {n:,} (tracemalloc; trial table {table_bytes / 1e6:.0f} MB, "
            f"push table {push_bytes / 1e6:.0f} MB):"
        )
        for name, fn, ref in (
            ("fit", lambda: TakumaModel(geometry=geometry, protocol="takuma2014").fit(fit_table), table_bytes),
            ("validate", lambda: evaluate(model, val_table, mode="pressure-only"), table_bytes),
            ("classify", lambda: classify_pushes(pushes, push_model, bands=bands, method="bands"), push_bytes),
        ):
            peak = peak_traced(fn)
            summary["peak_MB"][name], summary["peak_over_input"][name] = peak / 1e6, peak / ref
            print(f"  {name:<9} {peak / 1e6:8.0f} MB  = {peak / ref:5.2f} x its input")
    maxrss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    scale = 1 if sys.platform == "darwin" else 1024  # bytes on macOS, KiB on Linux
    summary["maxrss_MB"] = maxrss * scale / 1e6
    print(f"process peak resident set (ru_maxrss): {summary['maxrss_MB']:.0f} MB")
    if args.json:
        Path(args.json).write_text(json.dumps(summary, indent=1))


if __name__ == "__main__":
    main()
