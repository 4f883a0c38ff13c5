"""Wire protocol 1.1 on the host and on the simulated board: capabilities, valves, the pressure limit, events.

The simulated board (``sim://``, the firmware model) speaks 1.1 by default and 1.0 with
``fw=1.0``, so both host/board pairings are tested here without simavr; the firmware on simavr
has its own tests (tests/core/test_firmware_valves.py).
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

from labcli.core.board import V1, BoardCaps, format_states, limit_counts, parse_states
from labcli.core.boardlines import Event
from labcli.core.device import Device
from labcli.core.sim.firmware import Firmware
from labcli.core.sim.orifice import flow_factor
from labcli.core.wire import Frame, checksum, parse_line
from labcli.errors import DeviceError, DeviceUnsupported
from labcli.papers.takuma2014.sim.physics import P_ATM
from labcli.papers.takuma2014.sim.rig import SimRig

ROOT = Path(__file__).resolve().parents[2]
REFERENCE_GAIN, REFERENCE_ZERO = 5 / 16380, 819.0


# ---------------------------------------------------------------- capabilities


def test_caps_reply_round_trips_and_keeps_unknown_tokens():
    text = "CAPS,1.1,valves=P_L1:P_R1,pmax,events,wdt=1000,est=theta1:Fx,model=3f09a1c2,baseline,laser=2"
    caps = BoardCaps.parse(text)
    assert caps.valves == ("P_L1", "P_R1") and caps.pmax and caps.events and caps.baseline
    assert (caps.watchdog_ms, caps.estimates, caps.model, caps.extra) == (
        1000,
        ("theta1", "Fx"),
        "3f09a1c2",
        ("laser=2",),
    )
    assert caps.format() == text
    assert BoardCaps.parse("CAPS,1.2") == BoardCaps(protocol="1.2")
    assert V1.protocol == "1.0" and not V1.valves


@pytest.mark.parametrize("reply", ["CAPS", "CAPS,", "CAPS,one", "ID,x,1.0,A", "CAPS,1.x,pmax"])
def test_malformed_caps_replies_are_refused(reply):
    with pytest.raises(ValueError):
        BoardCaps.parse(reply)


def test_valve_letters_and_limits():
    assert parse_states("SHV", ("a", "b", "c")) == {"a": "supply", "b": "hold", "c": "vent"}
    assert format_states(["vent", "supply"]) == "VS"
    for bad in ("SH", "SHX", "shv"):
        with pytest.raises(ValueError):
            parse_states(bad, ("a", "b", "c"))
    # 0.7 MPa on the reference calibration: 819 + 0.7 / (5 / 16380) = 3112.2 counts, rounded down.
    assert limit_counts(0.7, [REFERENCE_GAIN] * 4, [REFERENCE_ZERO] * 4) == [3112] * 4
    assert limit_counts(2.0, [REFERENCE_GAIN], [REFERENCE_ZERO]) == [4095]  # clipped to the ADC
    with pytest.raises(ValueError):
        limit_counts(0.5, [0.0], [819])


def test_every_signed_line_in_the_protocol_document_checks():
    """The document's examples are what the code writes: every $ line's checksum and fields hold."""
    lines = re.findall(r"^< (\$[^\s]+)$", (ROOT / "docs" / "wire-protocol.md").read_text(), flags=re.M)
    assert len(lines) >= 5
    for line in lines:
        body, hh = line[1:].rsplit("*", 1)
        assert checksum(body.encode()) == int(hh, 16), line
        assert not isinstance(parse_line(line.encode()), type(parse_line(b"x"))), line  # not noise


# ---------------------------------------------------------------- the simulated board's replies


def settled(seed: int = 1) -> SimRig:
    rig = SimRig(seed=seed)
    rig.supply_air()
    rig.advance(5.0)
    rig.close_valves()
    rig.advance(2.0)
    return rig


def test_the_simulated_board_answers_every_1_1_command():
    rig = settled()
    fw = Firmware(rig, 200)
    assert fw.receive(b"CAPS?\n") == b"CAPS,1.1,valves=P_L1:P_R1:P_L2:P_R2,pmax,events\n"
    assert fw.receive(b"VALVE?\n") == b"OK VALVE HHHH\n"
    reply = fw.receive(b"VALVE P_L2 VENT\n").split(b"\n")
    assert parse_line(reply[0]) == Event(0, 7_000_000, "VALVE", ("HHVH", "host"))  # the event comes first
    assert reply[1:] == [b"OK VALVE HHVH", b""]
    assert rig.valve_states == ("hold", "hold", "vent", "hold")
    assert fw.receive(b"VALVE P_L2 VENT\n") == b"OK VALVE HHVH\n"  # no change, no event
    assert fw.receive(b"VALVE ALL supply\n").endswith(b"OK VALVE SSSS\n")
    assert (
        fw.receive(b"VALVE P_X SUPPLY\n")
        == b"ERR VALVE needs <P_L1|P_R1|P_L2|P_R2|ALL> <SUPPLY|HOLD|VENT>, got 'P_X SUPPLY'\n"
    )
    assert fw.receive(b"VALVE ALL\n").startswith(b"ERR VALVE needs")
    assert fw.receive(b"PMAX?\n") == b"OK PMAX 3112 3112 3112 3112\n"
    assert fw.receive(b"PMAX 2000\n") == b"OK PMAX 2000 2000 2000 2000\n"
    assert fw.receive(b"PMAX 1 2 3 4\n") == b"OK PMAX 1 2 3 4\n"
    for bad in (b"PMAX\n", b"PMAX 1 2\n", b"PMAX 4096\n", b"PMAX -1\n", b"PMAX 1.5\n"):
        assert fw.receive(bad) == b"ERR PMAX needs one limit or 4, in counts 0..4095, got '" + bad[5:-1] + b"'\n"


def test_a_1_0_board_and_a_board_without_valves_refuse_them():
    fw = Firmware(settled(), 200, version="1.0")
    assert fw.receive(b"ID?\n").startswith(b"ID,mckibben-2dof-sim,1.0,")
    for command in (b"CAPS?", b"VALVE ALL VENT", b"VALVE?", b"PMAX 100"):
        assert fw.receive(command + b"\n") == b"ERR unknown command '" + command + b"'\n"

    from labcli.core.sim import make_rig

    rpam = Firmware(make_rig("rpam"), 200)
    assert rpam.receive(b"CAPS?\n") == b"CAPS,1.1,events\n"
    assert rpam.receive(b"VALVE ALL VENT\n") == b"ERR this board has no valves, so no VALVE\n"


# ---------------------------------------------------------------- a 1.1 host against both boards


def test_the_host_moves_each_chamber_and_the_rig_follows():
    with Device.open("sim://?seed=2&ideal=1") as dev:
        assert dev.caps.valves == ("P_L1", "P_R1", "P_L2", "P_R2") and dev.caps.pmax
        assert dev.valve_states() == dict.fromkeys(dev.caps.valves, "vent")  # the rig starts vented
        assert dev.set_valves("supply") == dict.fromkeys(dev.caps.valves, "supply")
        dev.rig.advance(5.0)  # 7 time constants of the valves' lag
        p = dev.rig.true_state()["pressures_MPa"]
        np.testing.assert_allclose(p, 0.30, atol=1e-3)  # the regulator
        dev.set_valves("hold")
        dev.set_valves("vent", "P_R2")
        dev.rig.advance(5.0)
        p2 = dev.rig.true_state()["pressures_MPa"]
        assert abs(p2[3]) < 1e-3  # R2 vented
        assert np.all(p2[:3] > 0.2)  # the others kept their air (Boyle: the arm moved, so they changed a little)
        assert dev.valve_states() == {"P_L1": "hold", "P_R1": "hold", "P_L2": "hold", "P_R2": "vent"}
        events = dev.take_events()
        assert [(e.kind, e.fields) for e in events] == [
            ("VALVE", ("SSSS", "host")),
            ("VALVE", ("HHHH", "host")),
            ("VALVE", ("HHHV", "host")),
        ]
        assert [e.n for e in events] == [0, 1, 2] and events[0].t_us < events[1].t_us
        with pytest.raises(DeviceError, match=r"has no valve on POT1; its valves serve P_L1, P_R1, P_L2, P_R2\.$"):
            dev.set_valves("vent", "POT1")
        with pytest.raises(ValueError):
            dev.set_valves("open")


def test_a_1_1_host_drives_a_1_0_board_and_refuses_its_valves_in_one_sentence():
    url = "sim://?seed=1&fw=1.0"
    with Device.open(url) as dev:
        assert dev.caps == V1 and dev.info is not None and dev.info.firmware == "1.0"
        dev.set_rate(200)
        dev.start()
        n = 0
        while n < 200:
            n += len(dev.read(1.0))
        dev.stop()
        assert dev.counters["malformed"] == 0 and dev.counters["events"] == 0
        message = (
            f"The board on {url} (firmware 1.0) speaks wire protocol 1.0, which has no valve control; "
            "flash firmware 1.1 (`labcli flash`) or do it by hand at the rig."
        )
        for call in (lambda: dev.set_valves("vent"), dev.valve_states):
            with pytest.raises(DeviceUnsupported) as e:
                call()
            assert str(e.value) == message
        with pytest.raises(DeviceUnsupported, match="which has no pressure limit;"):
            dev.set_pressure_limit(3000)
        with pytest.raises(DeviceUnsupported, match="which has no model estimates;"):
            dev.stream_estimates(1)


def test_the_board_vents_a_chamber_over_its_limit_with_events():
    """The regulator at 0.30 MPa, the limit at 0.25 MPa: each chamber is vented as it crosses it."""
    with Device.open("sim://?seed=1&ideal=1") as dev:
        limit = limit_counts(0.25, [REFERENCE_GAIN] * 4, [REFERENCE_ZERO] * 4)
        assert dev.set_pressure_limit(limit) == (1638,) * 4 == dev.pressure_limit()
        dev.set_rate(200)
        dev.start()
        dev.set_valves("supply")
        frames = []
        while sum(map(len, frames)) < 1600:
            frames.append(dev.read(1.0))
        dev.stop()
        events = dev.take_events()
        assert dev.counters["events"] == len(events)
    pmax = [e for e in events if e.kind == "PMAX"]
    assert sorted(e.fields[0] for e in pmax) == ["P_L1", "P_L2", "P_R1", "P_R2"]
    # Caught within one check of crossing (every 20 ms while supplying): no chamber gets further past
    # the limit than its valve's orifice fills it in 20 ms.
    rig = dev.rig
    source, x = 0.30e6 + P_ATM, (0.25e6 + P_ATM) / (0.30e6 + P_ATM)
    rise = rig.valve.rate(rig.chamber_volumes()) * source * flow_factor(x, rig.valve.b) * 0.02 / 1e6 / REFERENCE_GAIN
    over = dict(zip(rig.valve_channels, rise + 3, strict=True))
    assert all(1638 < int(e.fields[1]) < 1638 + over[e.fields[0]] for e in pmax)
    assert events[-1].fields == ("VVVV", "pmax")
    assert dev.rig.valve_states == ("vent",) * 4
    values = np.concatenate([b.values for b in frames])
    assert np.all(values[:, :4].max(axis=0) < 1638 + rise + 3)  # the pressure never got far past the limit
    assert np.abs(dev.rig.true_state()["pressures_MPa"]).max() < 0.002  # then fell to the atmosphere's
    assert values[-1, :4].max() < 819 + 20  # 0 MPa gauge, give or take the sensors' zero offsets


def test_a_1_0_host_reads_a_1_1_board_without_noise():
    """Only data, log and reply lines reach a host that never asks for the 1.1 features."""
    import serial

    from labcli.core.sim import register

    register()
    with serial.serial_for_url("sim://?seed=1", timeout=0.2) as port:
        port.write(b"ID?\nRATE 200\nSTART\n")
        data = port.read(20_000)
        port.write(b"STOP\n")
        data += port.read(port.in_waiting)
    lines = data.split(b"\n")[:-1]
    parsed = [parse_line(line, 6) for line in lines[:-1]]
    kinds = {type(p).__name__ for p in parsed}
    assert kinds <= {"Frame", "LogLine", "Reply"}, kinds
    assert sum(isinstance(p, Frame) for p in parsed) > 300
