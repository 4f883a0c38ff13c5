"""End to end over a pseudo-terminal: the simulated rig at 1 kHz x 6 channels.

Run:  python tests/benchmarks/bench_link.py [--seconds 10] [--rounds 5] [--rate 1000]
                                       [--faults KIND:RATE[@X],...] [--figures FILE] [--realism kind] [--seeds 1]

The rig runs in its own process (``labcli sim --pty --seed S --realism R``, wall clock; the kind
rig, seed 1, by default, on which the docs' figures were measured: rig_options.py), as a
microcontroller would; this process is the host.  Measured per path, over the
same pty in the same run:

* labcli: ``Device`` (the stream reader, chunked reads);
* baseline: a raw ``port.read(in_waiting)`` loop and the numpy parser of
  ``bench_reader.py`` (non-digits blanked, one ``fromstring`` per read; no checksum, no
  noise handling), the floor a host written by hand could reach.

Each path runs in a fresh process (``--child``) for ``--seconds``; the two alternate for
``--rounds`` rounds (the order flipping every round) and each figure is the median.  The
host's CPU is the child's ``time.process_time`` over its reading loop.

Every wait has a deadline: the rig's start (``START_S``), each read (0.25 s),
the reply to ``STOP`` (``STOP_REPLY_S`` after it was sent, however far behind the
host is) and the rig's exit; a missing reply is reported, never waited for.  The
run fails (exit 1) when the labcli path loses frames without faults.  The simulator takes rates up to 50 kHz
(:data:`labcli.core.sim.firmware.RATE_MAX`), e.g. ``--rate 20000``.

Reported: frames, frames/s, lost frames (must be 0 without faults), and the
host's CPU share (``time.process_time`` over wall time), plus the ratio of CPU
per frame labcli / baseline (median of the rounds' ratios; the target is 2 or less),
and the machine's load average.  With ``--faults`` only the labcli path runs
and its counters are compared with what the rig reports it injected.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import resource
import select
import signal
import statistics
import subprocess
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))
sys.path.insert(0, str(Path(__file__).resolve().parent))

import serial  # noqa: E402
from fresh import command_line  # noqa: E402
from rig_options import add_rig_options, bench_parser  # noqa: E402

from labcli.core.device import Device  # noqa: E402

START_S = 15.0  # the rig process prints its port within this (imports on a busy machine)
STOP_REPLY_S = 5.0  # OK STOP arrives within this after STOP, the backlog drained
EXIT_S = 10.0  # the rig process exits within this after SIGINT


def start_rig(rate: float, faults: str, seed: int = 1, realism: str = "kind") -> tuple[subprocess.Popen, str]:
    cmd = [sys.executable, "-m", "labcli", "sim", "--pty", "--seed", str(seed), "--realism", realism]
    cmd += ["--rate", f"{rate:g}"]
    if faults:
        cmd += ["--faults", faults]
    # stdin from /dev/null: the rig's operator console sees the end of its input at once.
    proc = subprocess.Popen(
        cmd, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE, text=True, cwd=Path(__file__).resolve().parents[2]
    )
    ready, _, _ = select.select([proc.stdout], [], [], START_S)
    line = proc.stdout.readline() if ready else ""
    m = re.match(r"Simulated rig on (\S+) ", line)
    if not m:
        stop_rig(proc)
        raise SystemExit(f"the simulated rig did not start within {START_S:g} s: {line!r}")
    return proc, m.group(1)


def stop_rig(proc: subprocess.Popen) -> str:
    """Stop the rig process (SIGINT, then kill after ``EXIT_S``); its remaining output."""
    if proc.poll() is None:
        proc.send_signal(signal.SIGINT)
    try:
        out, _ = proc.communicate(timeout=EXIT_S)
    except subprocess.TimeoutExpired:
        proc.kill()
        out, _ = proc.communicate()
        print(f"the rig process did not exit within {EXIT_S:g} s of SIGINT: killed")
    return out or ""


def run_labcli(path: str, rate: float, seconds: float) -> dict:
    with Device.open(path, boot_wait=0, timeout=2.0) as dev:
        dev.set_rate(rate)
        c0, w0 = time.process_time(), time.monotonic()
        dev.start()
        frames = 0
        while time.monotonic() - w0 < seconds:
            frames += len(dev.read(timeout=0.25))
        frames += len(dev.stop())
        cpu, wall = time.process_time() - c0, time.monotonic() - w0
        c = dev.counters
    return {
        "path": "labcli Device",
        "wall": wall,
        "cpu": cpu,
        "frames": frames,
        "lost": c["lost"],
        "bad_checksum": c["bad_checksum"],
        "malformed": c["malformed"],
        "overlong": c["overlong"],
    }


def run_raw_numpy(path: str, rate: float, seconds: float) -> dict:
    """Raw reads and the one-``fromstring`` parser: what the reader is held to."""
    from bench_reader import K, numpy_rows  # the same parser as bench_reader's baseline

    port = serial.Serial(path, timeout=0.25)
    try:
        port.write(f"RATE {rate:g}\n".encode())
        time.sleep(0.2)
        port.reset_input_buffer()
        c0, w0 = time.process_time(), time.monotonic()
        port.write(b"START\n")
        frames = lost = 0
        last = None
        pending = b""
        stop_deadline = None  # set when STOP is written
        stop_reply = False
        while True:
            now = time.monotonic()
            if stop_deadline is None and now - w0 >= seconds:
                port.write(b"STOP\n")
                stop_deadline = now + STOP_REPLY_S
            elif stop_deadline is not None and now > stop_deadline:
                break  # the reply never came: reported below, not waited for
            buf = pending + port.read(port.in_waiting or 1)
            cut = buf.rfind(b"\n") + 1
            pending = buf[cut:]
            if not cut:
                continue
            block = buf[:cut]
            if b"O" in block or b"#" in block:  # a reply ("OK START", "OK STOP") or a log line
                stop_reply = stop_deadline is not None and b"OK STOP" in block
                block = b"".join(x for x in block.splitlines(True) if x.startswith(b"$"))
            rows = numpy_rows(block, K)
            if len(rows):
                seq = rows[:, 0]
                frames += len(seq)
                first = int(seq[0]) if last is None else last + 1
                lost += int(seq[-1]) - first + 1 - len(seq)
                last = int(seq[-1])
            if stop_reply:
                break
        cpu, wall = time.process_time() - c0, time.monotonic() - w0
    finally:
        port.close()
    return {
        "path": "raw read + numpy",
        "wall": wall,
        "cpu": cpu,
        "frames": frames,
        "lost": lost,
        "bad_checksum": 0,
        "malformed": 0,
        "overlong": 0,
        "stop_reply": stop_reply,
    }


def child(which: str, path: str, rate: float, seconds: float) -> None:
    row = run_labcli(path, rate, seconds) if which == "labcli" else run_raw_numpy(path, rate, seconds)
    print(json.dumps(row))


def run_child(which: str, path: str, rate: float, seconds: float) -> dict:
    cmd = [sys.executable, __file__, "--child", which, "--port", path, "--rate", f"{rate:g}"]
    out = subprocess.run(cmd + ["--seconds", f"{seconds:g}"], check=True, capture_output=True, text=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


def main() -> None:
    ap = bench_parser(__doc__)
    ap.add_argument("--seconds", type=float, default=10.0, help="duration of each path in each round, s")
    add_rig_options(ap, realism="kind", seeds="1", one=True)
    ap.add_argument("--rounds", type=int, default=5, help="rounds, each path once a round (fresh processes)")
    ap.add_argument("--rate", type=float, default=1000.0, help="frames per second")
    ap.add_argument("--faults", default="", help="fault specification for the rig (labcli path only, one round)")
    ap.add_argument("--figures", default=None, help="write the figures to this JSON file ({name: value})")
    ap.add_argument("--child", choices=("labcli", "raw"), help=argparse.SUPPRESS)
    ap.add_argument("--port", help=argparse.SUPPRESS)
    a = ap.parse_args()
    if a.child:
        child(a.child, a.port, a.rate, a.seconds)
        return

    t_start = time.monotonic()
    load = os.getloadavg()
    proc, path = start_rig(a.rate, a.faults, a.seeds[0], a.realism)
    rounds: list[list[dict]] = []
    try:
        for r in range(1 if a.faults else a.rounds):
            order = ("labcli",) if a.faults else ("labcli", "raw") if r % 2 == 0 else ("raw", "labcli")
            got = {w: run_child(w, path, a.rate, a.seconds) for w in order}
            rounds.append([got[w] for w in ("labcli", "raw") if w in got])
    finally:
        out = stop_rig(proc)
    rig_wall = time.monotonic() - t_start
    rig_cpu = resource.getrusage(resource.RUSAGE_CHILDREN)
    rig_cpu_s = rig_cpu.ru_utime + rig_cpu.ru_stime

    print(f"Rig wire link over a pty, {a.rate:g} Hz x 6 channels{', faults ' + a.faults if a.faults else ''}")
    print(f"{len(rounds)} round(s) of {a.seconds:g} s per path, fresh processes, interleaved; medians")
    print(
        f"{'path':<18} {'wall s':>7} {'frames':>8} {'frames/s':>9} {'lost':>6} {'bad cs':>7} "
        f"{'malformed':>9} {'CPU s':>7} {'CPU share':>9} {'CPU us/frame':>12}"
    )
    rows = []
    for col in range(len(rounds[0])):
        runs = [rd[col] for rd in rounds]
        for rr in runs:
            rr["per"] = 1e6 * rr["cpu"] / rr["frames"] if rr["frames"] else float("nan")
        r = dict(runs[0])
        for key in ("wall", "cpu", "frames", "per"):
            r[key] = statistics.median(rr[key] for rr in runs)
        for key in ("lost", "bad_checksum", "malformed", "overlong"):
            r[key] = max(rr[key] for rr in runs)
        r["stop_reply"] = all(rr.get("stop_reply", True) for rr in runs)
        rows.append(r)
        print(
            f"{r['path']:<18} {r['wall']:7.1f} {r['frames']:8.0f} {r['frames'] / r['wall']:9.1f} {r['lost']:6d} "
            f"{r['bad_checksum']:7d} {r['malformed']:9d} {r['cpu']:7.2f} {100 * r['cpu'] / r['wall']:8.2f}% "
            f"{r['per']:12.1f}"
        )
    figures: dict[str, float | str] = {}
    if len(rows) == 2:
        ratios = [rd[0]["per"] / rd[1]["per"] for rd in rounds]
        ratio = statistics.median(ratios)
        print(
            f"CPU per frame, labcli / raw read + numpy parser: {ratio:.2f} "
            f"(rounds {min(ratios):.2f}-{max(ratios):.2f}; target 2 or less)"
        )
        figures = {"labcli over raw numpy": round(ratio, 2), "labcli us per frame": round(rows[0]["per"], 1)}
        figures["raw numpy us per frame"] = round(rows[1]["per"], 1)
    load_after = os.getloadavg()
    print(f"load average before {load[0]:.2f}, after {load_after[0]:.2f} (2 CPUs)")
    print(
        f"rig process (simulator, not the host) and the children: {rig_cpu_s:.2f} s CPU over {rig_wall:.1f} s "
        f"({100 * rig_cpu_s / rig_wall:.1f} %)"
    )
    faults_line = next((x for x in out.splitlines() if x.startswith("Faults: ")), "")
    if faults_line:
        print(faults_line)
        m = re.search(r"must count (\d+) bad checksum, (\d+) malformed, (\d+) overlong, (\d+) lost", faults_line)
        r = rows[0]
        got = (r["bad_checksum"], r["malformed"], r["overlong"], r["lost"])
        want = tuple(int(x) for x in m.groups())
        print(f"host counters {'match' if got == want else 'DIFFER FROM'} the injected faults: {got} vs {want}")
    if not all(r.get("stop_reply", True) for r in rows):
        print(f"baseline: no 'OK STOP' within {STOP_REPLY_S:g} s of STOP (it fell behind the link)")
    if a.figures and figures:
        figures["load average"] = round(max(load[0], load_after[0]), 1)
        figures["command"] = command_line("bench_link.py", sys.argv[1:])
        Path(a.figures).write_text(json.dumps(figures, indent=1, sort_keys=True) + "\n")
    if not a.faults and rows[0]["lost"]:
        print("FRAMES LOST without faults")
        sys.exit(1)


if __name__ == "__main__":
    main()
