"""Throughput of the stream reader against a naive line-by-line baseline.

Run:  python tests/benchmarks/bench_reader.py [--frames N] [--repeat R] [--chunk BYTES]

Both sides parse the same bytes: N data lines of 6 integer channels (the
reference rig), with ``\\r\\n`` on one line in 50 and a log line every 500, the
way a real firmware mixes them.  The reader gets the stream in fixed-size
chunks as from ``serial.read(in_waiting)``; the baseline is what a first
version usually looks like: ``readline()`` from a BytesIO, ``split``, ``int``
and a per-byte XOR loop for the checksum.  Best of R runs for each; the ratio
is measured in the same run on the same machine.
"""

from __future__ import annotations

import argparse
import io
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

import numpy as np  # noqa: E402

from labcli.core.wire import StreamReader, format_frame, format_log  # noqa: E402


def make_stream(n: int, seed: int = 0) -> bytes:
    rng = np.random.default_rng(seed)
    counts = rng.integers(0, 4096, size=(n, 6))
    out = []
    for i in range(n):
        line = format_frame(i, (i * 5000) % (1 << 32), counts[i].tolist())
        if i % 50 == 0:
            line = line[:-1] + b"\r\n"
        out.append(line)
        if i % 500 == 499:
            out.append(format_log(f"heartbeat {i}"))
    return b"".join(out)


def naive(stream: bytes) -> int:
    """Line by line, as with pyserial's readline(); returns the frame count."""
    f = io.BytesIO(stream)
    frames = 0
    rows = []
    while True:
        line = f.readline()
        if not line:
            break
        line = line.rstrip(b"\r\n")
        if not line.startswith(b"$"):
            continue
        body, _, hh = line[1:].partition(b"*")
        x = 0
        for c in body:
            x ^= c
        try:
            if x != int(hh, 16):
                continue
            fields = body.split(b",")
            rows.append((int(fields[1]), int(fields[2]), [float(v) for v in fields[3:]]))
        except ValueError:
            continue
        frames += 1
    return frames


def reader(stream: bytes, chunk: int) -> int:
    r = StreamReader(n_channels=6)
    frames = 0
    for i in range(0, len(stream), chunk):
        frames += len(r.feed(stream[i : i + chunk]))
    assert r.counters["bad_checksum"] == r.counters["malformed"] == 0
    return frames


def best_of(fns, repeat: int) -> list[tuple[float, int]]:
    """Best time of each function; the runs alternate so a busy machine slows both alike."""
    best = [float("inf")] * len(fns)
    results = [0] * len(fns)
    for _ in range(repeat):
        for i, fn in enumerate(fns):
            t0 = time.perf_counter()
            results[i] = fn()
            best[i] = min(best[i], time.perf_counter() - t0)
    return list(zip(best, results, strict=False))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=200_000)
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--chunk", type=int, default=4096)
    args = ap.parse_args()

    stream = make_stream(args.frames)
    (t_naive, n_naive), (t_fast, n_fast) = best_of(
        [lambda: naive(stream), lambda: reader(stream, args.chunk)], args.repeat
    )
    if n_naive != args.frames or n_fast != args.frames:
        raise SystemExit(f"frame counts disagree: naive {n_naive}, reader {n_fast}, expected {args.frames}")
    mb = len(stream) / 1e6
    print(
        f"stream: {args.frames} frames x 6 channels, {mb:.1f} MB, fed in {args.chunk}-byte chunks, best of {args.repeat}"
    )
    print(f"naive readline baseline : {n_naive / t_naive:12,.0f} frames/s  ({mb / t_naive:6.1f} MB/s)")
    print(f"StreamReader.feed       : {n_fast / t_fast:12,.0f} frames/s  ({mb / t_fast:6.1f} MB/s)")
    print(f"speed-up                : {t_naive / t_fast:12.1f} x")


if __name__ == "__main__":
    main()
