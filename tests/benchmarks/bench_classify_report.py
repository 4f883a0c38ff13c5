"""``labcli classify --json`` on an archive of n pushes beside a pandas groupby that does the same by hand.

Run:  python tests/benchmarks/bench_classify_report.py [--sizes 1e5] [--repeat 5] [--figures FILE.json] [--keep DIR]
                                                       [--realism kind] [--seeds 1]

Input: the six demo objects pushed ten times each on the simulated rig, tiled to n pushes on
n / 10 objects (an archive: every copy of the pool named apart), written as a push CSV, and a
force model of the paper's form fitted on the shipped plan's weight trials through the same rig:
the kind rig, seed 1 (``--realism``, ``--seeds``: rig_options.py), on which docs/performance.md's
figures were measured.

Each side is a fresh process (tests/benchmarks/fresh.py: CPU time, wall time, peak resident
memory; medians of ``--repeat`` interleaved rounds, the order flipping every round):

* ``classify --json``: ``labcli classify pushes.csv --model force.model.json --method bands
  --json`` (the checked push table, the force model on every push, the stiffness with its flags
  and gains, each object's statistics and band, every push and object streamed as JSON), stdout
  to /dev/null;
* baseline: ``baselines/classify_groupby.py``, what a user writes with pandas and numpy and no
  labcli import: ``read_csv``, Eqs. 34-37 evaluated vectorised from the model file's
  coefficients, Section 4's k = |F| / delta_x per push, ``groupby("object")`` for each object's
  pushes, mean, sd and median of k and ln k and the band of the median, every push and object
  written as JSON (pandas' ``to_json``).

The ratio is classify's median over the baseline's: CPU first, then wall time and peak memory.
The human report (``classify`` without ``--json``) is measured beside the same baseline with
``--report``.
"""

from __future__ import annotations

import json
import shutil
import sys
import tempfile
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parents[1]))
sys.path.insert(0, str(HERE))

from fresh import HEADER, interleaved, machine, row, write_figures  # noqa: E402
from rig_options import add_rig_options, bench_parser  # noqa: E402


def inputs(folder: Path, n: int, realism: str = "kind", seed: int = 1) -> tuple[Path, Path]:
    """The push CSV of n pushes and the force model file (made once per folder and rig)."""
    from labcli.core.protocol import load_protocol
    from labcli.papers.takuma2014.models.takuma import TakumaModel
    from labcli.papers.takuma2014.protocol import load_plan
    from labcli.papers.takuma2014.sim.drive import simulate_pushes, simulate_weight_trials
    from labcli.papers.takuma2014.sim.nonideal import NonIdeal
    from labcli.papers.takuma2014.sim.objects import DEMO_OBJECTS
    from labcli.papers.takuma2014.sim.rig import SimRig
    from labcli.papers.takuma2014.tables import write_push_csv

    force, push = load_protocol("takuma2014"), load_protocol("takuma2014-stiffness")
    rig = SimRig(seed=seed, nonideal=NonIdeal(realism=realism))
    model_path = folder / f"force-{realism}-{seed}.model.json"
    if not model_path.exists():
        trials = simulate_weight_trials(rig, load_plan(force), calibration=force.calibration)
        TakumaModel(geometry=force.settings.rig, protocol=force.name).fit(trials).save(model_path)
    pool = simulate_pushes(rig, DEMO_OBJECTS, calibration=push.calibration, pushes_per_object=10)
    idx = np.arange(n) % len(pool)
    table = pool.iloc[idx].reset_index(drop=True)
    table["push"] = np.arange(1, n + 1)
    table["object"] = table["object"] + "#" + (np.arange(n) // len(pool)).astype(str)
    csv = folder / f"pushes-{n}-{realism}-{seed}.csv"
    write_push_csv(table, csv)
    return csv, model_path


def baseline_args(csv: Path, model: Path) -> list[str]:
    """The baseline script's arguments: the rig's h2, h3 and the protocol's bands, as a user copies them."""
    from labcli.core.protocol import load_protocol

    rig = load_protocol("takuma2014").settings.rig
    bands = load_protocol("takuma2014-stiffness").settings.push.stiffness_bands_N_per_m
    plain = {name: [lo, None if hi == float("inf") else hi] for name, (lo, hi) in dict(bands).items()}
    return [str(HERE / "baselines" / "classify_groupby.py"), str(csv), str(model)] + [
        str(rig["h2_m"]),
        str(rig["h3_m"]),
        json.dumps(plain),
    ]


def main() -> None:
    ap = bench_parser(__doc__)
    ap.add_argument("--sizes", default="1e5", help="comma-separated push counts (archive scale: 1e6)")
    add_rig_options(ap, realism="kind", seeds="1", one=True)
    ap.add_argument("--repeat", type=int, default=5, help="rounds per figure (the median is kept)")
    ap.add_argument("--report", action="store_true", help="also the human report (classify without --json)")
    ap.add_argument("--figures", default=None, help="write the figures to this JSON file ({name: value})")
    ap.add_argument("--keep", type=Path, default=None, help="folder for the CSVs (default: a temporary one)")
    args = ap.parse_args()
    folder = args.keep or Path(tempfile.mkdtemp(prefix="bench-classify-"))
    folder.mkdir(parents=True, exist_ok=True)
    figures: dict = {**machine(), "rounds per figure": args.repeat}
    print(f"medians of {args.repeat} interleaved rounds, fresh processes; CPU = user + system of the process")
    print(HEADER)
    try:
        for n in (int(float(s)) for s in args.sizes.split(",")):
            csv, model = inputs(folder, n, args.realism, args.seeds[0])
            figures[f"push csv {n:.0e} MiB"] = round(csv.stat().st_size / 2**20, 1)
            command = ["-m", "labcli", "classify", str(csv), "--model", str(model), "--method", "bands"]
            ways = [("classify --json", [*command, "--json"])] + ([("classify report", command)] if args.report else [])
            for name, mine in ways:
                pair = interleaved(f"{name} {n:.0e}", args.repeat, mine, baseline_args(csv, model))
                print(row(pair), flush=True)
                figures.update(pair.figures())
            if args.keep is None:
                csv.unlink()
    finally:
        if args.keep is None:
            shutil.rmtree(folder, ignore_errors=True)
    if args.figures:
        write_figures(args.figures, figures)


if __name__ == "__main__":
    main()
