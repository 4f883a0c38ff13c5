"""Accuracy, not time: the lab's actuator fitted to a stretch test, against the stand's truth.

Per seed (held-out seeds 11-30), the protocol's stretch test (6 payloads x 20 pressures) runs on
a seeded stand whose actuator is not the protocol's (moduli +12, -15 and +25 %, L0 2 mm longer,
radius 0.3 mm wider; friction and its own stretch correction as the stand draws them), and
``labcli fit``'s actuator fit starts from the protocol's.  Reported: how many parameters land
within 1 and 2 of their standard errors of the truth (68 % and 95 % for honest errors), the
largest deviation, the joint chi^2 of the truth against the fit's covariance (9 degrees of
freedom), and how many moduli the data determine per run.

    nice python tests/benchmarks/rpam_actuator_fit.py [--seeds 11-30] [--figures FILE.json]
"""

from __future__ import annotations

import json
import sys
import tempfile
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path[:0] = [str(HERE.parent), str(HERE.parent / "papers" / "rpam2015")]


def main() -> None:
    import test_actuator_fit as stand  # the test's stand, protocol and stretch run
    from rig_options import add_seeds_option, bench_parser

    from labcli.papers.rpam2015.models.rpam_fit import analyse_stretch

    ap = bench_parser(__doc__)
    add_seeds_option(ap, "11-30", what="seeds of the stand's actuator (held out: 11-30)")
    ap.add_argument("--figures", help="also write the figures to this JSON file ({name: value})")
    args = ap.parse_args()
    seeds = args.seeds
    devs, chi2, determined = [], [], []
    with tempfile.TemporaryDirectory() as tmp:
        protocol = stand.lab_protocol(Path(tmp))
        for seed in seeds:
            table, rig = stand.stretch_run(protocol, seed)
            a = analyse_stretch(table, "rpam2015").actuator_fit
            truth = stand.truth(rig)
            d = np.array([a.value(n) - truth[n] for n in a.names])
            devs.append(np.abs(d) / np.array(a.std_errors))
            chi2.append(float(d @ np.linalg.solve(np.asarray(a.covariance), d)))
            determined.append(sum(a.determined.values()))
            print(f"seed {seed}: chi2 {chi2[-1]:.1f}, largest deviation {devs[-1].max():.2f} s.e.")
    dev = np.concatenate(devs)
    fig = {
        "runs": len(chi2),
        "parameters": int(dev.size),
        "within 1 se percent": 100 * float(np.mean(dev < 1)),
        "within 2 se percent": 100 * float(np.mean(dev < 2)),
        "max deviation se": float(dev.max()),
        "median chi2": float(np.median(chi2)),
        "max chi2": float(max(chi2)),
        "runs above the 99.9 % chi2 limit": int(sum(c > 27.877 for c in chi2)),
        "runs with mu_1 alone determined": int(sum(n == 1 for n in determined)),
    }
    for k, v in fig.items():
        print(f"{k:40s} {v:.4g}" if isinstance(v, float) else f"{k:40s} {v}")
    if args.figures:
        rounded = {k: round(v, 6) if isinstance(v, float) else v for k, v in fig.items()}
        Path(args.figures).write_text(json.dumps(rounded, indent=1) + "\n")


if __name__ == "__main__":
    main()
