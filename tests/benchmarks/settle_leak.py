"""How many windows of the demo's force run settle, and how long they wait, per rig seed.

Run:  nice -n 10 python tests/benchmarks/settle_leak.py [--seeds 1-10] [--realism kind,literature]
                                                       [--runs DIR]

Per seed and realism, the demo's own path: the takuma2014 plan's 108 weight trials acquired
unattended over ``sim://`` with the board driving its valves (the hold check before the first
trial, the chambers re-pressurised as they leak; labcli.core.demo.acquire_unattended).  Printed per
seed: the baselines and the loaded windows that settled (out of 108; the rest were accepted at the
timeout), the mean wait of each (device s) and the hold check's largest leak (kPa/min).  A chamber
that leaks steadily is not a tail still to come (labcli.core.settle, the leak taken out of the
tail); ``--no-leak`` judges the same run without it, the rule before the leak was taken out (the
baseline of the same run).
``--runs DIR`` keeps each run file, so a rerun reads them again without acquiring.
"""

from __future__ import annotations

import sys
import tempfile
from pathlib import Path
from typing import Any

import numpy as np
from rig_options import add_rig_options, bench_parser, seeds_text

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))


def acquire_seed(seed: int, realism: str, path: Path) -> None:
    from labcli.core.demo import acquire_unattended, simulated_port
    from labcli.papers.takuma2014.demo import RUN_VALVES

    port = simulated_port(seed) + f"&realism={realism}"
    if not path.exists():
        path.parent.mkdir(parents=True, exist_ok=True)
        acquire_unattended(path, port, "force run", "run", None, protocol="takuma2014", valves=RUN_VALVES)


def settle_rows(path: Path) -> dict[str, Any]:
    from labcli.core.store import RunFile

    out: dict[str, Any] = {}
    with RunFile.open(path) as run:
        records = [run.records.read(i) for i in run.records.ids()]
    for window in ("baseline", "load"):
        s = [r["settle"][window] for r in records]
        out[window] = (sum(bool(x["settled"]) for x in s), len(s), float(np.mean([x["waited_s"] for x in s])))
    return out


def main() -> None:
    ap = bench_parser(__doc__)
    add_rig_options(ap, realism="kind,literature", seeds="1-10", several=True)
    ap.add_argument("--runs", type=Path, default=None, help="keep (and reuse) the run files here")
    ap.add_argument("--no-leak", action="store_true", help="the waits count the leak as a tail (the rule before)")
    args = ap.parse_args()
    if args.no_leak:
        from labcli.core import air

        known = air.AirDrift.__init__

        def unknown(self: Any, names: Any, cols: Any, settings: Any, rate_per_s: Any = None) -> None:
            known(self, names, cols, settings, None)

        air.AirDrift.__init__ = unknown  # type: ignore[method-assign]
    where = args.runs or Path(tempfile.mkdtemp(prefix="settle_leak_"))
    for realism in args.realism:
        totals = np.zeros(4)
        waits: dict[str, list[float]] = {"baseline": [], "load": []}
        seeds = args.seeds
        for seed in seeds:
            path = where / realism / f"seed{seed}.h5"
            acquire_seed(seed, realism, path)
            row = settle_rows(path)
            (bs, bn, bw), (ls, ln, lw) = row["baseline"], row["load"]
            totals += (bs, bn, ls, ln)
            waits["baseline"].append(bw)
            waits["load"].append(lw)
            print(
                f"{realism:10s} seed {seed:2d}: baselines settled {bs:3d}/{bn}, mean wait {bw:5.1f} s; "
                f"loads settled {ls:3d}/{ln}, mean wait {lw:5.1f} s",
                flush=True,
            )
        print(
            f"{realism:10s} {'(leak counted) ' if args.no_leak else ''}seeds {seeds_text(args.seeds)}: baselines {int(totals[0])}/{int(totals[1])} "
            f"(mean wait {np.mean(waits['baseline']):.1f} s), loads {int(totals[2])}/{int(totals[3])} "
            f"(mean wait {np.mean(waits['load']):.1f} s)",
            flush=True,
        )


if __name__ == "__main__":
    main()
