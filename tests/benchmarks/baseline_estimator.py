"""Accuracy, not time: today's estimators on the literature's rig, held-out seeds, with 95 % intervals.

The baseline an improved estimator is measured against (the same trials, the same pushes): on
the default rig (the literature's levels, docs/rig-realism.md) for each held-out rig seed
(:mod:`study`), the straight and bent protocols with both forms (the posture form, labcli fit's
default, and the paper's Eqs. 34-37), the six demo objects pushed on the straight arm with phi
given (both forms, the protocol's bands), and the same objects pushed on the bent arm with phi
left blank (posture form).  Reported:

* RMSE per protocol, form and quantity over the reported validation trials (and over all), pooled
  over seeds, with a 95 % interval from a bootstrap over seeds (the trials of one seed share its
  fit, so the seed is the unit that is resampled);
* trials reported, and the posture form's 95 % coverage per quantity with a Wilson interval;
* every object's k / k_true and category per seed, the steel can's among them; the phi-blank
  pushes used and objects in category per seed.

    nice python tests/benchmarks/baseline_estimator.py [--seeds 11-30] [--realism literature] [--cache FILE]
                                                       [--json OUT]

It writes docs/figures/baseline-estimator-new-rig.json (``{name: value}``) with the commit it ran
on and the last commit that changed the estimators (labcli/papers/takuma2014/models/).
"""

from __future__ import annotations

import math
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import study  # noqa: E402
from figures_file import cached_seeds, git_head, write_figures  # noqa: E402
from rig_options import add_rig_options, bench_parser, seeds_text  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
BOOTSTRAP = 2000


def raw_results(seeds: list[int], cache: Path | None, realism: str = "literature") -> dict[int, dict[str, Any]]:
    return cached_seeds(
        cache,
        seeds,
        lambda seed: study.measure_level({"realism": realism}, seed, 10, with_phi_blank=True),
        tag={"realism": realism},
        # files of before the option: the literature's
        same=lambda rec: rec.get("realism", "literature") == realism,
    )


def rmse_ci(per_seed: list[list[float]], rng: np.random.Generator) -> tuple[float, float, float]:
    """Pooled RMSE and a 95 % percentile interval, resampling seeds."""
    pooled = [e for errs in per_seed for e in errs]
    if not pooled:
        return math.nan, math.nan, math.nan
    k = len(per_seed)
    boots = []
    for _ in range(BOOTSTRAP):
        pick = rng.integers(0, k, k)
        x = np.concatenate([np.asarray(per_seed[i], dtype=float) for i in pick])
        if x.size:
            boots.append(np.sqrt(np.mean(x**2)))
    lo, hi = np.percentile(boots, [2.5, 97.5])
    return study.rms(pooled), float(lo), float(hi)


def wilson(hits: int, n: int, z: float = 1.96) -> tuple[float, float, float]:
    if n == 0:
        return math.nan, math.nan, math.nan
    p = hits / n
    centre = (p + z * z / (2 * n)) / (1 + z * z / n)
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / (1 + z * z / n)
    return p, centre - half, centre + half


def figures(raw: dict[int, dict[str, Any]]) -> dict[str, Any]:
    rng = np.random.default_rng(20240901)
    seeds = sorted(raw)
    out: dict[str, Any] = {}
    for proto in study.PROTOCOLS:
        for form in study.FORMS:
            for q in study.QUANTITIES:
                key = f"{proto}/{form}/{q}"
                for which in ("err_ok", "err_all"):
                    m, lo, hi = rmse_ci([raw[s][f"{key}/{which}"] for s in seeds], rng)
                    name = "rmse" if which == "err_ok" else "rmse_all"
                    out.update({f"{key}/{name}": m, f"{key}/{name}_ci95_lo": lo, f"{key}/{name}_ci95_hi": hi})
                out[f"{key}/reported"] = sum(len(raw[s][f"{key}/err_ok"]) for s in seeds)
                out[f"{key}/trials"] = sum(len(raw[s][f"{key}/err_all"]) for s in seeds)
                if form == "posture":
                    inside = [v for s in seeds for v in raw[s][f"{key}/inside"]]
                    p, lo, hi = wilson(sum(inside), len(inside))
                    out.update({f"{key}/coverage": p, f"{key}/coverage_ci95_lo": lo, f"{key}/coverage_ci95_hi": hi})
    for s in seeds:
        for k, v in raw[s].items():
            if k.startswith(("objects/", "phi_blank/")):
                out[f"{k}/seed{s}"] = v
    if all("phi_blank/used" in raw[s] for s in seeds):
        out["phi_blank/used/total"] = int(sum(raw[s]["phi_blank/used"] for s in seeds))
        out["phi_blank/pushes/total"] = int(sum(raw[s]["phi_blank/pushes"] for s in seeds))
        out["phi_blank/all_six/seeds"] = int(sum(raw[s]["phi_blank/right"] == 6 for s in seeds))
        out["phi_blank/right/min"] = int(min(raw[s]["phi_blank/right"] for s in seeds))
        out["phi_blank/right/max"] = int(max(raw[s]["phi_blank/right"] for s in seeds))
    for form in study.FORMS:
        for name in {k.split("/")[2] for k in raw[seeds[0]] if k.startswith("objects/")}:
            ratios = np.array([raw[s][f"objects/{form}/{name}/k_over_true"] for s in seeds], dtype=float)
            out[f"objects/{form}/{name}/k_over_true/median"] = float(np.nanmedian(ratios))
            out[f"objects/{form}/{name}/correct/count"] = int(
                sum(raw[s][f"objects/{form}/{name}/correct"] for s in seeds)
            )
            # Seeds on which the object has no category: every push's force flagged.
            out[f"objects/{form}/{name}/uncategorised/count"] = int(
                sum(not raw[s][f"objects/{form}/{name}/category"] for s in seeds)
            )
    return out


def git(*args: str) -> str:
    return subprocess.run(["git", *args], cwd=ROOT, capture_output=True, text=True).stdout.strip()


def main(argv: list[str] | None = None) -> None:
    ap = bench_parser(__doc__)
    add_rig_options(ap, realism="literature", seeds="11-30")  # 11-30: the held-out seeds
    ap.add_argument("--cache", type=Path, default=None, help="JSON-lines file of measured seeds (resumable)")
    ap.add_argument(
        "--json",
        "--figures",
        dest="json",
        type=Path,
        default=ROOT / "docs" / "figures" / "baseline-estimator-new-rig.json",
    )
    args = ap.parse_args(argv)
    seeds, seeds_label = args.seeds, seeds_text(args.seeds)
    head = git_head()  # read before the run, as the meta: the code measured is the code at its start
    meta = {
        "meta/estimator_commit": git("log", "-1", "--format=%H", "--", "labcli/papers/takuma2014/models"),
        "meta/uncommitted_changes_in_labcli": bool(git("status", "--porcelain", "--", "labcli")),
        "meta/rig": f"sim:// rig (realism={args.realism}), takuma2014 and takuma2014-bent protocols",
        "meta/seeds": seeds_label,
        "meta/bootstrap": BOOTSTRAP,
    }
    figs = figures(raw_results(seeds, args.cache, args.realism))
    print(
        f"{args.realism} rig, held-out seeds {seeds_label}: RMSE over reported trials [95 % interval], reported / trials, coverage"
    )
    for proto in study.PROTOCOLS:
        for form in study.FORMS:
            for q in study.QUANTITIES:
                k = f"{proto}/{form}/{q}"
                cover = (
                    f"  cover {100 * figs[k + '/coverage']:.1f} % [{100 * figs[k + '/coverage_ci95_lo']:.1f}, "
                    f"{100 * figs[k + '/coverage_ci95_hi']:.1f}]"
                    if form == "posture"
                    else ""
                )
                print(
                    f"{k:26s} {figs[k + '/rmse']:.4g} [{figs[k + '/rmse_ci95_lo']:.4g}, {figs[k + '/rmse_ci95_hi']:.4g}]"
                    f"  {figs[k + '/reported']}/{figs[k + '/trials']}{cover}"
                )
    for form in study.FORMS:
        steel = [figs[f"objects/{form}/can-steel-1/category/seed{s}"] for s in seeds]
        print(f"steel can, {form} form, per seed: {', '.join(steel)}")
        for name in ("pet-1", "pet-2", "pet-3", "can-al-1", "can-al-2", "can-steel-1"):
            print(
                f"  {name:12s} k/true median {figs[f'objects/{form}/{name}/k_over_true/median']:.3f}, "
                f"right on {figs[f'objects/{form}/{name}/correct/count']}/{len(seeds)} seeds"
            )
    used = sum(figs[f"phi_blank/used/seed{s}"] for s in seeds)
    total = sum(figs[f"phi_blank/pushes/seed{s}"] for s in seeds)
    right = [figs[f"phi_blank/right/seed{s}"] for s in seeds]
    print(f"phi blank, bent arm: {used}/{total} pushes used, objects in category per seed {right}")
    write_figures(args.json, meta, figs, commit=head)


if __name__ == "__main__":
    main()
