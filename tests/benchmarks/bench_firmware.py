"""The highest frame rate the reference firmware sustains with no frame lost, on simavr.

Run:  python tests/benchmarks/bench_firmware.py [--seconds 5] [--bauds 115200,1000000] [--max-rate 2000]
                                                 [--realism kind] [--seeds 1]

The firmware (firmware/) is built for each line rate with its RATE guard lifted
(RATE_MAX_HZ=5000), so rates past its limit can be tried, and twice per line
rate: fresh (seq and t_us start at 0, so lines are short) and "long lines"
(seq starts at 1,000,000 and t_us at 10^9 us: the data lines of a run 17 minutes
and a million frames in, 6 bytes longer).  For each build the highest whole
rate with no frame lost over ``--seconds`` of simulated time is found by
bisection; "lost" is what the host counts from sequence gaps, and the
firmware's own statistics (its log line at STOP) name the cause of any loss:

* ``uart full``: the line is slower than the frames (baud);
* ``adc late``: a frame's 96 conversions outlast the period, or ``unformatted``:
  the main loop had not taken the finished frame when the next tick came (both
  AVR time per frame: conversions, interrupts, formatting).

A rate a little above the baud limit loses nothing until the 256-byte transmit
ring has filled (at 1 Hz over the limit, some 4 s), so hold each rate for
several seconds: run_all's quick 2 s can read a hertz high.

Baselines measured in the same run: the baud limit, UART bytes per second
(10 bits per byte at the divider's real baud) over the mean length of the data
lines actually sent; and the AVR limit, one over the firmware's longest
sampling time per frame.  The simulator's own speed is measured too: simulated
seconds per wall second at the highest rate, which must stay above 1 for
``labcli sim --pty --firmware`` (wall clock) to keep up.
Needs gcc-avr, avr-libc and simavr (see firmware/README.md).
"""

from __future__ import annotations

import json
import re
import shutil
import subprocess
import sys
import tempfile
import threading
import time
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))

from rig_options import add_rig_options, bench_parser  # noqa: E402

from labcli.core.sim import make_rig  # noqa: E402
from labcli.core.sim.hil import HilLink  # noqa: E402
from labcli.core.wire import StreamReader  # noqa: E402

LONG = "-DSEQ_START=1000000UL -DT_US_START=1000000000UL"
INSTALL = "apt-get install gcc-avr avr-libc binutils-avr simavr libsimavr-dev libelf-dev"
STOPPED = re.compile(
    r"stopped: (\d+) frames sent, (\d+) dropped \((\d+) uart full, (\d+) adc late, "
    r"(\d+) unformatted\), sampling (\d+) us"
)


@dataclass
class Probe:
    rate: float
    frames: int
    lost: int
    uart_full: int
    adc_late: int
    unformatted: int
    sampling_us: int
    line_bytes: float
    sim_per_wall: float
    byte_us: float


def build(folder: Path, baud: int, long_lines: bool) -> Path:
    defs = "-DRATE_MAX_HZ=5000" + (" " + LONG if long_lines else "")
    subprocess.run(
        ["make", "-C", str(ROOT / "firmware"), f"BUILD={folder}", f"BAUD={baud}", f"DEFS={defs}", "all"],
        check=True,
        capture_output=True,
        text=True,
    )
    return folder / "labcli_rig.elf"


RIG = {"seed": 1, "realism": "kind"}  # --seeds, --realism: the kind rig, on which the docs' figures were measured


def rig():
    r = make_rig("mckibben", **RIG)
    r.supply_air()
    r.advance(5.0)  # 0.3 MPa: every value has four digits, as on a working rig
    r.close_valves()
    return r


def probe(elf: Path, rate: int, seconds: float) -> Probe:
    got = bytearray()
    lock = threading.Lock()

    def take(data: bytes) -> None:
        with lock:
            got.extend(data)

    link = HilLink(rig(), elf, pacing="demand", on_bytes=take)
    try:
        link.write(f"RATE {rate}\nSTART\n".encode())
        w0, t0 = time.monotonic(), link.avr_time_s
        while link.avr_time_s < seconds + 0.1:
            link.demand(0.2)
            time.sleep(0.002)
        sim_per_wall = (link.avr_time_s - t0) / (time.monotonic() - w0)
        link.write(b"STOP\n")
        deadline = time.monotonic() + 30
        while b"OK STOP" not in got and time.monotonic() < deadline:
            link.demand(0.2)
            time.sleep(0.002)
        byte_us = float(re.search(r"byte_us=([\d.]+)", link.uart).group(1))
    finally:
        link.stop()
    data = bytes(got)
    if b"OK RATE " not in data:
        raise SystemExit(f"the firmware refused RATE {rate}: {data[:300]!r}")
    reader = StreamReader(n_channels=6)
    batch = reader.feed(data)
    stats = STOPPED.search(data.decode("ascii", "replace"))
    sent, _, uart_full, adc_late, unformatted, sampling = map(int, stats.groups())
    lines = [ln for ln in data.split(b"\n") if ln.startswith(b"$D,")]
    return Probe(
        rate,
        len(batch),
        reader.counters["lost"],
        uart_full,
        adc_late,
        unformatted,
        sampling,
        sum(map(len, lines)) / len(lines) + 1,
        sim_per_wall,
        byte_us,
    )


def highest(elf: Path, seconds: float, max_rate: int) -> tuple[Probe, Probe | None]:
    """The highest whole rate with nothing lost, and the first rate above it (None if max_rate holds)."""
    lo = probe(elf, 10, seconds)
    if lo.lost:
        raise SystemExit("frames lost even at 10 Hz")
    top = probe(elf, max_rate, seconds)
    if not top.lost:
        return top, None
    bad = top
    while bad.rate - lo.rate > 1:
        mid = probe(elf, int((lo.rate + bad.rate) // 2), seconds)
        if mid.lost:
            bad = mid
        else:
            lo = mid
    return lo, bad


def cause(p: Probe) -> str:
    """Why frames were lost at this rate, from the firmware's counters and its sampling time."""
    period_us = 1e6 / p.rate
    detail = (
        f"{p.lost} lost: {p.uart_full} uart full, {p.adc_late} adc late, {p.unformatted} unformatted; "
        f"sampling {p.sampling_us} us of a {period_us:.0f} us period"
    )
    if p.uart_full >= p.adc_late + p.unformatted:
        return f"baud ({detail})"
    # A frame still converting, or finished but not yet taken, when the next tick comes.
    return f"AVR time per frame ({detail})"


def main() -> None:
    ap = bench_parser(__doc__)
    ap.add_argument("--seconds", type=float, default=5.0, help="simulated seconds per probe")
    add_rig_options(ap, realism="kind", seeds="1", one=True)
    ap.add_argument("--bauds", default="115200,1000000")
    ap.add_argument("--max-rate", type=int, default=2000)
    ap.add_argument("--figures", help="also write the figures to this JSON file ({name: value})")
    args = ap.parse_args()
    RIG.update(seed=args.seeds[0], realism=args.realism)
    figures: dict = {"simulated seconds per probe": args.seconds}
    if not (shutil.which("avr-gcc") and shutil.which("make") and Path("/usr/include/simavr/sim_avr.h").exists()):
        print(f"skipped: needs gcc-avr, avr-libc and simavr ({INSTALL})")
        return
    print(f"Highest rate with 0 lost frames over {args.seconds:g} s of simulated time, 6 channels, 16 conversions each")
    print(
        f"{'baud':>8} {'lines':<6} {'max Hz':>7} {'line B':>7} {'baud-limit Hz':>14} {'max/baud':>9} "
        f"{'sampling us':>12} {'AVR-limit Hz':>13} {'max/AVR':>8} {'sim/wall':>9}  first loss"
    )
    with tempfile.TemporaryDirectory() as tmp:
        for baud in map(int, args.bauds.split(",")):
            for long_lines in (False, True):
                elf = build(Path(tmp) / f"{baud}-{int(long_lines)}", baud, long_lines)
                best, first_bad = highest(elf, args.seconds, args.max_rate)
                baud_limit = 1e6 / best.byte_us / best.line_bytes
                avr_limit = 1e6 / best.sampling_us
                loss = f"{first_bad.rate:g} Hz, {cause(first_bad)}" if first_bad else f"none up to {args.max_rate} Hz"
                print(
                    f"{baud:>8} {'long' if long_lines else 'fresh':<6} {best.rate:>7g} {best.line_bytes:>7.1f} "
                    f"{baud_limit:>14.1f} {best.rate / baud_limit:>9.3f} {best.sampling_us:>12d} {avr_limit:>13.1f} "
                    f"{best.rate / avr_limit:>8.3f} {best.sim_per_wall:>9.2f}  {loss}",
                    flush=True,
                )
                key = f"{baud} {'long' if long_lines else 'fresh'}"
                figures[f"{key} max Hz"] = best.rate
                figures[f"{key} line bytes"] = best.line_bytes
                figures[f"{key} baud limit Hz"] = baud_limit
                figures[f"{key} AVR limit Hz"] = avr_limit
                figures[f"{key} sampling ms"] = best.sampling_us / 1e3
                figures[f"{key} sim per wall"] = best.sim_per_wall
                figures[f"{baud} UART bytes per s"] = 1e6 / best.byte_us
    if args.figures:
        speeds = [v for k, v in figures.items() if k.endswith("sim per wall")]
        figures["sim per wall min"], figures["sim per wall max"] = min(speeds), max(speeds)
        Path(args.figures).write_text(json.dumps(figures, indent=1) + "\n")


if __name__ == "__main__":
    main()
