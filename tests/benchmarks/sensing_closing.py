"""Loads found, false loads and detection latency when the estimator starts with the air.

Run:  nice -n 10 python tests/benchmarks/sensing_closing.py [--seeds 1-10] [--realism literature,kind]
                                                           [--loads 8] [--no-hold]

Per realism, over the seeds: each seed's random pulley loads (labcli.papers.takuma2014.sim.scenario's
random_script, 50-1000 g) acted out from 0 s, the air supplied at 0 s and the valves closed at 6 s,
the estimator reading from the first frame (so it sees the air and the closing), with the sample
force run's model.  Printed: the true loads, those found (a load event within 1 s of one), the
load events of no load (and of them those placed before 12 s, the closing's), and the latency
from a load coming on to its event (median, p90, max).  ``--no-hold`` takes the first change
after the air at once, as the estimator did before it held it for the joints (the baseline).
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(Path(__file__).resolve().parent))
from rig_options import add_rig_options, bench_parser  # noqa: E402


def measure(realism: str, seeds: list[int], loads: int) -> str:
    from labcli.core.protocol import load_protocol
    from labcli.papers.takuma2014.sim import scenario as sc
    from labcli.sensing import Event, load_model

    sensing = load_model(ROOT / "sample_runs" / "force.model.json")
    protocol = load_protocol(sensing.protocol)
    sc.SESSION_START_S = 0.0  # the estimator sees the air being supplied and the valves' closing
    found = missed = false = at_closing = 0
    lat = []
    for seed in seeds:
        script = sc.random_script(seed, loads=loads, idle_s=0.0)
        s = sc.run_session(sensing.model, protocol, script, seed, rig_options={"realism": realism}, keep_stream=False)
        ons = [c["on_s"] for c in s.changes if c["kind"] == "load"]
        events = [e for e in s.items if isinstance(e, Event) and e.kind == "load"]
        for on in ons:
            hit = [e for e in events if abs(e.t_device_s - on) < 1.0]
            found, missed = found + bool(hit), missed + (not hit)
            lat += [hit[0].t_detected_s - on] if hit else []
        for e in events:
            if not any(abs(e.t_device_s - on) < 1.0 for on in ons):
                false += 1
                at_closing += e.t_device_s < 12.0
    q = np.quantile(lat, [0.5, 0.9, 1.0]) if lat else [np.nan] * 3
    return (
        f"{realism}: true loads {found + missed}, found {found}, missed {missed}, false loads {false} "
        f"(before 12 s: {at_closing}), latency median {q[0]:.2f} s, p90 {q[1]:.2f} s, max {q[2]:.2f} s"
    )


def main() -> None:
    ap = bench_parser(__doc__)
    add_rig_options(ap, realism="literature,kind", seeds="1-10", several=True)
    ap.add_argument("--loads", type=int, default=8)
    ap.add_argument("--no-hold", action="store_true", help="take the first change after the air at once")
    args = ap.parse_args()
    if args.no_hold:
        from labcli.sensing.estimator import Estimator

        Estimator._closing_or_load = lambda self, tc, seq, *rest: self._begin(tc, seq)  # type: ignore[method-assign]
    for realism in args.realism:
        print(measure(realism, args.seeds, args.loads), flush=True)


if __name__ == "__main__":
    main()
