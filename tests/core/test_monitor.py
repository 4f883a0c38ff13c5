"""``labcli monitor`` and ``labcli ports`` end to end, over a pseudo-terminal."""

from __future__ import annotations

import json
import math
import os
from types import SimpleNamespace

import numpy as np
import pytest
from click.testing import CliRunner
from hypothesis import given, settings
from hypothesis import strategies as st
from support.firmware import REFERENCE_CHANNELS, REFERENCE_COUNTS, FakeFirmware

from labcli.cli import cli
from labcli.core.device import Device
from labcli.core.monitoring import RunningStats, channel_scale, watch
from labcli.core.protocol import load_protocol


def reference_si(name: str, counts: float) -> tuple[float, str]:
    """The reference rig calibration as the wire protocol document prints it."""
    if name.startswith("P_"):
        return (counts * 5.0 / 4095 - 1.0) / 4.0, "MPa"
    return math.radians((counts - 2048) * 340 / 4095), "rad"


FAULTS = {
    40: ["corrupt", "garbage"],
    90: [("gap", 7), "log"],
    130: ["truncated", "garbage", "corrupt"],
    170: ["overlong", "log", "log"],
}
# corrupt and truncated frames use up a seq number, so they are lost frames too
EXPECTED = dict(lost=7 + 2 + 1, bad_checksum=2, malformed=3, overlong=1, log_lines=3)


def test_monitor_json_reports_exactly_the_injected_faults():
    with FakeFirmware(rate=200, faults=FAULTS) as fw:
        result = CliRunner().invoke(cli, ["monitor", "--port", fw.port, "--seconds", "2", "--json", "--rate", "250"])
        sent = fw.frames_sent
        commands = list(fw.commands)
    assert result.exit_code == 0, result.output
    summary = json.loads(result.output)
    for key, value in EXPECTED.items():
        assert summary[key] == value, key
    assert summary["frames"] == sent  # every frame the firmware sent after START, in-flight one included
    assert 2.0 <= summary["seconds"] < 2.5
    assert summary["rate_hz"] == 250.0
    assert summary["frames_per_s"] == pytest.approx(250, rel=0.1)
    assert commands[-3:] == ["RATE 250", "START", "STOP"]
    assert list(summary["channels"]) == list(REFERENCE_CHANNELS)
    for name, counts in zip(REFERENCE_CHANNELS, REFERENCE_COUNTS, strict=False):
        value, unit = reference_si(name, counts)
        assert summary["channels"][name]["unit"] == unit
        assert summary["channels"][name]["mean"] == pytest.approx(value, abs=1e-12)
        # Constant counts have no spread; merging the per-read batches' statistics in floating point
        # may leave ~1e-17, eight orders of magnitude below one count (3e-4 MPa, 1.5e-3 rad).
        assert summary["channels"][name]["std"] == pytest.approx(0.0, abs=1e-12)


def test_monitor_table_output_has_units_and_the_summary_line():
    with FakeFirmware(rate=200, faults={5: [("gap", 3)]}) as fw:
        result = CliRunner().invoke(cli, ["monitor", "--port", fw.port, "--seconds", "0.6"])
    assert result.exit_code == 0, result.output
    last = [line for line in result.output.splitlines() if line.startswith(fw.port)][-1]
    assert ", 3 lost, 0 bad checksum, 0 malformed, 0 overlong, 0 log lines, 0 events." in last
    pot2_deg = (2300 - 2048) * 340 / 4095
    assert f"POT2  mean {pot2_deg:.2f} deg  std 0.000 deg" in result.output
    p_l1 = (1556 * 5.0 / 4095 - 1.0) / 4.0
    assert f"P_L1  mean {p_l1:.4f} MPa  std 0.00000 MPa" in result.output


def test_monitor_missing_port_is_one_line_error():
    port = "/dev/ttyUSB97"
    if os.path.exists(port):
        pytest.skip(f"{port} exists on this machine")
    result = CliRunner().invoke(cli, ["monitor", "--port", port, "--seconds", "1"])
    assert result.exit_code == 1
    assert result.output == (
        "Error: Cannot open serial port /dev/ttyUSB97: no such device. "
        "Check the cable and run `labcli ports` to list ports.\n"
    )


def test_monitor_silent_device_is_one_line_error():
    with FakeFirmware(silent=True) as fw:
        result = CliRunner().invoke(
            cli, ["monitor", "--port", fw.port, "--timeout", "0.3", "--boot-wait", "0.2", "--json"]
        )
    assert result.exit_code == 1
    assert result.output == (
        f"Error: No answer to ID? from {fw.port} within 0.5 s. Check that the rig is powered and "
        "that its firmware speaks the labcli wire protocol at 115200 baud.\n"
    )


def test_ctrl_c_stops_the_stream_and_still_summarises():
    with FakeFirmware(rate=500) as fw:
        with Device.open(fw.port, boot_wait=0, timeout=1.0) as dev:
            scale = channel_scale(dev.info.channels, load_protocol("takuma2014").calibration)
            calls = []

            def press_ctrl_c(snap):
                calls.append(snap.counters["frames"])
                if len(calls) == 3:
                    raise KeyboardInterrupt

            summary = watch(dev, scale, rate_hz=500, on_update=press_ctrl_c, refresh_s=0.05)
            assert not dev.streaming
        assert fw.commands[-1] == "STOP" and not fw.streaming
    assert summary.interrupted
    assert summary.counters["frames"] > calls[-1] > 0  # the in-flight frames were kept
    assert summary.to_json()["interrupted"] is True


def test_channels_the_protocol_does_not_know_stay_in_counts():
    cal = load_protocol("takuma2014").calibration
    scale = channel_scale(("POT2", "EXTRA", "P_L1"), cal)
    assert scale.units == ("rad", "counts", "MPa")
    assert scale.display_units == ("deg", "counts", "MPa")
    si = scale.to_si(np.array([[2048 + 4095 / 340 * 10, 17, 819]]))
    np.testing.assert_allclose(si, [[math.radians(10), 17, 0.0]], atol=1e-12)
    np.testing.assert_allclose(scale.to_display(si), [[10.0, 17, 0.0]], atol=1e-9)


@given(st.lists(st.integers(1, 30), min_size=1, max_size=8), st.integers(0, 2**32 - 1))
@settings(max_examples=60)
def test_running_stats_match_numpy_over_any_batching(sizes, seed):
    x = np.random.default_rng(seed).normal(1000.0, 3.0, size=(sum(sizes), 3))
    rs = RunningStats(3)
    i = 0
    for n in sizes:
        rs.update(x[i : i + n])
        i += n
    np.testing.assert_allclose(rs.mean, x.mean(axis=0), rtol=1e-12)
    if len(x) > 1:
        np.testing.assert_allclose(rs.std, x.std(axis=0, ddof=1), rtol=1e-9)


def test_ports_lists_device_description_and_hwid(monkeypatch, tmp_path):
    from serial.tools import list_ports

    monkeypatch.setenv("LABCLI_RUNTIME_DIR", str(tmp_path))  # no simulated rig serving

    fake = [
        SimpleNamespace(device="/dev/ttyUSB0", description="FT232R USB UART", hwid="USB VID:PID=0403:6001"),
        SimpleNamespace(device="/dev/ttyACM0", description="Arduino Uno", hwid="USB VID:PID=2341:0043"),
    ]
    monkeypatch.setattr(list_ports, "comports", lambda: fake)
    result = CliRunner().invoke(cli, ["ports"])
    assert result.exit_code == 0
    # Without USB ids (pyserial leaves vid and pid None for ports it cannot place) no board is named.
    assert result.output.splitlines() == [
        "DEVICE        BOARD  DESCRIPTION      HWID",
        "/dev/ttyACM0  -      Arduino Uno      USB VID:PID=2341:0043",
        "/dev/ttyUSB0  -      FT232R USB UART  USB VID:PID=0403:6001",
    ]


def test_ports_says_plainly_when_there_are_none(monkeypatch, tmp_path):
    from serial.tools import list_ports

    monkeypatch.setenv("LABCLI_RUNTIME_DIR", str(tmp_path))

    monkeypatch.setattr(list_ports, "comports", lambda: [])
    result = CliRunner().invoke(cli, ["ports"])
    assert result.exit_code == 0
    assert result.output == (
        "No serial ports found on this machine: plug in the rig's USB cable (and check its driver), "
        "or use --port sim:// for the simulated rig.\n"
    )


@pytest.mark.skipif(not hasattr(os, "openpty"), reason="needs pseudo-terminals")
def test_ports_lists_a_serving_simulated_rig_marked_as_such(monkeypatch, tmp_path):
    # pyserial lists no pseudo-terminals; a serving `labcli sim --pty` is listed, marked as the
    # simulated rig, only while it serves; a note left by a killed server is dropped.
    import subprocess
    import sys
    import time

    from serial.tools import list_ports

    monkeypatch.setenv("LABCLI_RUNTIME_DIR", str(tmp_path))
    usb = SimpleNamespace(device="/dev/ttyUSB0", description="FT232R USB UART", hwid="USB VID:PID=0403:6001")
    monkeypatch.setattr(list_ports, "comports", lambda: [usb])
    (tmp_path / "sim-999999999.json").write_text(
        json.dumps({"device": "/dev/pts/999", "pid": 999999999, "description": "simulated rig of a killed server"})
    )
    proc = subprocess.Popen(
        [sys.executable, "-m", "labcli", "sim", "--pty", "--seed", "3"],
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        text=True,
        env={**os.environ, "LABCLI_RUNTIME_DIR": str(tmp_path)},
    )
    try:
        path = proc.stdout.readline().split()[3]
        deadline = time.monotonic() + 10.0  # the note is written just after the banner
        while not (tmp_path / f"sim-{proc.pid}.json").exists() and time.monotonic() < deadline:
            time.sleep(0.05)
        result = CliRunner().invoke(cli, ["ports"])
        assert result.exit_code == 0
        description = "simulated rig mckibben-2dof-sim (labcli sim --pty, seed 3, firmware model)"
        width = max(len(path), len("/dev/ttyUSB0"))
        board = "labcli simulated rig"
        assert result.output.splitlines() == [
            f"{'DEVICE':<{width}}  {'BOARD':<{len(board)}}  {'DESCRIPTION':<{len(description)}}  HWID",
            f"{'/dev/ttyUSB0':<{width}}  {'-':<{len(board)}}  {'FT232R USB UART':<{len(description)}}  "
            "USB VID:PID=0403:6001",
            f"{path:<{width}}  {board}  {description}  sim pid {proc.pid}",
        ]
        assert not (tmp_path / "sim-999999999.json").exists()
        proc.stdin.write("quit\n")
        proc.stdin.flush()
        proc.communicate(timeout=10)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 0
    assert list(tmp_path.iterdir()) == []  # the note goes with the server
    assert CliRunner().invoke(cli, ["ports"]).output.splitlines()[1:] == [
        "/dev/ttyUSB0  -      FT232R USB UART  USB VID:PID=0403:6001"
    ]


def test_monitor_on_the_simulated_rig():
    pytest.importorskip("labcli.core.sim.protocol_sim")
    result = CliRunner().invoke(
        cli, ["monitor", "--port", "sim://?seed=3", "--seconds", "1", "--rate", "100", "--json"]
    )
    assert result.exit_code == 0, result.output
    summary = json.loads(result.output)
    assert summary["port"] == "sim://?seed=3&clock=wall"
    assert summary["frames_per_s"] == pytest.approx(100, rel=0.15)  # paced like hardware
    assert summary["lost"] == summary["bad_checksum"] == summary["malformed"] == 0
    for name in ("P_L1", "P_R1", "P_L2", "P_R2"):
        assert summary["channels"][name]["unit"] == "MPa"
        assert -0.25 <= summary["channels"][name]["mean"] <= 1.0
