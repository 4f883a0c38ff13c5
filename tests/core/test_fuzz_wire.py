"""Arbitrary bytes into the stream reader, beyond the codec properties of test_wire.py.

test_wire.py already feeds arbitrary bytes to ``parse_line`` and ``StreamReader.feed`` and checks
the fast path against the reference.  Left to check here: the stall accounting once a rate is
set (device times in arbitrary frames), the channel count fixed up front, ``read()`` from a port
that delivers arbitrary bytes in arbitrary bursts, and ``clear()`` at any point of a stream.
"""

from __future__ import annotations

import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from labcli.core.wire import COUNTER_NAMES, FrameBatch, StreamReader, checksum, format_frame

U32 = 1 << 32


def signed(payload: bytes) -> bytes:
    return b"$" + payload + b"*%02X\n" % checksum(payload)


@st.composite
def frame_lines(draw) -> bytes:
    """Correctly signed data lines with arbitrary fields: seq and t_us anywhere, odd value counts."""
    seq = draw(st.one_of(st.integers(0, U32 - 1), st.integers(-5, 2**70)))
    t_us = draw(st.one_of(st.integers(0, U32 - 1), st.integers(-5, 2**70)))
    vals = draw(
        st.lists(st.one_of(st.integers(-(2**64), 2**64), st.floats().map(repr).map(str)), min_size=0, max_size=8)
    )
    fields = [b"D", str(seq).encode(), str(t_us).encode(), *[str(v).encode() for v in vals]]
    return signed(b",".join(fields))


STREAM = st.lists(
    st.one_of(
        frame_lines(),
        st.binary(max_size=60),
        st.just(b"\n"),
        st.builds(lambda s, t: format_frame(s, t, [1, 2]), st.integers(0, U32 - 1), st.integers(0, U32 - 1)),
    ),
    max_size=40,
).map(b"".join)


def check_batch(batch: FrameBatch, k: int | None) -> None:
    n = len(batch)
    assert batch.seq.shape == (n,) and batch.t_us.shape == (n,)
    assert batch.seq.dtype == np.int64 and batch.t_us.dtype == np.int64
    if n:
        assert ((0 <= batch.seq) & (batch.seq < U32)).all() and ((0 <= batch.t_us) & (batch.t_us < U32)).all()
        assert batch.values.dtype == np.float64 and batch.values.shape[0] == n
        if k is not None:
            assert batch.values.shape[1] == k


def check_counters(r: StreamReader, fed: int, frames: int) -> None:
    assert set(r.counters) == set(COUNTER_NAMES)
    assert all(isinstance(v, int) and v >= 0 for v in r.counters.values())
    assert r.counters["bytes"] == fed and r.counters["frames"] == frames
    assert r.stalls >= 0 and math.isfinite(r.stalled_s) and r.stalled_s >= 0


@settings(max_examples=200, deadline=None)
@given(
    STREAM,
    st.lists(st.integers(1, 400), max_size=10),
    st.one_of(st.none(), st.integers(1, 8)),
    st.one_of(st.none(), st.floats(0.01, 1e6)),
    st.integers(0, 10**9),
)
def test_stall_accounting_never_raises_on_arbitrary_frames(stream, sizes, k, rate, stall_us) -> None:
    r = StreamReader(n_channels=k, stall_us=stall_us)
    r.set_rate(rate)
    frames, pos = 0, 0
    for size in sizes + [len(stream)]:
        batch = r.feed(stream[pos : pos + size])
        check_batch(batch, k)
        frames += len(batch)
        pos += size
        if pos >= len(stream):
            break
    check_counters(r, min(pos, len(stream)), frames)


@settings(max_examples=100, deadline=None)
@given(STREAM, st.integers(0, 400))
def test_clear_and_reset_anywhere_never_raise(stream, cut) -> None:
    r = StreamReader()
    r.set_rate(200.0)
    a = r.feed(stream[:cut])
    r.clear()
    r.reset_sequence()
    b = r.feed(stream[cut:])
    check_batch(a, None)
    check_batch(b, None)
    check_counters(r, len(stream), len(a) + len(b))


class BurstPort:
    """A port with pyserial's read/in_waiting that hands out a byte string in given bursts."""

    timeout = 0.0

    def __init__(self, data: bytes, bursts: list[int]) -> None:
        self.data, self.bursts = data, list(bursts)
        self.available = 0

    @property
    def in_waiting(self) -> int:
        if not self.available and self.data:
            self.available = min(len(self.data), self.bursts.pop(0) if self.bursts else len(self.data))
        return self.available

    def read(self, n: int = 1) -> bytes:
        self.in_waiting  # noqa: B018 - a burst arrives
        n = min(n, self.available)
        out, self.data = self.data[:n], self.data[n:]
        self.available -= n
        return out


@settings(max_examples=150, deadline=None)
@given(STREAM, st.lists(st.integers(1, 300), max_size=20), st.integers(1, 64))
def test_read_from_a_port_of_arbitrary_bytes_agrees_with_feed(stream, bursts, chunk) -> None:
    port = BurstPort(stream, bursts)
    r = StreamReader(port, chunk=chunk)
    got = []
    for _ in range(len(stream) + 2):
        batch = r.read(timeout=0.0)
        check_batch(batch, None)
        got.append(batch)
        if not port.data:
            break
    ref = StreamReader()
    want = ref.feed(stream)
    assert r.counters == ref.counters
    seq = np.concatenate([b.seq for b in got]) if got else np.empty(0, np.int64)
    assert seq.tolist() == want.seq.tolist()
