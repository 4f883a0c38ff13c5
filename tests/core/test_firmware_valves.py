"""The firmware's wire protocol 1.1 on simavr: valves on the pins and in the rig, the pressure limit, the watchdog.

Three builds: the firmware (fixture ``firmware_elf``), a test build whose ``TEST HANG`` command
hangs the main loop (``-DLABCLI_TEST_COMMANDS``), and a 1.0 board (``-DWIRE_PROTOCOL_1_0``, the
1.1 commands and event lines left out) for a 1.1 host against a 1.0 board.  The host talks to
the board through the harness directly (:class:`~labcli.core.sim.hil.HilLink`), so a test can
let simulated time run while the host sends nothing at all, or through ``sim://?firmware=``.
"""

from __future__ import annotations

import threading
import time
from pathlib import Path

import numpy as np
import pytest
from support.firmware_build import make

from labcli.core.board import limit_counts
from labcli.core.boardlines import Event
from labcli.core.device import Device
from labcli.core.sim.hil import VALVE_LAG_BATCHES, VALVE_PINS, HilLink
from labcli.core.sim.orifice import flow_factor
from labcli.core.wire import Frame, LogLine, Reply, StreamReader, parse_line
from labcli.errors import DeviceUnsupported
from labcli.papers.takuma2014.sim.physics import P_ATM
from labcli.papers.takuma2014.sim.rig import SimRig

REFERENCE_GAIN, REFERENCE_ZERO = 5 / 16380, 819.0


@pytest.fixture(scope="session")
def hang_elf(tmp_path_factory: pytest.TempPathFactory, firmware_elf: Path) -> Path:
    build = tmp_path_factory.mktemp("firmware-hang")
    make(build, "all", defs="-DLABCLI_TEST_COMMANDS")
    return build / "labcli_rig.elf"


@pytest.fixture(scope="session")
def v1_elf(tmp_path_factory: pytest.TempPathFactory, firmware_elf: Path) -> Path:
    build = tmp_path_factory.mktemp("firmware-1.0")
    make(build, "all", defs="-DWIRE_PROTOCOL_1_0")
    return build / "labcli_rig.elf"


@pytest.fixture(scope="session")
def quick_supply_elf(tmp_path_factory: pytest.TempPathFactory, firmware_elf: Path) -> Path:
    build = tmp_path_factory.mktemp("firmware-supply")
    make(build, "all", defs="-DSUPPLY_MAX_MS=500")  # the shipped board's 60 s, shortened
    return build / "labcli_rig.elf"


class Board:
    """A HilLink whose bytes are collected; ``run(s)`` lets ``s`` of simulated time pass."""

    def __init__(self, elf: Path, rig) -> None:
        self._lock = threading.Lock()
        self._bytes = bytearray()
        self.link = HilLink(rig, elf, pacing="demand", on_bytes=self._take)

    def _take(self, data: bytes) -> None:
        with self._lock:
            self._bytes += data

    def send(self, text: str) -> None:
        self.link.write(text.encode() + b"\n")

    def run(self, seconds: float) -> None:
        end = self.link.avr_time_s + seconds
        deadline = time.monotonic() + 120
        while self.link.avr_time_s < end and time.monotonic() < deadline:
            self.link.demand(0.05)
            time.sleep(0.005)
        assert self.link.avr_time_s >= end, "the simulation did not keep up"

    def lines(self) -> list:
        with self._lock:
            data = bytes(self._bytes)
        return [parse_line(line, 6) for line in data.split(b"\n")[:-1]]

    def events(self) -> list[Event]:
        return [p for p in self.lines() if isinstance(p, Event)]

    def close(self) -> None:
        self.link.stop()


def pressurised_rig() -> SimRig:
    rig = SimRig(seed=4, tau_s=0.3)  # a quick rig: the arm settles in about 1 s, the chambers fill in 0.5 s
    rig.supply_air()
    rig.advance(3.0)
    rig.close_valves()
    rig.advance(1.0)
    return rig


def pins_of(link: HilLink) -> dict[str, int]:
    ports = {"B": 0, "D": 0}
    for _, port, value in link.pins():
        ports[port] = value
    return ports


def test_valve_commands_move_the_pins_and_the_chambers(firmware_elf):
    rig = pressurised_rig()
    board = Board(firmware_elf, rig)
    try:
        board.run(0.2)
        board.send("VALVE ALL SUPPLY")
        board.run(0.3)
        ports = pins_of(board.link)
        # Every inlet on, every exhaust off, the main supply valve and the LED on.
        assert ports["D"] == 0b01010100 and ports["B"] == 0b00100101
        board.send("VALVE P_R2 VENT")
        board.send("VALVE P_L1 HOLD")
        board.run(2.5)
        ports = pins_of(board.link)
        assert ports["D"] == 0b01010000 and ports["B"] == 0b00100110  # L1 closed, R2 exhaust on
        assert board.link.valve_states == ("hold", "supply", "supply", "vent")
        assert rig.valve_states == ("hold", "supply", "supply", "vent")
        p = rig.true_state()["pressures_MPa"]
        assert abs(p[3]) < 0.01 and np.all(np.abs(p[1:3] - 0.30) < 0.01)  # R2 vented, R1 and L2 at the regulator
        board.send("VALVE?")
        board.send("VALVE ALL HOLD")
        board.run(0.2)
        assert pins_of(board.link) == {"B": 0, "D": 0}
        lines = board.lines()
        replies = [p.text for p in lines if isinstance(p, Reply)]
        assert replies == ["OK VALVE SSSS", "OK VALVE SSSV", "OK VALVE HSSV", "OK VALVE HSSV", "OK VALVE HHHH"]
        valve_events = [e.fields for e in board.events()]
        assert valve_events == [
            ("SSSS", "host"),
            ("SSSV", "host"),
            ("HSSV", "host"),
            ("HHHH", "host"),
        ]
        # Never a chamber open to both sides, at any port write (break before make).
        for _, port, value in board.link.pins():
            for p_name, inlet, exhaust in VALVE_PINS:
                if p_name == port:
                    assert not (value >> inlet & 1 and value >> exhaust & 1)
    finally:
        board.close()


def test_a_valve_acts_on_the_rig_a_fixed_lag_after_its_pin_however_far_ahead_the_rig_is(firmware_elf):
    """The rig is sampled up to VALVE_LAG_BATCHES batches ahead of the AVR, how far by the pump's
    luck.  A command read by an AVR at rest (the pump then grants a whole demand at once) and one
    read mid-stream both reach the rig exactly the lag after their pins moved, so the rig's chambers
    are supplied as long as the board supplied them (not 0 ms of a 10 ms supply, as under load)."""
    rig = pressurised_rig()
    changes: list[tuple[float, tuple[str, ...]]] = []
    set_valves = rig.set_valves

    def logged(states) -> None:
        changes.append((rig.time_s, tuple(states)))
        set_valves(states)

    rig.set_valves = logged
    board = Board(firmware_elf, rig)
    link = board.link
    try:
        board.run(0.2)
        deadline = time.monotonic() + 30
        while link.avr_time_s < link.rig_time_s and time.monotonic() < deadline:
            time.sleep(0.005)  # the AVR runs what it was given, then rests
        board.send("VALVE ALL SUPPLY")
        board.run(0.03)
        board.send("VALVE ALL HOLD")
        board.run(0.3)
    finally:
        board.close()
    # (The coils of port D move before those of port B: a change may pass through mixed states.)
    assert changes[0][1] == ("supply",) * 4 and changes[-1][1] == ("hold",) * 4, changes
    lag = VALVE_LAG_BATCHES * 10e-3  # the default 10 ms batches
    for t_rig, _ in changes:
        since = [t_rig - link.rig_t0 - t for t, _, _ in link.pins()]
        assert any(lag <= d < lag + 1e-3 for d in since), (t_rig - link.rig_t0, link.pins())
    # The rig's supply lasted the board's (to a slice or two): its VALVE events' times apart.
    events = [e for e in board.events() if e.kind == "VALVE"]
    supplied = (events[1].t_us - events[0].t_us) * 1e-6
    assert abs(changes[-1][0] - changes[0][0] - supplied) <= 2e-3, (changes, supplied)


def test_the_chip_vents_an_over_pressure_with_the_host_silent(firmware_elf):
    """The regulator at 0.30 MPa, the limit at 0.25 MPa; after the two commands the host sends nothing."""
    rig = SimRig(seed=4, tau_s=0.3)  # vented
    board = Board(firmware_elf, rig)
    try:
        board.run(0.1)
        limit = limit_counts(0.25, [REFERENCE_GAIN], [REFERENCE_ZERO])[0]
        board.send(f"PMAX {limit}")
        board.send("VALVE ALL SUPPLY")
        board.run(3.0)  # not streaming, no command: the board alone
        events = board.events()
        pmax = [e for e in events if e.kind == "PMAX"]
        assert sorted(e.fields[0] for e in pmax) == ["P_L1", "P_L2", "P_R1", "P_R2"]
        # Caught at the first check above it: idle, the board checks 50 times a second, so no
        # chamber gets further above the limit than its orifice fills it in 20 ms (ISO 6358 flow).
        source = 0.30e6 + P_ATM
        x = (0.25e6 + P_ATM) / source
        rise_MPa = rig.valve.rate(rig.chamber_volumes()) * source * flow_factor(x, rig.valve.b) * 0.02 / 1e6
        rise = dict(zip(rig.valve_channels, rise_MPa / REFERENCE_GAIN, strict=True))
        assert all(limit < int(e.fields[1]) <= limit + rise[e.fields[0]] + 2 for e in pmax)
        assert events[-1].fields == ("VVVV", "pmax")
        assert rig.valve_states == ("vent",) * 4
        assert np.abs(rig.true_state()["pressures_MPa"]).max() < 0.02
        # The limit stays stored: asked again after all that, the board still has it.
        board.send("PMAX?")
        board.run(0.1)
        assert [p.text for p in board.lines() if isinstance(p, Reply)][-1] == f"OK PMAX {limit} {limit} {limit} {limit}"
    finally:
        board.close()


def test_the_board_holds_chambers_the_host_left_supplying(quick_supply_elf):
    """A host that dies while the chambers fill: 0.5 s (60 s shipped) after its last VALVE command
    the board holds every supplied chamber by itself, with a VALVE event of cause timeout."""
    rig = SimRig(seed=4, tau_s=0.3)  # vented
    board = Board(quick_supply_elf, rig)
    try:
        board.run(0.1)
        board.send("VALVE ALL SUPPLY")
        board.run(0.3)
        board.send("VALVE P_R2 VENT")  # a VALVE command starts the time again
        board.run(1.0)  # the host says nothing more
        valve = [e for e in board.events() if e.kind == "VALVE"]
        assert [e.fields for e in valve] == [("SSSS", "host"), ("SSSV", "host"), ("HHHV", "timeout")]
        waited = (valve[2].t_us - valve[1].t_us) * 1e-6
        assert 0.5 <= waited <= 0.5 + 0.03  # checked on each 50 Hz sample (20 ms apart), idle as here
        assert rig.valve_states == ("hold", "hold", "hold", "vent")
        assert rig.true_state()["pressures_MPa"][:3].min() > 0.2  # held with the air they had
    finally:
        board.close()


def test_the_watchdog_vents_a_hung_loop_and_the_board_comes_back_vented(hang_elf):
    rig = pressurised_rig()
    board = Board(hang_elf, rig)
    try:
        board.run(0.1)
        board.send("PMAX 3000")  # stored in EEPROM: it must survive the reset
        board.send("VALVE ALL SUPPLY")
        board.run(0.3)
        hung_at = board.link.avr_time_s
        board.send("TEST HANG")
        board.run(3.0)
        pins = board.link.pins()
        vented = [t for t, port, value in pins if port == "B" and value & 0b10 and t > hung_at]
        assert vented, pins
        assert 0.8 < vented[0] - hung_at < 1.2  # the watchdog's 1 s, then its interrupt vents
        lines = board.lines()
        logs = [p.text for p in lines if isinstance(p, LogLine)]
        assert sum("ready" in t for t in logs) == 2  # power-up, then the watchdog's reset
        events = [(e.kind, e.fields) for e in board.events()]
        assert events[-2:] == [("RESET", ("wdt",)), ("VALVE", ("VVVV", "wdt"))]
        assert rig.valve_states == ("vent",) * 4
        assert np.abs(rig.true_state()["pressures_MPa"]).max() < 0.05
        board.send("PMAX?")
        board.send("VALVE?")
        board.run(0.2)
        replies = [p.text for p in board.lines() if isinstance(p, Reply)]
        assert replies[-2:] == ["OK PMAX 3000 3000 3000 3000", "OK VALVE VVVV"]
    finally:
        board.close()


def test_a_1_1_host_drives_the_board_through_the_serial_api(firmware_elf):
    with Device.open(f"sim://?firmware={firmware_elf}&seed=3") as dev:
        assert dev.info is not None and dev.info.firmware == "1.1-avr"
        assert dev.caps.valves == ("P_L1", "P_R1", "P_L2", "P_R2") and dev.caps.pmax and dev.caps.watchdog_ms == 1000
        assert dev.set_pressure_limit([3000, 3001, 3002, 3003]) == (3000, 3001, 3002, 3003)
        dev.set_rate(100)
        dev.start()
        assert dev.set_valves("supply") == dict.fromkeys(dev.caps.valves, "supply")
        n = 0
        while n < 300:
            n += len(dev.read(1.0))
        assert dev.set_valves("hold", "P_L2")["P_L2"] == "hold"
        dev.stop()
        assert dev.counters["lost"] == 0 and dev.counters["malformed"] == 0 and dev.counters["events"] == 2
        assert [e.fields for e in dev.take_events()] == [("SSSS", "host"), ("SSHS", "host")]
        assert np.all(np.abs(dev.rig.true_state()["pressures_MPa"] - 0.30) < 0.02)


def test_a_1_0_host_reads_the_1_1_board_as_before(firmware_elf):
    """Only 1.0 lines (data, log, replies) reach a host that never asks for more."""
    board = Board(firmware_elf, pressurised_rig())
    try:
        board.run(0.1)
        for command in ("ID?", "RATE 200", "START"):
            board.send(command)
        board.run(1.0)
        board.send("STOP")
        board.run(0.1)
        lines = board.lines()
    finally:
        board.close()
    assert {type(p) for p in lines} == {Frame, LogLine, Reply}
    assert sum(isinstance(p, Frame) for p in lines) >= 195
    reader = StreamReader(n_channels=6)
    reader.feed(b"".join(f"{p.text}\n".encode() for p in lines if isinstance(p, Reply)))
    assert list(reader.replies) == [
        "ID,mckibben-2dof,1.1-avr,P_L1,P_R1,P_L2,P_R2,POT1,POT2",
        "OK RATE 200",
        "OK START",
        "OK STOP",
    ]


def test_a_1_1_host_against_a_1_0_board(v1_elf):
    url = f"sim://?firmware={v1_elf}"
    with Device.open(url) as dev:
        assert dev.info is not None and dev.info.firmware == "1.0-avr" and dev.caps.protocol == "1.0"
        dev.set_rate(200)
        dev.start()
        n = 0
        while n < 200:
            n += len(dev.read(1.0))
        dev.stop()
        assert dev.counters["lost"] == 0 and dev.counters["events"] == 0
        with pytest.raises(DeviceUnsupported) as e:
            dev.set_valves("vent")
    assert str(e.value) == (
        f"The board on {url} (firmware 1.0-avr) speaks wire protocol 1.0, which has no valve control; "
        "flash firmware 1.1 (`labcli flash`) or do it by hand at the rig."
    )
