"""A rig that streams off the rate it confirmed: a warning in the session, a flag on every trial.

The simulated rig's ``ratefactor=X`` is a firmware whose timer is set wrong: it answers
``OK RATE 200`` and makes frames X times as often, its own clock stamping each as it is made.
The session compares the rig's clock with the rate it confirmed (``RATE_TOLERANCE``).
"""

from __future__ import annotations

import numpy as np
import pytest
import serial

from labcli.core.acquisition import acquire
from labcli.core.sim import register
from labcli.core.sim.url import accepted_form, firmware_options
from labcli.core.store import RunFile
from labcli.core.stream import RATE_TOLERANCE
from labcli.core.wire import parse_line

register()
PLAN = "trial,set,mass_g,direction_deg\n1,fit,800,-60\n2,fit,500,30\n"


def flag(rate_hz: float) -> str:
    return (
        f"the rig streams at {rate_hz:.4g} Hz by its own clock, not the 200 Hz it confirmed; check its firmware's timer"
    )


def test_the_rig_confirms_the_rate_asked_and_stamps_frames_at_its_own():
    port = serial.serial_for_url("sim://?seed=1&clock=virtual&ratefactor=10", timeout=1)
    try:
        assert port.readline().startswith(b"#")  # the power-up banner
        port.write(b"RATE 200\n")
        assert port.readline() == b"OK RATE 200\n"
        port.write(b"START\n")
        lines = [port.readline() for _ in range(60)]
    finally:
        port.close()
    t_us = [f.t_us for f in map(parse_line, lines) if getattr(f, "t_us", None) is not None]
    assert len(t_us) > 50
    assert set(np.diff(t_us)) == {500}  # 2000 frames per second by the rig's clock, 200 Hz confirmed


@pytest.mark.parametrize("value", ["0", "0.001", "101", "nan", "ten", ""])
def test_a_rate_factor_out_of_range_is_refused_with_the_accepted_form(value):
    with pytest.raises(serial.SerialException) as e:
        serial.serial_for_url(f"sim://?ratefactor={value}")
    assert str(e.value) == (
        f"option 'ratefactor' in sim:// URL must be a number within 0.01..100, got '{value}'; "
        f"expected {accepted_form()}"
    )


def test_the_compiled_firmware_takes_no_rate_factor():
    with pytest.raises(serial.SerialException, match="option 'ratefactor' in sim:// URL does not go with firmware="):
        firmware_options("sim://?firmware=rig.elf&ratefactor=10")


@pytest.mark.parametrize(
    "factor, flagged", [(10, True), (0.1, True), (1 + 0.8 * RATE_TOLERANCE, False), (1 + 1.2 * RATE_TOLERANCE, True)]
)
def test_a_stream_off_its_rate_warns_once_and_flags_every_trial(tmp_path, quiet_ui, factor, flagged):
    (tmp_path / "plan.csv").write_text(PLAN)
    run = tmp_path / "run.h5"
    ui = quiet_ui()
    outcome = acquire(
        run,
        f"sim://?seed=1&clock=virtual&ratefactor={factor}",
        protocol="takuma2014",
        plan=tmp_path / "plan.csv",
        unattended=True,
        ui=ui,
    )
    assert outcome.exit_code == 0, outcome.message
    said = ui.console.file.getvalue()
    with RunFile.open(run) as f:
        assert f.records.ids() == [1, 2]
        flags = [f.records.read(i).get("flags", []) for i in (1, 2)]
    rate = 200.0 * factor
    warning = f"{flag(rate)}; each trial recorded so carries a flag"
    if flagged:
        assert " ".join(said.split()).count(warning) == 1, said
        assert flags == [[flag(rate)], [flag(rate)]]
    else:
        assert "streams at" not in said
        assert flags == [[], []]
