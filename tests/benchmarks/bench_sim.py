"""Frame generation of the simulated rig against a per-frame baseline.

Run:  python tests/benchmarks/bench_sim.py [--frames N] [--repeat R] [--realism kind] [--seeds 1]

Both sides produce the same bytes for N frames of the reference rig (six
12-bit channels, 1 kHz): the rig's vectorised ``samples`` then either the
firmware's column-wise :func:`labcli.core.sim.firmware.format_frames` or the
baseline, :func:`labcli.core.wire.format_frame` called once per frame.  Also
reported: device seconds produced per wall second through a ``sim://`` port
(virtual clock) read in 64 KiB chunks.  Best of R runs; the ratio is measured
in the same run on the same machine.  The rig is the kind one (``--realism``, rig_options.py), the
one docs/performance.md's figures were measured on.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

import numpy as np  # noqa: E402

from labcli.core.sim.firmware import format_frames  # noqa: E402
from labcli.core.wire import format_frame  # noqa: E402
from labcli.papers.takuma2014.sim.nonideal import NonIdeal  # noqa: E402
from labcli.papers.takuma2014.sim.rig import SimRig  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
from rig_options import add_rig_options, bench_parser  # noqa: E402


def best(fn, repeat: int) -> tuple[float, object]:
    times, out = [], None
    for _ in range(repeat):
        t = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t)
    return min(times), out


def main() -> None:
    ap = bench_parser(__doc__)
    ap.add_argument("--frames", type=int, default=100_000)
    ap.add_argument("--repeat", type=int, default=3)
    add_rig_options(ap, realism="kind", seeds="1", one=True)
    a = ap.parse_args()
    n, seed = a.frames, a.seeds[0]

    def samples():
        rig = SimRig(seed=seed, nonideal=NonIdeal(realism=a.realism))
        rig.supply_air()
        return rig.samples(n, 1000.0)

    t_samples, (t_us, counts) = best(samples, a.repeat)
    seq = np.arange(n, dtype=np.int64)
    t_fast, fast = best(lambda: format_frames(seq, t_us % (1 << 32), counts), a.repeat)
    rows = counts.tolist()
    t_base, base = best(
        lambda: b"".join(format_frame(i, int(t_us[i]) % (1 << 32), rows[i]) for i in range(n)), a.repeat
    )
    assert fast == base, "column-wise formatting differs from wire.format_frame"

    import serial

    from labcli.core.sim import register

    register()
    port = serial.serial_for_url(f"sim://?seed={seed}&rate=1000&realism={a.realism}", timeout=1.0)
    port.write(b"START\n")
    t = time.perf_counter()
    got = 0
    while got < 40 * n:
        got += len(port.read(1 << 16))
    wall = time.perf_counter() - t
    device_s = port.rig.time_s
    port.close()

    print(f"frames: {n}")
    print(f"rig.samples:            {t_samples * 1e3:8.1f} ms")
    print(f"format_frames:          {t_fast * 1e3:8.1f} ms")
    print(f"format_frame per frame: {t_base * 1e3:8.1f} ms  (baseline)")
    print(f"speed-up vs baseline:   {t_base / t_fast:8.1f} x")
    print(f"sim:// virtual clock:   {device_s / wall:8.0f} device s per wall s at 1 kHz")


if __name__ == "__main__":
    main()
