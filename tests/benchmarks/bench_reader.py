"""Throughput of the stream reader against a one-``fromstring`` numpy parser, fresh processes.

Run:  python tests/benchmarks/bench_reader.py [--frames N] [--rounds R] [--chunks 4096,65536]
                                           [--figures FILE]

Both sides parse the same bytes: N data lines of 6 integer channels (the reference rig), with
``\\r\\n`` on one line in 50, fed in fixed-size chunks as from ``serial.read(in_waiting)``, the
partial last line of each chunk carried over to the next.

The baseline is what a user who knows numpy writes for such a stream (:func:`numpy_parser`):
blank the two checksum digits after each ``*`` and every other byte that is not a digit, then
one ``np.fromstring(..., dtype=np.int64, sep=" ")`` per chunk, reshaped to (seq, t_us, values)
with the values as float64.  It checks nothing (no checksum, no field count, no noise), so it
is a floor: the reader does all of that and must still keep up.

Each figure is one fresh Python process (``python bench_reader.py --child WHICH ...``) that reads
the stream from a file and times its parse alone (``time.process_time``).  Reader and baseline
alternate, the order flipping every round; each figure is the median of the rounds, and the
spread of the per-round ratios is printed beside it.  The machine's load average is printed
with the result.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))
sys.path.insert(0, str(Path(__file__).resolve().parent))

import numpy as np  # noqa: E402
from fresh import command_line  # noqa: E402

K = 6  # channels of the reference rig
_DIGIT = np.zeros(256, bool)
_DIGIT[48:58] = True


def make_stream(n: int, seed: int = 0) -> bytes:
    from labcli.core.wire import format_frame

    rng = np.random.default_rng(seed)
    counts = rng.integers(0, 4096, size=(n, K))
    out = []
    for i in range(n):
        line = format_frame(i, (i * 1000) % (1 << 32), counts[i].tolist())
        if i % 50 == 0:
            line = line[:-1] + b"\r\n"
        out.append(line)
    return b"".join(out)


def numpy_rows(block: bytes, k: int) -> np.ndarray:
    """Complete data lines to an (n, k + 2) int64 array: seq, t_us, values.  No check at all."""
    a = np.frombuffer(block, np.uint8).copy()
    star = np.flatnonzero(a == 42)
    a[star + 1] = 32  # the checksum's two hex digits
    a[star + 2] = 32
    a[~_DIGIT[a]] = 32
    return np.fromstring(a.tobytes(), dtype=np.int64, sep=" ").reshape(-1, k + 2)


def numpy_parser(stream: bytes, chunk: int) -> int:
    """The baseline: per chunk, blank every non-digit (the checksum too), one ``fromstring``."""
    pending = b""
    frames = 0
    for i in range(0, len(stream), chunk):
        buf = pending + stream[i : i + chunk]
        cut = buf.rfind(b"\n") + 1
        pending = buf[cut:]
        if not cut:
            continue
        rows = numpy_rows(buf[:cut], K)
        batch = (rows[:, 0], rows[:, 1], rows[:, 2:].astype(np.float64))  # seq, t_us, values
        frames += len(batch[0])
    return frames


def reader(stream: bytes, chunk: int) -> int:
    from labcli.core.wire import StreamReader

    r = StreamReader(n_channels=K)
    frames = 0
    for i in range(0, len(stream), chunk):
        frames += len(r.feed(stream[i : i + chunk]))
    if r.counters["bad_checksum"] or r.counters["malformed"] or r.counters["lost"]:
        raise SystemExit(f"the reader counted noise in a clean stream: {r.counters}")
    return frames


def child(which: str, path: str, chunk: int) -> None:
    stream = Path(path).read_bytes()
    fn = reader if which == "reader" else numpy_parser
    fn(stream[: 64 * chunk], chunk)  # imports and first calls, untimed
    c0 = time.process_time()
    frames = fn(stream, chunk)
    cpu = time.process_time() - c0
    print(json.dumps({"frames": frames, "cpu": cpu}))


def run_child(which: str, path: str, chunk: int) -> dict:
    out = subprocess.run(
        [sys.executable, __file__, "--child", which, "--file", path, "--chunks", str(chunk)],
        check=True,
        capture_output=True,
        text=True,
        env={**os.environ, "OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1"},
    )
    return json.loads(out.stdout.strip().splitlines()[-1])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=200_000)
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--chunks", default="4096,65536", help="chunk sizes in bytes, comma-separated")
    ap.add_argument("--figures", default=None, help="write the figures to this JSON file ({name: value})")
    ap.add_argument("--child", choices=("reader", "numpy"), help=argparse.SUPPRESS)
    ap.add_argument("--file", help=argparse.SUPPRESS)
    args = ap.parse_args()
    chunks = [int(c) for c in args.chunks.split(",")]
    if args.child:
        child(args.child, args.file, chunks[0])
        return

    stream = make_stream(args.frames)
    load = os.getloadavg()
    figures: dict[str, float | int | str] = {"frames": args.frames, "rounds": args.rounds}
    with tempfile.TemporaryDirectory() as tmp:
        path = str(Path(tmp) / "stream.bin")
        Path(path).write_bytes(stream)
        print(
            f"stream: {args.frames} frames x {K} channels, {len(stream) / 1e6:.1f} MB; "
            f"fresh process per figure, {args.rounds} rounds interleaved, medians"
        )
        print(f"{'chunk':>7} {'numpy fromstring':>18} {'StreamReader':>14} {'ratio':>7} {'ratio range':>15}")
        for chunk in chunks:
            rates: dict[str, list[float]] = {"reader": [], "numpy": []}
            ratios = []
            for r in range(args.rounds):
                order = ("reader", "numpy") if r % 2 == 0 else ("numpy", "reader")
                got = {w: run_child(w, path, chunk) for w in order}
                for w, g in got.items():
                    if g["frames"] != args.frames:
                        raise SystemExit(f"{w} parsed {g['frames']} frames of {args.frames}")
                    rates[w].append(g["frames"] / g["cpu"])
                ratios.append(got["numpy"]["cpu"] / got["reader"]["cpu"])
            reader_rate, numpy_rate = statistics.median(rates["reader"]), statistics.median(rates["numpy"])
            ratio = statistics.median(ratios)
            print(
                f"{chunk:>7} {numpy_rate:>12,.0f} fr/s {reader_rate:>8,.0f} fr/s {ratio:>6.2f}x "
                f"{min(ratios):>6.2f}-{max(ratios):.2f}x"
            )
            figures[f"{chunk} B reader frames per s"] = round(reader_rate)
            figures[f"{chunk} B numpy frames per s"] = round(numpy_rate)
            figures[f"{chunk} B reader over numpy"] = round(ratio, 2)
            figures[f"{chunk} B reader over numpy lowest round"] = round(min(ratios), 2)
            figures[f"{chunk} B reader over numpy highest round"] = round(max(ratios), 2)
    load_after = os.getloadavg()
    print("ratio: the baseline's CPU time over the reader's (above 1: the reader is faster)")
    print(f"load average before {load[0]:.2f}, after {load_after[0]:.2f} (2 CPUs)")
    figures["load average"] = round(max(load[0], load_after[0]), 1)
    figures["command"] = command_line("bench_reader.py", sys.argv[1:])
    if args.figures:
        Path(args.figures).write_text(json.dumps(figures, indent=1, sort_keys=True) + "\n")


if __name__ == "__main__":
    main()
