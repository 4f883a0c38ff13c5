"""A third paper, defined entirely in the tests, runs through the whole toolkit.

The toy paper (:mod:`support.toy`: a 1-DoF rig, one pressure and one angle, two
trials) is registered at run time; nothing in labcli names it.  ``labcli acquire
--unattended`` records it on its own simulated rig (``sim://?mode=toy``), ``labcli
export`` writes its table and ``labcli inspect`` describes the run, each through the
interfaces of :mod:`labcli.core.paper` only.  Its own options (``compliance`` of its rig,
``--through-origin`` of its fit) are declared as data and reach ``labcli fit``, ``labcli sim``
and ``sim://`` with no line of the core or the commands naming them.
"""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from support import toy
from support.procs import finish

from labcli.core import registry
from labcli.core.protocol import load_protocol
from labcli.core.store import RunFile

PORT = f"sim://?mode={toy.MODE}&seed=3&clock=virtual"


@pytest.fixture
def acquired(toy_paper, tmp_path, invoke):
    run = tmp_path / "toy.h5"
    result = invoke("acquire", run, "--protocol", toy_paper, "--port", PORT, "--unattended")
    assert result.exit_code == 0, result.output
    return run, result


def test_the_registry_knows_the_toy_only_while_it_is_registered(toy_paper):
    assert registry.for_run_kind("toy").name == "toy"
    assert "toy" in registry.sim_modes() and "toy" in registry.protocol_kinds()
    registry.unregister("toy")
    assert "toy" not in registry.sim_modes()
    with pytest.raises(Exception, match="kind 'toy'"):
        registry.for_run_kind("toy")
    registry.register(toy.ToyPaper())  # the fixture's clean-up removes it again


def test_its_protocol_is_checked_by_the_core_loader_with_its_own_sections(toy_paper, tmp_path):
    p = load_protocol(toy_paper)
    assert p.kind == "toy" and p.channels == ("P", "ANG") and p.settings == {"masses_g": [200.0, 500.0]}
    assert p.calibration.units == ("MPa", "rad")
    bad = tmp_path / "bad.toml"
    bad.write_text(toy.PROTOCOL_TEXT.replace("masses_g = [200.0, 500.0]", "masses_g = [200.0]"), encoding="utf-8")
    with pytest.raises(Exception) as e:
        load_protocol(bad)
    assert str(e.value) == (
        f"{bad}: key 'load.masses_g' must be a list of two numbers [low, high] in g "
        "(the two trials' masses), not the list [200.0]."
    )


def test_acquire_records_two_trials_on_its_own_simulated_rig(acquired):
    run, result = acquired
    assert f"Session complete: 2 trials stored in {run}" in result.output
    with RunFile.open(run) as rf:
        assert rf.kind == "toy" and rf.channels == ("P", "ANG") and rf.records.ids() == [1, 2]
        for trial, mass in ((1, 0.2), (2, 0.5)):
            rec = rf.records.read(trial)
            # The rig's physics, read back through its ADC: 0.05 MPa and 10 deg per kg.
            assert rec["mass_kg"] == mass
            assert rec["P_MPa"] == pytest.approx(toy.P_REST_MPA + toy.P_PER_KG * mass, abs=2e-4)
            assert rec["theta_rad"] == pytest.approx(toy.ANGLE_PER_KG_RAD * mass, abs=math.radians(0.02))
            assert set(rec["raw"]) == {"baseline", "load"} and rec["raw"]["load"].counts.shape[1] == 2
            assert rec["settle"]["load"]["settled"] is True


def test_export_writes_its_table_and_import_reads_it_back(acquired, invoke, toy_paper, tmp_path):
    run, _ = acquired
    csv = tmp_path / "toy.csv"
    result = invoke("export", run, "-o", csv)
    assert result.exit_code == 0 and result.output == f"Wrote 2 trials from {run} to {csv}.\n"
    table = pd.read_csv(csv)
    assert list(table.columns) == ["trial", "mass_g", "P_MPa", "theta_deg"]
    assert table["mass_g"].tolist() == [200.0, 500.0]
    np.testing.assert_allclose(table["theta_deg"], [2.0, 5.0], atol=0.02)
    again = tmp_path / "again.h5"
    result = invoke("import", csv, "-o", again, "--protocol", toy_paper)
    assert result.exit_code == 0 and result.output == f"Imported 2 trials from {csv} into {again}.\n"
    csv2 = tmp_path / "again.csv"
    assert invoke("export", again, "-o", csv2).exit_code == 0
    assert csv2.read_bytes() == csv.read_bytes()


def test_inspect_describes_the_run(acquired, invoke):
    run, _ = acquired
    result = invoke("inspect", run)
    assert result.exit_code == 0
    lines = result.output.splitlines()
    assert lines[1] == "  kind        toy, protocol toy"
    assert lines[2].startswith("  rig         toy-rig-sim firmware 1.0 on sim://?mode=toy")
    assert "  trials      2 complete, 0 incomplete" in lines
    assert any(line.startswith("  settling    median ") and "over 2 trials" in line for line in lines)
    summary = invoke("inspect", run, "--json")
    assert '"kind": "toy"' in summary.output and '"complete": 2' in summary.output


def test_a_real_port_or_an_unknown_mode_is_refused_in_its_words(toy_paper, tmp_path, invoke):
    result = invoke("acquire", tmp_path / "x.h5", "--protocol", toy_paper, "--port", "sim://?mode=toys", "--unattended")
    assert result.exit_code == 1
    assert "option 'mode' in sim:// URL must be one of mckibben, rpam, toy, got 'toys'" in result.output


def test_a_paper_declaring_no_captures_refuses_more_than_one_capture_a_load(toy_paper, tmp_path, invoke):
    """The toy paper lists no ``capture_kinds``: its session takes each load once, so ``--captures 3`` and a
    protocol's ``captures_per_load = 3`` are refused before the rig is woken, not silently ignored."""
    run = tmp_path / "x.h5"
    result = invoke("acquire", run, "--protocol", toy_paper, "--port", PORT, "--unattended", "--captures", "3")
    assert result.exit_code == 1 and not run.exists()
    assert result.output == (
        "Error: --captures 3 asks for each load 3 times, but paper toy takes each load of a toy run once; leave it out.\n"
    )
    three = tmp_path / "three.toml"
    three.write_text(toy.PROTOCOL_TEXT.replace("[acquisition]\n", "[acquisition]\ncaptures_per_load = 3\n"))
    result = invoke("acquire", run, "--protocol", three, "--port", PORT, "--unattended")
    assert result.exit_code == 1 and not run.exists()
    assert result.output == (
        "Error: Protocol toy gives acquisition.captures_per_load = 3, but paper toy takes each load of a toy run "
        "once: set the key to 1 or leave it out.\n"
    )
    # One capture a load is what the paper takes: the run is recorded with the protocol as written.
    result = invoke("acquire", run, "--protocol", toy_paper, "--port", PORT, "--unattended", "--captures", "1")
    assert result.exit_code == 0, result.output
    with RunFile.open(run) as f:
        assert f.records.ids() == [1, 2] and f.protocol_text == toy.PROTOCOL_TEXT


def test_a_record_type_must_give_its_four_hooks():
    from labcli.core.store.record_type import BaseRecordType

    class Half(BaseRecordType):
        def check(self, record, label, run):
            return record

        def read(self, row):
            return dict(row)

    with pytest.raises(TypeError, match="abstract methods from_row, table"):
        Half()


# --------------------------------------------------------------------------- options declared as data


def acquire_toy(invoke, protocol, run, *extra_url: str):
    url = "&".join([PORT, *extra_url])
    result = invoke("acquire", run, "--protocol", protocol, "--port", url, "--unattended")
    assert result.exit_code == 0, result.output
    return run


def fitted(invoke, *args) -> dict:
    result = invoke("fit", *args, "--json")
    assert result.exit_code == 0, (result.output, result.exception)
    return json.loads(result.output)


def test_its_rig_option_changes_the_physics_and_its_fit_option_the_fit(toy_paper, tmp_path, invoke):
    # compliance= is the toy rig's own sim:// option; --through-origin the toy fit's own option.
    run = acquire_toy(invoke, toy_paper, tmp_path / "stiff.h5", "compliance=20")
    free = fitted(invoke, run)
    assert free["slope_deg_per_kg"] == pytest.approx(20.0, abs=0.1)
    assert abs(free["offset_deg"]) < 0.05 and free["offset_deg"] != 0.0
    through = fitted(invoke, run, "--through-origin")
    assert through["offset_deg"] == 0.0 and through["slope_deg_per_kg"] == pytest.approx(20.0, abs=0.1)
    default = acquire_toy(invoke, toy_paper, tmp_path / "default.h5")
    slope = fitted(invoke, default, "--through-origin")["slope_deg_per_kg"]
    assert slope == pytest.approx(math.degrees(toy.ANGLE_PER_KG_RAD), abs=0.1)


def test_options_of_other_papers_are_refused_in_the_core_sentence(toy_paper, tmp_path, invoke):
    run = acquire_toy(invoke, toy_paper, tmp_path / "toy.h5")
    result = invoke("fit", run, "--form", "paper")
    assert result.exit_code == 1
    assert result.output == f"Error: --form is an option of takuma2014 runs; {run} is a run of kind toy (toy).\n"
    csv = tmp_path / "trials.csv"
    csv.write_text("trial,set\n", encoding="utf-8")
    result = invoke("fit", csv, "--through-origin")
    assert result.exit_code == 1
    assert (
        result.output == f"Error: --through-origin is an option of toy runs; labcli fit reads {csv} with takuma2014.\n"
    )
    # A command the toy offers no analysis for does not take its options at all.
    assert "No such option '--through-origin'" in invoke("validate", csv, "--through-origin").output


def test_help_shows_its_options_under_its_name_only_while_registered(toy_paper, invoke):
    shown = invoke("fit", "--help").output
    assert "Options of toy (toy):" in shown
    assert "--through-origin" in shown.split("Options of toy (toy):")[1]
    assert "Options of the toy rig (--mode toy):" in invoke("sim", "--help").output
    assert "[units: deg/kg; default: 10]" in " ".join(invoke("sim", "--help").output.split())
    registry.unregister("toy")
    try:
        assert "--through-origin" not in invoke("fit", "--help").output
        assert "No such option '--through-origin'" in invoke("fit", "x.csv", "--through-origin").output
    finally:
        registry.register(toy.ToyPaper())


@pytest.mark.parametrize(
    "url,message",
    [
        ("sim://?mode=toy&compliance=-1", "option 'compliance' in sim:// URL must be a number > 0, got '-1'"),
        ("sim://?compliance=20", "option 'compliance' in sim:// URL applies to mode=toy only"),
        ("sim://?compliance=20&mode=toy&ideal=1", "option 'ideal' in sim:// URL applies to mode=mckibben only"),
    ],
)
def test_its_rig_option_is_read_from_the_url_with_its_declaration(toy_paper, url, message):
    import serial

    from labcli.core.sim import register
    from labcli.core.sim.url import accepted_form

    register()
    with pytest.raises(ValueError) as e:
        serial.serial_for_url(url)
    assert str(e.value) == f"{message}; expected {accepted_form()}"
    assert "[&compliance=X]" in accepted_form()


def test_labcli_sim_refuses_another_rigs_option_in_the_core_sentence(toy_paper, invoke):
    result = invoke("sim", "--pty", "--mode", "toy", "--ideal")
    assert result.exit_code == 1
    assert result.output == "Error: --ideal is an option of the mckibben rig; --mode toy serves the toy rig.\n"
    result = invoke("sim", "--pty", "--compliance", "20")
    assert (
        result.output == "Error: --compliance is an option of the toy rig; --mode mckibben serves the mckibben rig.\n"
    )


@pytest.mark.skipif(not hasattr(os, "openpty"), reason="needs pseudo-terminals")
def test_labcli_sim_serves_the_toy_rig_with_its_option_and_console(tmp_path):
    # The toy is registered in a process of its own (support.toy_main); the port and the console
    # are the real ones: a pty read with pyserial, the operator's lines on standard input.
    import serial

    from labcli.core.wire import Frame, parse_line

    tests = Path(__file__).resolve().parents[1]
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(tests), os.environ.get("PYTHONPATH", "")]))
    proc = subprocess.Popen(
        [sys.executable, "-m", "support.toy_main", "sim", "--pty", "--mode", "toy", "--compliance", "30"],
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        bufsize=1,
        env=env,
    )

    def say(line: str) -> str:
        proc.stdin.write(line + "\n")
        proc.stdin.flush()
        return proc.stdout.readline().rstrip("\n")

    def mean_angle_deg(port: serial.Serial) -> float:
        port.reset_input_buffer()
        data, end = b"", time.monotonic() + 1.0
        while time.monotonic() < end:
            data += port.read(port.in_waiting or 1)
        frames = [f for f in (parse_line(x) for x in data.split(b"\n")) if isinstance(f, Frame)]
        assert len(frames) > 20
        return float(np.mean([(f.values[1] - toy.A_ZERO) * 0.1 for f in frames[1:]]))

    def reply(port: serial.Serial) -> bytes:
        """The next line that is not a firmware log line (the boot banner comes first)."""
        while (line := port.readline()).startswith(b"#"):
            pass
        return line

    try:
        path = proc.stdout.readline().split()[3]
        with serial.Serial(path, timeout=2.0) as port:
            port.write(b"ID?\n")
            assert reply(port) == b"ID,toy-rig-sim,1.0,P,ANG\n"
            port.write(b"START\n")
            assert reply(port) == b"OK START\n"
            rest = mean_angle_deg(port)
            assert say("hang 500").startswith("ok hang 500 g")
            assert mean_angle_deg(port) - rest == pytest.approx(15.0, abs=0.1)  # 30 deg/kg x 0.5 kg
            assert say("hang heavy") == "error: mass must be a number, got 'heavy'; usage: hang GRAMS"
            assert say("help") == "commands: hang GRAMS, wait SECONDS, help, quit"
            port.write(b"STOP\n")
        assert say("quit") == "ok quit"
        out, err = finish(proc)
        assert proc.returncode == 0, err
    finally:
        if proc.poll() is None:
            proc.kill()


def test_sense_takes_its_models_own_option_and_refuses_its_one_chamber(toy_paper, tmp_path, invoke):
    """A toy model file reaches ``labcli sense`` through the registry (its ``model_schemas`` and
    ``sensing_model``), and the toy's declared ``--weight-scale`` reaches the model.  The toy has
    one pressure channel, so the estimator refuses to stream it: its detector removes the
    chambers' common mode (the leak, the room), which leaves one chamber nothing to see a load in."""
    from labcli.core.options import Typed
    from labcli.sensing import load_model

    model = toy.write_model(tmp_path, toy_paper)
    r = invoke("sense", "--help")
    assert "Options of toy models:" in r.output and "--weight-scale" in r.output
    r = invoke("sense", "--port", PORT, "--model", model, "--seconds", "4", "--jsonl", "--weight-scale", "2")
    assert r.exit_code == 1
    assert r.output == (
        "Error: A sensing model needs at least two pressure channels (an antagonistic pair), got 1: "
        "with one, the leak cannot be told from a load.\n"
    )
    one_kg = np.array([[toy.P_REST_MPA + toy.P_PER_KG]])
    for scale in (1.0, 2.0):
        m = load_model(model, Typed({"weight_scale": scale}, {}))
        w = m.predict(np.array([[toy.P_REST_MPA]]), one_kg, np.zeros((1, 1))).values
        assert w[0, 0] == pytest.approx(scale * toy.G)


def test_sense_refuses_an_option_the_models_paper_does_not_declare(toy_paper, tmp_path, invoke):
    toy_model = toy.write_model(tmp_path, toy_paper)
    mck_model = Path(__file__).resolve().parents[2] / "sample_runs" / "force.model.json"
    r = invoke("sense", "--port", PORT, "--model", toy_model, "--range-margin", "0.2")
    assert r.exit_code == 1
    assert r.output == (
        f"Error: --range-margin is an option of takuma2014 models; the model file {toy_model} is a model of toy.\n"
    )
    r = invoke("sense", "--port", "sim://", "--model", mck_model, "--weight-scale", "2")
    assert r.exit_code == 1
    assert r.output == (
        f"Error: --weight-scale is an option of toy models; the model file {mck_model} is a model of takuma2014.\n"
    )
