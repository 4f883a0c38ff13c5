"""The two signed lines a wire-protocol 1.1 board adds: event lines and estimate lines.

Both are checksummed like data lines (``docs/wire-protocol.md``)::

    $E,<n>,<t_us>,<KIND>[,<field>...]*HH          an event: valves, over-pressure, reset, baseline
    $S,<seq>,<t_us>,<v1>,...,<vK>,<flags>*HH        the board's model estimates of one data frame

``n`` numbers the board's events since power-up (a gap is an event lost on the line), ``seq`` is
the data frame the estimate was computed from, ``t_us`` the board's clock; both unsigned 32-bit.
An event's kind is upper-case letters and ``_``; its fields are short tokens (letters, digits,
``_ . : + -``).  An estimate's values are decimals in SI units (rad, N) and ``flags`` an unsigned
integer bit mask (:data:`ESTIMATE_FLAGS`).

:func:`parse_board_fields` is called by :func:`labcli.core.wire.parse_line` once the checksum
holds; it returns the line, or the reason it is noise, and never raises.
"""

from __future__ import annotations

import re
from collections.abc import Iterable, Sequence
from dataclasses import dataclass

U32 = 1 << 32

EVENT_KIND = b"E"
ESTIMATE_KIND = b"S"
_KIND_RE = re.compile(rb"[A-Z][A-Z_]*")
_TOKEN_RE = re.compile(rb"[A-Za-z0-9_.:+-]*")
_DEC_RE = re.compile(rb"[+-]?(?:[0-9]+(?:\.[0-9]*)?|\.[0-9]+)(?:[eE][+-]?[0-9]+)?")

# Bits of an estimate line's flags (the board's model, firmware/src/estimate.h, sets them).
ESTIMATE_FLAGS: dict[int, str] = {
    1: "theta1-uncertain",
    2: "theta2-uncertain",
    4: "Fx-uncertain",
    8: "Fy-uncertain",
    16: "bad-pressure",
    32: "theta1-clipped",
    64: "theta2-clipped",
    128: "singular-jacobian",
    256: "no-baseline",
    512: "loaded",
}


@dataclass(frozen=True, slots=True)
class Event:
    """``$E`` line: event number ``n``, board clock ``t_us``, ``kind`` and its fields."""

    n: int
    t_us: int
    kind: str
    fields: tuple[str, ...]


@dataclass(frozen=True, slots=True)
class Estimate:
    """``$S`` line: the board's estimates (rad, N) of data frame ``seq`` and their ``flags``."""

    seq: int
    t_us: int
    values: tuple[float, ...]
    flags: int

    @property
    def flag_names(self) -> list[str]:
        """The set flags by name (unknown bits as ``bit<k>``)."""
        return [ESTIMATE_FLAGS.get(1 << k, f"bit{k}") for k in range(32) if self.flags >> k & 1]


def _u32(field: bytes) -> int | None:
    if not field.isdigit() or len(field) > 10:
        return None
    v = int(field)
    return v if v < U32 else None


def parse_board_fields(fields: Sequence[bytes]) -> Event | Estimate | str:
    """An ``E`` or ``S`` line's comma-split payload as its line, or the reason it is noise."""
    if fields[0] == EVENT_KIND:
        return _event(fields)
    return _estimate(fields)


def _event(fields: Sequence[bytes]) -> Event | str:
    if len(fields) < 4:
        return "event line has no kind"
    n, t_us = _u32(fields[1]), _u32(fields[2])
    if n is None or t_us is None:
        return "event number or t_us is not an unsigned 32-bit integer"
    if not _KIND_RE.fullmatch(fields[3]):
        return "event kind is not upper-case letters"
    if not all(_TOKEN_RE.fullmatch(f) for f in fields[4:]):
        return "event field holds characters outside letters, digits and _.:+-"
    return Event(n, t_us, fields[3].decode("ascii"), tuple(f.decode("ascii") for f in fields[4:]))


def _estimate(fields: Sequence[bytes]) -> Estimate | str:
    if len(fields) < 5:
        return "estimate line has no values"
    seq, t_us = _u32(fields[1]), _u32(fields[2])
    if seq is None or t_us is None:
        return "seq or t_us is not an unsigned 32-bit integer"
    flags = _u32(fields[-1])
    if flags is None:
        return "estimate flags are not an unsigned 32-bit integer"
    values = []
    for f in fields[3:-1]:
        if not _DEC_RE.fullmatch(f):
            return "an estimate is not a finite number"
        v = float(f)
        if v != v or v in (float("inf"), float("-inf")):
            return "an estimate is not a finite number"
        values.append(v)
    return Estimate(seq, t_us, tuple(values), flags)


def _signed(body: bytes) -> bytes:
    x = 0
    for b in body:
        x ^= b
    return b"$" + body + b"*%02X\n" % x


def format_event(n: int, t_us: int, kind: str, fields: Iterable[object] = ()) -> bytes:
    """Encode an event line, ``\\n`` included."""
    parts = ["E", str(int(n) % U32), str(int(t_us) % U32), kind, *(str(f) for f in fields)]
    return _signed(",".join(parts).encode("ascii"))


def format_estimate(seq: int, t_us: int, values: Iterable[float], flags: int) -> bytes:
    """Encode an estimate line, ``\\n`` included (values to 6 significant digits, as the board writes them)."""
    parts = ["S", str(int(seq) % U32), str(int(t_us) % U32), *(f"{float(v):.6g}" for v in values), str(int(flags))]
    return _signed(",".join(parts).encode("ascii"))
