"""Trial tables at archive scale: ``labcli fit``, ``validate`` and ``import`` of a CSV beside what a user writes.

Run:  python tests/benchmarks/bench_tables.py [--sizes 1e4,1e5,1e6] [--splits contiguous,interleaved]
                                              [--steps fit,validate,import] [--repeat 5] [--figures FILE.json]

Inputs, written once before any timing: a trial CSV of n rows cycled from 2000 trials of
:func:`labcli.papers.takuma2014.models.synthetic.paper_trials` (Eqs. 34-37 exact) with one ADC
count of fresh sensor noise, the rows numbered 0 .. n - 1, about 240 bytes a row.  Two shapes
of the split: ``contiguous`` (the first 4/5 of the rows fit, the rest validation) and
``interleaved`` (every sixth trial in the validation set, as a random split gives).

Each path is a fresh process beside its independent baseline, a script under
tests/benchmarks/baselines/ written as a user would, with no labcli import:

* ``fit``: ``labcli fit t.csv -o m.json`` (the default posture form, its route choice, the
  model file) against ``baselines/paper_lstsq.py fit``: ``pandas.read_csv`` and numpy ``lstsq``
  of the same four regressions (Eqs. 34-37) on the fit rows;
* ``validate``: ``labcli validate t.csv --model m.json`` (the model's accuracy on the validation
  trials beside the paper's form fitted on the fit trials) against ``paper_lstsq.py validate``:
  ``read_csv``, the four regressions on the fit rows, their predictions of the validation rows
  (angles from the pressures, forces at those angles) and the error measures;
* ``import``: ``labcli import t.csv -o t.h5`` (the checked table into a crash-safe run file)
  against ``baselines/import_h5py.py``: ``read_csv`` and one gzip-1 h5py dataset per column.

Every figure is the median of ``--repeat`` rounds, labcli and the baseline alternating (the
order flips every round); the ratio is labcli's median over the baseline's, CPU time first (the
figure a shared machine disturbs least), then wall time and peak resident memory; the spread of
the per-round CPU ratios is the noise.  Last, the growth exponent of labcli's CPU time from the
smallest to the largest n (log-log slope; 1 is linear), and from 10^5 up when measured.
"""

from __future__ import annotations

import argparse
import math
import shutil
import sys
import tempfile
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(HERE))

from fresh import HEADER, Pair, interleaved, machine, row, write_figures  # noqa: E402

POOL = 2000
STEPS = ("fit", "validate", "import")
SPLITS = ("contiguous", "interleaved")
COLUMNS = [
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


def validation_rows(n: int, split: str) -> object:
    """Which of n rows are validation trials: the last fifth, or every sixth."""
    import numpy as np

    rows = np.arange(n)
    return rows >= n * 4 // 5 if split == "contiguous" else rows % 6 == 5


def write_table(n: int, path: Path, split: str = "contiguous") -> None:
    import numpy as np

    from labcli.papers.takuma2014.models.synthetic import add_sensor_noise, paper_trials

    pool = paper_trials(POOL, seed=3, noise=False)
    out = pool.iloc[np.arange(n) % POOL].reset_index(drop=True)
    out["trial"] = np.arange(n)
    out = add_sensor_noise(out, seed=n, noise_counts=1.0)
    out["set"] = np.where(validation_rows(n, split), "validation", "fit")
    out[COLUMNS].to_csv(path, index=False)


def geometry() -> tuple[str, str]:
    """h2, h3 in m, as the baselines take them (a user copies them from the rig)."""
    from labcli.core.protocol import load_protocol

    rig = load_protocol("takuma2014").settings.rig
    return str(rig["h2_m"]), str(rig["h3_m"])


def commands(step: str, csv: Path, work: Path) -> tuple[list[str], list[str]]:
    """labcli's command and its baseline's, as ``python`` arguments."""
    h2, h3 = geometry()
    model = work / f"{csv.stem}.model.json"
    base = HERE / "baselines"
    if step == "fit":
        return (
            ["-m", "labcli", "fit", str(csv), "-o", str(model)],
            [str(base / "paper_lstsq.py"), "fit", str(csv), h2, h3],
        )
    if step == "validate":
        return (
            ["-m", "labcli", "validate", str(csv), "--model", str(model)],
            [str(base / "paper_lstsq.py"), "validate", str(csv), h2, h3],
        )
    out = work / f"{csv.stem}.h5"
    return (
        ["-m", "labcli", "import", str(csv), "-o", str(out), "--protocol", "takuma2014", "--force"],
        [str(base / "import_h5py.py"), str(csv), str(work / f"{csv.stem}.baseline.h5")],
    )


def slope(n0: int, t0: float, n1: int, t1: float) -> float:
    return math.log(t1 / t0) / math.log(n1 / n0)


def exponents(pairs: dict[tuple[str, str, int], Pair], sizes: list[int]) -> dict[str, float]:
    """Growth exponents of labcli's CPU time and peak memory, per step and split."""
    out: dict[str, float] = {}
    for step, split in sorted({(s, p) for s, p, _ in pairs}):
        ns = [n for n in sizes if (step, split, n) in pairs]
        if len(ns) < 2:
            continue
        spans = [(ns[0], ns[-1])] + ([(100_000, ns[-1])] if 100_000 in ns and ns[0] < 100_000 < ns[-1] else [])
        for a, b in spans:
            pa, pb = pairs[step, split, a], pairs[step, split, b]
            for key, what in (("cpu_s", "cpu"), ("peak_mib", "memory")):
                e = slope(a, pa.median("labcli", key), b, pb.median("labcli", key))
                out[f"{step} {split} {what} growth exponent {a:.0e} to {b:.0e}"] = round(e, 3)
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", default="1e4,1e5,1e6", help="rows of the trial CSV, comma-separated")
    ap.add_argument("--splits", default=",".join(SPLITS), help="contiguous, interleaved or both")
    ap.add_argument("--steps", default=",".join(STEPS), help="fit, validate, import (comma-separated)")
    ap.add_argument("--repeat", type=int, default=5, help="rounds per figure (the median is kept)")
    ap.add_argument("--figures", default=None, help="write the figures to this JSON file ({name: value})")
    ap.add_argument("--keep", type=Path, default=None, help="folder for the tables (default: a temporary one)")
    args = ap.parse_args()
    sizes = sorted(int(float(s)) for s in args.sizes.split(","))
    splits = [s for s in args.splits.split(",") if s]
    steps = [s for s in args.steps.split(",") if s]
    for name, chosen, known in (("split", splits, SPLITS), ("step", steps, STEPS)):
        bad = sorted(set(chosen) - set(known))
        if bad:
            raise SystemExit(f"unknown {name} {bad[0]!r}; choose from {', '.join(known)}")
    work = args.keep or Path(tempfile.mkdtemp(prefix="labcli_bench_tables_"))
    work.mkdir(parents=True, exist_ok=True)
    figures: dict = {**machine(), "rounds per figure": args.repeat}
    pairs: dict[tuple[str, str, int], Pair] = {}
    print(f"medians of {args.repeat} interleaved rounds, fresh processes; CPU = user + system of the process")
    print(HEADER)
    try:
        for n in sizes:
            for split in splits:
                csv = work / f"t{n}-{split}.csv"
                write_table(n, csv, split)
                figures[f"csv {n:.0e} {split} MiB"] = round(csv.stat().st_size / 2**20, 1)
                for step in steps:
                    if step == "validate" and "fit" not in steps:
                        from fresh import fresh

                        fresh(commands("fit", csv, work)[0])  # the model validate checks
                    mine, base = commands(step, csv, work)
                    pair = interleaved(f"{step} {n:.0e} {split}", args.repeat, mine, base)
                    pairs[step, split, n] = pair
                    print(row(pair), flush=True)
                    figures.update(pair.figures())
                if args.keep is None:
                    for f in work.glob(f"t{n}-{split}*"):
                        f.unlink()
    finally:
        if args.keep is None:
            shutil.rmtree(work, ignore_errors=True)
    growth = exponents(pairs, sizes)
    for name, value in growth.items():
        print(f"{name}: {value:.2f}")
    figures.update(growth)
    if args.figures:
        write_figures(args.figures, figures)


if __name__ == "__main__":
    main()
