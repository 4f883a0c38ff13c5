"""A small rig firmware on a pseudo-terminal, written from the wire protocol document alone.

It shares no code with ``labcli.core.wire`` (its own checksum loop, its own line
formatting), so tests that drive labcli against it check the host against an
independent reading of the protocol, the way a third-party microcontroller
sketch would.

    fw = FakeFirmware(rate=500)
    with fw:                      # thread starts; fw.port is e.g. /dev/pts/7
        dev = Device.open(fw.port, boot_wait=0)

Fault injection: ``faults`` maps a data-line index (0 = first line after
START) to a list of events emitted *before* that line:

* ``"corrupt"``   the frame for the next seq, one checksum digit wrong
  (its seq is used up, so the host also counts it lost);
* ``"truncated"`` the frame for the next seq cut before ``*HH`` (seq used up);
* ``"garbage"``   a line of junk; ``"log"`` a ``#`` line;
* ``"overlong"``  300 bytes without a newline, then ``\\n``;
* ``("gap", m)``  skip ``m`` sequence numbers (frames lost on the wire).

A misbehaving clock or stream: ``clock_scale`` stretches ``t_us`` (0.1: the timer runs ten
times fast, so frames come ten times closer by the rig's own clock than the rate it
confirmed); ``clock_back_at`` restarts ``t_us`` from 0 at that line index, as a board that
reset mid-stream; ``junk_only`` sends lines of junk in place of every frame.
"""

from __future__ import annotations

import os
import pty
import select
import threading
import time
import tty

REFERENCE_CHANNELS = ("P_L1", "P_R1", "P_L2", "P_R2", "POT1", "POT2")
# Constant counts per channel: the host's mean is then known exactly.
REFERENCE_COUNTS = (1556, 1560, 1549, 1551, 2048, 2300)


def xor_checksum(body: bytes) -> int:
    x = 0
    for byte in body:
        x ^= byte
    return x


def data_line(seq: int, t_us: int, values, eol: bytes = b"\n") -> bytes:
    body = "D,%d,%d,%s" % (seq % 2**32, t_us % 2**32, ",".join(str(v) for v in values))
    raw = body.encode("ascii")
    return b"$" + raw + (f"*{xor_checksum(raw):02x}").encode("ascii") + eol


class FakeFirmware:
    def __init__(
        self,
        *,
        channels=REFERENCE_CHANNELS,
        counts=REFERENCE_COUNTS,
        device: str = "fake-rig",
        firmware: str = "0.9",
        rate: float = 200.0,
        max_rate: float = 2000.0,
        silent: bool = False,
        babble: bytes | None = None,
        boot_delay: float = 0.0,
        crlf: bool = False,
        faults: dict | None = None,
        start_seq: int = 0,
        max_frames: int | None = None,
        id_line: str | None = None,
        clock_scale: float = 1.0,
        clock_back_at: int | None = None,
        junk_only: bool = False,
    ) -> None:
        self.clock_scale = clock_scale
        self.clock_back_at = clock_back_at
        self.junk_only = junk_only
        self.channels = tuple(channels)
        self.counts = tuple(counts)
        self.device = device
        self.firmware = firmware
        self.rate = float(rate)
        self.max_rate = max_rate
        self.silent = silent
        self.babble = babble
        self.boot_delay = boot_delay
        self.eol = b"\r\n" if crlf else b"\n"
        self.faults = dict(faults or {})
        self.start_seq = start_seq
        self.max_frames = max_frames
        self.id_line = id_line
        self.commands: list[str] = []  # every command line received, in order
        self.frames_sent = 0
        self.streaming = False
        self._t0 = 0.0
        self._line_index = 0
        self._seq = start_seq
        self._master, self._slave = pty.openpty()
        tty.setraw(self._slave)  # no echo or newline mangling before the host configures the port
        self.port = os.ttyname(self._slave)
        self._stop = threading.Event()
        self._unplug = threading.Event()
        self._thread = threading.Thread(target=self._run, name="fake-firmware", daemon=True)
        self._born = time.monotonic()

    # -- lifecycle ----------------------------------------------------------

    def __enter__(self) -> FakeFirmware:
        self.start()
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def start(self) -> None:
        self._born = time.monotonic()
        self._thread.start()

    def unplug(self) -> None:
        """Close the master side, as a cable pulled mid-stream."""
        self._unplug.set()
        self._thread.join(2)

    def close(self) -> None:
        self._stop.set()
        if self._thread.is_alive():
            self._thread.join(2)
        for fd in (self._master, self._slave):
            try:
                os.close(fd)
            except OSError:
                pass
        self._master = self._slave = -1

    # -- firmware loop ---------------------------------------------------------

    def _write(self, data: bytes) -> None:
        view = memoryview(data)
        while view:
            n = os.write(self._master, view)
            view = view[n:]

    def _run(self) -> None:
        inbuf = b""
        try:
            while not self._stop.is_set():
                if self._unplug.is_set():
                    os.close(self._master)
                    self._master = -1
                    return
                ready, _, _ = select.select([self._master], [], [], 0.003)
                if ready:
                    inbuf += os.read(self._master, 4096)
                    while b"\n" in inbuf:
                        raw, inbuf = inbuf.split(b"\n", 1)
                        command = raw.strip().decode("ascii", "replace")
                        self.commands.append(command)
                        self._answer(command)
                if self.streaming:
                    due = int((time.monotonic() - self._t0) * self.rate) + 1
                    if self.max_frames is not None:
                        due = min(due, self.max_frames)
                    self._emit(due)
        except OSError:
            return  # the host side went away

    def _emit(self, due: int) -> None:
        out = []
        while self._line_index < due:
            for event in self.faults.get(self._line_index, ()):
                chunk, used = self._fault(event, self._seq, self._line_index)
                out.append(chunk)
                self._seq += used
            ticks = self._line_index
            if self.clock_back_at is not None and ticks >= self.clock_back_at:
                ticks -= self.clock_back_at
            t_us = int(ticks * 1e6 / self.rate * self.clock_scale)
            if self.junk_only:
                out.append(b"\x13garbled %d\xff" % self._line_index + self.eol)
            else:
                out.append(data_line(self._seq, t_us, self.counts, self.eol))
            self._seq += 1
            self._line_index += 1
            self.frames_sent += 1
        if out:
            self._write(b"".join(out))

    def _fault(self, event, seq: int, line_index: int) -> tuple[bytes, int]:
        t_us = int(line_index * 1e6 / self.rate)
        if event == "corrupt":
            line = data_line(seq, t_us, self.counts, b"")
            last = line[-1:]
            bad = b"0" if last != b"0" else b"1"
            return line[:-1] + bad + self.eol, 1
        if event == "truncated":
            line = data_line(seq, t_us, self.counts, b"")
            return line[: len(line) // 2] + self.eol, 1
        if event == "garbage":
            return b"\x00\xffnoise on the line" + self.eol, 0
        if event == "log":
            return b"# firmware note at line %d" % line_index + self.eol, 0
        if event == "overlong":
            return b"x" * 300 + self.eol, 0
        if isinstance(event, tuple) and event[0] == "gap":
            return b"", int(event[1])
        raise ValueError(f"unknown fault {event!r}")

    def _answer(self, command: str) -> None:
        if self.silent:
            return
        if time.monotonic() - self._born < self.boot_delay:
            return  # still in the bootloader after the DTR reset
        if self.babble is not None:
            self._write(self.babble)
            return
        if command == "ID?":
            text = self.id_line or ",".join(("ID", self.device, self.firmware) + self.channels)
            reply = text
        elif command.startswith("RATE "):
            try:
                hz = float(command.split()[1])
            except (IndexError, ValueError):
                reply = "ERR RATE needs a number"
            else:
                if 0 < hz <= self.max_rate:
                    self.rate = float(round(hz))  # a timer only does whole hertz
                    reply = "OK RATE %d" % self.rate
                else:
                    reply = "ERR rate out of range 1-%d" % self.max_rate
        elif command == "START":
            reply = "OK START"
            self.streaming = True
            self._t0 = time.monotonic()
            self._line_index = 0
            self._seq = self.start_seq
        elif command == "STOP":
            if self.streaming:
                # One frame is always in flight when STOP arrives.
                self._emit(self._line_index + 1)
            self.streaming = False
            reply = "OK STOP"
        else:
            reply = "ERR unknown command"
        self._write(reply.encode("ascii") + self.eol)
