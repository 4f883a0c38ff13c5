"""Accuracy, not time: every headline sensing figure across the rig's harshness, with its spread over seeds.

The levels depart one at a time from the literature's rig (the default; sim/nonideal.py,
docs/rig-realism.md): sleeve friction x0.5-4, the sensors' white noise x1-30 (``noise``, per
sample; the pressure sensors' repeatability stays at its level), the chambers' leak x0-3, the
repeatability x0 and x2 (x2: the datasheet's bound as three standard deviations), and the kind rig
the earlier figures were measured on.  Per level and rig seed (:mod:`study`): theta1, theta2, Fx,
Fy RMSE on the straight and the bent protocol for both forms (over the reported trials, and over
all), trials reported, the posture form's 95 % coverage per quantity, and the six demo objects'
k / k_true and category (straight arm, phi given, bands; the paper's form as the README demo uses
it, and the posture form), the steel can among them.  The posture form is fitted as ``labcli fit``
fits it by default, with the sleeves' friction terms.

    python tests/benchmarks/sensitivity.py --quick               # 2 seeds, the sweep's ends: minutes
    nice python tests/benchmarks/sensitivity.py                  # the full sweep: seeds 11-15, all levels
    nice python tests/benchmarks/sensitivity.py --cache /tmp/s.jsonl --jobs 1 &    # in the background,
                                                                 # resumable: done (level, seed) pairs are kept

Held-out seeds (11 and up) by default: nothing here is tuned. ``--seeds`` and ``--realism`` as every
benchmark takes them (rig_options.py); ``--realism`` is the rig of the scaled levels, the
literature's by default. It prints a headline table (the posture form, mean over seeds +- sd) and
every figure per level, and writes them all as one flat JSON object ``{"LEVEL/FIGURE/STAT": value}``
(default docs/figures/sensitivity.json) for the docs.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import study  # noqa: E402
from figures_file import cache_append, cache_records, git_head, write_figures  # noqa: E402
from rig_options import add_rig_options, bench_parser, seeds_text  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
LEVELS: dict[str, dict[str, Any]] = {
    "literature": {"realism": "literature"},
    "kind": {"realism": "kind"},
    "friction x0.5": {"friction": 0.5},
    "friction x2": {"friction": 2.0},
    "friction x4": {"friction": 4.0},
    "noise x3": {"noise": 3.0},
    "noise x10": {"noise": 10.0},
    "noise x30": {"noise": 30.0},
    "leak x0": {"leak": 0.0},
    "leak x3": {"leak": 3.0},
    "repeat x0": {"repeat": 0.0},
    "repeat x2": {"repeat": 2.0},
}
# The posture form as ``labcli fit`` fits it by default: with the sleeves' friction terms.
FRICTION_TERMS = True
QUICK_LEVELS = ("literature", "friction x0.5", "friction x4", "noise x30", "leak x3")
HEADLINE = (  # (column, figure, scale, format) of the headline table
    ("th1 str", "straight/posture/theta1/rmse", 1, "{:.3f}"),
    ("th2 str", "straight/posture/theta2/rmse", 1, "{:.3f}"),
    ("Fx str", "straight/posture/Fx/rmse", 1, "{:.2f}"),
    ("th1 bent", "bent/posture/theta1/rmse", 1, "{:.3f}"),
    ("th2 bent", "bent/posture/theta2/rmse", 1, "{:.3f}"),
    ("Fx bent", "bent/posture/Fx/rmse", 1, "{:.2f}"),
    ("Fy bent", "bent/posture/Fy/rmse", 1, "{:.2f}"),
    ("Fy n/18", "bent/posture/Fy/reported", 1, "{:.1f}"),
    ("Fx cover", "bent/posture/Fx/coverage", 100, "{:.0f}%"),
    ("steel k/k", "objects/paper/can-steel-1/k_over_true", 1, "{:.2f}"),
    ("PET-1 k/k", "objects/paper/pet-1/k_over_true", 1, "{:.2f}"),
)


def load_cache(path: Path | None, realism: str = "literature") -> dict[tuple[str, int], dict[str, float]]:
    """The cache's (level, seed) figures measured with the levels on ``realism`` (records of before
    --realism: the literature's)."""

    def same(rec: dict[str, Any]) -> bool:
        # Records of before the posture form took the friction terms were fitted without them.
        same_form = rec.get("friction_terms", False) == FRICTION_TERMS
        return rec.get("realism", "literature") == realism and same_form

    return {(rec["level"], int(rec["seed"])): rec["figures"] for rec in cache_records(path, same)}


def _run(job: tuple[str, int, int, str]) -> tuple[str, int, dict[str, float]]:
    level, seed, pushes, realism = job
    figs = study.measure_level({"realism": realism, **LEVELS[level]}, seed, pushes, friction_terms=FRICTION_TERMS)
    return level, seed, study.per_seed(figs)


def gather(
    levels: list[str], seeds: list[int], pushes: int, cache: Path | None, jobs: int, realism: str = "literature"
) -> dict:
    """Per level and seed, the figures (from the cache where done); appends new ones to it.
    ``realism``: the rig of the levels that name none (``kind`` and ``literature`` name theirs)."""
    done = load_cache(cache, realism)
    todo = [(lv, s, pushes, realism) for lv in levels for s in seeds if (lv, s) not in done]
    if jobs > 1:
        from multiprocessing import Pool

        with Pool(jobs) as pool:
            results = pool.imap_unordered(_run, todo)
            for level, seed, figs in results:
                _keep(done, cache, level, seed, figs, realism)
    else:
        for job in todo:
            _keep(done, cache, *_run(job), realism)
    return {lv: {s: done[(lv, s)] for s in seeds} for lv in levels}


def _keep(done: dict, cache: Path | None, level: str, seed: int, figs: dict[str, float], realism: str) -> None:
    done[(level, seed)] = figs
    print(f"  measured {level}, seed {seed}", file=sys.stderr, flush=True)
    record = {"level": level, "seed": seed, "realism": realism, "friction_terms": FRICTION_TERMS, "figures": figs}
    cache_append(cache, record)


def summarise(per_level: dict[str, dict[int, dict[str, float]]]) -> dict[str, float]:
    """``LEVEL/FIGURE/mean|sd|min|max`` over seeds (NaN seeds left out; ``n`` counts the rest)."""
    out: dict[str, float] = {}
    for level, by_seed in per_level.items():
        names = sorted({k for figs in by_seed.values() for k in figs})
        for name in names:
            v = np.array([figs.get(name, math.nan) for figs in by_seed.values()], dtype=float)
            v = v[np.isfinite(v)]
            stats = {"n": float(v.size)}
            if v.size:
                stats.update(mean=float(v.mean()), sd=float(v.std(ddof=1)) if v.size > 1 else 0.0)
                stats.update(min=float(v.min()), max=float(v.max()))
            for stat, value in stats.items():
                out[f"{level}/{name}/{stat}"] = value
    return out


def headline(summary: dict[str, float], levels: list[str]) -> str:
    cols = [c for c, *_ in HEADLINE]
    lines = ["| level | " + " | ".join(cols) + " | objects right (paper form) |", "|---" * (len(cols) + 2) + "|"]
    for level in levels:
        cells = []
        for _, fig, scale, fmt in HEADLINE:
            m, sd = summary.get(f"{level}/{fig}/mean"), summary.get(f"{level}/{fig}/sd")
            cells.append("-" if m is None else f"{fmt.format(scale * m)} ± {fmt.format(scale * sd).rstrip('%')}")
        right = [summary.get(f"{level}/objects/paper/{o}/correct/mean", math.nan) for o in _objects()]
        cells.append(f"{np.nansum(right):.1f}/6")
        lines.append(f"| {level} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def _objects() -> list[str]:
    from labcli.papers.takuma2014.sim.objects import DEMO_OBJECTS

    return [o.name for o in DEMO_OBJECTS]


def details(summary: dict[str, float], levels: list[str]) -> str:
    names = sorted({k.rsplit("/", 1)[0].split("/", 1)[1] for k in summary})
    lines = []
    for name in names:
        cells = []
        for level in levels:
            m, sd = summary.get(f"{level}/{name}/mean"), summary.get(f"{level}/{name}/sd")
            cells.append(f"{level}: " + ("-" if m is None else f"{m:.4g} ± {sd:.2g}"))
        lines.append(f"{name:44s} " + "; ".join(cells))
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> None:
    ap = bench_parser(__doc__)
    ap.add_argument("--quick", action="store_true", help=f"seeds 11-12, levels {', '.join(QUICK_LEVELS)}, 5 pushes")
    # The scaled levels' rig: the literature's, around whose levels docs/rig-realism.md's sweep was measured.
    pre = argparse.ArgumentParser(add_help=False)  # --quick's own seeds are the default of --seeds
    pre.add_argument("--quick", action="store_true")
    quick = pre.parse_known_args(argv)[0].quick
    add_rig_options(ap, realism="literature", seeds="11-12" if quick else "11-15")
    ap.add_argument("--levels", default=None, help="comma-separated level names (default: all)")
    ap.add_argument("--pushes", type=int, default=None, help="pushes per object (default 10; --quick 5)")
    ap.add_argument("--cache", type=Path, default=None, help="JSON-lines file of measured (level, seed) pairs")
    ap.add_argument("--jobs", type=int, default=1, help="processes (default 1: the machine is shared)")
    ap.add_argument(
        "--json", "--figures", dest="json", type=Path, default=ROOT / "docs" / "figures" / "sensitivity.json"
    )
    args = ap.parse_args(argv)
    levels = args.levels.split(",") if args.levels else list(QUICK_LEVELS if args.quick else LEVELS)
    unknown = [lv for lv in levels if lv not in LEVELS]
    if unknown:
        raise SystemExit(f"unknown level {unknown[0]!r}; levels: {', '.join(LEVELS)}")
    seeds = args.seeds
    pushes = args.pushes or (5 if args.quick else 10)
    head = git_head()  # the code measured is the code at the start
    summary = summarise(gather(levels, seeds, pushes, args.cache, args.jobs, args.realism))
    print(f"\nseeds {seeds_text(seeds)} ({len(seeds)}), {pushes} pushes per object; posture form unless named")
    table = headline(summary, levels)
    print(table)
    print("\nEvery figure, mean ± sd over seeds:")
    print(details(summary, levels))
    meta = {
        "meta/seeds": f"{seeds[0]}-{seeds[-1]}" if seeds == list(range(seeds[0], seeds[-1] + 1)) else str(seeds),
        "meta/pushes_per_object": pushes,
        "meta/posture_friction_terms": FRICTION_TERMS,
        **{f"meta/level/{lv}": json.dumps(LEVELS[lv], sort_keys=True) for lv in levels},
        "headline": table,  # the pages show it whole (docs/rig-realism.md)
    }
    print()
    write_figures(args.json, meta, summary, commit=head)


if __name__ == "__main__":
    main()
