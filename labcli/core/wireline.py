"""One line of the rig wire protocol: its checksum, its encoding, and a few lines read in Python.

The line-level pieces :mod:`labcli.core.wire` (the reference parser and the stream reader) and the
simulated firmware share; :func:`few_rows` is the stream reader's path for a read of a few lines,
where numpy's fixed cost per call outweighs its work.
"""

from __future__ import annotations

from collections.abc import Iterable
from numbers import Integral
from typing import Any

import numpy as np

MAX_LINE = 256  # bytes per line, '\n' excluded; longer runs are noise
U32 = 1 << 32
HEX_DIGITS = frozenset(b"0123456789abcdefABCDEF")
_EXACT = 1 << 53  # counts below this stay exact in float64


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


def format_frame(seq: int, t_us: int, values: Iterable[Any]) -> bytes:
    """Encode a data line, ``\\n`` included.  Integers (numpy's too) stay integers."""
    body = ",".join(
        ["D", str(int(seq) % U32), str(int(t_us) % U32)]
        + [str(int(v)) if isinstance(v, Integral) else repr(float(v)) for v in values]
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


def few_rows(block: bytes, k: int) -> np.ndarray | None:
    """The frames of ``block`` (complete lines) as int64 rows ``seq, t_us, values...``, or None
    unless each line is a plain integer data line.

    What is taken is exactly what :func:`labcli.core.wire.parse_line` makes a frame of ``k`` values (the property
    tests hold both to that): ``$D,`` then ``k + 2`` fields of ASCII digits (seq and t_us below
    2**32, values below 2**53, so exact as float64), ``*`` and two hex digits naming the XOR
    checksum, at most ``MAX_LINE`` bytes before the ``\\n`` (less one ``\\r``).  Anything else is
    left to the reader's other paths, which count it.
    """
    lines = block.split(b"\n")
    lines.pop()  # after the final '\n'
    flat: list[int] = []
    for line in lines:
        if line[-1:] == b"\r":
            line = line[:-1]
        if len(line) > MAX_LINE or line[:3] != b"$D," or line[-3:-2] != b"*":
            return None
        if line[-2] not in HEX_DIGITS or line[-1] not in HEX_DIGITS or checksum(line[1:-3]) != int(line[-2:], 16):
            return None
        fields = line[3:-3].split(b",")
        if len(fields) != k + 2 or not all(map(bytes.isdigit, fields)):
            return None
        row = list(map(int, fields))
        if row[0] >= U32 or row[1] >= U32 or max(row) >= _EXACT:
            return None
        flat += row
    return np.array(flat, np.int64).reshape(len(lines), k + 2)
