"""Resuming a run on the rig that began it, the session log, and --baud on every command that opens a port."""

from __future__ import annotations

import hashlib
import io

from click.testing import CliRunner
from rich.console import Console
from support.firmware import FakeFirmware
from support.sessionlog import LoggingRunFile

from labcli.cli import cli
from labcli.core.acquisition import resume_command
from labcli.core.device import Device
from labcli.core.engine import RunEngine
from labcli.core.protocol import load_protocol
from labcli.core.sessionlog import RigIdentity, SessionInfo
from labcli.core.simoperator import operator_for
from labcli.core.store import RunFile
from labcli.core.ui import UnattendedUI
from labcli.papers.takuma2014.protocol import load_plan
from labcli.papers.takuma2014.session import force_session

PROTOCOL = load_protocol("takuma2014")
PLAN = load_plan(PROTOCOL).iloc[:4]
PORT = "sim://?seed=1&clock=virtual"


def partial_run(path, store_wrap=lambda s: s, trials=2):
    """A run of a 4-trial plan recorded on the simulated rig, stopped after ``trials`` trials."""
    dev = Device.open(PORT)
    run = RunFile.create(path, protocol=PROTOCOL, device_info=dev.info, port=PORT, plan=PLAN)
    store = store_wrap(run)
    info = SessionInfo("2026-01-01T00:00:00.000000Z", PORT, 115200, RigIdentity.of(dev.info, PROTOCOL.calibration))
    engine = RunEngine(
        dev,
        store,
        PROTOCOL,
        UnattendedUI(console=Console(file=io.StringIO(), width=200)),
        run_path=str(path),
        resume_command=resume_command(str(path), PORT),
        simulated_operator=operator_for(dev),
        session=info,
    )
    outcome = engine.run(force_session(PROTOCOL, PLAN.iloc[:trials]))
    run.close()
    dev.close()
    return store, outcome


def digest(path):
    return hashlib.sha256(path.read_bytes()).hexdigest()


def test_resume_on_another_rig_is_refused_naming_what_differs(tmp_path):
    path = tmp_path / "run.h5"
    partial_run(path)
    before = digest(path)
    with FakeFirmware(device="mckibben-2dof", firmware="2.1") as fw:
        result = CliRunner().invoke(cli, ["acquire", str(path), "--port", fw.port, "--resume"], input="")
    assert result.exit_code == 1
    assert result.output == (
        f"Error: {path} was recorded on mckibben-2dof-sim (firmware 1.1), but the rig on {fw.port} has device "
        "'mckibben-2dof', not 'mckibben-2dof-sim' and firmware '2.1', not '1.1': resume on the rig that began the "
        "run, or pass --allow-other-rig to continue it on this one.\n"
    )
    assert digest(path) == before


def test_allow_other_rig_continues_with_a_warning_and_keeps_the_flag_in_the_resume_line(tmp_path):
    path = tmp_path / "run.h5"
    partial_run(path)
    with FakeFirmware(device="mckibben-2dof", firmware="2.1") as fw:
        result = CliRunner().invoke(
            cli, ["acquire", str(path), "--port", fw.port, "--resume", "--allow-other-rig", "--baud", "57600"], input=""
        )
    text = " ".join(result.output.split())
    assert (
        f"continuing {path} on another rig (device 'mckibben-2dof', not 'mckibben-2dof-sim' and firmware "
        "'2.1', not '1.1'), as --allow-other-rig allows"
    ) in text
    # No one answered the prompts: the session ends for want of input, and the line that continues the
    # run carries the baud rate and the flag.
    assert result.exit_code == 1
    assert text.endswith(
        f"Error: No input: standard input ended at a question during the setup; 2 trials stored in {path}. Resume "
        f"where someone at the rig can answer: labcli acquire {path} --port {fw.port} --resume --baud 57600 "
        "--allow-other-rig"
    )


def test_a_calibration_change_alone_is_named():
    dev_info = type("Info", (), {"device": "rig", "firmware": "1", "channels": PROTOCOL.calibration.names})()
    ours = RigIdentity.of(dev_info, PROTOCOL.calibration)
    other = RigIdentity(ours.device, ours.firmware, ours.channels, (ours.gain[0] * 1.01, *ours.gain[1:]), ours.offset)
    assert ours.differences(other) == ["another calibration of P_L1"]
    assert ours.differences(ours) == []


def test_the_session_log_hears_every_session_and_how_it_ended(tmp_path):
    path = tmp_path / "run.h5"
    store, outcome = partial_run(path, LoggingRunFile)
    assert outcome.stored == 2
    [session] = store.sessions.heard
    assert session["info"].port == PORT and session["info"].baud == 115200
    assert session["info"].rig.device == "mckibben-2dof-sim"
    assert session["added"] == [1, 2] and session["redone"] == [] and session["ended"] == "finished"


def test_the_resume_line_carries_the_baud_rate_and_the_other_rig_flag():
    assert resume_command("r.h5", "/dev/ttyACM0") == "labcli acquire r.h5 --port /dev/ttyACM0 --resume"
    assert resume_command("r.h5", "/dev/ttyACM0", baud=1000000, other_rig=True) == (
        "labcli acquire r.h5 --port /dev/ttyACM0 --resume --baud 1000000 --allow-other-rig"
    )


def test_baud_is_offered_where_a_port_is_opened_and_checked():
    for command in ("acquire", "monitor"):
        assert "--baud" in CliRunner().invoke(cli, [command, "--help"]).output
    result = CliRunner().invoke(cli, ["monitor", "--port", "sim://", "--baud", "12"])
    assert result.exit_code == 2 and "--baud" in result.output
