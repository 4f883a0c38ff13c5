"""Codec and stream reader for the rig wire protocol, versions 1.0 and 1.1 (``docs/wire-protocol.md``).

A line from the device is one of:

* :class:`Frame`   ``$D,<seq>,<t_us>,<v1>,...,<vN>*<HH>`` with a valid XOR checksum;
* :class:`Event`   ``$E,<n>,<t_us>,<KIND>,...*<HH>``, a 1.1 board's event (valves, over-pressure, reset);
* :class:`Estimate` ``$S,<seq>,<t_us>,<v1>,...,<flags>*<HH>``, a 1.1 board's model estimates;
* :class:`LogLine` ``#<free text>`` from the firmware;
* :class:`Reply`   ``ID,...``, ``CAPS,...``, ``OK ...`` or ``ERR ...``, the answer to a command;
* :class:`Noise`   anything else, with the reason it was rejected.

A 1.0 host met ``$E`` and ``$S`` lines as noise; they are told apart here (their fields in
:mod:`labcli.core.boardlines`), counted, and kept for the device (``events``, ``estimates``).

Nothing here raises on bad input: noise is a value, so the stream reader can
count it and move on.

:func:`parse_line` is the reference: short, line by line, obviously right.
:class:`StreamReader` parses whole chunks at once with numpy for the common
line (unsigned integer values; a chunk of nothing else in one pass,
:mod:`labcli.core.wirechunk`) and hands every other line to
:func:`parse_line`, so both paths agree by construction on everything but the
fast path's own checks, which the property tests compare line by line.
"""

from __future__ import annotations

import re
import time
from collections import deque
from collections.abc import Iterable
from dataclasses import dataclass
from typing import Any

import numpy as np

from .boardlines import ESTIMATE_KIND, EVENT_KIND, Estimate, Event, parse_board_fields
from .wirechunk import clean_rows, digits_to_rows, follows_on, steps_bytes, whole_chunk
from .wireline import HEX_DIGITS, MAX_LINE, U32, checksum, few_rows
from .wireline import format_command as format_command
from .wireline import format_frame as format_frame
from .wireline import format_log as format_log

OVERLONG = f"line longer than {MAX_LINE} bytes"  # Noise reasons the reader counts apart
BAD_CHECKSUM = "bad checksum"
STALL_US = 250_000  # device-time excess over the expected gap that counts as a stall


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


Parsed = Frame | Event | Estimate | LogLine | Reply | Noise

# A value is an integer (raw ADC counts) or a decimal; nothing Python's int()
# or float() would also swallow (spaces, '_', 'nan', 'inf') is on the wire.
_INT_RE = re.compile(rb"[+-]?[0-9]+")
_DEC_RE = re.compile(rb"[+-]?(?:[0-9]+(?:\.[0-9]*)?|\.[0-9]+)(?:[eE][+-]?[0-9]+)?")


def _number(field: bytes) -> float | int:
    # int first so raw ADC counts stay exact integers.
    if _INT_RE.fullmatch(field):
        return int(field)
    if not _DEC_RE.fullmatch(field):
        raise ValueError("not a number")
    v = float(field)
    if v != v or v in (float("inf"), float("-inf")):
        raise ValueError("not finite")
    return v


def _is_reply(line: bytes) -> bool:
    if line.startswith((b"ID,", b"CAPS,")):
        return True
    for word in (b"OK", b"ERR"):
        if line == word or line.startswith(word + b" "):
            return True
    return False


def parse_line(line: bytes, n_channels: int | None = None) -> Parsed:
    """Classify one line (with or without its trailing ``\\n`` / ``\\r\\n``).

    ``n_channels``, when given, is the number of values a data line must carry.
    """
    line = bytes(line)
    if line.endswith(b"\n"):
        line = line[:-1]
    if line.endswith(b"\r"):
        line = line[:-1]
    if len(line) > MAX_LINE:
        return Noise(line[:64], OVERLONG)
    if not line:
        return Noise(line, "empty line")
    first = line[0]
    if first == 0x24:  # '$'
        return _parse_data(line, n_channels)
    if first == 0x23:  # '#'
        return LogLine(line[1:].decode("ascii", "replace").strip())
    if _is_reply(line):
        try:
            return Reply(line.decode("ascii"))
        except UnicodeDecodeError:
            return Noise(line, "reply is not ASCII")
    return Noise(line, "not a data, log or reply line")


def _parse_data(line: bytes, n_channels: int | None) -> Parsed:
    star = line.rfind(b"*")
    if star < 0 or len(line) - star != 3:
        return Noise(line, "data line without '*HH' checksum at its end")
    hh = line[star + 1 :]
    if not all(c in HEX_DIGITS for c in hh):
        return Noise(line, "checksum is not two hex digits")
    want = int(hh, 16)
    payload = line[1:star]
    if checksum(payload) != want:
        return Noise(line, BAD_CHECKSUM)
    fields = payload.split(b",")
    if fields[0] in (EVENT_KIND, ESTIMATE_KIND):
        board = parse_board_fields(fields)
        return Noise(line, board) if isinstance(board, str) else board
    if fields[0] != b"D":
        return Noise(line, "data line does not start with '$D,', '$E,' or '$S,'")
    if len(fields) < 4:
        return Noise(line, "data line has no values")
    if n_channels is not None and len(fields) - 3 != n_channels:
        return Noise(line, f"expected {n_channels} values, got {len(fields) - 3}")
    if not (fields[1].isdigit() and fields[2].isdigit()):
        return Noise(line, "seq or t_us is not an unsigned integer")
    seq = int(fields[1])
    t_us = int(fields[2])
    if not (seq < U32 and t_us < U32):
        return Noise(line, "seq or t_us outside unsigned 32-bit range")
    try:
        values = tuple(_number(f) for f in fields[3:])
    except ValueError:
        return Noise(line, "a value is not a finite number")
    return Frame(seq, t_us, values)


def noise_counter(reason: str) -> str:
    """The :class:`StreamReader` counter a :class:`Noise` line of this ``reason`` adds to."""
    if reason == BAD_CHECKSUM:
        return "bad_checksum"
    if reason == OVERLONG:
        return "overlong"
    return "malformed"


@dataclass(frozen=True)
class FrameBatch:
    """Frames in arrival order: ``seq`` and ``t_us`` int64 ``(n,)``, ``values`` float64 ``(n, k)``."""

    seq: np.ndarray
    t_us: np.ndarray
    values: np.ndarray

    def __len__(self) -> int:
        return int(self.seq.shape[0])

    @classmethod
    def empty(cls, n_channels: int = 0) -> FrameBatch:
        return cls(np.empty(0, np.int64), np.empty(0, np.int64), np.empty((0, n_channels), np.float64))

    @classmethod
    def concat(cls, batches: Iterable[FrameBatch], n_channels: int = 0) -> FrameBatch:
        parts = [b for b in batches if len(b)]
        if not parts:
            return cls.empty(n_channels)
        if len(parts) == 1:
            return parts[0]
        return cls(
            np.concatenate([b.seq for b in parts]),
            np.concatenate([b.t_us for b in parts]),
            np.concatenate([b.values for b in parts]),
        )


_V1_COUNTERS = ("frames", "lost", "bad_checksum", "malformed", "log_lines", "overlong", "replies", "bytes")
COUNTER_NAMES = _V1_COUNTERS + ("events", "estimates")  # a 1.1 board's $E and $S lines

_HEXVAL = np.full(256, -1, np.int16)
for _i, _c in enumerate(b"0123456789abcdef"):
    _HEXVAL[_c] = _i
for _i, _c in enumerate(b"ABCDEF"):
    _HEXVAL[_c] = 10 + _i
_IS_DIGIT = np.zeros(256, bool)
_IS_DIGIT[48:58] = True
_IS_FIELD = _IS_DIGIT.copy()
_IS_FIELD[44] = True  # ','
_MIN_VECTOR_LINES = 8  # below this, line by line is quicker than numpy's fixed cost per call
# A read this long holds more lines than that unless they are overlong (which the other paths
# count): a full chunk skips the count of its line breaks.
_FEW_BYTES = 1024


class StreamReader:
    """Turns a byte stream from the rig into frame batches, replies and log lines.

    ``port`` is any object with pyserial's ``read``/``in_waiting`` (or None for :meth:`feed`
    only).  Its ``timeout`` is the poll interval of :meth:`read`, so it must be finite (the
    Device sets 0.05 s).  A port with ``read_burst(timeout, size)`` (the Device's on a POSIX
    system) is read through that instead: one wait for the first byte, one read of all that waits.  ``n_channels=None`` takes the channel count from the first valid
    frame; later frames with another count are malformed.

    A 1.1 board's event and estimate lines are counted and kept in ``events`` and ``estimates``
    (bounded; the device takes them).  A line longer than ``MAX_LINE`` is counted once as
    ``overlong`` and skipped up to the next ``\\n``.  Lost frames are counted from gaps in
    ``seq`` (modulo 2**32); a backwards jump (firmware restarted) resynchronises without
    counting loss.

    Stalls: once the sample rate is known (:meth:`set_rate`, which ``Device.set_rate`` calls
    with the rate the firmware confirmed), a gap between consecutive frames whose device time
    (``t_us``) exceeds ``seq`` difference x period by more than ``stall_us`` counts as one
    stall (``stalls``; their total excess in ``stalled_s``).  Device time, not arrival time, is
    judged, so a burst held back by a USB bridge is not a stall and a stall is seen even when
    the host read late.
    """

    def __init__(
        self,
        port: Any = None,
        n_channels: int | None = None,
        chunk: int = 65536,
        max_logs: int = 1000,
        stall_us: int = STALL_US,
    ) -> None:
        if n_channels is not None and n_channels < 1:
            raise ValueError("a data line carries at least one value")
        self.port = port
        self.chunk = int(chunk)
        self.n_channels = n_channels
        self.counters: dict[str, int] = dict.fromkeys(COUNTER_NAMES, 0)
        self.replies: deque[str] = deque(maxlen=256)
        self.logs: deque[str] = deque(maxlen=max_logs)
        self.events: deque[Event] = deque(maxlen=1024)  # a 1.1 board's, until the device takes them
        self.estimates: deque[Estimate] = deque(maxlen=4096)
        self.noise: deque[tuple[str, bytes]] = deque(maxlen=32)  # (reason, first bytes) for diagnostics
        self.lines = 0  # complete lines consumed, overlong runs included
        self._pending = b""
        self._skipping = False
        self._last_seq: int | None = None
        self._last_t_us: int | None = None
        self.stall_us = int(stall_us)
        self.period_us: float | None = None
        self.stalls = 0
        self.stalled_s = 0.0

    # -- state -------------------------------------------------------------

    def reset_sequence(self) -> None:
        """Forget the last seq (call at START: the firmware may restart its counter)."""
        self._last_seq = None
        self._last_t_us = None

    def reset_counters(self) -> None:
        for name in COUNTER_NAMES:
            self.counters[name] = 0
        self.stalls = 0
        self.stalled_s = 0.0

    def set_rate(self, rate_hz: float | None) -> None:
        """The firmware's sample rate, whose period the stall check expects between frames."""
        self.period_us = None if not rate_hz else 1e6 / float(rate_hz)

    def clear(self) -> None:
        """Drop the partial line held between reads (after the port's input was flushed)."""
        self._pending = b""
        self._skipping = False

    # -- input -------------------------------------------------------------

    def read(self, timeout: float) -> FrameBatch:
        """Read the port in chunks until at least one line is complete or ``timeout`` s pass."""
        port = self.port
        deadline = time.monotonic() + timeout
        lines_before = self.lines
        batches = []
        # A port that waits for its first byte and reads what it holds in one call (the Device's
        # serial port on a POSIX system): read_burst(timeout, size).
        burst = getattr(port, "read_burst", None)
        while True:
            if burst is not None:
                data = burst(max(0.0, deadline - time.monotonic()), self.chunk)
            else:
                waiting = port.in_waiting
                data = port.read(min(waiting, self.chunk) if waiting else 1)
                # The blocking read(1) woke on the first byte; take the rest of the burst too.
                waiting = port.in_waiting if data else 0
                if waiting:
                    data += port.read(min(waiting, self.chunk))
            if data:
                batch = self.feed(data)
                if len(batch):
                    batches.append(batch)
                if self.lines != lines_before:
                    break
            if time.monotonic() >= deadline:
                break
        return FrameBatch.concat(batches, self.n_channels or 0)

    def feed(self, data: bytes) -> FrameBatch:
        """Consume ``data`` (any split of the stream) and return the frames it completed."""
        data = bytes(data)
        self.counters["bytes"] += len(data)
        if self._skipping:
            nl = data.find(b"\n")
            if nl < 0:
                return FrameBatch.empty(self.n_channels or 0)
            data = data[nl + 1 :]
            self._skipping = False
        end = data.rfind(b"\n") + 1
        k = self.n_channels
        if end and k is not None and end < _FEW_BYTES and data.count(b"\n", 0, end) < _MIN_VECTOR_LINES:
            # An idle host's read: a frame or a few, judged line by line in Python (at a few lines a
            # read, numpy's calls cost more than their work, all the more from a cold cache).
            few = few_rows(self._pending + data[:end] if self._pending else data[:end], k)
            if few is not None:
                batch = _new_batch(few[:, 0], few[:, 1], few[:, 2:].astype(_F64))
                self._pending = data[end:]
                if len(self._pending) > MAX_LINE + 1:
                    self._check_pending()
                self.lines += len(batch)
                return self._count_frames(batch)
        if end and k is not None:  # the common chunk: the carried bytes and this one's lines, whole
            rows = clean_rows(self._pending, data, end, k, MAX_LINE)
            if rows is not None:
                self._pending = data[end:]
                if len(self._pending) > MAX_LINE + 1:
                    self._check_pending()
                return self._take_rows(rows)
        buf = self._pending + data if self._pending else data
        last = buf.rfind(b"\n")
        if last < 0:
            self._pending = buf
            self._check_pending()
            return FrameBatch.empty(self.n_channels or 0)
        self._pending, batch = buf[last + 1 :], self._parse_block(buf[: last + 1], tried=k is not None)
        self._check_pending()
        return batch

    def _take_rows(self, rows: np.ndarray) -> FrameBatch:
        """The batch of a clean chunk's rows (:func:`clean_rows`), counted."""
        n = rows.shape[0]
        self.lines += n
        seq = rows[:, 0]
        batch = _new_batch(seq, rows[:, 1], rows[:, 2:-1].astype(_F64))
        last = self._last_seq
        if self.period_us is None and last is not None and seq.tobytes() == steps_bytes(n, last + 1):
            self.counters["frames"] += n  # nothing lost, no stall to time
            self._last_seq = last + n
            self._last_t_us = int(rows[n - 1, 1])
            return batch
        return self._count_frames(batch)

    def _check_pending(self) -> None:
        # One '\r' may still precede the '\n', so MAX_LINE + 1 bytes can yet be a good line.
        if len(self._pending) > MAX_LINE + 1:
            self.counters["overlong"] += 1
            self.lines += 1
            self.noise.append((OVERLONG, self._pending[:64]))
            self._pending = b""
            self._skipping = True

    # -- parsing -----------------------------------------------------------

    def _parse_block(self, block: bytes, tried: bool = False) -> FrameBatch:
        """Parse complete lines (``block`` ends with ``\\n``) and count loss across them.

        ``tried``: :func:`clean_rows` already refused the whole block.
        """
        clean = not tried and self.n_channels is not None and whole_chunk(block, self.n_channels, MAX_LINE)
        if clean:  # the common block, whole: no list of batches, no concatenation
            self.lines += clean[0].shape[0]
            return self._count_frames(FrameBatch(*clean))
        batches: list[FrameBatch] = []
        offset = 0
        # The channel count comes from the first valid frame; until then go line by line.
        while self.n_channels is None and offset < len(block):
            nl = block.index(b"\n", offset)
            parsed = self._classify(block[offset:nl])
            self.lines += 1
            if isinstance(parsed, Frame):
                self.n_channels = len(parsed.values)
                batches.append(_batch_of([parsed], self.n_channels))
            offset = nl + 1
        if offset < len(block):
            rest = block[offset:] if offset else block
            clean = bool(offset) and whole_chunk(rest, self.n_channels or 0, MAX_LINE)  # (tried above at 0)
            self.lines += len(clean[0]) if clean else 0
            few = not clean and rest.count(b"\n") < _MIN_VECTOR_LINES
            batches.append(
                FrameBatch(*clean) if clean else self._parse_lines(rest) if few else self._parse_vectorised(rest)
            )
        return self._count_frames(batches[0] if len(batches) == 1 else FrameBatch.concat(batches, self.n_channels or 0))

    def _count_frames(self, batch: FrameBatch) -> FrameBatch:
        """Count ``batch``'s frames, and the frames lost and stalls before and among them; returns it."""
        seq, n, last = batch.seq, batch.seq.shape[0], self._last_seq
        if not n:
            return batch
        self.counters["frames"] += n
        if self.period_us is None and follows_on(seq, last):  # nothing lost, no stall to time
            self._last_seq, self._last_t_us = int(seq[-1]), int(batch.t_us[-1])
            return batch
        if n < _MIN_VECTOR_LINES:  # an idle host's read of a frame or a few: numpy's cost per call is the most of it
            self._count_few(seq.tolist(), batch.t_us.tolist())
            return batch
        gap: np.ndarray | int = 0
        forward: np.ndarray | bool = True  # one step each, on from the last frame (the common batch)
        if not follows_on(seq, last):
            prev = np.concatenate(([seq[0] - 1 if self._last_seq is None else self._last_seq], seq[:-1]))
            gaps = (seq - prev - 1) % U32
            ahead = gaps < (U32 >> 1)
            self.counters["lost"] += int(gaps[ahead].sum())
            if self._last_seq is None:
                ahead[0] = False  # the first frame since START has nothing before it
            gap, forward = gaps, ahead
        if self.period_us is not None:
            t = batch.t_us
            prev_t = np.concatenate(([t[0] if self._last_t_us is None else self._last_t_us], t[:-1]))
            # t_us wraps like seq: differences modulo 2**32 stay right across the wrap.
            excess = (t - prev_t) % U32 - (gap + 1) * self.period_us
            stalled = forward & (excess > self.stall_us)
            if stalled.any():
                self.stalls += int(stalled.sum())
                self.stalled_s += float(excess[stalled].sum()) * 1e-6
        self._last_t_us = int(batch.t_us[-1])
        self._last_seq = int(seq[-1])
        return batch

    def _count_few(self, seqs: list[int], times: list[int]) -> None:
        """:meth:`_count_frames`' loss and stalls frame by frame, for fewer than 8 frames.

        A stall's excess is the same number as there; the stalls' excesses are summed by numpy as there.
        """
        last, last_t, period = self._last_seq, self._last_t_us, self.period_us
        lost = 0
        stalled: list[float] = []
        for s, t in zip(seqs, times, strict=True):
            if last is None:  # the first frame since START has nothing before it
                gap, forward = 0, False
            else:
                gap = (s - last - 1) % U32
                forward = gap < U32 >> 1
                if forward:
                    lost += gap
            if period is not None:
                # t_us wraps like seq: differences modulo 2**32 stay right across the wrap.
                excess = (t - (t if last_t is None else last_t)) % U32 - (gap + 1) * period
                if forward and excess > self.stall_us:
                    stalled.append(excess)
            last, last_t = s, t
        self.counters["lost"] += lost
        if stalled:  # (rare)
            self.stalls += len(stalled)
            self.stalled_s += float(np.array(stalled).sum()) * 1e-6
        self._last_seq, self._last_t_us = last, last_t

    def _classify(self, line: bytes) -> Parsed:
        """Slow path: one line through the reference parser, counted."""
        parsed = parse_line(line, self.n_channels)
        if isinstance(parsed, LogLine):
            self.counters["log_lines"] += 1
            self.logs.append(parsed.text)
        elif isinstance(parsed, Reply):
            self.counters["replies"] += 1
            self.replies.append(parsed.text)
        elif isinstance(parsed, Event):
            self.counters["events"] += 1
            self.events.append(parsed)
        elif isinstance(parsed, Estimate):
            self.counters["estimates"] += 1
            self.estimates.append(parsed)
        elif isinstance(parsed, Noise):
            self.counters[noise_counter(parsed.reason)] += 1
            self.noise.append((parsed.reason, parsed.line[:64]))
        return parsed  # a Frame is counted with its batch

    def _parse_lines(self, block: bytes) -> FrameBatch:
        """A few lines (a slow rate's poll): numpy's per-call cost would exceed the work."""
        lines = block.split(b"\n")
        lines.pop()  # after the final '\n'
        self.lines += len(lines)
        frames = [p for p in map(self._classify, lines) if isinstance(p, Frame)]
        return _batch_of(frames, self.n_channels or 0) if frames else FrameBatch.empty(self.n_channels or 0)

    def _parse_vectorised(self, block: bytes) -> FrameBatch:
        k = self.n_channels
        assert k is not None
        a = np.frombuffer(block, np.uint8)
        nl = np.flatnonzero(a == 10)
        n_lines = nl.shape[0]
        self.lines += n_lines
        starts = np.empty(n_lines, np.int64)
        starts[0] = 0
        starts[1:] = nl[:-1] + 1
        ends = nl.astype(np.int64)
        cr = (ends > starts) & (a[ends - 1] == 13)
        ends = ends - cr  # content is a[starts:ends], one '\r' stripped as parse_line does
        length = ends - starts

        # Candidates for the fast path: "$D," digits and commas "*HH", right size.
        cand = np.flatnonzero((length >= 2 * k + 9) & (length <= MAX_LINE))
        s = starts[cand]
        e = ends[cand]
        ok = (a[s] == 36) & (a[s + 1] == 68) & (a[s + 2] == 44) & (a[e - 3] == 42)
        h1 = _HEXVAL[a[e - 2]]
        h2 = _HEXVAL[a[e - 1]]
        ok &= (h1 >= 0) & (h2 >= 0)
        ok &= _IS_DIGIT[a[s + 3]] & _IS_DIGIT[a[e - 4]]
        # Prefix sums make every per-line range query O(1): XOR, stray bytes, commas.
        px = np.zeros(a.shape[0] + 1, np.uint8)
        np.bitwise_xor.accumulate(a, out=px[1:])
        ok &= (px[e - 3] ^ px[s + 1]) == (h1 * 16 + h2)
        is_comma = a == 44
        bad = ~_IS_FIELD[a]
        bad[:-1] |= is_comma[:-1] & is_comma[1:]  # ",," is an empty field
        pbad = np.zeros(a.shape[0] + 1, np.int32)
        np.cumsum(bad, out=pbad[1:])
        pcom = np.zeros(a.shape[0] + 1, np.int32)
        np.cumsum(is_comma, out=pcom[1:])
        ok &= (pbad[e - 3] == pbad[s + 3]) & (pcom[e - 3] - pcom[s + 3] == k + 1)

        good = cand[ok]
        slow = np.ones(n_lines, bool)
        fast = None
        if good.shape[0]:
            seq, t_us, values, valid = digits_to_rows(a, starts[good] + 3, ends[good] - 2, k)
            fast = FrameBatch(seq, t_us, values)
            if not valid.all():
                good = good[valid]
                fast = FrameBatch(fast.seq[valid], fast.t_us[valid], fast.values[valid])
            slow[good] = False
        # Everything else (logs, replies, noise, decimals, signs, long numbers) goes line by line.
        slow_idx = np.flatnonzero(slow)
        if fast is None:
            fast = FrameBatch.empty(k)
        if not slow_idx.shape[0]:
            return fast
        frame_lines: list[int] = []
        frames: list[Frame] = []
        for i in slow_idx.tolist():
            parsed = self._classify(block[starts[i] : nl[i]])
            if isinstance(parsed, Frame):
                frame_lines.append(i)
                frames.append(parsed)
        if not frames:
            return fast
        if not len(fast):
            return _batch_of(frames, k)
        # Interleave both paths' frames back into line order.
        keys = np.concatenate([good, np.array(frame_lines, np.int64)])
        merged = FrameBatch.concat([fast, _batch_of(frames, k)], k)
        order = np.argsort(keys, kind="stable")
        return FrameBatch(merged.seq[order], merged.t_us[order], merged.values[order])


_F64 = np.float64


def _new_batch(seq: np.ndarray, t_us: np.ndarray, values: np.ndarray) -> FrameBatch:
    """``FrameBatch(seq, t_us, values)`` less the frozen dataclass's three guarded assignments."""
    batch = _NEW(FrameBatch)
    batch.__dict__.update(seq=seq, t_us=t_us, values=values)
    return batch


_NEW = object.__new__


def _batch_of(frames: list[Frame], k: int) -> FrameBatch:
    return FrameBatch(
        np.fromiter((f.seq for f in frames), np.int64, len(frames)),
        np.fromiter((f.t_us for f in frames), np.int64, len(frames)),
        np.array([f.values for f in frames], np.float64).reshape(len(frames), k),
    )
