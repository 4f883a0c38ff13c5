"""An unplugged link while the board supplies the chambers: the board holds them by itself.

The session supplies the chambers by command (``VALVE ALL SUPPLY``) and the link is pulled out
while they fill, so the host can neither read nor send the hold.  The session ends with the
device's sentence; the board, streaming on by itself, holds every supplied chamber once they have
been supplied for its ``supply_max_s`` (60 s of rig time), with a ``VALVE`` event of cause
``timeout``: never supplying unattended.  (A host killed instead: tests/cli/test_valves_pty.py;
the AVR firmware's own timeout with the host silent: tests/core/test_firmware_valves.py.)
"""

from __future__ import annotations

import pytest
from test_valves_session import LOADS, run

from labcli.core.sim.valves import SUPPLY_MAX_S
from labcli.core.steps import Valves
from labcli.errors import DeviceError

SUPPLIED = ("supply",) * 4


def test_a_link_unplugged_while_the_chambers_fill_leaves_them_held_by_the_board(tmp_path):
    held: dict = {}

    def unplug_at_the_supply(step, reply):
        if isinstance(step, Valves) and step.state == "supply" and not held:
            held["dev"] = dev = current["dev"]
            held["at"] = dev.rig.time_s
            dev.serial.unplug()

    current: dict = {}
    import test_valves_session as tv

    real_open = tv.Device.open

    def opening(url, *a, **k):
        current["dev"] = real_open(url, *a, **k)
        return current["dev"]

    tv.Device.open = staticmethod(opening)
    try:
        with pytest.raises(DeviceError) as e:
            run(tmp_path, "sim://?seed=12&clock=virtual", loads=LOADS[:1], watch=unplug_at_the_supply)
    finally:
        tv.Device.open = staticmethod(real_open)
    assert "disconnected" in str(e.value) or "Lost the connection" in str(e.value)
    dev = held["dev"]
    rig, firmware = dev.rig, dev.serial.firmware
    assert rig.valve_states == SUPPLIED  # the host could not hold them
    events = b""
    while rig.valve_states == SUPPLIED and rig.time_s - held["at"] < 2 * SUPPLY_MAX_S:
        # One second of the board's own time: streaming into a link nobody reads, or idle.
        events += firmware.frames(200) if firmware.streaming else firmware.idle(rig.time_s + 1.0)
    waited = rig.time_s - held["at"]
    assert rig.valve_states == ("hold",) * 4 and rig.true_state()["valves"] == "closed"
    assert SUPPLY_MAX_S <= waited <= SUPPLY_MAX_S + 1.5
    assert b",VALVE,HHHH,timeout*" in events
    assert rig.true_state()["pressures_MPa"].min() > 0.2  # held with the air they had
    dev.close()
