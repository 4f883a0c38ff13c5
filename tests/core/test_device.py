"""Device over a real pseudo-terminal, against an independently written firmware."""

from __future__ import annotations

import os
import time

import numpy as np
import pytest
from support.firmware import REFERENCE_CHANNELS, REFERENCE_COUNTS, FakeFirmware

from labcli.core.device import Device, DeviceInfo
from labcli.errors import DeviceDisconnected, DeviceError, DeviceNotFound, DeviceTimeout


@pytest.fixture
def firmware(request):
    kwargs = getattr(request, "param", {})
    fw = FakeFirmware(**{"rate": 500, **kwargs})
    fw.start()
    yield fw
    fw.close()


def read_frames(dev: Device, n: int, limit_s: float = 2.0):
    seqs, vals = [], []
    deadline = time.monotonic() + limit_s
    while len(seqs) < n and time.monotonic() < deadline:
        b = dev.read(timeout=0.2)
        seqs.extend(b.seq.tolist())
        vals.extend(b.values.tolist())
    return seqs, vals


def test_handshake_learns_the_firmware_and_its_channels(firmware):
    with Device.open(firmware.port, boot_wait=0, timeout=1.0) as dev:
        assert dev.info == DeviceInfo("fake-rig", "0.9", REFERENCE_CHANNELS, firmware.port)
        assert dev.rig is None  # a real port has no simulated rig behind it
        assert firmware.commands[0] == "ID?"
        assert dev.counters["bad_checksum"] == dev.counters["malformed"] == 0


@pytest.mark.parametrize("firmware", [{"boot_delay": 0.8}], indirect=True)
def test_handshake_waits_for_a_board_that_is_still_booting(firmware):
    t0 = time.monotonic()
    with Device.open(firmware.port, boot_wait=1.0, timeout=0.5) as dev:
        assert dev.info.channels == REFERENCE_CHANNELS
    assert 0.7 < time.monotonic() - t0 < 1.5
    assert firmware.commands.count("ID?") >= 2  # asked again while the board booted


def test_rate_returns_what_the_firmware_set(firmware):
    with Device.open(firmware.port, boot_wait=0, timeout=1.0) as dev:
        assert dev.set_rate(1000.4) == 1000.0  # the firmware only does whole hertz
        assert firmware.commands[-1] == "RATE 1000.4"
        assert dev.set_rate(250) == 250.0
        assert firmware.commands[-1] == "RATE 250"
        with pytest.raises(DeviceError) as err:
            dev.set_rate(5000)
    assert str(err.value) == (
        f"The device on {firmware.port} refused RATE 5000: 'ERR rate out of range 1-2000'. "
        "Check the values its firmware accepts for that command."
    )


@pytest.mark.parametrize("firmware", [{"crlf": False}, {"crlf": True}], indirect=True)
def test_start_stream_stop(firmware):
    with Device.open(firmware.port, boot_wait=0, timeout=1.0) as dev:
        dev.set_rate(1000)
        dev.start()
        seqs, vals = read_frames(dev, 200)
        in_flight = dev.stop()
        seqs += in_flight.seq.tolist()
        vals += in_flight.values.tolist()
        assert len(seqs) >= 200
        assert seqs == list(range(len(seqs)))  # contiguous from 0, nothing lost
        np.testing.assert_array_equal(np.array(vals), np.tile(REFERENCE_COUNTS, (len(vals), 1)))
        assert len(in_flight) >= 1  # the firmware always has one frame in flight at STOP
        assert dev.counters["frames"] == len(seqs) and dev.counters["lost"] == 0
        assert firmware.commands[-2:] == ["START", "STOP"]
        time.sleep(0.05)
        assert len(dev.read(timeout=0.1)) == 0  # stopped means quiet


def test_nonexistent_port_is_one_clear_sentence():
    port = "/dev/ttyUSB97"
    if os.path.exists(port):
        pytest.skip(f"{port} exists on this machine")
    with pytest.raises(DeviceNotFound) as err:
        Device.open(port)
    assert str(err.value) == (
        "Cannot open serial port /dev/ttyUSB97: no such device. Check the cable and run `labcli ports` to list ports."
    )


def test_unknown_url_scheme():
    with pytest.raises(DeviceNotFound) as err:
        Device.open("nosuch://x")
    assert str(err.value) == (
        "Cannot open serial port nosuch://x: unknown URL scheme 'nosuch://'. "
        "Use a port name such as /dev/ttyUSB0 or COM3, or sim:// for the simulated rig."
    )


@pytest.mark.parametrize("firmware", [{"silent": True}], indirect=True)
def test_silent_device_times_out(firmware):
    t0 = time.monotonic()
    with pytest.raises(DeviceTimeout) as err:
        Device.open(firmware.port, boot_wait=0.2, timeout=0.3)
    assert 0.45 < time.monotonic() - t0 < 1.0
    assert str(err.value) == (
        f"No answer to ID? from {firmware.port} within 0.5 s. Check that the rig is powered and "
        "that its firmware speaks the labcli wire protocol at 115200 baud."
    )
    assert firmware.commands.count("ID?") >= 1


@pytest.mark.parametrize("firmware", [{"babble": b"Hello from bootloader v2\r\n"}], indirect=True)
def test_device_speaking_something_else(firmware):
    with pytest.raises(DeviceError) as err:
        Device.open(firmware.port, boot_wait=0, timeout=0.3)
    assert type(err.value) is DeviceError
    assert str(err.value) == (
        f"The device on {firmware.port} answered 'Hello from bootloader v2', which is not the labcli wire "
        "protocol. Check the baud rate (115200) and that the firmware speaks wire protocol version 1."
    )


@pytest.mark.parametrize("firmware", [{"id_line": "ERR what?"}], indirect=True)
def test_device_that_refuses_id(firmware):
    with pytest.raises(DeviceError) as err:
        Device.open(firmware.port, boot_wait=0, timeout=0.3)
    assert str(err.value) == (
        f"The device on {firmware.port} answered 'ERR what?', which is not the labcli wire "
        "protocol. Check the baud rate (115200) and that the firmware speaks wire protocol version 1."
    )


@pytest.mark.parametrize("firmware", [{"id_line": "ID,lonely,1.0"}], indirect=True)
def test_id_without_channels(firmware):
    with pytest.raises(DeviceError) as err:
        Device.open(firmware.port, boot_wait=0, timeout=0.3)
    assert str(err.value) == (
        f"The device on {firmware.port} sent an ID line without channel names ('ID,lonely,1.0'). "
        "Check that its firmware answers ID? with ID,<device>,<firmware>,<ch1>,...,<chN>."
    )


def test_unplugged_mid_stream(firmware):
    dev = Device.open(firmware.port, boot_wait=0, timeout=1.0)
    dev.start()
    assert len(read_frames(dev, 10)[0]) >= 10
    firmware.unplug()
    with pytest.raises(DeviceDisconnected) as err:
        for _ in range(50):
            dev.read(timeout=0.1)
    assert str(err.value) == (
        f"Lost the connection to {firmware.port}: the device was disconnected. "
        "Check the cable and USB power, then run the command again."
    )
    assert not dev.streaming
    dev.close()  # closing a dead device is quiet


def test_a_read_takes_every_byte_waiting_in_one_system_call(firmware, monkeypatch):
    """On a POSIX serial port a wake costs one wait and one os.read of all that waits (no read(1), no in_waiting)."""
    dev = Device.open(firmware.port, boot_wait=0, timeout=1.0)
    try:
        dev.start()
        assert len(read_frames(dev, 5)[0]) >= 5
        time.sleep(0.1)  # 50 frames at 500 Hz wait in the port
        fd, calls = dev.serial.fd, []
        real_read = os.read

        def counting_read(f, n):
            data = real_read(f, n)
            if f == fd:
                calls.append(len(data))
            return data

        monkeypatch.setattr(os, "read", counting_read)
        monkeypatch.setattr(type(dev.serial), "in_waiting", property(lambda _: pytest.fail("in_waiting asked")))
        before = dev.counters["frames"]
        batch = dev.read(timeout=0.5)
        assert len(calls) == 1 and calls[0] > 40 * 30  # one read, of 40 frames or more
        assert len(batch) == dev.counters["frames"] - before >= 40
        assert np.all(np.diff(batch.seq) == 1) and dev.arrived is not None
    finally:
        monkeypatch.undo()
        dev.close()


@pytest.mark.parametrize("firmware", [{"max_frames": 20}], indirect=True)
def test_stream_that_goes_quiet_times_out(firmware):
    dev = Device.open(firmware.port, boot_wait=0, timeout=0.4)
    dev.start()
    seqs, _ = read_frames(dev, 20)
    assert seqs == list(range(20))
    t0 = time.monotonic()
    with pytest.raises(DeviceTimeout) as err:
        while True:
            dev.read(timeout=0.1)
    assert 0.3 < time.monotonic() - t0 < 1.0
    assert str(err.value) == (
        f"No data from {firmware.port} for 0.4 s while streaming. Check the cable and that the rig is powered."
    )
    dev.close()


def test_device_left_streaming_is_quieted_at_open(firmware):
    firmware.streaming = True  # as if an earlier session never sent STOP
    firmware._t0 = time.monotonic()
    time.sleep(0.05)
    with Device.open(firmware.port, boot_wait=0, timeout=1.0) as dev:
        assert dev.info.channels == REFERENCE_CHANNELS
        assert "STOP" in firmware.commands and not firmware.streaming
        assert dev.counters["frames"] == 0
        assert dev.set_rate(100) == 100.0


def test_sim_url_when_the_simulated_rig_is_installed():
    pytest.importorskip("labcli.core.sim.protocol_sim")
    with Device.open("sim://?seed=1", timeout=2.0) as dev:
        assert dev.info.channels == REFERENCE_CHANNELS
        assert dev.rig is not None
        dev.set_rate(200)
        dev.start()
        seqs, vals = read_frames(dev, 50)
        dev.stop()
        assert len(seqs) >= 50 and dev.counters["lost"] == 0
        assert np.all((np.array(vals) >= 0) & (np.array(vals) <= 4095))


def test_sim_unplugged_mid_stream():
    pytest.importorskip("labcli.core.sim.protocol_sim")
    dev = Device.open("sim://?seed=2&clock=wall", timeout=1.0)
    dev.start()
    assert len(read_frames(dev, 5)[0]) >= 5
    dev.serial.unplug()
    with pytest.raises(DeviceDisconnected) as err:
        for _ in range(20):
            dev.read(timeout=0.1)
    assert str(err.value) == (
        "Lost the connection to sim://?seed=2&clock=wall: the device was disconnected. "
        "Check the cable and USB power, then run the command again."
    )
    dev.close()
