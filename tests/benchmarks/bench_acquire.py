"""Wall time of an unattended 108-trial acquisition on the simulated rig (virtual clock).

Run:  python tests/benchmarks/bench_acquire.py [--seeds N] [--realism kind] [--block S]

Three figures, measured in the same run:

* the unattended run itself (``labcli acquire RUN --port 'sim://?clock=virtual'
  --unattended`` through the library call the command makes): setup, air,
  108 trials of baseline, load, settling, capture and review, 108 crash-safe
  trial writes, the split;
* the baseline: the same number of frames streamed from a fresh simulated rig
  through ``Device.read`` with nothing else done (rig model, firmware, wire
  codec and reader only);
* the device time the run covered, i.e. how long the same protocol keeps a real
  rig busy at the same settling rule.

Reported: run / baseline (the cost of the engine, settle detection and store on
top of the link) and device time / run (how much faster than real time).
``--block`` sets the virtual clock's on-demand block (``BLOCK_S`` of the
``sim://`` URL handler, device seconds generated per read) to show how much of the
run is the simulated link.
"""

from __future__ import annotations

import io
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from rich.console import Console  # noqa: E402
from rig_options import add_rig_options, bench_parser  # noqa: E402

import labcli.core.sim.protocol_sim as protocol_sim  # noqa: E402
from labcli.core.acquisition import acquire  # noqa: E402
from labcli.core.device import Device  # noqa: E402
from labcli.core.ui import UnattendedUI  # noqa: E402


def main() -> None:
    ap = bench_parser(__doc__)
    add_rig_options(ap, realism="kind", seeds="1", one=True)  # the rig of docs/performance.md's figures
    ap.add_argument("--block", type=float, default=None, help="virtual-clock block, device s per read")
    args = ap.parse_args()
    if args.block:
        protocol_sim.BLOCK_S = args.block
    seed = args.seeds[0]
    port = f"sim://?seed={seed}&clock=virtual&realism={args.realism}"

    frames = 0
    original_read = Device.read

    def counting_read(self, timeout=1.0):
        nonlocal frames
        batch = original_read(self, timeout)
        frames += len(batch)
        return batch

    Device.read = counting_read
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "run.h5"
        ui = UnattendedUI(console=Console(file=io.StringIO()))
        t0 = time.perf_counter()
        outcome = acquire(path, port, protocol="takuma2014", unattended=True, ui=ui)
        t_run = time.perf_counter() - t0
    Device.read = original_read
    assert outcome.stored == 108, outcome.message

    with Device.open(f"sim://?seed={seed + 1}&clock=virtual&realism={args.realism}") as dev:
        rate = dev.set_rate(200)
        got = 0
        t0 = time.perf_counter()
        dev.start()
        while got < frames:
            got += len(dev.read(1.0))
        dev.stop()
        t_base = time.perf_counter() - t0

    device_s = frames / rate
    print(f"virtual-clock block: {protocol_sim.BLOCK_S:g} s of device time per read")
    print(f"unattended run, 108 trials: {t_run:.2f} s wall, {frames} frames, {device_s:.0f} s of device time")
    print(f"baseline, same frames through Device.read only: {t_base:.2f} s wall")
    print(f"run / baseline: {t_run / t_base:.2f}")
    print(f"device time / run wall time: {device_s / t_run:.0f}x faster than real time")


if __name__ == "__main__":
    main()
