"""``labcli sense``: live estimates over the real serial code path (``sim://`` with a scripted session),
against the script's known loads; its outputs (JSON lines, TCP, the live view); and its refusals.

The scripted session (docs/sensing-example.toml) hangs 500 g at -45 deg from 20 s to 35 s of the
rig's clock: the tip force is m g (cos -45 deg, sin -45 deg) = (3.467, -3.467) N.  The straight arm
cannot sense a force along it (Fy is flagged unobservable), so Fx is the force checked.
"""

from __future__ import annotations

import json
import math
import re
import socket
import subprocess
import sys
import time
from pathlib import Path

import pytest
from click.testing import CliRunner

from labcli.cli import cli

ROOT = Path(__file__).resolve().parents[2]
MODEL = ROOT / "sample_runs" / "force.model.json"  # the demo's model: the simulated rig of seed 1
SCRIPT = ROOT / "docs" / "sensing-example.toml"
PORT = f"sim://?seed=1&clock=virtual&script={SCRIPT}"
G = 9.80665
FX_TRUE = 0.5 * G * math.cos(math.radians(-45.0))
KEYS = ("theta1_deg", "theta2_deg", "Fx_N", "Fy_N")


def sense(*args: str):
    return CliRunner().invoke(cli, ["sense", *args], catch_exceptions=False)


def lines_of(text: str) -> list[dict]:
    return [json.loads(line) for line in text.splitlines() if line.startswith("{")]


@pytest.fixture(scope="module")
def stream():
    """The JSON lines of 40 s of the scripted session, every estimate."""
    result = sense("--port", PORT, "--model", str(MODEL), "--seconds", "40", "--jsonl")
    assert result.exit_code == 0, result.output
    return result, lines_of(result.stdout)


def test_jsonl_finds_the_scripted_load_and_settles_on_its_force(stream):
    result, lines = stream
    events = [e for e in lines if "event" in e]
    assert [e["event"] for e in events] == ["load", "settled", "release"]
    assert events[0]["t_device_s"] == pytest.approx(20.0, abs=0.2)
    assert events[2]["t_device_s"] == pytest.approx(35.0, abs=0.3)
    assert events[0]["t_detected_s"] - 20.0 < 0.5  # the detector's latency
    settled = [e for e in lines if "state" in e and e["state"] == "loaded"]
    assert len(settled) > 50  # 26-35 s at ten a second
    for e in settled:
        assert abs(e["Fx_N"] - FX_TRUE) < 2.5 * e["Fx_N_se"], e
        assert "unobservable:Fy" in e["flags"]
    idle = [e for e in lines if e.get("state") == "idle"]
    assert all(abs(e["Fx_N"]) < 2.5 * e["Fx_N_se"] for e in idle)  # no load: no force
    # The summary goes to stderr, so stdout stays pure JSON lines.
    assert result.stderr.startswith("stopped after 40.")
    assert "1 load, 1 settled, 1 release" in result.stderr


AIR_NOTICE = "flagged bad-input: the pressures read as no air. Supply the chambers and close their valves"


def test_a_rig_without_air_is_told_once_and_a_supplied_one_not(stream):
    """The simulated rig starts vented: the flags alone would say bad-input forever."""
    result = sense("--port", "sim://?seed=1&clock=virtual", "--model", str(MODEL), "--seconds", "8", "--jsonl")
    assert result.exit_code == 0, result.output
    assert all("bad-input" in e["flags"] for e in lines_of(result.stdout))
    said = [line for line in result.stderr.splitlines() if AIR_NOTICE in line]
    assert len(said) == 1, result.stderr
    assert said[0].startswith("The first 31 estimates (3.0 s of the rig's clock) are all flagged bad-input")
    assert AIR_NOTICE not in stream[0].stderr  # the script supplies the chambers at 0 s


def test_each_line_carries_the_fields_a_controller_reads(stream):
    _, lines = stream
    est = [e for e in lines if "state" in e]
    for e in est:
        assert set(e) >= {"seq", "t_device_s", "t_host_s", "state", "flags", *KEYS, *(k + "_se" for k in KEYS)}
        assert isinstance(e["flags"], list)
    t = [e["t_device_s"] for e in est]
    assert all(b - a == pytest.approx(0.1, abs=1e-6) for a, b in zip(t, t[1:], strict=False))  # ten a second
    assert [e["seq"] for e in est] == sorted(e["seq"] for e in est)
    assert abs(est[-1]["t_host_s"] - time.time()) < 600


def test_every_thins_the_estimates_but_keeps_every_event(tmp_path, stream):
    _, full = stream
    out = tmp_path / "thin.jsonl"
    result = sense("--port", PORT, "--model", str(MODEL), "--seconds", "40", "--jsonl", str(out), "--every", "10")
    assert result.exit_code == 0, result.output
    thin = lines_of(out.read_text())
    strip = lambda e: {k: v for k, v in e.items() if k != "t_host_s"}  # noqa: E731
    full_est = [strip(e) for e in full if "state" in e]
    assert [strip(e) for e in thin if "state" in e] == full_est[::10]  # the same estimates, every tenth
    assert [strip(e) for e in thin if "event" in e] == [strip(e) for e in full if "event" in e]
    # A file output leaves stdout to the live view, which ends with the summary.
    assert "state releasing" in result.stdout and "Fx" in result.stdout
    assert re.search(
        r"1 load, 1 settled, 1 release; from a frame's bytes at the host to its estimate's line written: "
        r"median [0-9.]+ ms, p99 [0-9.]+ ms\.\n$",
        result.stdout,
    ), result.stdout[-300:]


def test_the_live_view_shows_estimates_with_units_intervals_state_and_events():
    result = sense("--port", PORT, "--model", str(MODEL), "--seconds", "30")
    assert result.exit_code == 0, result.output
    out = result.stdout
    assert "state loaded" in out
    for q, unit in (("theta1", "deg"), ("theta2", "deg"), ("Fx", "N"), ("Fy", "N")):
        row = next(line for line in out.splitlines() if line.split()[:1] == [q])
        assert row.count(unit) == 2 and "±" in row, row
    fx_row = next(line for line in out.splitlines() if line.split()[:1] == ["Fx"])
    assert abs(float(fx_row.split()[1]) - FX_TRUE) < 1.0
    assert "unobservable:Fy" in out
    assert sum(1 for line in out.splitlines() if "kPa" in line) == 4  # a rolling trace per pressure
    assert "events: load at 20.0 s · settled at" in out
    assert re.search(
        r"stopped after 30\.\d s of the rig's clock: \d+ frames, 30\d estimates, 1 load, 1 settled\.\n$", out
    )


def test_pushes_are_classified_online_from_a_push_plan(tmp_path):
    plan = tmp_path / "plan.csv"
    plan.write_text("push,object,R_mm,d_mm,phi_deg,category\n1,pet-1,33,10,0,soft\n2,can-al-1,33,15,15,medium\n")
    script = tmp_path / "pushes.toml"
    script.write_text(
        "[air]\nsupply_s = 0.0\nclose_s = 6.0\n\n"
        '[[push]]\nat_s = 30.0\nhold_s = 15.0\nobject = "pet-1"\nradius_mm = 33.0\ndistance_mm = 10.0\n'
        "phi_deg = 0.0\nstiffness_N_per_m = 420.0\n\n"
        '[[push]]\nat_s = 65.0\nhold_s = 15.0\nobject = "can-al-1"\nradius_mm = 33.0\ndistance_mm = 15.0\n'
        "phi_deg = 15.0\nstiffness_N_per_m = 2000.0\n"
    )
    # The kind rig: on the literature's (seed 1) can-al-1 comes out soft.
    result = sense(
        "--port", f"sim://?seed=1&clock=virtual&realism=kind&script={script}", "--model", str(MODEL),
        "--protocol", "takuma2014-stiffness", "--classify", str(plan), "--seconds", "85", "--jsonl", "--every", "50",
    )  # fmt: skip
    assert result.exit_code == 0, result.output
    pushes = [e for e in lines_of(result.stdout) if e.get("event") == "push"]
    assert [p["object"] for p in pushes] == ["pet-1", "can-al-1"]
    assert [p["category"] for p in pushes] == ["soft", "medium"]
    assert pushes[0]["k_N_per_m"] == pytest.approx(420.0, rel=0.35)
    assert pushes[1]["k_N_per_m"] == pytest.approx(2000.0, rel=0.35)
    assert pushes[0]["t_device_s"] < 45.0 and pushes[1]["t_device_s"] < 80.0  # while each object is pushed


# ------------------------------------------------------------------ refusals: one sentence each


def test_a_model_file_that_does_not_exist():
    result = sense("--port", PORT, "--model", "nope.json")
    assert result.exit_code == 1
    assert result.output == "Error: The model file nope.json does not exist; write one with `labcli fit`.\n"


def test_a_model_file_of_another_paper(tmp_path):
    other = tmp_path / "stretch.model.json"
    other.write_text((ROOT / "sample_runs" / "stretch.model.json").read_text())
    result = sense("--port", PORT, "--model", str(other))
    assert result.exit_code == 1
    assert result.output == (
        f"Error: The model file {other} is not a model any installed paper can estimate with; "
        "pass the .json file `labcli fit` wrote.\n"
    )


def test_a_protocol_of_another_rig():
    result = sense("--port", PORT, "--model", str(MODEL), "--protocol", "rpam2015")
    assert result.exit_code == 1
    assert result.output == (
        "Error: The model was fitted on the rig of protocol takuma2014, and rpam2015 describes another rig "
        "(its calibration or geometry differ); fit a model on this rig, or use a protocol of the model's rig.\n"
    )


def test_a_rig_whose_channels_differ_from_the_models():
    result = sense("--port", "sim://?mode=rpam&clock=virtual", "--model", str(MODEL), "--seconds", "1")
    assert result.exit_code == 1
    assert result.output.splitlines()[-1] == (
        "Error: The rig sends the channels P_A,P_B,POT,LEN but the model reads P_L1,P_R1,P_L2,P_R2,POT1,POT2 too; "
        "connect the rig the model was fitted on, or fit a model for this one."
    )


def test_classify_under_a_protocol_without_stiffness_bands(tmp_path):
    plan = tmp_path / "plan.csv"
    plan.write_text("push,object,R_mm,d_mm\n1,pet-1,33,10\n")
    result = sense("--port", PORT, "--model", str(MODEL), "--classify", str(plan))
    assert result.exit_code == 1
    assert result.output == (
        "Error: The protocol takuma2014 has no [stiffness_bands_N_per_m] table, which online pushes need to name "
        "a category; use a push protocol such as takuma2014-stiffness.\n"
    )


def test_a_tcp_port_in_use():
    holder = socket.socket()
    holder.bind(("127.0.0.1", 0))
    holder.listen(1)
    port = holder.getsockname()[1]
    try:
        result = sense("--port", PORT, "--model", str(MODEL), "--publish", f"tcp://127.0.0.1:{port}")
    finally:
        holder.close()
    assert result.exit_code == 1
    assert result.output == (
        f"Error: Cannot publish on tcp://127.0.0.1:{port}: the port is in use; choose another port or stop the "
        "program holding it.\n"
    )


@pytest.mark.parametrize("url", ["udp://127.0.0.1:5555", "tcp://127.0.0.1", "tcp://:80", "tcp://127.0.0.1:99999"])
def test_a_publish_address_of_the_wrong_form(url):
    result = sense("--port", PORT, "--model", str(MODEL), "--publish", url)
    assert result.exit_code == 1
    assert result.output == (
        f"Error: Cannot publish on {url!r}: expected tcp://HOST:PORT, e.g. tcp://127.0.0.1:5555 "
        "(tcp://0.0.0.0:5555 for every interface).\n"
    )


def test_a_stalled_rig_ends_with_one_sentence_and_the_summary_so_far(tmp_path):
    out = tmp_path / "out.jsonl"
    port = "sim://?seed=1&clock=wall&faults=stall:0.01@3"  # a 3 s silence within the first second or so
    result = sense("--port", port, "--model", str(MODEL), "--timeout", "0.5", "--jsonl", str(out))
    assert result.exit_code == 1
    assert result.stderr.splitlines()[-1] == (
        f"Error: No data from {port} for 0.5 s while streaming. Check the cable and that the rig is powered."
    )
    assert "stopped by an error after" in result.stderr
    assert all(json.loads(line) for line in out.read_text().splitlines())  # every line written is whole


# ------------------------------------------------------------------ a TCP subscriber


def test_a_tcp_client_receives_the_stream_as_the_file_has_it(tmp_path):
    """A real subscriber on the real process: the lines it reads are the file's, from when it joined."""
    out = tmp_path / "out.jsonl"
    proc = subprocess.Popen(
        [sys.executable, "-m", "labcli", "sense", "--port", "sim://?seed=1&clock=wall", "--model", str(MODEL),
         "--seconds", "4", "--publish", "tcp://127.0.0.1:0", "--jsonl", str(out)],
        stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
    )  # fmt: skip
    try:
        first = proc.stderr.readline()
        assert first.startswith("Publishing JSON lines on tcp://127.0.0.1:"), first
        port = int(first.strip().rstrip(".").rsplit(":", 1)[1])
        with socket.create_connection(("127.0.0.1", port), timeout=10) as client:
            got = client.makefile("r", encoding="utf-8").read()  # until the command closes the stream
        rest = proc.stderr.read()
    finally:
        proc.wait(timeout=60)
    assert proc.returncode == 0, rest
    assert rest.startswith("Client 127.0.0.1:") and " connected to tcp://127.0.0.1:" in rest
    received = got.splitlines()
    written = out.read_text().splitlines()
    assert len(received) >= 10
    assert received == written[-len(received) :]  # the same lines, byte for byte, to the end
