"""A noisy link between the simulated firmware and the host: seeded fault injection.

A :class:`FaultInjector` sits on the firmware's outgoing byte stream and
spoils it the ways a real serial link does, frame by frame, with rates given
as probabilities per frame.  Its grammar (``sim://?faults=...``,
``labcli sim --pty --faults ...``)::

    KIND:RATE[@X][,KIND:RATE[@X]...]     e.g. checksum:0.01,drop:0.01,stall:0.001@2.5

Frame faults (the frame's ``seq`` is used up: the host sees a gap there):

* ``checksum`` one bit of one byte between ``$`` and ``*`` flips: a bad checksum.
* ``truncate`` bytes of the line are lost before its ``\\n``: either its tail
  (from a random byte on, ``*HH`` included: malformed) or a run of 1-8 bytes
  inside it (``*HH`` survives: bad checksum, or malformed when the lost bytes
  XOR to zero and the rest is not a valid frame).  A loss the XOR checksum
  cannot see (the rest still a valid frame) is never produced.
* ``overlong`` the line end is lost and noise follows: one run of 260-600
  bytes, then ``\\n``.
* ``drop`` the whole line is lost.

A frame hit by several frame faults suffers the first of drop, overlong,
truncate, checksum.

Added lines and timing (no ``seq`` used up):

* ``garbage`` a line of 1-80 random bytes (never starting with ``$``, ``#``
  or a reply word) before the frame: malformed.
* ``stall@S`` (S seconds, default 1) the firmware hangs before the frame:
  no frames are made or sent for S s; the device clock runs on, so the next
  frame's ``t_us`` is S s late.  In wall-clock mode the link is silent for S s.
* ``burst@N`` (N frames, default 50) the device holds N frames from this one
  on and sends them in one write, N periods late (a USB bridge not polled);
  nothing is lost.  A burst starting inside another is not counted.

Faults are drawn per frame number (frames made since power-up) from the
seed alone, so the same seed spoils the same frames whatever the reads'
sizes, and the same rig seed without faults samples the same values.

Ground truth, exact: ``injected`` (events by kind, ``stall_s`` total),
``noise`` (how each spoiled line classifies under :func:`labcli.core.wire.parse_line`,
i.e. what a stream reader must count as ``bad_checksum``/``malformed``/
``overlong``), ``stalls`` ``[(seq, seconds)]``, ``destroyed`` (the ``seq`` of
every frame not delivered intact) and, with ``record = True``, every frame
made with its fate (:meth:`FaultInjector.emitted`).  :meth:`FaultInjector.expected`
gives the counters a reader that saw the whole stream since START must show:
``frames`` sent intact, ``bad_checksum``, ``malformed``, ``overlong``, and
``lost`` = drop + checksum + truncate + overlong faults between the first and
the last intact frame (a spoiled frame's ``seq`` is used up, so the reader
sees it as a gap too).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields
from typing import Any

import numpy as np

from ..wire import MAX_LINE, U32, Frame, Noise, noise_counter, parse_line
from .firmware import format_frames

FRAME_FAULTS = ("drop", "overlong", "truncate", "checksum")  # order of precedence
FAULT_KINDS = ("checksum", "garbage", "truncate", "overlong", "drop", "stall", "burst")
FAULTS_FORM = (
    "KIND:RATE[@X][,KIND:RATE[@X]...] with KIND one of checksum, garbage, truncate, overlong, drop, "
    "stall@SECONDS, burst@FRAMES and RATE a probability per frame within 0..1 "
    "(e.g. checksum:0.01,stall:0.001@2.5)"
)
DEFAULT_STALL_S = 1.0
DEFAULT_BURST_FRAMES = 50
BLOCK = 4096  # frames per block of fault draws
# Fates of frames in the record.
OK, DROP, OVERLONG, TRUNCATE, CHECKSUM, OVERFLOW = range(6)
FATE_NAMES = ("ok", "drop", "overlong", "truncate", "checksum", "overflow")
_ROW = {"drop": 0, "overlong": 1, "truncate": 2, "checksum": 3, "garbage": 4, "stall": 5, "burst": 6}
_REPLY_START = frozenset(b"$#IOE\n")


class FaultSpecError(ValueError):
    """A malformed fault specification; ``detail`` says what, the message adds the accepted form."""

    def __init__(self, detail: str) -> None:
        self.detail = detail
        super().__init__(f"{detail}; expected {FAULTS_FORM}")


@dataclass(frozen=True)
class FaultSpec:
    """Rates per frame (0..1) of each fault; ``stall_s`` seconds, ``burst_frames`` frames."""

    checksum: float = 0.0
    garbage: float = 0.0
    truncate: float = 0.0
    overlong: float = 0.0
    drop: float = 0.0
    stall: float = 0.0
    stall_s: float = DEFAULT_STALL_S
    burst: float = 0.0
    burst_frames: int = DEFAULT_BURST_FRAMES

    def __post_init__(self) -> None:
        for kind in FAULT_KINDS:
            p = getattr(self, kind)
            if not (isinstance(p, (int, float)) and 0.0 <= p <= 1.0):
                raise FaultSpecError(f"rate of '{kind}' must be a number within 0..1, got {p!r}")
        if not (isinstance(self.stall_s, (int, float)) and math.isfinite(self.stall_s) and self.stall_s > 0):
            raise FaultSpecError(f"stall duration must be a number of seconds > 0, got {self.stall_s!r}")
        if not (isinstance(self.burst_frames, int) and self.burst_frames >= 2):
            raise FaultSpecError(f"burst length must be a whole number of frames >= 2, got {self.burst_frames!r}")

    @property
    def active(self) -> bool:
        return any(getattr(self, kind) > 0 for kind in FAULT_KINDS)

    @classmethod
    def parse(cls, text: str) -> FaultSpec:
        """``"checksum:0.01,stall:0.001@2.5"`` -> FaultSpec; :class:`FaultSpecError` if malformed."""
        kw: dict[str, Any] = {}
        for item in filter(None, (s.strip() for s in text.split(","))):
            kind, colon, rest = item.partition(":")
            kind = kind.strip()
            if kind not in FAULT_KINDS:
                raise FaultSpecError(f"unknown fault '{kind}'")
            if not colon:
                raise FaultSpecError(f"'{item}' is not KIND:RATE[@X]")
            if kind in kw:
                raise FaultSpecError(f"fault '{kind}' given twice")
            rate, at, x = rest.partition("@")
            kw[kind] = _probability(kind, rate)
            if at:
                if kind == "stall":
                    kw["stall_s"] = _seconds(x)
                elif kind == "burst":
                    kw["burst_frames"] = _frames(x)
                else:
                    raise FaultSpecError(f"fault '{kind}' takes no @ value, got '{item}'")
        return cls(**kw)

    @classmethod
    def from_data(cls, data: FaultSpec | str | dict | None) -> FaultSpec:
        """A FaultSpec from itself, its text form, or a dict of its fields (plain data)."""
        if data is None:
            return cls()
        if isinstance(data, FaultSpec):
            return data
        if isinstance(data, str):
            return cls.parse(data)
        unknown = set(data) - {f.name for f in fields(cls)}
        if unknown:
            raise FaultSpecError(f"unknown fault '{sorted(unknown)[0]}'")
        return cls(**data)

    def to_text(self) -> str:
        """The grammar form (``parse(to_text())`` round-trips); empty when no fault is set."""
        out = []
        for kind in FAULT_KINDS:
            p = getattr(self, kind)
            if p > 0:
                item = f"{kind}:{p:g}"
                if kind == "stall":
                    item += f"@{self.stall_s:g}"
                elif kind == "burst":
                    item += f"@{self.burst_frames}"
                out.append(item)
        return ",".join(out)

    def as_dict(self) -> dict[str, float]:
        return {f.name: getattr(self, f.name) for f in fields(self)}


def _probability(kind: str, text: str) -> float:
    try:
        p = float(text)
    except ValueError:
        p = float("nan")
    if not 0.0 <= p <= 1.0:
        raise FaultSpecError(f"rate of '{kind}' must be a number within 0..1, got '{text}'")
    return p


def _seconds(text: str) -> float:
    try:
        s = float(text)
    except ValueError:
        s = float("nan")
    if not (math.isfinite(s) and s > 0):
        raise FaultSpecError(f"stall duration must be a number of seconds > 0, got '{text}'")
    return s


def _frames(text: str) -> int:
    try:
        n = int(text)
    except ValueError:
        n = 0
    if n < 2:
        raise FaultSpecError(f"burst length must be a whole number of frames >= 2, got '{text}'")
    return n


@dataclass(frozen=True)
class Emitted:
    """Every frame the firmware made, in order: ``seq``, ``t_us`` (n,), ``values`` (n, k), ``fate`` (n,)."""

    seq: np.ndarray
    t_us: np.ndarray
    values: np.ndarray
    fate: np.ndarray  # index into FATE_NAMES

    def __len__(self) -> int:
        return int(self.seq.shape[0])


class FaultInjector:
    """Seeded faults on the firmware's output (see module docstring).

    ``FaultInjector(spec, seed=0, n_channels=6)``; ``spec`` is a
    :class:`FaultSpec`, its text form or a dict.  The firmware calls
    :meth:`emit` instead of formatting frames itself, :meth:`flush` before
    ``OK STOP`` and :meth:`skipped` for frames lost to a full buffer.
    """

    def __init__(self, spec: FaultSpec | str | dict, seed: int = 0, n_channels: int = 6, record: bool = False) -> None:
        self.spec = FaultSpec.from_data(spec)
        self.seed = int(seed)
        self.n_channels = int(n_channels)
        self.record = record
        self._p = np.zeros(len(_ROW))
        for kind, row in _ROW.items():
            self._p[row] = getattr(self.spec, kind)
        self.injected: dict[str, float] = {kind: 0 for kind in FAULT_KINDS}
        self.injected["stall_s"] = 0.0
        self.noise: dict[str, int] = {"bad_checksum": 0, "malformed": 0, "overlong": 0}
        self.frames = 0  # frames made
        self.delivered = 0  # frames sent intact
        self.stalls: list[tuple[int, float]] = []
        self.destroyed: list[int] = []
        self.first_intact: int | None = None  # seq of the first and last frames sent intact
        self.last_intact: int | None = None
        self._block_id = -1
        self._block_events: np.ndarray = np.empty(0, np.int64)
        self._block_rows: np.ndarray = np.empty((0, len(_ROW)), bool)
        self._stall_done = -1
        self._burst_end = -1  # slot after the current burst window
        self._held = bytearray()
        self._rec: list[tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]] = []

    # ------------------------------------------------------------ plan

    def _events(self, first: int, end: int) -> tuple[np.ndarray, np.ndarray]:
        """Slots in ``[first, end)`` with any fault, and their fault rows (bool (m, 7))."""
        slots, rows = [], []
        b = first // BLOCK
        while b * BLOCK < end:
            if b != self._block_id:
                rng = np.random.default_rng([self.seed, 0xFA17, b])
                hit = rng.random((BLOCK, len(_ROW))) < self._p
                ev = np.flatnonzero(hit.any(axis=1))
                self._block_id, self._block_events, self._block_rows = b, ev + b * BLOCK, hit[ev]
            ev = self._block_events
            lo, hi = np.searchsorted(ev, [first, end])
            slots.append(ev[lo:hi])
            rows.append(self._block_rows[lo:hi])
            b += 1
        if len(slots) == 1:
            return slots[0], rows[0]
        return np.concatenate(slots), np.concatenate(rows)

    def _rng(self, slot: int, salt: int) -> np.random.Generator:
        return np.random.default_rng([self.seed, 0xFA18, slot, salt])

    # ------------------------------------------------------------ firmware side

    def emit(self, fw: Any, n: int) -> bytes:
        """Make up to ``n`` frames on firmware ``fw`` and return the spoiled bytes.

        A stall ends the block early: ``fw.stall`` becomes ``(seconds, frames
        not made)`` and the device clock is advanced by the stall.
        """
        first = fw.count
        end = first + n
        slots, rows = self._events(first, end)
        stall_idx = np.flatnonzero(rows[:, _ROW["stall"]] & (slots > self._stall_done))
        stall_slot = None
        if stall_idx.shape[0]:
            stall_slot = int(slots[stall_idx[0]])
            end = stall_slot
            keep = slots < end
            slots, rows = slots[keep], rows[keep]
        out = self._make(fw, first, end, slots, rows) if end > first else b""
        if stall_slot is not None:
            secs = self.spec.stall_s
            fw.rig.advance(secs)
            self._stall_done = stall_slot
            self.injected["stall"] += 1
            self.injected["stall_s"] += secs
            self.stalls.append((fw.seq, secs))
            fw.stall = (secs, first + n - stall_slot)
        return out

    def _make(self, fw: Any, first: int, end: int, slots: np.ndarray, rows: np.ndarray) -> bytes:
        m = end - first
        t_us, counts = fw.sample(m, fw.stream_hz)
        seq = (fw.seq + np.arange(m, dtype=np.int64)) % U32
        t_us = t_us % U32
        fw.seq = int((fw.seq + m) % U32)
        fw.count += m
        self.frames += m
        block = format_frames(seq, t_us, counts)
        fate = np.zeros(m, np.int8) if self.record else None
        if not slots.shape[0] and self._burst_end <= first:
            self.delivered += m
            self._intact(int(seq[0]), int(seq[-1]))
            if fate is not None:
                self._rec.append((seq, t_us, counts, fate))
            return block
        out = bytearray()
        new_start = None  # offset in ``out`` where a burst window opened in this block
        bad: list[int] = []
        if slots.shape[0]:
            a = np.frombuffer(block, np.uint8)
            nl = np.flatnonzero(a == 10)
            pos = 0
            for slot, hit in zip(slots.tolist(), rows, strict=False):
                i = slot - first
                start = int(nl[i - 1]) + 1 if i else 0
                stop = int(nl[i]) + 1
                out += block[pos:start]
                pos = stop
                if hit[_ROW["burst"]] and slot >= self._burst_end:
                    self._burst_end = slot + self.spec.burst_frames
                    self.injected["burst"] += 1
                    new_start = len(out)
                if hit[_ROW["garbage"]]:
                    out += self._garbage(slot)
                kind = next((k for k in FRAME_FAULTS if hit[_ROW[k]]), None)
                line = block[start:stop]
                if kind is None:
                    out += line
                    continue
                out += self._spoil(kind, slot, line)
                self.destroyed.append(int(seq[i]))
                bad.append(i)
                if fate is not None:
                    fate[i] = FATE_NAMES.index(kind)
            out += block[pos:]
        else:
            out += block
        self.delivered += m - len(bad)
        if len(bad) < m:
            spoilt = set(bad)
            lo = next(i for i in range(m) if i not in spoilt)
            hi = next(i for i in range(m - 1, -1, -1) if i not in spoilt)
            self._intact(int(seq[lo]), int(seq[hi]))
        if fate is not None:
            self._rec.append((seq, t_us, counts, fate))
        combined = self._held + out
        self._held = bytearray()
        if self._burst_end > end:
            # The bytes of an unfinished burst window stay with the device.
            cut = 0 if new_start is None else len(combined) - len(out) + new_start
            self._held = combined[cut:]
            return bytes(combined[:cut])
        return bytes(combined)

    def _intact(self, first_seq: int, last_seq: int) -> None:
        if self.first_intact is None:
            self.first_intact = first_seq
        self.last_intact = last_seq

    def schedule(self, first: int, end: int) -> dict[str, list[int]]:
        """Frame numbers in ``[first, end)`` each fault kind will hit (before precedence and burst overlap)."""
        slots, rows = self._events(first, end)
        return {kind: slots[rows[:, row]].tolist() for kind, row in _ROW.items()}

    def flush(self) -> bytes:
        """Release held bytes (the firmware sends them before ``OK STOP``)."""
        out = bytes(self._held)
        self._held.clear()
        self._burst_end = -1
        return out

    def skipped(self, fw: Any, n: int) -> None:
        """``n`` frames made but never sent (the device's buffer was full)."""
        if n <= 0:
            return
        t_us, counts = fw.rig.samples(n, fw.stream_hz)
        seq = (fw.seq + np.arange(n, dtype=np.int64)) % U32
        fw.seq = int((fw.seq + n) % U32)
        fw.count += n
        self.frames += n
        self.destroyed.extend(seq.tolist())
        if self.record:
            self._rec.append((seq, t_us % U32, counts, np.full(n, OVERFLOW, np.int8)))

    # ------------------------------------------------------------ lines

    def _count(self, line: bytes) -> None:
        parsed = parse_line(line, self.n_channels)
        if not isinstance(parsed, Noise):  # the generators below make sure of it
            raise AssertionError(f"a spoiled line classified as {type(parsed).__name__}: {line[:64]!r}")
        self.noise[noise_counter(parsed.reason)] += 1

    def _garbage(self, slot: int) -> bytes:
        rng = self._rng(slot, 1)
        while True:
            n = int(rng.integers(1, 81))
            body = rng.integers(0, 256, n).astype(np.uint8)
            body[body == 10] = 0x7E
            line = body.tobytes()
            if line[0] in _REPLY_START:
                continue
            parsed = parse_line(line, self.n_channels)
            if isinstance(parsed, Noise):
                break
        self.injected["garbage"] += 1
        self._count(line)
        return line + b"\n"

    def _spoil(self, kind: str, slot: int, line: bytes) -> bytes:
        self.injected[kind] += 1
        if kind == "drop":
            return b""
        rng = self._rng(slot, 2)
        body = bytearray(line[:-1])
        star = body.rfind(b"*")
        if kind == "checksum":
            i = int(rng.integers(1, star))
            for bit in rng.permutation(7).tolist():
                c = body[i] ^ (1 << bit)
                if c not in (10, 13):
                    body[i] = c
                    break
        elif kind == "overlong":
            total = int(rng.integers(MAX_LINE + 4, 601))
            body += rng.integers(0x21, 0x7F, total - len(body)).astype(np.uint8).tobytes()
        elif rng.random() < 0.5:  # truncate: the tail is lost
            del body[int(rng.integers(1, len(body))) :]
        else:  # truncate: a run inside the line is lost, '*HH' survives
            a = int(rng.integers(1, star))
            k = int(rng.integers(1, min(8, star - a) + 1))
            while isinstance(parse_line(bytes(body[:a] + body[a + k :]), self.n_channels), Frame):
                k += 1  # the XOR checksum cannot see this loss: lose one more byte
            del body[a : a + k]
        out = bytes(body)
        self._count(out)
        return out + b"\n"

    # ------------------------------------------------------------ truth

    def expected(self) -> dict[str, int]:
        """Counters a stream reader that saw every byte since START must show.

        ``lost`` counts the frames destroyed between the first and the last
        intact frame: a reader counts loss from seq gaps, so it cannot see
        destroyed frames before the first or after the last frame it gets.
        """
        if self.first_intact is None or self.last_intact is None:  # set together, by the first intact frame
            lost = 0
        else:
            lost = self.lost_between(self.first_intact, self.last_intact)
        return {"frames": self.delivered, "lost": lost, **self.noise}

    def lost_between(self, first_seq: int, last_seq: int) -> int:
        """Frames destroyed with ``first_seq < seq < last_seq`` (no wrap of seq in between)."""
        d = np.asarray(self.destroyed, np.int64)
        return int(((d > first_seq) & (d < last_seq)).sum())

    def emitted(self) -> Emitted:
        """Every frame made since ``record`` was set, with its fate (``FATE_NAMES``)."""
        k = self.n_channels
        if not self._rec:
            return Emitted(
                np.empty(0, np.int64), np.empty(0, np.int64), np.empty((0, k), np.int64), np.empty(0, np.int8)
            )
        seq, t_us, values, fate = (np.concatenate(x) for x in zip(*self._rec, strict=False))
        return Emitted(seq, t_us, values, fate)

    def summary(self) -> str:
        """One line for people: what was injected and what the host must count."""
        i, nz = self.injected, self.expected()
        return (
            f"{self.frames} frames made, {self.delivered} sent intact; injected {i['checksum']} checksum, "
            f"{i['truncate']} truncate, {i['overlong']} overlong, {i['drop']} drop, {i['garbage']} garbage, "
            f"{i['stall']} stalls ({i['stall_s']:g} s), {i['burst']} bursts; the host must count "
            f"{nz['bad_checksum']} bad checksum, {nz['malformed']} malformed, {nz['overlong']} overlong, "
            f"{nz['lost']} lost."
        )
