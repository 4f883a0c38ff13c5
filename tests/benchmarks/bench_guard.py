"""The load check's false alarms on correct runs: the shipped plan acquired unattended, nothing wrong done.

Run:  python tests/benchmarks/bench_guard.py [--seeds 1-10] [--realism kind,literature] [--rigs NAME=OPTIONS;...]
                                            [--relief [L|R]] [--jobs 2] [--figures FILE]

For each rig and seed, the paper's 108-trial plan is acquired unattended on the simulated rig
(``sim://?seed=N&clock=virtual&OPTIONS``, its 1.1 board driving the valves) through the real
serial code path, every weight hung and taken off as the prompts say.  Every warning the review
prints (the load check's, the seal's) is a false alarm, and so is a baseline the removal check
stops ("The readings have not returned ..." or "The arm is not where it rests unloaded ...": the
unattended run ends there).  Figures per rig: runs, runs with any false alarm, false alarms in
all, runs stopped, trials stored.

Default rigs: the kind rig (the default when these figures were measured); the literature's (the
default now); the kind rig at two, three and four times its sleeve friction (four times is the
literature's level); the literature's at twice its own.  ``--realism`` (rig_options.py) keeps the
rigs of the realisms it names (default both); a rig of ``--rigs`` that names no realism runs on the
first of them.  ``--relief``: the shipped protocol with the friction relief before every trial,
venting the side named (L without one; rig_options.py).
"""

from __future__ import annotations

import io
import json
import shutil
import sys
import tempfile
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))

from rig_options import add_relief_option, add_rig_options, bench_parser, relieved, seeds_text  # noqa: E402

RIGS = (
    "kind=realism=kind",
    "literature=realism=literature",
    "kind friction x2=realism=kind&friction=2",
    "kind friction x3=realism=kind&friction=3",
    "kind friction x4=realism=kind&friction=4",
    "literature friction x2=realism=literature&friction=2",
)


def one(url: str, relief: str | None = None) -> tuple[int, bool, int, list[str]]:
    """(trials stored, stopped, false alarms, their sentences) of one unattended run; ``relief``:
    the side the friction relief before every trial vents (none without)."""
    from rich.console import Console

    from labcli.core.acquisition import acquire
    from labcli.core.protocol import load_protocol
    from labcli.core.ui import UnattendedUI
    from labcli.errors import LabcliError

    with tempfile.TemporaryDirectory() as tmp:
        out = io.StringIO()
        ui = UnattendedUI(console=Console(file=out, width=400))
        stopped, stored, why = False, 0, []
        protocol = "takuma2014"
        if relief:  # beside a copy of the plan it names
            shipped = load_protocol("takuma2014")
            for f in shipped.path.parent.glob("takuma2014-plan*.csv"):
                shutil.copy(f, tmp)
            protocol = str(Path(tmp) / "relieved.toml")
            Path(protocol).write_text(relieved(shipped.text, relief), encoding="utf-8")
        try:
            stored = acquire(Path(tmp) / "run.h5", url, protocol=protocol, unattended=True, ui=ui).stored
        except LabcliError as e:
            stopped, why = True, [str(e).split(";")[0]]
        warned = [
            line[len("Warning: ") :]
            for line in out.getvalue().splitlines()
            if line.startswith("Warning: ") and "not settled" not in line
        ]
        return stored, stopped, len(warned) + stopped, warned + why


def main() -> None:
    ap = bench_parser(__doc__)
    add_rig_options(ap, realism="kind,literature", seeds="1-10", several=True)  # 1-10: the tuning seeds
    ap.add_argument("--rigs", default=";".join(RIGS), help="NAME=SIM_OPTIONS;... (default: the six of the docstring)")
    add_relief_option(ap)
    ap.add_argument("--jobs", type=int, default=2, help="runs at once")
    ap.add_argument("--figures", help="also write the figures to this JSON file ({name: value})")
    args = ap.parse_args()
    seeds = args.seeds
    rigs = []
    for name, _, opts in (r.partition("=") for r in args.rigs.split(";")):
        if "realism=" not in opts:
            opts = "&".join(filter(None, (f"realism={args.realism[0]}", opts)))
        if any(f"realism={r}" in opts.split("&") for r in args.realism):
            rigs.append((name, opts))
    urls = [
        (name, f"sim://?seed={s}&clock=virtual" + (f"&{opts}" if opts else "")) for name, opts in rigs for s in seeds
    ]
    figures: dict = {"seeds": seeds_text(seeds), "trials per run": 108, "relief": args.relief or "none"}
    with ProcessPoolExecutor(args.jobs) as ex:
        results = list(ex.map(one, [u for _, u in urls], [args.relief] * len(urls)))
    for name, _ in rigs:
        mine = [(u, r) for (n, u), r in zip(urls, results, strict=True) if n == name]
        alarms = sum(r[2] for _, r in mine)
        figures[f"{name}.runs"] = len(mine)
        figures[f"{name}.runs with a false alarm"] = sum(r[2] > 0 for _, r in mine)
        figures[f"{name}.false alarms"] = alarms
        figures[f"{name}.runs stopped"] = sum(r[1] for _, r in mine)
        figures[f"{name}.trials stored"] = sum(r[0] for _, r in mine)
        print(f"{name}: {alarms} false alarms in {len(mine)} runs ({figures[f'{name}.runs stopped']} stopped)")
        for url, r in mine:
            for sentence in r[3]:
                print(f"  {url}: {sentence[:160]}")
    print(json.dumps(figures, indent=1))
    if args.figures:
        Path(args.figures).write_text(json.dumps(figures, indent=1) + "\n", encoding="utf-8")


if __name__ == "__main__":
    main()
