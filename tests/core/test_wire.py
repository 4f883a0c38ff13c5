"""Wire codec and stream reader: round trips, hostile bytes, and the fast path against the reference."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from support.firmware import data_line, xor_checksum

from labcli.core import wirechunk
from labcli.core.boardlines import Estimate, Event, format_estimate, format_event
from labcli.core.wire import (
    MAX_LINE,
    U32,
    Frame,
    LogLine,
    Noise,
    Reply,
    StreamReader,
    checksum,
    format_command,
    format_frame,
    format_log,
    parse_line,
)

u32 = st.integers(0, U32 - 1)
counts = st.integers(-(10**15) + 1, 10**15 - 1)
finite = st.floats(allow_nan=False, allow_infinity=False)
values = st.lists(st.one_of(counts, finite), min_size=1, max_size=12)


# -- codec ------------------------------------------------------------------


def test_protocol_document_example_checksum():
    line = b"$D,0,1000,1556,1560,1549,1551,2048,2047*76"
    assert checksum(b"D,0,1000,1556,1560,1549,1551,2048,2047") == 0x76
    assert parse_line(line) == Frame(0, 1000, (1556, 1560, 1549, 1551, 2048, 2047))
    assert format_frame(0, 1000, [1556, 1560, 1549, 1551, 2048, 2047]) == line + b"\n"


@given(st.binary(max_size=600))
def test_checksum_is_the_bytewise_xor(payload):
    assert checksum(payload) == xor_checksum(payload)


@given(u32, u32, values)
def test_format_then_parse_round_trips(seq, t_us, vals):
    line = format_frame(seq, t_us, vals)
    if len(line) - 1 > MAX_LINE:
        assert isinstance(parse_line(line), Noise)
        return
    parsed = parse_line(line, len(vals))
    assert parsed == Frame(seq, t_us, tuple(vals))
    assert all(type(a) is type(b) for a, b in zip(parsed.values, vals, strict=False))  # ints stay ints


@given(u32, u32, st.lists(st.integers(0, 4095), min_size=1, max_size=8))
def test_an_independent_encoder_is_understood(seq, t_us, vals):
    """The test firmware formats lines its own way (lower-case hex, CRLF)."""
    assert parse_line(data_line(seq, t_us, vals, b"\r\n")) == Frame(seq, t_us, tuple(vals))


def test_numpy_integers_are_encoded_as_integers():
    assert format_frame(1, 2, np.array([7, 8])) == format_frame(1, 2, [7, 8])


# Bytes that look like the protocol make the accept path likely, not just noise.
_alphabet = st.sampled_from(list(b"$D,0123456789*.-+eE#OKRIabcfx \r\x00\xff"))
_protocolish = st.lists(_alphabet, max_size=80).map(bytes)


@st.composite
def _maybe_signed(draw):
    body = draw(_protocolish)
    if draw(st.booleans()):
        # A correct checksum on arbitrary content: only the field checks stand between it and a frame.
        payload = body[1:] if body.startswith(b"$") else body
        body = b"$" + payload + b"*%02X" % checksum(payload)
    return body


@given(st.one_of(st.binary(max_size=400), _maybe_signed()), st.one_of(st.none(), st.integers(1, 8)))
@settings(max_examples=250)
def test_arbitrary_bytes_never_raise_and_frames_are_genuine(line, k):
    parsed = parse_line(line, k)
    assert isinstance(parsed, (Frame, Event, Estimate, LogLine, Reply, Noise))
    if isinstance(parsed, Frame):
        stripped = line.rstrip(b"\n")
        stripped = stripped[:-1] if stripped.endswith(b"\r") else stripped
        star = stripped.rindex(b"*")
        assert checksum(stripped[1:star]) == int(stripped[star + 1 :], 16)
        assert 0 <= parsed.seq < U32 and 0 <= parsed.t_us < U32
        assert k is None or len(parsed.values) == k
        again = format_frame(parsed.seq, parsed.t_us, parsed.values)
        body, hh = again[1:-1].split(b"*")
        assert checksum(body) == int(hh, 16)
        assert parse_line(again) == parsed


@pytest.mark.parametrize(
    "line, reason",
    [
        (b"$D,1,2,3*FF", "bad checksum"),
        (b"$D,1,2,3", "data line without '*HH' checksum at its end"),
        (b"$D,1,2,3*G1", "checksum is not two hex digits"),
        (b"", "empty line"),
        (b"hello", "not a data, log or reply line"),
        (b"OKAY", "not a data, log or reply line"),
        (b"x" * 257, f"line longer than {MAX_LINE} bytes"),
    ],
)
def test_noise_reasons(line, reason):
    parsed = parse_line(line)
    assert isinstance(parsed, Noise) and parsed.reason == reason


@pytest.mark.parametrize(
    "body, reason",
    [
        ("D,1,2", "data line has no values"),
        ("X,1,2,3", "data line does not start with '$D,', '$E,' or '$S,'"),
        ("E,1,2", "event line has no kind"),
        ("E,1,x,VALVE", "event number or t_us is not an unsigned 32-bit integer"),
        ("E,4294967296,2,VALVE", "event number or t_us is not an unsigned 32-bit integer"),
        ("E,1,2,valve", "event kind is not upper-case letters"),
        ("E,1,2,VALVE,S S", "event field holds characters outside letters, digits and _.:+-"),
        ("S,1,2,0", "estimate line has no values"),
        ("S,1,-2,0.1,0", "seq or t_us is not an unsigned 32-bit integer"),
        ("S,1,2,0.1,-1", "estimate flags are not an unsigned 32-bit integer"),
        ("S,1,2,0.1,nan,0", "an estimate is not a finite number"),
        ("S,1,2,1e999,0", "an estimate is not a finite number"),
        ("D,+1,2,3", "seq or t_us is not an unsigned integer"),
        ("D,4294967296,2,3", "seq or t_us outside unsigned 32-bit range"),
        ("D,1,2,nan", "a value is not a finite number"),
        ("D,1,2,1_000", "a value is not a finite number"),
        ("D,1,2, 7", "a value is not a finite number"),
        ("D,1,2,1e999", "a value is not a finite number"),
        ("D,1,2,3,4", "expected 1 values, got 2"),
    ],
)
def test_signed_lines_with_bad_fields_are_noise(body, reason):
    line = b"$" + body.encode() + b"*%02x" % checksum(body.encode())
    parsed = parse_line(line, 1 if body.endswith("3,4") else None)
    assert isinstance(parsed, Noise) and parsed.reason == reason


def test_event_and_estimate_lines_round_trip():
    line = format_event(7, 12345, "VALVE", ["SSHV", "host"])
    assert line == b"$E,7,12345,VALVE,SSHV,host*%02X\n" % checksum(b"E,7,12345,VALVE,SSHV,host")
    assert parse_line(line) == Event(7, 12345, "VALVE", ("SSHV", "host"))
    assert parse_line(format_event(0, 0, "RESET", ["wdt"]), 6) == Event(0, 0, "RESET", ("wdt",))  # not a frame's count
    est = parse_line(format_estimate(9, 5000, [0.0123456, -0.5, 1.25, -3e-7], 513))
    assert est == Estimate(9, 5000, (0.0123456, -0.5, 1.25, -3e-7), 513)
    assert est.flag_names == ["theta1-uncertain", "loaded"]
    assert parse_line(b"CAPS,1.1,valves=P_L1:P_R1,pmax") == Reply("CAPS,1.1,valves=P_L1:P_R1,pmax")


@given(u32, u32, st.lists(st.floats(allow_nan=False, allow_infinity=False, width=32), min_size=1, max_size=6), u32)
def test_estimates_round_trip_to_six_digits(seq, t_us, vals, flags):
    got = parse_line(format_estimate(seq, t_us, vals, flags))
    assert isinstance(got, Estimate) and (got.seq, got.t_us, got.flags) == (seq, t_us, flags)
    np.testing.assert_allclose(got.values, vals, rtol=1e-5, atol=0)


def test_logs_replies_and_commands():
    assert parse_line(b"# boot ok \r\n") == LogLine("boot ok")
    assert parse_line(format_log("two\nlines")) == LogLine("two lines")
    assert parse_line(b"OK RATE 200\r\n") == Reply("OK RATE 200")
    assert parse_line(b"ERR unknown command") == Reply("ERR unknown command")
    assert parse_line(b"ID,rig,1.0,A,B") == Reply("ID,rig,1.0,A,B")
    assert format_command("RATE", 200) == b"RATE 200\n"
    with pytest.raises(ValueError):
        format_command("RATE\n")


# -- stream reader ------------------------------------------------------------


def reference(stream: bytes, k: int | None = None) -> tuple[list[Frame], dict[str, int], list[str], list[str]]:
    """What the reader must produce: parse_line on every complete line, seq gaps counted mod 2**32."""
    *complete, tail = stream.split(b"\n")
    c = dict(frames=0, lost=0, bad_checksum=0, malformed=0, log_lines=0, overlong=0, replies=0, bytes=len(stream))
    c.update(events=0, estimates=0)
    frames, logs, replies, board = [], [], [], []
    last = None
    for line in complete:
        p = parse_line(line, k)
        if isinstance(p, Frame):
            k = len(p.values)
            if last is not None:
                gap = (p.seq - last - 1) % U32
                c["lost"] += gap if gap < U32 // 2 else 0
            last = p.seq
            frames.append(p)
            c["frames"] += 1
        elif isinstance(p, LogLine):
            c["log_lines"] += 1
            logs.append(p.text)
        elif isinstance(p, Reply):
            c["replies"] += 1
            replies.append(p.text)
        elif isinstance(p, (Event, Estimate)):
            c["events" if isinstance(p, Event) else "estimates"] += 1
            board.append(p)
        elif p.reason == "bad checksum":
            c["bad_checksum"] += 1
        elif p.reason.startswith("line longer"):
            c["overlong"] += 1
        else:
            c["malformed"] += 1
    if len(tail) > MAX_LINE + 1:  # already known to be overlong ('\r' may still come)
        c["overlong"] += 1
    return frames, c, logs, replies, board


def run_reader(chunks, k=None):
    r = StreamReader(n_channels=k)
    batches = [r.feed(ch) for ch in chunks]
    seq = np.concatenate([b.seq for b in batches]) if batches else np.empty(0)
    t = np.concatenate([b.t_us for b in batches]) if batches else np.empty(0)
    vals = [b.values for b in batches if len(b)]
    return r, seq, t, vals


def assert_agrees(stream: bytes, cuts: list[int], k: int | None = None) -> StreamReader:
    cuts = sorted(set(c for c in cuts if 0 < c < len(stream)))
    chunks = [stream[a:b] for a, b in zip([0] + cuts, cuts + [len(stream)], strict=False)]
    r, seq, t, vals = run_reader(chunks, k)
    frames, counters, logs, replies, board = reference(stream, k)
    assert r.counters == counters
    assert seq.tolist() == [f.seq for f in frames]
    assert t.tolist() == [f.t_us for f in frames]
    got = np.concatenate(vals) if vals else np.empty((0, 0))
    want = np.array([f.values for f in frames], dtype=np.float64)
    if frames:
        np.testing.assert_array_equal(got, want)
    assert list(r.logs) == logs and list(r.replies) == replies
    assert list(r.events) == [b for b in board if isinstance(b, Event)]
    assert list(r.estimates) == [b for b in board if isinstance(b, Estimate)]
    return r


def _good(seq, vals, crlf=False):
    return format_frame(seq, seq * 5000, vals)[:-1] + (b"\r\n" if crlf else b"\n")


@st.composite
def streams(draw):
    """A stream mixing good frames with every kind of damage the link produces."""
    k = draw(st.integers(1, 7))
    seq = draw(u32)
    parts = []
    for _ in range(draw(st.integers(0, 40))):
        kind = draw(
            st.sampled_from(
                ["good"] * 6
                + [
                    "decimal",
                    "gap",
                    "corrupt",
                    "cut",
                    "junk",
                    "log",
                    "reply",
                    "long",
                    "wrongk",
                    "bigint",
                    "protocolish",
                    "event",
                    "estimate",
                    "boardcut",
                ]
            )
        )
        vals = draw(st.lists(st.integers(0, 4095), min_size=k, max_size=k))
        if kind == "good":
            parts.append(_good(seq, vals, draw(st.booleans())))
            seq += 1
        elif kind == "decimal":
            parts.append(_good(seq, [v / 8 - 100 for v in vals]))
            seq += 1
        elif kind == "bigint":
            parts.append(_good(seq, [v * 10**14 for v in vals]))
            seq += 1
        elif kind == "gap":
            seq += draw(st.integers(1, 5))
        elif kind == "corrupt":
            line = bytearray(_good(seq, vals))
            i = draw(st.integers(0, len(line) - 2))
            line[i] = draw(st.integers(0, 255))
            parts.append(bytes(line))
            seq += 1
        elif kind == "cut":
            line = _good(seq, vals)
            parts.append(line[: draw(st.integers(0, len(line) - 1))])  # no '\n': merges with the next
            seq += 1
        elif kind == "junk":
            parts.append(draw(st.binary(max_size=40)))
        elif kind == "log":
            parts.append(b"#note\r\n")
        elif kind == "reply":
            parts.append(b"OK RATE 200\n")
        elif kind == "long":
            parts.append(b"y" * draw(st.integers(250, 700)) + draw(st.sampled_from([b"\n", b"\r\n", b""])))
        elif kind == "wrongk":
            parts.append(_good(seq, vals + [1]))
        elif kind == "event":
            parts.append(format_event(draw(u32), seq * 5000, draw(st.sampled_from(["VALVE", "PMAX", "RESET"])), vals))
        elif kind == "estimate":
            parts.append(format_estimate(max(seq - 1, 0), seq * 5000, [v / 1000 - 2 for v in vals], draw(u32)))
        elif kind == "boardcut":
            line = format_estimate(seq, 0, [0.5] * k, 0)
            parts.append(line[: draw(st.integers(0, len(line) - 1))])
        else:
            parts.append(draw(_maybe_signed()) + b"\n")
        seq %= U32
    stream = b"".join(parts)
    cuts = draw(st.lists(st.integers(0, max(len(stream), 1)), max_size=30))
    fixed_k = draw(st.sampled_from([None, k]))
    return stream, cuts, fixed_k


@given(streams())
@settings(max_examples=60, suppress_health_check=[HealthCheck.too_slow])
def test_fast_path_agrees_with_parse_line_on_any_stream(case):
    stream, cuts, k = case
    assert_agrees(stream, cuts, k)


@pytest.mark.slow
@given(streams())
@settings(max_examples=3000, suppress_health_check=[HealthCheck.too_slow])
def test_fast_path_agrees_with_parse_line_on_many_streams(case):
    stream, cuts, k = case
    assert_agrees(stream, cuts, k)


@st.composite
def clean_chunks(draw):
    """Chunks of good frames (the whole-chunk path's case), then at most a few bytes changed.

    Lines end "\\r\\n" all, none or some of them (each a case of its own in the reader); a field
    may carry leading zeros, up to lines longer than the protocol allows.
    """
    k = draw(st.integers(1, 14))
    big = st.integers(0, 10 ** draw(st.sampled_from([4, 10, 18, 20])))
    crlf = draw(st.sampled_from(["none", "all", "some"]))
    zeros = draw(st.sampled_from([0, 0, 3, 11, 12, 40]))
    lines = []
    for i in range(draw(st.integers(8, 30))):
        seq = draw(st.one_of(st.just(i), u32, st.integers(U32, 10**12)))
        vals = draw(st.lists(big, min_size=k, max_size=k))
        pad = b"0" * draw(st.integers(0, zeros))
        body = b",".join([b"D", b"%d" % seq, b"%d" % draw(u32)] + [pad + b"%d" % v for v in vals])
        hh = b"%02x" % checksum(body) if draw(st.booleans()) else b"%02X" % checksum(body)
        cr = crlf == "all" or (crlf == "some" and draw(st.booleans()))
        lines.append(b"$" + body + b"*" + hh + (b"\r\n" if cr else b"\n"))
    stream = bytearray(b"".join(lines))
    for _ in range(draw(st.integers(0, 2))):
        i = draw(st.integers(0, len(stream) - 2))
        stream[i] = draw(st.sampled_from(list(b"$D*,\r\n0123456789aAfF- .x#")) | st.integers(0, 255))
    return bytes(stream), k


@given(clean_chunks(), st.booleans())
@settings(max_examples=400, suppress_health_check=[HealthCheck.too_slow])
def test_whole_chunk_path_agrees_with_parse_line_after_any_damage(case, fixed_k):
    stream, k = case
    assert_agrees(stream, [], k if fixed_k else None)


def test_whole_chunk_path_takes_a_clean_chunk_and_refuses_a_damaged_one():
    k = 6
    lines = [_good(i, [i, 4095, 0, 7, 10**17, 2048], crlf=i % 3 == 0) for i in range(20)]
    block = b"".join(lines)
    batch = wirechunk.whole_chunk(block, k, MAX_LINE)
    assert batch is not None and batch[0].tolist() == list(range(20))
    assert batch[2][:, 4].tolist() == [1e17] * 20
    for damaged in (
        block.replace(b"4095", b"40a5", 1),  # a hex letter inside a value
        block.replace(b",7,", b",-7,", 1),
        block.replace(b",2048", b",", 1),
        block.replace(lines[5], lines[5][:-1] + b"\r\r\n"),
        block.replace(lines[6], lines[6][:-2] + b"0\n"),  # three checksum digits
        block.replace(b"$D,3,", b"$D,4294967296,", 1),
        block.replace(lines[4], lines[4][:-3] + b"\r" + lines[4][-3:]),  # a '\r' inside the checksum
        block.replace(lines[4], lines[4][:-4] + b"\r" + lines[4][-4:]),  # ... before it
        block.replace(lines[4], b"\r" + lines[4]),  # ... before the '$'
        block.replace(lines[4], lines[4].replace(b"$D,", b"$D,,", 1)),  # an empty field ...
        block.replace(lines[4], lines[4].replace(b"$D,", b"x$D,", 1)),  # a byte before the '$'
        block.replace(lines[4], _resum(lines[4].replace(b",2048*", b",*"))),  # an empty last field
        block.replace(lines[4], _resum(lines[4].replace(b"$D,4,", b"$D,,"))),  # an empty first field
        block.replace(lines[4], _resum(lines[4].replace(b",7,", b"*7,"))),  # a '*' for a ','
        block.replace(lines[4], _resum(lines[4].replace(b",7,", b",7*0,"))),  # a '*' inside a field
        block.replace(lines[4], _resum(lines[4].replace(b",7,", b",7,0,"))),  # one value too many
        block.replace(lines[4], _resum(lines[4].replace(b",7,", b",0$7,"))),  # a '$' inside a field
        block.replace(lines[4], _resum(lines[4].replace(b",7,", b", 7,"))),  # a blank before a value
        block.replace(lines[4], _resum(lines[4].replace(b",7,", b",-7,"))),  # a sign, checksum right
        block.replace(lines[4], _resum(lines[4].replace(b",7,", b",7" + b"0" * 200 + b",")), 1),  # too long
        block.replace(lines[4], _resum(lines[4].replace(b",7,", b"," + b"0" * 220 + b"7,"))),  # ... in zeros
    ):
        assert wirechunk.whole_chunk(damaged, k, MAX_LINE) is None
        assert_agrees(damaged, [], k)


def _resum(line: bytes) -> bytes:
    """``line`` (``$...*HH`` and its end) with its checksum made right again."""
    star = line.rindex(b"*")
    return line[: star + 1] + b"%02X" % checksum(line[1:star]) + line[star + 3 :]


def test_whole_chunk_path_takes_every_kind_of_line_end():
    k = 6
    for crlf in ([False] * 20, [True] * 20, [i == 7 for i in range(20)], [i % 2 == 0 for i in range(20)]):
        lines = [_good(i, [i, 4095, 0, 7, 10**17, 2048], crlf=crlf[i]) for i in range(20)]
        block = b"".join(lines)
        batch = wirechunk.whole_chunk(block, k, MAX_LINE)
        assert batch is not None and batch[0].tolist() == list(range(20)), crlf
        assert batch[1].tolist() == [i * 5000 for i in range(20)]
        assert batch[2][:, 0].tolist() == list(range(20)) and batch[2][:, 5].tolist() == [2048] * 20
        for i in (0, 7, 19):
            body = lines[i].rstrip(b"\r\n")
            inside = block.replace(lines[i], body[:-1] + b"\r" + body[-1:] + b"\n")  # a '\r' in the checksum
            doubled = block.replace(lines[i], body + b"\r\r\n")
            for damaged in (inside, doubled):
                assert wirechunk.whole_chunk(damaged, k, MAX_LINE) is None
                assert_agrees(damaged, [], k)


def test_an_empty_field_is_refused_before_a_numpy_that_only_warns_reads_it(monkeypatch):
    """An older numpy reads up to an empty field or a NUL, warns and stops: whole_chunk must not call it then."""
    real = np.fromstring

    def older_numpy(text, dtype, sep):
        text = bytes(text)
        assert b",," not in text and text[:1] != b",", "fromstring met an empty field"
        assert b"\0" not in text, "fromstring met a NUL"
        return real(text, dtype=dtype, sep=sep)

    monkeypatch.setattr(wirechunk, "_EMPTY_FIELD_RAISES", False)
    monkeypatch.setattr(np, "fromstring", older_numpy)
    lines = [_good(i, [i, 1, 2, 3, 4, 5]) for i in range(20)]
    assert wirechunk.whole_chunk(b"".join(lines), 6, MAX_LINE) is not None
    for i in (0, 7, 19):
        for old, new in (
            (b"$D,%d," % i, b"$D,,"),
            (b",5*", b",*"),
            (b",2,", b",,"),
            (b",2,", b",2x,"),
            (b",3", b",\x003"),
        ):
            damaged = b"".join(lines[:i] + [_resum(lines[i].replace(old, new))] + lines[i + 1 :])
            assert wirechunk.whole_chunk(damaged, 6, MAX_LINE) is None


def test_fromstring_here_refuses_a_nul_and_an_empty_field_or_the_reader_checks_first():
    """Where numpy's fromstring raises at both, the whole-chunk path leaves finding them to it.

    A blank or a sign fromstring reads past (or as a number's): the path refuses those itself.
    """
    if wirechunk._EMPTY_FIELD_RAISES:
        for text in (b"1,,2", b"1,2\x00,3", b"1,\x002", b"7,1\x00"):
            with pytest.raises(ValueError):
                np.fromstring(text, dtype=np.int64, sep=",")
    lines = [_good(i, [i, 1, 2, 3, 4, 5]) for i in range(20)]
    for i in (0, 7, 19):
        nul = ((b",2,", b",2\x00,"), (b",2,", b",\x002,"), (b",5*", b",5\x00*"), (b",5*", b",5x*"))
        blank = tuple((b",2,", b",%s2," % c) for c in (b" ", b"\t", b"\x0b", b"\x0c", b"+", b"-", b"\r"))
        for old, new in nul + blank + ((b",2,", b",2 ,"), (b",2,", b",2\t,"), (b",5*", b",5 *")):
            damaged = b"".join(lines[:i] + [_resum(lines[i].replace(old, new))] + lines[i + 1 :])
            assert wirechunk.whole_chunk(damaged, 6, MAX_LINE) is None
            assert_agrees(damaged, [], 6)


def test_a_line_of_leading_zeros_is_refused_exactly_past_256_bytes():
    good = [_good(i, [i, 1, 2, 3, 4, 5]) for i in range(20)]
    for length in (255, 256, 257, 258):
        line = _good(5, [5, 1, 2, 3, 4, 5])
        line = _resum(line.replace(b",1,", b"," + b"0" * (length - len(line) + 1) + b"1,"))
        assert len(line) == length + 1
        block = b"".join(good[:5] + [line] + good[6:])
        batch = wirechunk.whole_chunk(block, 6, MAX_LINE)
        assert (batch is not None) == (length <= MAX_LINE)
        assert_agrees(block, [], 6)


@given(st.binary(max_size=2000), st.lists(st.integers(0, 2000), max_size=20))
@settings(max_examples=200)
def test_reader_never_raises_on_random_bytes(stream, cuts):
    assert_agrees(stream, cuts)


SAMPLE = (
    _good(7, [1556, 1560, 1549, 1551, 2048, 2047])
    + b"#boot done\r\n"
    + _good(8, [1, 2, 3, 4, 5, 6], crlf=True)
    + b"OK START\n"
    + _good(9, [10, 20, 30, 40, 50, 60])[:-3]
    + b"00\n"  # corrupted checksum
    + b"\x00\xffjunk\n"
    + format_event(3, 50000, "PMAX", ["P_L1", 3200])
    + format_estimate(9, 45000, [0.01, -0.02, 1.5, -0.25], 0)
    + _good(11, [0, 0, 0, 0, 0, 4095])
)


def test_split_at_every_byte_position_gives_the_same_result():
    whole = assert_agrees(SAMPLE, [])
    assert whole.counters == dict(
        frames=3, lost=2, bad_checksum=1, malformed=1, log_lines=1, overlong=0, replies=1, bytes=len(SAMPLE)
    ) | dict(events=1, estimates=1)
    for i in range(1, len(SAMPLE)):
        r = assert_agrees(SAMPLE, [i], k=6)
        assert r.counters == whole.counters
    r = assert_agrees(SAMPLE, list(range(len(SAMPLE))))  # one byte at a time
    assert r.counters == whole.counters


def test_overlong_run_is_counted_once_and_the_next_line_is_read():
    r = StreamReader(n_channels=1)
    noise = b"z" * 10_000
    for i in range(0, len(noise), 100):
        assert len(r.feed(noise[i : i + 100])) == 0
    batch = r.feed(b"still noise\n" + format_frame(3, 4, [5]))
    assert batch.seq.tolist() == [3] and batch.values.tolist() == [[5.0]]
    assert r.counters["overlong"] == 1 and r.counters["malformed"] == 0 and r.counters["frames"] == 1


def test_line_length_limit_is_exactly_256_bytes_before_the_newline():
    r = StreamReader()
    r.feed(b"#" + b"a" * 255 + b"\r\n")  # 256 bytes + CRLF: fine
    r.feed(b"#" + b"a" * 256 + b"\n")  # 257: noise
    assert r.counters["log_lines"] == 1 and r.counters["overlong"] == 1
    r.feed(b"#" + b"b" * 256)  # 257 pending: a '\r' may still come... it does not
    assert r.counters["overlong"] == 1
    r.feed(b"c\n")
    assert r.counters["overlong"] == 2


@pytest.mark.parametrize(
    "seqs, lost",
    [
        ([U32 - 2, U32 - 1, 0, 1], 0),  # wrap without loss
        ([U32 - 2, 1], 2),  # U32-1 and 0 lost across the wrap
        ([U32 - 1, 3], 3),
        ([5, 6, 10], 3),
        ([100, 101, 0, 1], 0),  # firmware restarted: not a loss
        ([4, 4, 5], 0),  # repeated line
    ],
)
def test_lost_frames_from_sequence_gaps(seqs, lost):
    stream = b"".join(format_frame(s, 0, [1, 2]) for s in seqs)
    r = assert_agrees(stream, [len(stream) // 2])
    assert r.counters["lost"] == lost and r.counters["frames"] == len(seqs)


def test_reset_sequence_forgets_the_last_seq():
    r = StreamReader()
    r.feed(format_frame(50, 0, [1]))
    r.reset_sequence()
    r.feed(format_frame(0, 0, [1]) + format_frame(2, 0, [1]))
    assert r.counters["lost"] == 1


def test_channel_count_is_fixed_by_the_first_frame():
    r = StreamReader()
    b = r.feed(format_frame(0, 0, [1, 2]) + format_frame(1, 0, [1, 2, 3]) + format_frame(2, 0, [3, 4]))
    assert r.n_channels == 2 and b.values.tolist() == [[1, 2], [3, 4]]
    assert r.counters["malformed"] == 1


class ChunkPort:
    """A pyserial stand-in that hands out the stream in bursts and forbids line-wise reading."""

    timeout = 0.01

    def __init__(self, bursts):
        self.bursts = list(bursts)
        self.sizes = []

    @property
    def in_waiting(self):
        return len(self.bursts[0]) if self.bursts else 0

    def read(self, size=1):
        self.sizes.append(size)
        if not self.bursts:
            return b""
        burst = self.bursts.pop(0)
        out, rest = burst[:size], burst[size:]
        if rest:
            self.bursts.insert(0, rest)
        return out

    def readline(self):  # pragma: no cover - the reader must never call it
        raise AssertionError("readline is byte by byte in pyserial")


def test_read_takes_whole_bursts_from_the_port():
    frames = b"".join(format_frame(i, i, [i, i]) for i in range(100))
    port = ChunkPort([frames[:1234], frames[1234:]])
    r = StreamReader(port, n_channels=2)
    got = []
    while len(got) < 100:
        got.extend(r.read(0.5).seq.tolist())
    assert got == list(range(100))
    assert port.sizes == [1234, len(frames) - 1234]


def test_read_returns_empty_after_timeout_on_a_silent_port():
    port = ChunkPort([])
    r = StreamReader(port, n_channels=2)
    assert len(r.read(0.05)) == 0
    assert set(port.sizes) == {1}


def test_place_value_decoder_agrees_when_numpy_has_no_text_parser(monkeypatch):
    stream = b"".join(format_frame(i, 7 * i, [i, 10**15 - 1, 0, 10**16 + i]) for i in range(40))
    stream += b"".join(format_frame(U32 - 1 + i, U32 + i, [3, 2, 1, 0]) for i in range(12))  # t_us wraps
    want = assert_agrees(stream, [1000])
    monkeypatch.delattr(np, "fromstring")
    got = assert_agrees(stream, [1000])
    assert got.counters == want.counters and got.counters["frames"] == 52


@given(st.lists(st.tuples(st.integers(-(2**40), 2**40), st.integers(0, 3000)), min_size=1, max_size=30))
def test_steps_bytes_are_the_run_of_numbers_asked_for_from_any_first(calls):
    for first, n in calls:  # climbing, falling and far jumps: the kept run is cut or made again
        assert wirechunk.steps_bytes(n, first) == np.arange(first, first + n, dtype=np.int64).tobytes()


@given(st.lists(st.sampled_from([1, 1, 1, 2, 0, -3, 40_000]), min_size=1, max_size=80), st.integers(0, U32 - 1))
def test_loss_over_many_clean_chunks_is_counted_as_frame_by_frame(steps, start):
    # Chunks of 20 frames each (the whole-chunk path), seq climbing by the given steps.
    seqs, s = [], start
    for step in steps:
        s = (s + step) % U32
        seqs.append(s)
    lines = [format_frame(q, 0, [1, 2, 3]) for q in seqs]
    r = StreamReader()
    for i in range(0, len(lines), 20):
        r.feed(b"".join(lines[i : i + 20]))
    gaps = [(b - a - 1) % U32 for a, b in zip(seqs, seqs[1:], strict=False)]
    assert r.counters["frames"] == len(seqs)
    assert r.counters["lost"] == sum(g for g in gaps if g < U32 >> 1)


@st.composite
def clean_streams(draw):
    """Long runs of good frames of one channel count (the clean-chunk path), cut anywhere.

    Now and then a frame is lost, the firmware restarts, the device time jumps (a stall), a line
    ends "\\r\\n", a value (fine) or the device time (noise) is too big for 32 bits, a field carries
    leading zeros (up to a line too long), or a line is damaged: the chunks around it take the
    other paths.
    """
    k = draw(st.integers(1, 8))
    seq, t = draw(u32), draw(u32)
    period = draw(st.sampled_from([1000, 5000]))
    kinds = ["good"] * 14 + ["gap", "restart", "stall", "crlf", "crlf", "big", "bigt", "zeros", "damage"]
    lines = []
    for _ in range(draw(st.integers(20, 160))):
        kind = draw(st.sampled_from(kinds))
        vals = draw(st.lists(st.integers(0, 4095), min_size=k, max_size=k))
        if kind == "gap":
            seq += draw(st.integers(1, 3))
        elif kind == "restart":
            seq = draw(st.integers(0, 5))
        elif kind == "stall":
            t += draw(st.integers(0, 3 * STALL))
        elif kind == "big":
            vals[-1] = draw(st.integers(U32, 10**15))
        line = format_frame(seq, t, vals)
        if kind == "crlf":
            line = line[:-1] + b"\r\n"
        elif kind == "zeros":
            line = _resum(line.replace(b",", b"," + b"0" * draw(st.sampled_from([11, 12, 20, 21, 40, 250])), 2))
        elif kind == "bigt":  # device time past 32 bits: noise
            fields = line.split(b",")
            line = _resum(b",".join(fields[:2] + [b"%d" % (t + U32)] + fields[3:]))
        elif kind == "damage":
            i = draw(st.integers(0, len(line) - 2))
            line = line[:i] + bytes([draw(st.integers(0, 255))]) + line[i + 1 :]
        lines.append(line)
        seq, t = (seq + 1) % U32, (t + period) % U32
    stream = b"".join(lines)
    cuts = draw(st.lists(st.integers(0, len(stream)), max_size=12))
    return stream, cuts, draw(st.sampled_from([None, k])), period


STALL = 20_000


def reference_stalls(frames: list[Frame], period_us: float, stall_us: int) -> int:
    """Stalls frame by frame: device time beyond the seq step's periods, between frames that go forward."""
    stalls = 0
    for prev, f in zip(frames, frames[1:], strict=False):
        gap = (f.seq - prev.seq - 1) % U32
        if gap < U32 // 2 and (f.t_us - prev.t_us) % U32 - (gap + 1) * period_us > stall_us:
            stalls += 1
    return stalls


@given(clean_streams())
@settings(max_examples=150, suppress_health_check=[HealthCheck.too_slow])
def test_clean_chunks_cut_anywhere_give_the_reference_frames_losses_and_stalls(case):
    stream, cuts, k, period = case
    cuts = sorted(set(c for c in cuts if 0 < c < len(stream)))
    for rate in (None, 1e6 / period):
        r = StreamReader(n_channels=k, stall_us=STALL)
        r.set_rate(rate)
        batches = [r.feed(stream[a:b]) for a, b in zip([0] + cuts, cuts + [len(stream)], strict=False)]
        frames, counters, *_ = reference(stream, k)
        assert r.counters == counters
        assert np.concatenate([b.seq for b in batches]).tolist() == [f.seq for f in frames]
        assert np.concatenate([b.t_us for b in batches]).tolist() == [f.t_us for f in frames]
        got = [b.values for b in batches if len(b)]
        if frames:
            np.testing.assert_array_equal(np.concatenate(got), np.array([f.values for f in frames], np.float64))
        assert r.stalls == (0 if rate is None else reference_stalls(frames, r.period_us, STALL))


def reference_stalled_s(frames: list[Frame], period_us: float, stall_us: int) -> float:
    """The device time lost to stalls, frame by frame (as :func:`reference_stalls` finds them), s."""
    total = 0.0
    for prev, f in zip(frames, frames[1:], strict=False):
        gap = (f.seq - prev.seq - 1) % U32
        excess = (f.t_us - prev.t_us) % U32 - (gap + 1) * period_us
        if gap < U32 // 2 and excess > stall_us:
            total += excess * 1e-6
    return total


@given(clean_streams(), st.lists(st.integers(1, 3), min_size=1, max_size=40))
@settings(max_examples=150, suppress_health_check=[HealthCheck.too_slow])
def test_chunks_of_one_to_three_lines_give_the_reference_frames_losses_and_stalls(case, sizes):
    """An idle host reads a line or a few at a time: each chunk's frames are counted one by one."""
    stream, _, k, period = case
    lines = stream.splitlines(keepends=True)
    chunks, i = [], 0
    while i < len(lines):
        size = sizes[len(chunks) % len(sizes)]
        chunks.append(b"".join(lines[i : i + size]))
        i += size
    frames, counters, *_ = reference(stream, k)
    for rate in (None, 1e6 / period, 1e6 / (period + 1 / 3)):  # a period not a whole number of us too
        r = StreamReader(n_channels=k, stall_us=STALL)
        r.set_rate(rate)
        batches = [r.feed(ch) for ch in chunks]
        assert r.counters == counters
        assert np.concatenate([b.seq for b in batches]).tolist() == [f.seq for f in frames]
        assert np.concatenate([b.t_us for b in batches]).tolist() == [f.t_us for f in frames]
        if rate is None:
            assert r.stalls == 0 and r.stalled_s == 0.0
        else:
            assert r.stalls == reference_stalls(frames, r.period_us, STALL)
            assert r.stalled_s == pytest.approx(reference_stalled_s(frames, r.period_us, STALL), rel=1e-12, abs=1e-12)


def _resummed(body: bytes, hexdigits: bytes = b"%02X") -> bytes:
    return b"$" + body + b"*" + hexdigits % checksum(body) + b"\n"


@pytest.mark.parametrize(
    "line",
    [
        _resummed(b"D,1,2,%d,7" % (2**53 - 1)),  # the largest count exact in float64: the few-frames path
        _resummed(b"D,1,2,%d,7" % 2**53),  # one more: left to the other paths (a frame all the same)
        _resummed(b"D,%d,2,3,7" % (U32 - 1)),
        _resummed(b"D,%d,2,3,7" % U32),  # seq past 32 bits: noise
        _resummed(b"D,1,2,3,7", b"%02x"),  # a lowercase checksum
        _resummed(b"D,1,2,+3,7"),  # a sign: a frame by parse_line, not by the few-frames path
        _resummed(b"D,1,2,3.5,7"),
        _resummed(b"D,1,2,,7"),
        _resummed(b"D,1,2,3,7,8"),  # a value too many
        _resummed(b"D,1,2,3,7")[:-1] + b"\r\n",
        _resummed(b"D,1,2,3,7")[:-1] + b"\r\r\n",
        _resummed(b"D,1,2,3,7").replace(b"*", b"**"),
        _resummed(b"D,1,2,3\r,7"),
        _resummed(b"D,1,2,3,7\xb2"),  # a non-ASCII digit
        _resummed(b"D,1,2," + b"0" * 240 + b"3,7"),  # leading zeros up to a line too long
        _resummed(b"D,1,2," + b"0" * 235 + b"3,7"),
        _resummed(b"E,1,2,VALVE,S"),
        b"#boot\n",
    ],
)
def test_a_line_read_alone_or_beside_two_frames_is_what_parse_line_makes_of_it(line):
    """A read of one to three lines (an idle host's) judges each line as the reference parser does."""
    good = [_good(7 + i, [1, 2]) for i in range(2)]
    stream = good[0] + line + good[1]
    for k in (None, 2):
        assert_agrees(stream, [len(good[0]), len(good[0]) + len(line)], k)  # the line alone
        assert_agrees(stream, [], k)  # with a frame before and after it
        assert_agrees(stream, [len(good[0]) + 3], k)  # cut inside it


def test_reads_of_a_few_clean_lines_take_the_python_path_and_eight_take_numpy(monkeypatch):
    calls = []
    monkeypatch.setattr("labcli.core.wire.clean_rows", lambda *a: calls.append(a) or wirechunk.clean_rows(*a))
    lines = [_good(i, [i, 4095, 0, 7, 2048, 1], crlf=i == 2) for i in range(19)]
    r = StreamReader(n_channels=6)
    r.set_rate(200)
    got = [r.feed(b"".join(lines[:3])), r.feed(lines[3][:10]), r.feed(lines[3][10:])]
    assert not calls  # 3 lines, then a line cut in two: no numpy parse
    got.append(r.feed(b"".join(lines[4:11])))  # 7 lines
    assert not calls
    got.append(r.feed(b"".join(lines[11:19])))
    assert len(calls) == 1  # 8 lines: the whole-chunk path
    assert np.concatenate([b.seq for b in got]).tolist() == list(range(19))
    assert r.counters["frames"] == 19 and r.counters["lost"] == 0 and r.lines == 19


def test_a_few_frames_are_counted_as_a_batch_of_many_counts_them():
    """Loss, a restart and stalls read a frame at a time (counted one by one) and in one read (by numpy)."""
    seqs = [5, 6, 9, 10, 2, 3, 4, 5]  # two lost before 9, a restart at 2 (nothing lost)
    times = [0, 1000, 900_000, 901_000, 1_400_000, 1_401_000, 1_700_000, 2_000_000]  # stalls before 9, 4, 5
    lines = [format_frame(q, t, [1, 2]) for q, t in zip(seqs, times, strict=True)]
    few, many = (StreamReader(n_channels=2, stall_us=100_000) for _ in range(2))
    for r in (few, many):
        r.set_rate(1000)
    for line in lines:
        few.feed(line)
    many.feed(b"".join(lines))
    assert few.counters == many.counters and few.counters["lost"] == 2
    assert few.stalls == many.stalls == 3
    want_us = (900_000 - 1000 - 3000) + (1_700_000 - 1_401_000 - 1000) + (2_000_000 - 1_700_000 - 1000)
    assert few.stalled_s == many.stalled_s == pytest.approx(want_us * 1e-6, abs=1e-12)


def test_a_clean_stream_in_4_kib_chunks_is_read_whole_chunk_by_chunk(monkeypatch):
    """Each chunk, with the line carried from the one before, is taken by clean_rows in one piece."""
    taken = []

    def counting(*args):
        rows = wirechunk.clean_rows(*args)
        taken.append(rows is not None)
        return rows

    monkeypatch.setattr("labcli.core.wire.clean_rows", counting)
    lines = [_good(i, [i % 4096, 4095, 0, 7, 2048, 1], crlf=i % 50 == 0) for i in range(2000)]
    stream = b"".join(lines)
    r = assert_agrees(stream, list(range(4096, len(stream), 4096)), 6)
    assert r.counters["frames"] == 2000 and taken and all(taken)
    assert r.lines == 2000


def test_many_carriage_returns_not_one_a_line_are_each_checked():
    """More '\\r' than are found one by one, but not on every line: still only before a '\\n'."""
    lines = [_good(i, [i, 1, 2, 3, 4, 5], crlf=i % 3 != 0) for i in range(60)]  # 40 of 60 lines
    block = b"".join(lines)
    rows = wirechunk.clean_rows(b"", block, len(block), 6, MAX_LINE)
    assert rows is not None and rows[:, 0].tolist() == list(range(60))
    for i in (0, 1, 59):
        body = lines[i].rstrip(b"\r\n")
        for damaged in (body[:-1] + b"\r" + body[-1:] + b"\n", body + b"\r\r\n", b"\r" + body + b"\n"):
            block_d = b"".join(lines[:i] + [damaged] + lines[i + 1 :])
            assert wirechunk.clean_rows(b"", block_d, len(block_d), 6, MAX_LINE) is None
            assert_agrees(block_d, [], 6)


@given(st.integers(0, 4000), st.sampled_from([1, 6, 9]))
def test_clean_rows_of_a_carried_head_and_a_chunk_are_those_of_the_whole_block(cut, k):
    lines = [_good(i, [(i * 37 + j) % 4096 for j in range(k)], crlf=i % 7 == 0) for i in range(80)]
    block = b"".join(lines)
    cut = min(cut, len(block) - 1)
    data = block[cut:] + b"$D,12"  # a partial line after the last '\n' is left out
    whole = wirechunk.clean_rows(b"", block, len(block), k, MAX_LINE)
    split = wirechunk.clean_rows(block[:cut], data, len(data) - 5, k, MAX_LINE)
    assert whole is not None and split is not None
    assert whole.tolist() == split.tolist()
    assert whole[:, -1].tolist() == [-1] * 80 and whole[:, 0].tolist() == list(range(80))
