"""``labcli sim --pty --mode rpam``: the rPAM stand served on a pseudo-terminal, driven from its console.

The rig's own options (``experiment``, ``nominal``) are declared as data by the paper
(:mod:`labcli.papers.rpam2015.sim.options`) and reach ``sim://`` and ``labcli sim`` alike; the
operator's lines typed on ``labcli sim``'s standard input (:mod:`labcli.papers.rpam2015.sim.console`)
act on the stand, and a serial program reading the pty sees the physics.
"""

from __future__ import annotations

import math
import os
import subprocess
import sys
import time

import numpy as np
import pytest
import serial
from click.testing import CliRunner
from support.procs import finish

from labcli.cli import cli
from labcli.core.sim import register
from labcli.core.sim.console import execute
from labcli.core.wire import Frame, parse_line
from labcli.papers.rpam2015.actuator import FORCE_READINGS
from labcli.papers.rpam2015.sim import options as rig_options
from labcli.papers.rpam2015.sim.rig import EXPERIMENTS, RpamRig, counts_to_si

register()


def test_the_declared_configurations_are_the_rigs():
    assert set(rig_options.EXPERIMENTS) == set(EXPERIMENTS)
    assert rig_options.FORCE_READINGS == FORCE_READINGS


def test_the_url_builds_the_stand_on_the_reading_it_names():
    with serial.serial_for_url("sim://?mode=rpam&reading=paper&seed=2") as port:
        assert {a.force_reading for a in port.rig.actuators} == {"paper"}
    with serial.serial_for_url("sim://?mode=rpam&seed=2") as port:
        assert {a.force_reading for a in port.rig.actuators} == {"derived"}  # the protocol's
    with pytest.raises(ValueError, match="option 'reading' in sim:// URL must be one of derived, paper, got 'printed'"):
        serial.serial_for_url("sim://?mode=rpam&reading=printed")


def test_the_url_builds_the_rig_its_options_name():
    with serial.serial_for_url("sim://?mode=rpam&experiment=stretch&nominal=1&seed=2") as port:
        rig = port.rig
        assert isinstance(rig, RpamRig) and rig.experiment == "stretch" and rig.variation is False
        assert rig.true_stretch_coefficients_N["A"] == rig.true_stretch_coefficients_N["B"]
    with serial.serial_for_url("sim://?mode=rpam&seed=2") as port:
        assert port.rig.experiment == "joint" and port.rig.variation is True
    with pytest.raises(ValueError, match="option 'experiment' in sim:// URL must be one of joint, stretch, got 'side'"):
        serial.serial_for_url("sim://?mode=rpam&experiment=side")
    with pytest.raises(ValueError, match="option 'experiment' in sim:// URL applies to mode=rpam only"):
        serial.serial_for_url("sim://?experiment=stretch")


def test_console_lines_act_on_the_stand_in_the_units_people_type():
    rig = RpamRig(seed=1, noise=0.0, variation=False)
    assert execute(rig, "hang 100") == "error: payloads hang from the stretch stand; type 'mount stretch' first"
    assert execute(rig, "pressures 120 40").startswith("ok pressures 120,40 kPa")
    rig.advance(10.0)
    st = rig.true_state()
    assert st["setpoints_MPa"] == pytest.approx([0.120, 0.040], abs=1e-12)  # kPa typed, MPa inside
    assert st["pressures_MPa"] == pytest.approx([0.120, 0.040], abs=1e-6)  # 10 s is many lags
    line = execute(rig, "state")
    assert f"alpha_deg={math.degrees(st['alpha_rad']):.3f}" in line and "P_kPa=120.00,40.00" in line
    assert execute(rig, "mount side") == "error: unknown configuration 'side'; usage: mount joint|stretch"
    assert execute(rig, "pressures 2000 0") == (
        "error: regulator pressures must be within 0..1 MPa gauge (the sensors' span)"
    )
    assert execute(rig, "mount stretch").startswith("ok mount stretch")
    assert rig.true_state()["pressures_MPa"] == pytest.approx([0.0, 0.0])  # re-rigged vented
    assert execute(rig, "hang -5") == "error: mass must be >= 0 g, got -5"
    assert execute(rig, "help") == (
        "commands: pressures KPA_A KPA_B, vent, mount joint|stretch, hang GRAMS, remove, state, wait SECONDS, help, quit"
    )


def test_labcli_sim_refuses_the_mckibben_rigs_options_for_the_rpam_stand():
    result = CliRunner().invoke(cli, ["sim", "--pty", "--mode", "rpam", "--supply", "0.3"])
    assert result.exit_code == 1
    assert result.output == "Error: --supply is an option of the mckibben rig; --mode rpam serves the rpam rig.\n"
    result = CliRunner().invoke(cli, ["sim", "--pty", "--mode", "rpam", "--experiment", "side"])
    assert result.exit_code == 2 and "'side' is not one of 'joint', 'stretch'" in result.output


def _settled(port: serial.Serial, seconds: float) -> np.ndarray:
    """SI values (P_A, P_B MPa, POT rad, LEN m) averaged over the last 0.5 s of ``seconds`` of frames.

    8 s after an action is over eight lag constants (0.7 s, jittered up to 1.4 times): settled
    to a few micrometres and hundredths of a degree.
    """
    data, end = b"", time.monotonic() + seconds
    while time.monotonic() < end:
        data += port.read(port.in_waiting or 1)
    frames = [f for f in (parse_line(x) for x in data.split(b"\n")) if isinstance(f, Frame)]
    assert len(frames) > 60
    return counts_to_si(np.array([f.values for f in frames[-50:]], dtype=float)).mean(axis=0)


@pytest.mark.skipif(not hasattr(os, "openpty"), reason="needs pseudo-terminals")
def test_labcli_sim_serves_the_rpam_stand_and_its_console_drives_it():
    # Two terminals, no Python: the stand starts rigged for the stretch test (--experiment), the
    # operator hangs payloads and sets pressures by typing, and the port's counts follow the truth.
    proc = subprocess.Popen(
        [sys.executable, "-m", "labcli", "sim", "--pty", "--mode", "rpam", "--experiment", "stretch", "--seed", "3"],
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        bufsize=1,
    )

    def say(line: str) -> str:
        proc.stdin.write(line + "\n")
        proc.stdin.flush()
        return proc.stdout.readline().rstrip("\n")

    def state() -> dict[str, str]:
        return dict(f.split("=", 1) for f in say("state").split()[1:] if "=" in f)

    try:
        path = proc.stdout.readline().split()[3]
        with serial.Serial(path, timeout=2.0) as port:
            port.write(b"ID?\n")
            while (line := port.readline()).startswith(b"#"):
                pass
            assert line == b"ID,rpam-joint-sim,1.0,P_A,P_B,POT,LEN\n"
            assert state()["experiment"] == "stretch"
            port.write(b"START\n")
            unloaded = _settled(port, 1.0)
            assert say("pressures 60 0").startswith("ok pressures 60,0 kPa")
            assert say("hang 300").startswith("ok hang 300 g")
            loaded, truth = _settled(port, 8.0), state()
            # A payload on a pressurised rPAM stretches it: the draw-wire length grows, as the truth says.
            assert float(truth["lambda"]) > 1.0 and truth["payload_g"] == "300"
            assert loaded[3] * 1e3 == pytest.approx(float(truth["L_mm"]), abs=0.2)
            assert loaded[3] > unloaded[3] + 1e-3
            assert loaded[0] * 1e3 == pytest.approx(60.0, abs=0.5)
            assert say("mount joint").startswith("ok mount joint")
            rest = _settled(port, 1.0)
            alpha0 = float(state()["alpha_deg"])
            assert say("pressures 120 40").startswith("ok pressures 120,40 kPa")
            moved, truth = _settled(port, 8.0), state()
            # The joint turns where the two actuators' torques balance; the potentiometer shows the turn.
            d_true = float(truth["alpha_deg"]) - alpha0
            assert abs(d_true) > 1.0
            assert math.degrees(moved[2] - rest[2]) == pytest.approx(d_true, abs=0.15)
            assert (moved[0] * 1e3, moved[1] * 1e3) == pytest.approx((120.0, 40.0), abs=0.5)
            port.write(b"STOP\n")
        assert say("quit") == "ok quit"
        out, err = finish(proc)
        assert proc.returncode == 0, err
        assert out == "Simulated rig stopped.\n"
    finally:
        if proc.poll() is None:
            proc.kill()
