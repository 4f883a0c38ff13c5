"""Firmware of the simulated rig: the device side of the rig wire protocol, version 1.1 (or 1.0).

:class:`Firmware` turns host command bytes into reply bytes and, while
streaming, turns the rig's ADC samples into data lines.  It knows nothing of
time sources: the ``sim://`` port (virtual or wall clock) and the pty server
decide how many frames are due and ask for them with :meth:`Firmware.frames`.

Commands (one per line, ``\\r`` tolerated): ``ID?``, ``RATE <hz>`` (1..50000),
``START``, ``STOP``, and those of wire protocol 1.1 (``CAPS?``, ``VALVE``, ``PMAX``: the
valves, the pressure limit and the event lines of :mod:`.valves`); anything else is answered
with ``ERR ...``.  ``version="1.0"`` makes a 1.0 board (``sim://?fw=1.0``).  ``seq`` counts
data lines since power-up and ``t_us`` is the rig's clock, both unsigned 32-bit
and wrapping.

A :class:`~labcli.core.sim.faults.FaultInjector` (``faults=``) spoils the data
lines the way a noisy link does; without one the output is exact.
"""

from __future__ import annotations

import numpy as np

from ..wire import MAX_LINE, U32, checksum, format_log
from .valves import BoardValves

IDLE_HZ = 50.0  # an idle board's sampling for its checks (the AVR firmware's idle loop)

RATE_MIN = 1.0
# As far as the host's stream reader goes: it spends 6-8 us of CPU per 6-channel frame
# (tests/benchmarks/bench_link.py), so 50 kHz (2.5 MB/s over a pty) takes a third to two
# fifths of one core, a USB-native board's link on a lab PC; beyond it a reader sharing
# its core loses frames.  Links of 10-50 kHz can be tested; the reference firmware on an
# ATmega328P stops far lower (its UART and ADC: firmware/src/config.h).
RATE_MAX = 50000.0
# A firmware whose timer is set wrong streams at rate_factor times the rate it confirms
# (``sim://?ratefactor=X``), its own clock stamping the frames as they are made.
FACTOR_MIN, FACTOR_MAX = 0.01, 100.0
_OVERLONG = f"ERR line longer than {MAX_LINE} bytes\n".encode()


class Firmware:
    """Device-side protocol state machine over a rig (see :mod:`labcli.core.sim`)."""

    def __init__(
        self, rig, rate_hz: float = 200.0, faults=None, rate_factor: float = 1.0, version: str = "1.1"
    ) -> None:
        if not RATE_MIN <= rate_hz <= RATE_MAX:
            raise ValueError(f"rate must be within {RATE_MIN:g}..{RATE_MAX:g} Hz")
        if not FACTOR_MIN <= rate_factor <= FACTOR_MAX:
            raise ValueError(f"rate factor must be within {FACTOR_MIN:g}..{FACTOR_MAX:g}")
        self.rig = rig
        self.rate_hz = float(rate_hz)  # the rate set and confirmed (RATE, OK RATE)
        self.rate_factor = float(rate_factor)
        self.seq = 0
        self.count = 0  # frames made since power-up (not wrapped): the fault plan's frame number
        self.faults = faults
        self.stall: tuple[float, int] | None = None  # (seconds, frames not made), see frames()
        self.streaming = False
        self._pending = bytearray()
        self.board = BoardValves(rig, version)
        self.version = version
        self._seen: tuple[np.ndarray, np.ndarray] | None = None  # the last frames sampled: (t_us, counts)

    @property
    def stream_hz(self) -> float:
        """Frames per second of the rig's own clock: the rate confirmed, times the timer's error."""
        return self.rate_hz * self.rate_factor

    # ------------------------------------------------------------ host -> device

    def banner(self) -> bytes:
        """The log line printed at power-up."""
        return format_log(f"{self.rig.device} {self.firmware_version} ready, {len(self.rig.channels)} channels")

    @property
    def firmware_version(self) -> str:
        """What ``ID?`` names as the firmware: the rig's, or 1.0 for a 1.0 board."""
        return "1.0" if self.version == "1.0" else self.rig.firmware

    def receive(self, data: bytes) -> bytes:
        """Feed bytes written by the host; return the reply lines they cause."""
        self._pending += data
        out = bytearray()
        while True:
            nl = self._pending.find(b"\n")
            if nl < 0:
                if len(self._pending) > MAX_LINE:
                    self._pending.clear()
                    out += _OVERLONG
                break
            line = bytes(self._pending[:nl])
            del self._pending[: nl + 1]
            out += self.command(line)
        return bytes(out)

    def command(self, line: bytes) -> bytes:
        """Answer one command line (without its ``\\n``)."""
        if line.endswith(b"\r"):
            line = line[:-1]
        if len(line) > MAX_LINE:
            return _OVERLONG
        text = line.decode("ascii", "replace").strip()
        if not text:
            return b""
        word, _, arg = text.partition(" ")
        arg = arg.strip()
        if text == "ID?":
            return ("ID," + ",".join([self.rig.device, self.firmware_version, *self.rig.channels]) + "\n").encode()
        if word == "RATE":
            try:
                hz = float(arg)
            except ValueError:
                return f"ERR RATE needs a number of Hz, got '{arg}'\n".encode()
            if not RATE_MIN <= hz <= RATE_MAX:
                return f"ERR RATE must be within {RATE_MIN:g}..{RATE_MAX:g} Hz, got {arg}\n".encode()
            self.rate_hz = hz
            return f"OK RATE {hz:g}\n".encode()
        if text == "START":
            self.streaming = True
            return b"OK START\n" + format_log(f"streaming {len(self.rig.channels)} channels at {self.rate_hz:g} Hz")
        if text == "STOP":
            self.streaming = False
            held = self.faults.flush() if self.faults is not None else b""
            return held + b"OK STOP\n"
        reply = self.board.command(word, arg, self._now_us())
        if reply is not None:
            return reply
        shown = text if len(text) <= 40 else text[:40] + "..."
        return f"ERR unknown command '{shown}'\n".encode("ascii", "replace")

    # ------------------------------------------------------------ device -> host

    def _now_us(self) -> int:
        return int(round(self.rig.time_s * 1e6)) % U32

    def sample(self, n: int, rate_hz: float) -> tuple[np.ndarray, np.ndarray]:
        """The rig's next ``n`` samples (advancing its clock), kept for the pressure-limit check."""
        t_us, counts = self.rig.samples(n, rate_hz)
        self._seen = (t_us % U32, counts)
        return t_us, counts

    def frames(self, n: int) -> bytes:
        """``n`` data lines (advancing the rig's clock); empty when not streaming.

        With a fault injector a stall can end the block early: ``stall`` is
        then ``(seconds, frames not made)`` for the caller's pacing (see
        :meth:`take_stall`), and the rig's clock has run on by the stall.
        Event lines of the pressure limit follow the frames that crossed it.
        """
        if n <= 0 or not self.streaming:
            return b""
        out = bytearray()
        left = n
        before, self.stall = self.stall, None
        while left > 0:
            k = min(left, self.board.check_every(self.stream_hz) or left)
            out += self.faults.emit(self, k) if self.faults is not None else self._frames(k)
            left -= k
            if self._seen is not None:
                out += self.board.check(*self._seen)
                self._seen = None
            if self.stall is not None:
                self.stall = (self.stall[0], self.stall[1] + left)
                break
        if self.stall is None:
            self.stall = before
        return bytes(out)

    def _frames(self, n: int) -> bytes:
        t_us, counts = self.sample(n, self.stream_hz)
        seq = (self.seq + np.arange(n, dtype=np.int64)) % U32
        self.seq = int((self.seq + n) % U32)
        self.count += n
        return format_frames(seq, t_us % U32, counts)

    def idle(self, until_s: float) -> bytes:
        """An idle board's own time, up to rig time ``until_s``: while a chamber is supplied (or near
        its limit) it samples at ``IDLE_HZ`` for its checks, as the AVR firmware does between
        commands, so a host that is gone (killed, unplugged) never leaves the chambers supplying;
        otherwise the rig's clock just moves on.  The event lines those checks make."""
        out = bytearray()
        step = 1.0 / IDLE_HZ
        while self.board.check_every(IDLE_HZ) is not None and self.rig.time_s + step <= until_s:
            t_us, counts = self.rig.samples(1, IDLE_HZ)
            out += self.board.check(np.asarray(t_us) % U32, counts)
        if self.rig.time_s < until_s:
            self.rig.advance_to(until_s)
        return bytes(out)

    def take_stall(self) -> tuple[float, int] | None:
        """The stall that ended the last :meth:`frames` block early, once; else None."""
        stall, self.stall = self.stall, None
        return stall

    def skip(self, n: int) -> None:
        """Make ``n`` frames and lose them (the device's output buffer is full)."""
        if n <= 0 or not self.streaming:
            return
        if self.faults is not None:
            self.faults.skipped(self, n)
            return
        self.rig.samples(n, self.stream_hz)
        self.seq = int((self.seq + n) % U32)
        self.count += n


_HEX = np.frombuffer(b"0123456789ABCDEF", dtype=np.uint8)


def format_frames(seq: np.ndarray, t_us: np.ndarray, values: np.ndarray) -> bytes:
    """Many integer data lines at once: the same bytes as :func:`labcli.core.wire.format_frame`.

    Lines are built as rows of a byte matrix, a few numpy passes per field,
    so a block of 10^5 frames costs far less than 10^5 Python formats.
    """
    cols = np.column_stack([seq, t_us, values]).astype(np.int64)
    n, m = cols.shape
    if n == 0:
        return b""
    if n < 64:
        # numpy's fixed costs outweigh per-line formatting for short blocks; one
        # "%d" format per line is some 3x quicker than format_frame's per-value checks.
        fmt = "D" + ",%d" * m
        out = []
        for row in cols.tolist():
            body = (fmt % tuple(row)).encode("ascii")
            out.append(b"$%s*%02X\n" % (body, checksum(body)))
        return b"".join(out)
    if cols.min() < 0:
        raise ValueError("data line fields must be unsigned integers")
    # One fixed-width row per line: every field gets as many digit columns as
    # its widest value; leading zeros are masked out, and masked bytes (0)
    # leave the XOR checksum unchanged.
    parts, keeps = [np.full((n, 2), (0x24, 0x44), dtype=np.uint8)], [np.ones((n, 2), bool)]
    for f in range(m):
        x = cols[:, f]
        width = len(str(int(x.max())))
        p10 = 10 ** np.arange(width - 1, -1, -1, dtype=np.int64)
        digits = (x[:, None] // p10) % 10
        keep = (x[:, None] >= p10) | (p10 == 1)
        parts += [np.full((n, 1), 0x2C, np.uint8), (digits + 48).astype(np.uint8)]
        keeps += [np.ones((n, 1), bool), keep]
    mat = np.concatenate(parts + [np.zeros((n, 4), np.uint8)], axis=1)
    kept = np.concatenate(keeps + [np.ones((n, 4), bool)], axis=1)
    mat[~kept] = 0
    cs = np.bitwise_xor.reduce(mat[:, 1:-4], axis=1)
    mat[:, -4] = 0x2A  # '*'
    mat[:, -3] = _HEX[cs >> 4]
    mat[:, -2] = _HEX[cs & 15]
    mat[:, -1] = 0x0A
    return mat[kept].tobytes()
