"""Firmware of the simulated rig: the device side of the rig wire protocol, version 1.

:class:`Firmware` turns host command bytes into reply bytes and, while
streaming, turns the rig's ADC samples into data lines.  It knows nothing of
time sources: the ``sim://`` port (virtual or wall clock) and the pty server
decide how many frames are due and ask for them with :meth:`Firmware.frames`.

Commands (one per line, ``\\r`` tolerated): ``ID?``, ``RATE <hz>`` (1..5000),
``START``, ``STOP``; anything else is answered with ``ERR ...``.  ``seq`` counts
data lines since power-up and ``t_us`` is the rig's clock, both unsigned 32-bit
and wrapping.
"""

from __future__ import annotations

import numpy as np

from ..wire import MAX_LINE, U32, checksum, format_log

RATE_MIN = 1.0
RATE_MAX = 5000.0


class Firmware:
    """Device-side protocol state machine over a rig (see :mod:`labcli.sim`)."""

    def __init__(self, rig, rate_hz: float = 200.0) -> None:
        if not RATE_MIN <= rate_hz <= RATE_MAX:
            raise ValueError(f"rate must be within {RATE_MIN:g}..{RATE_MAX:g} Hz")
        self.rig = rig
        self.rate_hz = float(rate_hz)
        self.seq = 0
        self.streaming = False
        self._pending = bytearray()

    # ------------------------------------------------------------ host -> device

    def banner(self) -> bytes:
        """The log line printed at power-up."""
        return format_log(f"{self.rig.device} {self.rig.firmware} ready, {len(self.rig.channels)} channels")

    def receive(self, data: bytes) -> bytes:
        """Feed bytes written by the host; return the reply lines they cause."""
        self._pending += data
        out = bytearray()
        while True:
            nl = self._pending.find(b"\n")
            if nl < 0:
                if len(self._pending) > MAX_LINE:
                    self._pending.clear()
                    out += b"ERR line longer than 256 bytes\n"
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
            return b"ERR line longer than 256 bytes\n"
        text = line.decode("ascii", "replace").strip()
        if not text:
            return b""
        word, _, arg = text.partition(" ")
        arg = arg.strip()
        if text == "ID?":
            return ("ID," + ",".join([self.rig.device, self.rig.firmware, *self.rig.channels]) + "\n").encode()
        if word == "RATE":
            try:
                hz = float(arg)
            except ValueError:
                return f"ERR RATE needs a number of Hz, got '{arg}'\n".encode()
            if not RATE_MIN <= hz <= RATE_MAX:
                return f"ERR RATE must be within 1..5000 Hz, got {arg}\n".encode()
            self.rate_hz = hz
            return f"OK RATE {hz:g}\n".encode()
        if text == "START":
            self.streaming = True
            return b"OK START\n" + format_log(
                f"streaming {len(self.rig.channels)} channels at {self.rate_hz:g} Hz"
            )
        if text == "STOP":
            self.streaming = False
            return b"OK STOP\n"
        shown = text if len(text) <= 40 else text[:40] + "..."
        return f"ERR unknown command '{shown}'\n".encode("ascii", "replace")

    # ------------------------------------------------------------ device -> host

    def frames(self, n: int) -> bytes:
        """``n`` data lines (advancing the rig's clock); empty when not streaming."""
        if n <= 0 or not self.streaming:
            return b""
        t_us, counts = self.rig.samples(n, self.rate_hz)
        seq = (self.seq + np.arange(n, dtype=np.int64)) % U32
        self.seq = int((self.seq + n) % U32)
        return format_frames(seq, t_us % U32, counts)


_HEX = np.frombuffer(b"0123456789ABCDEF", dtype=np.uint8)


def format_frames(seq: np.ndarray, t_us: np.ndarray, values: np.ndarray) -> bytes:
    """Many integer data lines at once: the same bytes as :func:`labcli.wire.format_frame`.

    Digits are written into one byte buffer column by column, so a block of
    10^5 frames costs a few numpy passes instead of 10^5 Python formats.
    """
    cols = np.column_stack([seq, t_us, values]).astype(np.int64)
    n, m = cols.shape
    if n == 0:
        return b""
    if n < 64:  # numpy's fixed costs outweigh per-line formatting for short blocks
        fmt = "D" + ",%d" * m
        out = []
        for row in cols.tolist():
            body = (fmt % tuple(row)).encode("ascii")
            out.append(b"$%s*%02X\n" % (body, checksum(body)))
        return b"".join(out)
    if cols.min() < 0:
        raise ValueError("data line fields must be unsigned integers")
    nd = np.ones((n, m), dtype=np.int64)
    top = int(cols.max())
    p10 = 10
    while p10 <= top:
        nd += cols >= p10
        p10 *= 10
    linelen = 6 + m + nd.sum(axis=1)  # '$D' + m commas + digits + '*HH\n'
    ends = np.cumsum(linelen)
    starts = ends - linelen
    buf = np.empty(int(ends[-1]), dtype=np.uint8)
    buf[starts] = 0x24  # '$'
    buf[starts + 1] = 0x44  # 'D'
    pos = starts + 2
    for f in range(m):
        buf[pos] = 0x2C  # ','
        pos = pos + 1
        x = cols[:, f].copy()
        d = nd[:, f]
        last = pos + d - 1
        for k in range(int(d.max())):
            live = d > k
            buf[(last - k)[live]] = 48 + x[live] % 10
            x //= 10
        pos = pos + d
    # XOR over each payload: reduceat on [start+1, pos) pairs, keep the even results.
    idx = np.empty(2 * n, dtype=np.int64)
    idx[0::2] = starts + 1
    idx[1::2] = pos
    cs = np.bitwise_xor.reduceat(buf, idx)[0::2]
    buf[pos] = 0x2A  # '*'
    buf[pos + 1] = _HEX[cs >> 4]
    buf[pos + 2] = _HEX[cs & 15]
    buf[pos + 3] = 0x0A
    return buf.tobytes()
