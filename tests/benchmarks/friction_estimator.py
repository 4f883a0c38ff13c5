"""Accuracy, not time: the posture form with the sleeves' friction terms against the posture form alone.

On the literature's rig (docs/rig-realism.md) for each held-out rig seed, the straight and the bent
protocol (108 trials; fitted on the 90 fit trials, checked on the 18 validation trials,
pressure-only), the posture form as ``labcli fit`` makes it and the same with
``PostureModel(friction=True)`` (models/posture.py, ``friction_columns``), on the same trials.
Reported per protocol and quantity: RMSE over every validation trial and over the trials both
report, with 95 % intervals from a bootstrap over seeds (a seed's trials share its fit, so the seed
is what is resampled), the ratio friction / plain with its interval, the trials each reports, and
the coverage of each form's 95 % intervals with a Wilson interval.

    nice python tests/benchmarks/friction_estimator.py [--seeds 11-30] [--cache FILE] [--figures OUT]

The friction terms' fade (FRICTION_MOTION_RAD) was chosen on seeds 1-10; nothing here is tuned.
"""

from __future__ import annotations

import argparse
import json
import math
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from baseline_estimator import wilson  # noqa: E402
from sensitivity import seeds_of  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
PROTOCOLS = {"straight": "takuma2014", "bent": "takuma2014-bent"}
FORMS = ("plain", "friction")
QUANTITIES = ("theta1", "theta2", "Fx", "Fy")
BOOTSTRAP = 2000


def measure(seed: int) -> dict[str, Any]:
    """Per protocol, form and quantity: the validation errors, which trials are reported, interval hits."""
    from sensing_accuracy import trials

    from labcli.papers.takuma2014.models.metrics import evaluate
    from labcli.papers.takuma2014.models.posture import PostureModel, limits_from_protocol
    from labcli.papers.takuma2014.sim.nonideal import NonIdeal

    out: dict[str, Any] = {}
    for short, name in PROTOCOLS.items():
        proto, table = trials(name, seed, 8.0, rig_kw={"nonideal": NonIdeal(realism="literature")})
        for form in FORMS:
            model = PostureModel(
                geometry=proto.settings.rig, limits=limits_from_protocol(proto), friction=form == "friction"
            ).fit(table)
            ev = evaluate(model, table)
            for q in QUANTITIES:
                err = np.asarray(ev["calculated"][q] - ev["observed"][q], dtype=float)
                out[f"{short}/{form}/{q}/err"] = err.tolist()
                out[f"{short}/{form}/{q}/ok"] = np.asarray(ev["ok"][q], dtype=bool).tolist()
                out[f"{short}/{form}/{q}/inside"] = (np.abs(err) <= 1.96 * np.asarray(ev["se"][q])).tolist()
            out[f"{short}/{form}/terms"] = [t for t in model.torque_terms if t.startswith("friction")]
    return out


def _rms(x: np.ndarray) -> float:
    return float(np.sqrt(np.mean(x**2))) if x.size else math.nan


def figures(raw: dict[int, dict[str, Any]]) -> dict[str, Any]:
    rng = np.random.default_rng(20261126)
    seeds = sorted(raw)
    picks = [rng.integers(0, len(seeds), len(seeds)) for _ in range(BOOTSTRAP)]
    out: dict[str, Any] = {}
    for short in PROTOCOLS:
        for q in QUANTITIES:
            err = {f: [np.asarray(raw[s][f"{short}/{f}/{q}/err"]) for s in seeds] for f in FORMS}
            ok = {f: [np.asarray(raw[s][f"{short}/{f}/{q}/ok"], dtype=bool) for s in seeds] for f in FORMS}
            both = [ok["plain"][i] & ok["friction"][i] for i in range(len(seeds))]
            for which, mask in (("all", None), ("both", both)):

                def rmse(form: str, idx: Any, mask: Any = mask) -> float:
                    parts = [err[form][i] if mask is None else err[form][i][mask[i]] for i in idx]
                    return _rms(np.concatenate(parts)) if parts else math.nan

                whole = {f: rmse(f, range(len(seeds))) for f in FORMS}
                boots = np.array([[rmse(f, p) for f in FORMS] for p in picks])
                for k, f in enumerate(FORMS):
                    lo, hi = np.nanpercentile(boots[:, k], [2.5, 97.5])
                    out[f"{short}/{q}/{f}/rmse_{which}"] = whole[f]
                    out[f"{short}/{q}/{f}/rmse_{which}_ci95"] = [float(lo), float(hi)]
                ratio = boots[:, 1] / boots[:, 0]
                lo, hi = np.nanpercentile(ratio, [2.5, 97.5])
                out[f"{short}/{q}/ratio_{which}"] = whole["friction"] / whole["plain"]
                out[f"{short}/{q}/ratio_{which}_ci95"] = [float(lo), float(hi)]
            out[f"{short}/{q}/both_reported"] = int(sum(int(b.sum()) for b in both))
            for f in FORMS:
                out[f"{short}/{q}/{f}/reported"] = int(sum(int(o.sum()) for o in ok[f]))
                inside = np.concatenate(
                    [
                        np.asarray(raw[s][f"{short}/{f}/{q}/inside"], dtype=bool)[o]
                        for s, o in zip(seeds, ok[f], strict=True)
                    ]
                )
                p, lo, hi = wilson(int(inside.sum()), int(inside.size))
                out[f"{short}/{q}/{f}/coverage"] = p
                out[f"{short}/{q}/{f}/coverage_ci95"] = [lo, hi]
            out[f"{short}/trials"] = int(sum(len(raw[s][f"{short}/plain/Fx/err"]) for s in seeds))
        kept = [raw[s][f"{short}/friction/terms"] for s in seeds]
        out[f"{short}/friction_terms_kept_seeds"] = int(sum(bool(k) for k in kept))
    return out


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", default="11-30", help="held-out rig seeds (default 11-30)")
    ap.add_argument("--cache", type=Path, default=None, help="JSON-lines file of measured seeds (resumable)")
    ap.add_argument(
        "--figures", "--json", dest="json", type=Path, default=ROOT / "docs" / "figures" / "friction-estimator.json"
    )
    args = ap.parse_args(argv)
    seeds = seeds_of(args.seeds)
    head = subprocess.run(["git", "rev-parse", "HEAD"], cwd=ROOT, capture_output=True, text=True).stdout.strip()
    done: dict[int, dict[str, Any]] = {}
    if args.cache is not None and args.cache.exists():
        for line in args.cache.read_text().splitlines():
            if line.strip():
                rec = json.loads(line)
                done[int(rec["seed"])] = rec["raw"]
    for seed in seeds:
        if seed not in done:
            done[seed] = measure(seed)
            print(f"  measured seed {seed}", file=sys.stderr, flush=True)
            if args.cache is not None:
                with args.cache.open("a") as f:
                    f.write(json.dumps({"seed": seed, "raw": done[seed]}) + "\n")
    figs = figures({s: done[s] for s in seeds})
    print(f"held-out seeds {args.seeds}, literature's rig: posture form plain -> with friction terms, same trials")
    for short in PROTOCOLS:
        for q in QUANTITIES:
            k = f"{short}/{q}"
            lo, hi = figs[f"{k}/ratio_all_ci95"]
            print(
                f"{k:16s} RMSE all {figs[f'{k}/plain/rmse_all']:.3f} -> {figs[f'{k}/friction/rmse_all']:.3f} "
                f"(ratio {figs[f'{k}/ratio_all']:.2f} [{lo:.2f}, {hi:.2f}]); both reported "
                f"({figs[f'{k}/both_reported']}) {figs[f'{k}/plain/rmse_both']:.3f} -> "
                f"{figs[f'{k}/friction/rmse_both']:.3f}; coverage {figs[f'{k}/plain/coverage']:.2f} -> "
                f"{figs[f'{k}/friction/coverage']:.2f}"
            )
    meta = {"meta/commit": head, "meta/seeds": args.seeds, "meta/bootstrap": BOOTSTRAP}
    flat: dict[str, Any] = {}
    for k, v in {**meta, **figs}.items():
        if isinstance(v, list):
            flat[f"{k}/lo"], flat[f"{k}/hi"] = v
        else:
            flat[k] = v
    args.json.parent.mkdir(parents=True, exist_ok=True)
    args.json.write_text(json.dumps(flat, indent=1, sort_keys=True) + "\n")
    print(f"wrote {args.json}")


if __name__ == "__main__":
    main()
