"""What both ``sim://`` ports share (labcli.core.sim.port): the URL's rig kept across reopenings,
and a USB-serial bridge with nothing on its modem lines.

Each test runs on the firmware model's port and, where simavr is installed, on the compiled
firmware's (``sim://?firmware=ELF``), so the one base class is held to the same behaviour twice.
"""

from __future__ import annotations

import pytest
import serial
from serial.serialutil import PortNotOpenError

from labcli.core.sim import register
from labcli.core.sim.hil_port import HilSerial
from labcli.core.sim.port import SimulatedPort
from labcli.core.sim.protocol_sim import Serial


@pytest.fixture(params=["model", "firmware"])
def url(request) -> str:
    """A sim:// URL of each port; the firmware's skips without the AVR tools and simavr."""
    if request.param == "model":
        return "sim://?seed=3"
    return f"sim://?firmware={request.getfixturevalue('firmware_elf')}&seed=3"


def test_both_ports_are_simulated_ports(url):
    register()
    with serial.serial_for_url(url, timeout=0.1) as port:
        assert isinstance(port, SimulatedPort)
        assert type(port) is (HilSerial if "firmware=" in url else Serial)


def test_reopening_powers_the_board_up_again_but_keeps_the_rig(url):
    register()
    port = serial.serial_for_url(url, timeout=0.1)
    rig = port.rig
    port.close()
    rig.advance(2.0)  # the rig's clock: physical time, which a reopened port must not undo
    port.open()
    assert port.rig is rig and rig.time_s >= 2.0
    port.close()
    port.port = url + "&noise=0"  # another URL: another rig
    port.open()
    assert port.rig is not rig and port.rig.time_s < 2.0
    port.close()


def test_the_bridge_takes_any_line_settings_and_has_no_modem_lines_wired(url):
    register()
    with serial.serial_for_url(url, timeout=0.1) as port:
        port.baudrate = 1_000_000
        port.rtscts = True
        port.rts = False
        port.dtr = False
        port.break_condition = True
        port.break_condition = False
        assert (port.cts, port.dsr, port.cd, port.ri) == (True, True, True, False)
        assert port.out_waiting == 0
        port.reset_output_buffer()
    with pytest.raises(PortNotOpenError):
        port.out_waiting
    with pytest.raises(PortNotOpenError):
        port.reset_output_buffer()


def test_a_port_without_a_url_refuses_to_open():
    port = Serial()
    with pytest.raises(serial.SerialException, match="Port must be configured before it can be used."):
        port.open()
    port.port = "sim://"
    port.open()
    with pytest.raises(serial.SerialException, match="Port is already open."):
        port.open()
    port.close()
