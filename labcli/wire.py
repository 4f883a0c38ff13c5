"""Codec for the rig wire protocol, version 1 (``rig-wire-protocol.md``).

A line from the device is one of:

* :class:`Frame`   ``$D,<seq>,<t_us>,<v1>,...,<vN>*<HH>`` with a valid XOR checksum;
* :class:`LogLine` ``#<free text>`` from the firmware;
* :class:`Reply`   ``ID,...``, ``OK ...`` or ``ERR ...``, the answer to a command;
* :class:`Noise`   anything else, with the reason it was rejected.

Nothing here raises on bad input: noise is a value, so the stream reader can
count it and move on.
"""

from __future__ import annotations

from dataclasses import dataclass

MAX_LINE = 256  # bytes per line, '\n' excluded; longer runs are noise
U32 = 1 << 32


def checksum(payload: bytes) -> int:
    """XOR of every byte of ``payload`` (the bytes strictly between ``$`` and ``*``)."""
    # XOR of bytes == XOR of the big integer's byte lanes; folding the int is
    # far quicker in CPython than a per-byte loop.
    n = len(payload)
    if n == 0:
        return 0
    x = int.from_bytes(payload, "little")
    width = n * 8
    while width > 8:
        half = ((width // 8 + 1) // 2) * 8
        x = (x ^ (x >> half)) & ((1 << half) - 1)
        width = half
    return x & 0xFF


@dataclass(frozen=True, slots=True)
class Frame:
    seq: int
    t_us: int
    values: tuple[float, ...]


@dataclass(frozen=True, slots=True)
class LogLine:
    text: str


@dataclass(frozen=True, slots=True)
class Reply:
    text: str


@dataclass(frozen=True, slots=True)
class Noise:
    line: bytes
    reason: str


Parsed = Frame | LogLine | Reply | Noise

_REPLY_PREFIXES = (b"ID,", b"OK", b"ERR")


def _number(field: bytes) -> float | int:
    # int() first so raw ADC counts stay exact integers.
    try:
        return int(field)
    except ValueError:
        v = float(field)
        if v != v or v in (float("inf"), float("-inf")):
            raise ValueError("not finite") from None
        return v


def parse_line(line: bytes, n_channels: int | None = None) -> Parsed:
    """Classify one line (with or without its trailing ``\\n`` / ``\\r\\n``).

    ``n_channels``, when given, is the number of values a data line must carry.
    """
    if line.endswith(b"\n"):
        line = line[:-1]
    if line.endswith(b"\r"):
        line = line[:-1]
    if len(line) > MAX_LINE:
        return Noise(line[:64], f"line longer than {MAX_LINE} bytes")
    if not line:
        return Noise(line, "empty line")
    first = line[0]
    if first == 0x24:  # '$'
        return _parse_data(line, n_channels)
    if first == 0x23:  # '#'
        return LogLine(line[1:].decode("ascii", "replace").strip())
    if line.startswith(_REPLY_PREFIXES):
        try:
            return Reply(line.decode("ascii"))
        except UnicodeDecodeError:
            return Noise(line, "reply is not ASCII")
    return Noise(line, "not a data, log or reply line")


def _parse_data(line: bytes, n_channels: int | None) -> Parsed:
    star = line.rfind(b"*")
    if star < 0 or len(line) - star != 3:
        return Noise(line, "data line without '*HH' checksum at its end")
    try:
        want = int(line[star + 1 :], 16)
    except ValueError:
        return Noise(line, "checksum is not two hex digits")
    hh = line[star + 1 :]
    if not all(c in b"0123456789abcdefABCDEF" for c in hh):
        return Noise(line, "checksum is not two hex digits")
    payload = line[1:star]
    if checksum(payload) != want:
        return Noise(line, "bad checksum")
    fields = payload.split(b",")
    if fields[0] != b"D":
        return Noise(line, "data line does not start with '$D,'")
    if len(fields) < 4:
        return Noise(line, "data line has no values")
    if n_channels is not None and len(fields) - 3 != n_channels:
        return Noise(line, f"expected {n_channels} values, got {len(fields) - 3}")
    try:
        seq = int(fields[1])
        t_us = int(fields[2])
    except ValueError:
        return Noise(line, "seq or t_us is not an integer")
    if not (0 <= seq < U32 and 0 <= t_us < U32):
        return Noise(line, "seq or t_us outside unsigned 32-bit range")
    if not (fields[1].isdigit() and fields[2].isdigit()):
        return Noise(line, "seq or t_us is not an unsigned integer")
    try:
        values = tuple(_number(f) for f in fields[3:])
    except ValueError:
        return Noise(line, "a value is not a finite number")
    return Frame(seq, t_us, values)


def format_frame(seq: int, t_us: int, values) -> bytes:
    """Encode a data line, ``\\n`` included.  Integers stay integers."""
    body = ",".join(
        ["D", str(seq % U32), str(t_us % U32)]
        + [str(v) if isinstance(v, int) else repr(float(v)) for v in values]
    ).encode("ascii")
    return b"$" + body + b"*%02X\n" % checksum(body)


def format_log(text: str) -> bytes:
    return b"#" + text.replace("\n", " ").encode("ascii", "replace") + b"\n"


def format_command(command: str, *args: object) -> bytes:
    """Encode a host command: ``format_command("RATE", 200) == b"RATE 200\\n"``."""
    text = " ".join([command, *(str(a) for a in args)])
    if "\n" in text or "\r" in text:
        raise ValueError("a command is one line")
    return text.encode("ascii") + b"\n"
