"""End to end over a pseudo-terminal: the simulated rig at 1 kHz x 6 channels.

Run:  python tests/benchmarks/bench_link.py [--seconds 60] [--baseline-seconds 10] [--rate 1000]
                                       [--faults KIND:RATE[@X],...]

The rig runs in its own process (``labcli sim --pty``, wall clock), as a
microcontroller would; this process is the host.  Measured per path, over the
same pty in the same run:

* labcli: ``Device`` (the stream reader, chunked reads) for ``--seconds``;
* baseline: pyserial ``readline()`` + :func:`labcli.core.wire.parse_line` per line,
  what a first host usually looks like, for ``--baseline-seconds``.

Every wait has a deadline: the rig's start (``START_S``), each read (0.25 s),
the reply to ``STOP`` (``STOP_REPLY_S`` after it was sent, however far behind the
host is) and the rig's exit; a missing reply is reported, never waited for.  The
run fails (exit 1) when the labcli path loses frames without faults.  The simulator takes rates up to 50 kHz
(:data:`labcli.core.sim.firmware.RATE_MAX`), e.g. ``--rate 20000``.

Reported: frames, frames/s, lost frames (must be 0 without faults), and the
host's CPU share (``time.process_time`` over wall time), plus the ratio of CPU
per frame labcli / baseline, and the rig process's own CPU share
(``getrusage(RUSAGE_CHILDREN)``).  With ``--faults`` only the labcli path runs
and its counters are compared with what the rig reports it injected.
"""

from __future__ import annotations

import argparse
import re
import resource
import select
import signal
import subprocess
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

import serial  # noqa: E402

from labcli.core.device import Device  # noqa: E402
from labcli.core.wire import Frame, Noise, parse_line  # noqa: E402

START_S = 15.0  # the rig process prints its port within this (imports on a busy machine)
STOP_REPLY_S = 5.0  # OK STOP arrives within this after STOP, the backlog drained
EXIT_S = 10.0  # the rig process exits within this after SIGINT


def start_rig(rate: float, faults: str) -> tuple[subprocess.Popen, str]:
    cmd = [sys.executable, "-m", "labcli", "sim", "--pty", "--seed", "1", "--rate", f"{rate:g}"]
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


def run_readline(path: str, rate: float, seconds: float) -> dict:
    port = serial.Serial(path, timeout=0.25)
    try:
        port.write(f"RATE {rate:g}\n".encode())
        port.reset_input_buffer()
        c0, w0 = time.process_time(), time.monotonic()
        port.write(b"START\n")
        frames = lost = bad = malformed = 0
        last = None
        stop_deadline = None  # set when STOP is written
        stop_reply = False
        while True:
            now = time.monotonic()
            if stop_deadline is None and now - w0 >= seconds:
                port.write(b"STOP\n")
                stop_deadline = now + STOP_REPLY_S
            elif stop_deadline is not None and now > stop_deadline:
                break  # the reply never came: reported below, not waited for
            line = port.readline()
            p = parse_line(line, 6)
            if isinstance(p, Frame):
                frames += 1
                if last is not None:
                    lost += (p.seq - last - 1) % (1 << 32)
                last = p.seq
            elif isinstance(p, Noise) and line:
                bad += p.reason == "bad checksum"
                malformed += p.reason != "bad checksum"
            elif stop_deadline is not None and line.startswith(b"OK STOP"):
                stop_reply = True
                break
        cpu, wall = time.process_time() - c0, time.monotonic() - w0
    finally:
        port.close()
    return {
        "path": "pyserial readline",
        "wall": wall,
        "cpu": cpu,
        "frames": frames,
        "lost": lost,
        "bad_checksum": bad,
        "malformed": malformed,
        "overlong": 0,
        "stop_reply": stop_reply,
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=60.0, help="labcli path duration, s")
    ap.add_argument("--baseline-seconds", type=float, default=10.0, help="readline baseline duration, s (0: skip)")
    ap.add_argument("--rate", type=float, default=1000.0, help="frames per second")
    ap.add_argument("--faults", default="", help="fault specification for the rig (labcli path only)")
    a = ap.parse_args()

    t_start = time.monotonic()
    proc, path = start_rig(a.rate, a.faults)
    rows = []
    try:
        rows.append(run_labcli(path, a.rate, a.seconds))
        if a.baseline_seconds > 0 and not a.faults:
            rows.append(run_readline(path, a.rate, a.baseline_seconds))
    finally:
        out = stop_rig(proc)
    rig_wall = time.monotonic() - t_start
    rig_cpu = resource.getrusage(resource.RUSAGE_CHILDREN)
    rig_cpu_s = rig_cpu.ru_utime + rig_cpu.ru_stime

    print(f"Rig wire link over a pty, {a.rate:g} Hz x 6 channels{', faults ' + a.faults if a.faults else ''}")
    print(
        f"{'path':<18} {'wall s':>7} {'frames':>8} {'frames/s':>9} {'lost':>6} {'bad cs':>7} "
        f"{'malformed':>9} {'CPU s':>7} {'CPU share':>9} {'CPU us/frame':>12}"
    )
    for r in rows:
        per = 1e6 * r["cpu"] / r["frames"] if r["frames"] else float("nan")
        r["per"] = per
        print(
            f"{r['path']:<18} {r['wall']:7.1f} {r['frames']:8d} {r['frames'] / r['wall']:9.1f} {r['lost']:6d} "
            f"{r['bad_checksum']:7d} {r['malformed']:9d} {r['cpu']:7.2f} {100 * r['cpu'] / r['wall']:8.2f}% "
            f"{per:12.1f}"
        )
    if len(rows) == 2:
        print(f"CPU per frame, labcli / readline baseline: {rows[0]['per'] / rows[1]['per']:.3f}")
    print(
        f"rig process (simulator, not the host): {rig_cpu_s:.2f} s CPU over {rig_wall:.1f} s "
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
        # Reported, not waited for: a host slower than the link leaves a backlog behind the reply.
        print(f"readline baseline: no 'OK STOP' within {STOP_REPLY_S:g} s of STOP (it fell behind the link)")
    if not a.faults and rows[0]["lost"]:
        print("FRAMES LOST without faults")
        sys.exit(1)


if __name__ == "__main__":
    main()
