"""Stall reporting: gaps in the rig's own clock, counted by the stream reader.

A stall is a gap between consecutive frames whose device time (``t_us``)
exceeds what their ``seq`` difference allows at the confirmed rate by more
than ``stall_us`` (0.25 s).  The fault injector (``labcli.core.sim.faults``) knows
every stall it made, ``[(seq of the frame after it, seconds)]``: the counts
here are compared with that ground truth exactly.
"""

from __future__ import annotations

import json

import numpy as np
import pytest
import serial
from click.testing import CliRunner

from labcli.cli import cli
from labcli.core.device import Device
from labcli.core.sim import register
from labcli.core.sim.pty import serve_pty
from labcli.core.wire import STALL_US, U32, FrameBatch, StreamReader, format_frame
from labcli.errors import DeviceTimeout

register()


def expected_stalls(seqs: np.ndarray, stalls: list[tuple[int, float]], stall_us: int = STALL_US) -> tuple[int, float]:
    """Gaps between consecutive received frames holding injected stall time above ``stall_us``."""
    by_seq = dict(stalls)
    count, total = 0, 0.0
    for a, b in zip(seqs[:-1].tolist(), seqs[1:].tolist(), strict=False):
        s = sum(by_seq.get(q, 0.0) for q in range(a + 1, b + 1))
        if s * 1e6 > stall_us:
            count += 1
            total += s
    return count, total


def read_frames(dev: Device, n: int) -> FrameBatch:
    dev.start()
    batches, got = [], 0
    while got < n:
        b = dev.read(timeout=1.0)
        batches.append(b)
        got += len(b)
    batches.append(dev.stop())
    return FrameBatch.concat(batches, len(dev.info.channels))


def frames(rows) -> bytes:
    return b"".join(format_frame(seq, t, (1, 2)) for seq, t in rows)


# ---------------------------------------------------------------- the rule, on hand-made streams


def test_a_gap_counts_only_beyond_the_threshold_and_only_once_the_rate_is_known():
    period = 5000  # 200 Hz
    rows = [(i, i * period) for i in range(10)]
    rows += [(10, 10 * period + 250_000)]  # exactly at the threshold: not a stall
    rows += [(11, 11 * period + 250_000 + 250_001)]  # just beyond it
    rows += [(15, 15 * period + 500_001)]  # 3 frames lost in between: their periods are expected
    rows += [(16, 16 * period + 500_001)]
    data = frames(rows)

    blind = StreamReader(n_channels=2)
    blind.feed(data)
    assert blind.stalls == 0  # no rate, no expectation

    r = StreamReader(n_channels=2)
    r.set_rate(200)
    r.feed(data)
    assert r.stalls == 1 and r.counters["lost"] == 3
    assert r.stalled_s == pytest.approx(0.250001, abs=1e-9)
    assert "stalls" not in r.counters  # the wire counters stay the protocol's own

    # Byte by byte: a gap straddling two reads is still one stall.
    r2 = StreamReader(n_channels=2)
    r2.set_rate(200)
    for i in range(len(data)):
        r2.feed(data[i : i + 1])
    assert r2.stalls == 1

    r.reset_counters()
    assert r.stalls == 0 and r.stalled_s == 0.0


def test_device_time_wraps_and_restarts_are_not_stalls():
    period = 1000
    start = U32 - 3 * period  # t_us wraps at 2**32 us (71.6 min) between frames 2 and 3
    rows = [(i, (start + i * period) % U32) for i in range(6)]
    rows += [(0, 123), (1, 123 + period)]  # the firmware restarted: seq and clock begin again
    r = StreamReader(n_channels=2)
    r.set_rate(1000)
    r.feed(frames(rows))
    assert r.stalls == 0 and r.counters["lost"] == 0

    stalled = [(0, 0), (1, period), (2, 2 * period + 400_000)]
    r = StreamReader(n_channels=2)
    r.set_rate(1000)
    r.feed(frames(stalled))
    r.reset_sequence()  # START: the first frame after it has no predecessor
    r.feed(frames([(7, 10**9)]))
    assert r.stalls == 1 and r.stalled_s == pytest.approx(0.4)


@pytest.mark.parametrize("lines_per_read", [1, 3, 8, 40, 1000])
def test_losses_and_stalls_do_not_depend_on_how_the_stream_is_cut(lines_per_read):
    """Against the rule written frame by frame: runs of consecutive frames take a shortcut in the reader."""
    period, rng = 1000, np.random.default_rng(5)
    rows, seq, t = [], 0, 0
    for _ in range(400):
        step = 1 if rng.random() < 0.95 else int(rng.integers(2, 5))
        seq, t = seq + step, t + step * period + (300_000 if rng.random() < 0.03 else 0)
        rows.append((seq % U32, t % U32))
    lost = stalls = 0
    stalled_s = 0.0
    for (a, ta), (b, tb) in zip(rows[:-1], rows[1:], strict=False):
        lost += b - a - 1
        excess = tb - ta - (b - a) * period
        if excess > STALL_US:
            stalls, stalled_s = stalls + 1, stalled_s + excess * 1e-6
    r = StreamReader(n_channels=2)
    r.set_rate(1000)
    for i in range(0, len(rows), lines_per_read):
        r.feed(frames(rows[i : i + lines_per_read]))
    assert 5 < stalls and 5 < lost
    assert (r.counters["frames"], r.counters["lost"], r.stalls) == (len(rows), lost, stalls)
    assert r.stalled_s == pytest.approx(stalled_s, abs=1e-9)


# ---------------------------------------------------------------- the simulated rig's injected stalls


@pytest.mark.parametrize("seconds, noisy", [(0.75, True), (0.3, False), (0.2, False)])
def test_stall_count_equals_the_injected_stalls_exactly(seconds, noisy):
    spec = f"stall:0.002@{seconds}" + (",drop:0.01,checksum:0.01,truncate:0.005,burst:0.001@40" if noisy else "")
    with Device.open(f"sim://?seed=3&rate=1000&faults={spec}") as dev:
        assert dev.set_rate(1000) == 1000.0
        inj = dev.serial.faults
        batch = read_frames(dev, 30_000)
        counters = dev.counters
    want, want_s = expected_stalls(batch.seq, inj.stalls)
    assert inj.injected["stall"] > 20
    assert counters["stalls"] == dev.stalls == want
    if seconds > STALL_US * 1e-6:
        # Every injected stall between the first and last frame received is one stall.
        inside = sum(1 for s, _ in inj.stalls if batch.seq[0] < s <= batch.seq[-1])
        assert want == inside > 20
        assert dev.stalled_s == pytest.approx(want_s, abs=want * 2e-6)
    else:
        assert want == 0 == dev.stalls


def test_a_stall_longer_than_the_silence_timeout_is_a_device_timeout_then_counts_as_a_stall():
    url = "sim://?seed=0&rate=1000&clock=wall&faults=stall:0.002@1.5"
    first_stall = serial.serial_for_url(url).faults.schedule(0, 2000)["stall"][0]
    with Device.open(url, timeout=1.0) as dev:
        dev.set_rate(1000)
        dev.start()
        with pytest.raises(DeviceTimeout) as e:
            while True:
                dev.read(timeout=0.5)
        assert str(e.value) == (
            f"No data from {url} for 1 s while streaming. Check the cable and that the rig is powered."
        )
        assert dev.stalls == 0  # nothing came after the silence yet
        batch = dev.read(timeout=1.5)  # the rig comes back
        assert batch.seq[0] == first_stall
        assert dev.stalls == 1 and dev.stalled_s == pytest.approx(1.5, abs=2e-6)
        dev.stop()


def test_monitor_reports_stalls_in_json_and_text_exactly():
    server = serve_pty(seed=12, rate=1000, faults="stall:0.003@0.3")
    try:
        result = CliRunner().invoke(
            cli, ["monitor", "--port", server.path, "--seconds", "2", "--json", "--rate", "1000", "--boot-wait", "0"]
        )
        last_seq = server.firmware.seq - 1  # every frame made was sent: no other fault
        stalls = list(server.faults.stalls)
    finally:
        server.stop()
    assert result.exit_code == 0, result.output
    summary = json.loads(result.output)
    want = sum(1 for s, _ in stalls if 0 < s <= last_seq)
    assert summary["stalls"] == want >= 2
    assert summary["lost"] == 0

    server = serve_pty(seed=12, rate=1000, faults="stall:0.003@0.3")
    try:
        result = CliRunner().invoke(
            cli, ["monitor", "--port", server.path, "--seconds", "1.5", "--rate", "1000", "--boot-wait", "0"]
        )
        last_seq = server.firmware.seq - 1
        stalls = list(server.faults.stalls)
    finally:
        server.stop()
    assert result.exit_code == 0, result.output
    want = sum(1 for s, _ in stalls if 0 < s <= last_seq)
    line = [ln for ln in result.output.splitlines() if ln.startswith(server.path)][-1]
    assert f" Hz set), {want} stalls, 0 lost, " in line
    assert want >= 1


def test_monitor_without_stalls_says_zero():
    result = CliRunner().invoke(
        cli, ["monitor", "--port", "sim://?seed=2&clock=virtual", "--seconds", "0.3", "--json", "--rate", "500"]
    )
    assert result.exit_code == 0, result.output
    summary = json.loads(result.output)
    assert summary["stalls"] == 0 and summary["frames"] > 1000
