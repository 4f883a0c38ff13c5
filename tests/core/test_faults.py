"""A noisy link: seeded faults on the simulated rig's output against the host's counters.

Every test compares the stream reader's counters with the injector's ground
truth exactly, and every frame the host yields with the frames the rig made.
Identities (see ``labcli.core.sim.faults``):

    frames       == frames sent intact
    bad_checksum == checksum faults + truncations that kept '*HH'
    malformed    == garbage lines + truncations that lost '*HH'
    overlong     == overlong faults
    lost         == drop + checksum + truncate + overlong faults between the
                    first and the last intact frame (their seq is used up)
"""

from __future__ import annotations

import json
import re
import signal
import subprocess
import sys
import time

import numpy as np
import pytest
import serial
from click.testing import CliRunner
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from labcli.cli import cli
from labcli.core.device import Device
from labcli.core.sim import register
from labcli.core.sim.faults import FAULTS_FORM, FaultInjector, FaultSpec, FaultSpecError
from labcli.core.sim.firmware import Firmware
from labcli.core.sim.pty import serve_pty
from labcli.core.wire import FrameBatch, StreamReader
from labcli.errors import DeviceTimeout
from labcli.papers.takuma2014.sim.rig import SimRig

register()

ALL = "checksum:0.01,garbage:0.005,truncate:0.005,overlong:0.001,drop:0.01,stall:0.001@2.5,burst:0.001@50"
HEAVY = "checksum:0.03,garbage:0.02,truncate:0.03,overlong:0.01,drop:0.03,stall:0.003@0.5,burst:0.003@40"
NOISE_KEYS = ("frames", "lost", "bad_checksum", "malformed", "overlong")


def read_frames(dev: Device, n: int) -> FrameBatch:
    dev.start()
    batches, got = [], 0
    while got < n:
        b = dev.read(timeout=1.0)
        batches.append(b)
        got += len(b)
    batches.append(dev.stop())
    return FrameBatch.concat(batches, len(dev.info.channels))


def assert_yields_exactly_the_intact_frames(batch: FrameBatch, inj: FaultInjector) -> None:
    e = inj.emitted()
    ok = e.fate == 0
    assert len(batch) == int(ok.sum()) == inj.delivered
    np.testing.assert_array_equal(batch.seq, e.seq[ok])
    np.testing.assert_array_equal(batch.t_us, e.t_us[ok])
    np.testing.assert_array_equal(batch.values, e.values[ok])


# ---------------------------------------------------------------- grammar


def test_grammar_round_trips_and_takes_plain_data():
    spec = FaultSpec.parse(ALL)
    assert spec == FaultSpec(
        checksum=0.01,
        garbage=0.005,
        truncate=0.005,
        overlong=0.001,
        drop=0.01,
        stall=0.001,
        stall_s=2.5,
        burst=0.001,
        burst_frames=50,
    )
    assert FaultSpec.parse(spec.to_text()) == spec
    assert FaultSpec.from_data(spec.as_dict()) == spec
    assert FaultSpec.parse("stall:0.5").stall_s == 1.0 and FaultSpec.parse("burst:0.1").burst_frames == 50
    assert not FaultSpec.parse("").active and not FaultSpec.parse("drop:0").active


@pytest.mark.parametrize(
    "text,detail",
    [
        ("chksum:0.1", "unknown fault 'chksum'"),
        ("drop", "'drop' is not KIND:RATE[@X]"),
        ("drop:1.5", "rate of 'drop' must be a number within 0..1, got '1.5'"),
        ("drop:x", "rate of 'drop' must be a number within 0..1, got 'x'"),
        ("drop:0.1@3", "fault 'drop' takes no @ value, got 'drop:0.1@3'"),
        ("stall:0.1@0", "stall duration must be a number of seconds > 0, got '0'"),
        ("burst:0.1@1", "burst length must be a whole number of frames >= 2, got '1'"),
        ("drop:0.1,drop:0.2", "fault 'drop' given twice"),
    ],
)
def test_malformed_specs_name_the_problem_and_show_the_accepted_form(text, detail):
    with pytest.raises(FaultSpecError) as e:
        FaultSpec.parse(text)
    assert str(e.value) == f"{detail}; expected {FAULTS_FORM}"
    with pytest.raises(serial.SerialException) as e:
        serial.serial_for_url(f"sim://?faults={text}")
    assert str(e.value) == f"option 'faults' in sim:// URL: {detail}; expected faults={FAULTS_FORM}"
    assert isinstance(e.value, ValueError)


def test_sim_command_rejects_a_malformed_spec_in_one_line():
    result = CliRunner().invoke(cli, ["sim", "--pty", "--faults", "chksum:0.1"])
    assert result.exit_code == 2
    assert result.output.splitlines()[-1] == (
        f"Error: Invalid value for '--faults': unknown fault 'chksum'; expected {FAULTS_FORM}"
    )


def test_no_faults_means_no_injector_and_exact_output():
    port = serial.serial_for_url("sim://?seed=2&faults=drop:0")
    assert port.faults is None and port.firmware.faults is None


# ---------------------------------------------------------------- sim://, virtual clock


def test_every_fault_at_once_counters_match_ground_truth_exactly():
    with Device.open(f"sim://?seed=5&rate=1000&faults={ALL}") as dev:
        inj = dev.serial.faults
        inj.record = True
        batch = read_frames(dev, 60_000)
        counters = dev.counters
    want = inj.expected()
    assert {k: counters[k] for k in NOISE_KEYS} == want
    i = inj.injected
    assert min(i[k] for k in ("checksum", "garbage", "truncate", "overlong", "drop", "stall", "burst")) > 0
    # Where the identities come from: each kind's share, exactly.
    spoilt = i["checksum"] + i["truncate"]
    assert want["bad_checksum"] + want["malformed"] == spoilt + i["garbage"]
    assert want["bad_checksum"] >= i["checksum"] and want["malformed"] >= i["garbage"]
    assert want["overlong"] == i["overlong"]
    first, last = int(batch.seq[0]), int(batch.seq[-1])
    destroyed = i["checksum"] + i["truncate"] + i["overlong"] + i["drop"]
    outside = sum(1 for s in inj.destroyed if not first < s < last)
    assert want["lost"] == destroyed - outside
    assert inj.frames == inj.delivered + destroyed
    assert_yields_exactly_the_intact_frames(batch, inj)


def test_yielded_frames_equal_a_clean_run_of_the_same_seed():
    # The clean rig, not the injector's own record, is the reference here.
    spec = "checksum:0.05,garbage:0.05,truncate:0.05,overlong:0.02,drop:0.05,burst:0.01@30"
    with Device.open("sim://?seed=9&rate=500") as clean:
        ref = read_frames(clean, 20_000)
    with Device.open(f"sim://?seed=9&rate=500&faults={spec}") as dev:
        got = read_frames(dev, 15_000)
        assert dev.counters["lost"] > 1000 and dev.counters["bad_checksum"] > 500
    idx = np.searchsorted(ref.seq, got.seq)
    np.testing.assert_array_equal(ref.seq[idx], got.seq)
    np.testing.assert_array_equal(ref.t_us[idx], got.t_us)
    np.testing.assert_array_equal(ref.values[idx], got.values)


def test_stalls_are_device_time_gaps_of_exactly_their_length():
    with Device.open("sim://?seed=3&rate=1000&faults=stall:0.002@0.75,drop:0.01") as dev:
        inj = dev.serial.faults
        batch = read_frames(dev, 30_000)
        assert dev.counters["lost"] == inj.expected()["lost"]
    stalls = dict(inj.stalls)
    assert len(stalls) == inj.injected["stall"] > 20
    assert inj.injected["stall_s"] == pytest.approx(0.75 * len(stalls))
    # Between consecutive yielded frames a and b, the device clock ran
    # (b - a) periods plus every stall before a frame in (a, b].
    dseq = np.diff(batch.seq)
    excess_us = np.diff(batch.t_us) - dseq * 1000
    want_us = np.array(
        [
            sum(stalls.get(s, 0.0) for s in range(a + 1, b + 1)) * 1e6
            for a, b in zip(batch.seq[:-1].tolist(), batch.seq[1:].tolist(), strict=False)
        ]
    )
    assert np.abs(excess_us - want_us).max() <= 1  # microsecond rounding of t_us
    assert (excess_us > 0.5e6).sum() == sum(1 for s in stalls if batch.seq[0] < s <= batch.seq[-1])


def test_output_does_not_depend_on_how_the_host_reads():
    def stream(sizes) -> bytes:
        inj = FaultInjector(HEAVY, seed=4)
        fw = Firmware(SimRig(seed=4), 1000, faults=inj)
        out = bytearray(fw.receive(b"START\n"))
        i = 0
        while fw.count < 9000:  # a stall ends a block early; ask again as a pacer would
            out += fw.frames(min(sizes[i % len(sizes)], 9000 - fw.count))
            fw.take_stall()
            i += 1
        assert inj.injected["stall"] > 10 and inj.injected["burst"] > 10
        return bytes(out + fw.receive(b"STOP\n"))

    one = stream([9000])
    assert stream([1] * 300 + [7, 4093, 13, 4096, 499]) == one
    assert stream([3000]) == one


# ---------------------------------------------------------------- property


@st.composite
def specs(draw):
    rate = st.sampled_from([0.0, 0.001, 0.02, 0.2, 1.0])
    return FaultSpec(
        checksum=draw(rate),
        garbage=draw(rate),
        truncate=draw(rate),
        overlong=draw(rate),
        drop=draw(rate),
        stall=draw(rate),
        stall_s=draw(st.sampled_from([0.001, 0.3])),
        burst=draw(rate),
        burst_frames=draw(st.integers(2, 300)),
    )


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    spec=specs(),
    seed=st.integers(0, 2**31),
    blocks=st.lists(st.integers(1, 700), min_size=1, max_size=6),
    cuts=st.lists(st.integers(1, 5000), min_size=1, max_size=8),
)
def test_random_faults_never_make_the_reader_yield_a_frame_the_rig_did_not_send(spec, seed, blocks, cuts):
    inj = FaultInjector(spec, seed=seed, record=True)
    fw = Firmware(SimRig(seed=seed % 7, noise=2.0), 1000, faults=inj)
    fw.receive(b"START\n")
    data = bytearray()
    for n in blocks:
        data += fw.frames(n)
        fw.take_stall()
    data += inj.flush()
    reader = StreamReader(n_channels=6)
    batches, pos, i = [], 0, 0
    while pos < len(data):  # the host's reads split lines anywhere
        step = cuts[i % len(cuts)]
        batches.append(reader.feed(bytes(data[pos : pos + step])))
        pos, i = pos + step, i + 1
    batch = FrameBatch.concat(batches, 6)
    assert_yields_exactly_the_intact_frames(batch, inj)
    assert {k: reader.counters[k] for k in NOISE_KEYS} == inj.expected()


# ---------------------------------------------------------------- wall clock: stalls a person sees


def test_a_stall_longer_than_the_silence_threshold_is_a_device_timeout():
    url = "sim://?seed=0&rate=1000&clock=wall&faults=stall:0.002@1.5"
    probe = serial.serial_for_url(url)
    first_stall = probe.faults.schedule(0, 2000)["stall"][0]
    assert 50 < first_stall < 1000  # a few frames, then the firmware hangs
    with Device.open(url, timeout=1.0) as dev:
        dev.start()
        frames = 0
        with pytest.raises(DeviceTimeout) as e:
            while True:
                frames += len(dev.read(timeout=0.5))
        silent_from = time.monotonic()
        assert str(e.value) == (
            f"No data from {url} for 1 s while streaming. Check the cable and that the rig is powered."
        )
        assert frames == first_stall
        assert dev.serial.faults.stalls == [(first_stall, 1.5)]
        # The rig comes back after the stall: the next frame carries on the sequence.
        batch = dev.read(timeout=1.5)
        assert 0.2 < time.monotonic() - silent_from < 1.2
        assert batch.seq[0] == first_stall and dev.counters["lost"] == 0


def test_short_stalls_are_silences_on_the_wall_clock():
    with Device.open("sim://?seed=8&rate=500&clock=wall&faults=stall:0.003@0.3", timeout=1.0) as dev:
        inj = dev.serial.faults
        dev.start()
        arrivals, t0 = [], time.monotonic()
        while time.monotonic() - t0 < 1.2:
            b = dev.read(timeout=0.1)
            if len(b):
                arrivals.append((time.monotonic(), int(b.seq[0])))
        dev.stop()
    stalled = [s for s, _ in inj.stalls if s <= arrivals[-1][1]]
    assert len(stalled) >= 1
    silences = [(b[0] - a[0], b[1]) for a, b in zip(arrivals, arrivals[1:], strict=False) if b[0] - a[0] > 0.2]
    assert [s for _, s in silences] == stalled  # each silence ends with the stalled frame
    assert all(0.25 < gap < 0.45 for gap, _ in silences)


# ---------------------------------------------------------------- a real pseudo-terminal


def test_monitor_over_a_pty_reports_exactly_the_injected_faults():
    spec = "checksum:0.01,garbage:0.01,truncate:0.01,overlong:0.003,drop:0.01,stall:0.001@0.2,burst:0.002@50"
    server = serve_pty(seed=12, rate=1000, faults=spec)
    try:
        result = CliRunner().invoke(
            cli, ["monitor", "--port", server.path, "--seconds", "2", "--json", "--rate", "1000", "--boot-wait", "0"]
        )
    finally:
        server.stop()
    assert result.exit_code == 0, result.output
    summary = json.loads(result.output)
    want = server.faults.expected()
    assert {k: summary[k] for k in NOISE_KEYS} == want
    # Not 0 == 0: every kind of fault was injected and counted.  How many frames 2 s of wall clock
    # bring depends on the machine's load; seed 12 puts each kind within the first 400 frames.
    injected = server.faults.injected
    assert all(injected[kind] > 0 for kind in ("checksum", "garbage", "truncate", "overlong", "drop")), injected
    assert all(want[key] > 0 for key in NOISE_KEYS), want


def test_sim_command_prints_what_a_host_must_count():
    proc = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "labcli",
            "sim",
            "--pty",
            "--seed",
            "6",
            "--rate",
            "1000",
            "--faults",
            "checksum:0.02,garbage:0.01,truncate:0.01,overlong:0.005,drop:0.02",
        ],
        stdout=subprocess.PIPE,
        text=True,
    )
    try:
        path = re.match(r"Simulated rig on (\S+) ", proc.stdout.readline()).group(1)
        result = CliRunner().invoke(
            cli, ["monitor", "--port", path, "--seconds", "1", "--json", "--rate", "1000", "--boot-wait", "0"]
        )
    finally:
        proc.send_signal(signal.SIGINT)
        out, _ = proc.communicate(timeout=10)
    assert result.exit_code == 0, result.output
    s = json.loads(result.output)
    line = out.splitlines()[-1]
    assert line.startswith("Faults: ")
    assert f"{s['frames']} sent intact" in line
    assert line.endswith(
        f"the host must count {s['bad_checksum']} bad checksum, {s['malformed']} malformed, "
        f"{s['overlong']} overlong, {s['lost']} lost."
    )
    assert s["lost"] > 10


# ---------------------------------------------------------------- soak


@pytest.mark.slow
def test_soak_two_million_frames_with_every_fault():
    with Device.open(f"sim://?seed=21&rate=5000&faults={HEAVY}") as dev:
        inj = dev.serial.faults
        inj.record = True
        batch = read_frames(dev, 2_000_000)
        counters = dev.counters
    assert {k: counters[k] for k in NOISE_KEYS} == inj.expected()
    assert_yields_exactly_the_intact_frames(batch, inj)
