"""Accuracy, not time: do the bands' confidences know when a category is wrong?

For each held-out rig seed, on the kind rig (the default) and the literature's, the six demo
objects pushed ten times each on the straight arm with phi given, classified by the protocol's
bands with the posture form (whose standard errors make each confidence, models/classify.py
``_band_confidence``).  Reported per rig: the objects put in the wrong category and the largest
confidence among them, the objects left without a category because every push was flagged, and
how many right ones carry a confidence under 0.9.

    nice python tests/benchmarks/band_confidence.py [--seeds 11-30] [--realism kind,literature] [--figures OUT]
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

import study  # noqa: E402
from rig_options import add_rig_options, bench_parser, seeds_text  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]


def main(argv: list[str] | None = None) -> None:
    ap = bench_parser(__doc__)
    add_rig_options(ap, realism="kind,literature", seeds="11-30", several=True)
    ap.add_argument(
        "--friction-terms",
        action="store_true",
        help="the posture form with the sleeves' friction terms (fit's default)",
    )
    ap.add_argument("--figures", type=Path, default=ROOT / "docs" / "figures" / "band-confidence.json")
    args = ap.parse_args(argv)
    seeds = args.seeds
    out: dict[str, object] = {"meta/seeds": seeds_text(seeds), "meta/friction_terms": args.friction_terms}
    for rig in args.realism:
        kw = study.rig_kw({"realism": rig})
        wrong: list[tuple[int, str, str, float]] = []
        right: list[float] = []
        for s in seeds:
            figs = study.objects(s, kw, 10, friction_terms=args.friction_terms)
            for key, ok in figs.items():
                if key.startswith("objects/posture/") and key.endswith("/correct"):
                    base = key[: -len("/correct")]
                    conf = float(figs[f"{base}/confidence"])
                    if ok:
                        right.append(conf)
                    else:
                        wrong.append((s, base.split("/")[2], str(figs[f"{base}/category"]), conf))
        # An object whose every push was flagged has no category (nor a confidence): unmeasured, not wrong.
        unmeasured = [w for w in wrong if not w[2]]
        wrong = [w for w in wrong if w[2]]
        out[f"{rig}/objects"] = len(right) + len(wrong) + len(unmeasured)
        out[f"{rig}/wrong"] = len(wrong)
        out[f"{rig}/unmeasured"] = len(unmeasured)
        out[f"{rig}/wrong_max_confidence"] = max((w[3] for w in wrong), default=0.0)
        out[f"{rig}/right_below_0.9"] = sum(c < 0.9 for c in right)
        print(
            f"{rig}: {len(wrong)} of {out[f'{rig}/objects']} objects in the wrong category, confidence at most "
            f"{out[f'{rig}/wrong_max_confidence']:.2f} ({wrong}); {len(unmeasured)} unmeasured (every push "
            f"flagged: {unmeasured}); {out[f'{rig}/right_below_0.9']} right ones under 0.9"
        )
    args.figures.write_text(json.dumps(out, indent=1, sort_keys=True) + "\n")
    print(f"wrote {args.figures}")


if __name__ == "__main__":
    main()
