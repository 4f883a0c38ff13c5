"""The optional outputs (labcli/sensing/outlets.py): ZeroMQ PUB and a Lab Streaming Layer outlet.

Each is tested when its package is installed (``pytest.importorskip``); without it, asking for
it is one sentence naming the extra to install, and neither is imported unless asked for.
"""

from __future__ import annotations

import json
import math
import socket
import subprocess
import sys
import time

import pytest
from click.testing import CliRunner

from labcli.cli import cli
from labcli.errors import ConfigError
from labcli.sensing.outlets import LslOutlet, ZmqPublisher

LINE = json.dumps({"seq": 19, "t_device_s": 0.1, "state": "idle", "theta1_deg": 1.5, "theta1_deg_se": 0.2,
                   "Fx_N": -0.25, "Fx_N_se": 0.1, "Fy_N": None, "Fy_N_se": None, "flags": []})  # fmt: skip
EVENT = json.dumps({"event": "load", "t_device_s": 3.2, "t_detected_s": 3.4, "seq": 700})


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def test_neither_package_is_imported_unless_asked_for():
    code = (
        "import sys, labcli.sensing.sense, labcli.sensing.outlets; print(sorted({'zmq', 'pylsl'} & set(sys.modules)))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "[]"


def test_a_missing_package_is_one_sentence_naming_its_extra(monkeypatch):
    monkeypatch.setitem(sys.modules, "zmq", None)  # as if not installed: importing it raises ImportError
    monkeypatch.setitem(sys.modules, "pylsl", None)
    with pytest.raises(ConfigError) as exc:
        ZmqPublisher("zmq+tcp://127.0.0.1:5556")
    assert str(exc.value) == (
        "Publishing on ZeroMQ (--publish zmq+tcp://...) needs the optional package pyzmq, which is not installed; "
        "install it with pip install 'labcli[zmq]'."
    )
    with pytest.raises(ConfigError) as exc:
        LslOutlet("arm", ["theta1_deg"], 10.0)
    assert str(exc.value) == (
        "An LSL outlet (--lsl) needs the optional package pylsl, which is not installed; "
        "install it with pip install 'labcli[lsl]'."
    )
    model = "sample_runs/force.model.json"
    result = CliRunner().invoke(cli, ["sense", "--port", "sim://?clock=virtual", "--model", model, "--lsl", "arm"])
    assert result.exit_code == 1
    assert result.output.splitlines()[-1] == f"Error: {exc.value}"


@pytest.mark.parametrize("url", ["zmq+tcp://127.0.0.1", "zmq+tcp://:5556", "zmq+ipc:///tmp/x", "zmq+tcp://h:0"])
def test_a_zmq_address_of_the_wrong_form(url):
    with pytest.raises(ConfigError) as exc:
        ZmqPublisher(url)
    assert str(exc.value) == (
        f"Cannot publish on {url!r}: expected zmq+tcp://HOST:PORT, e.g. zmq+tcp://127.0.0.1:5556 "
        "(zmq+tcp://*:5556 for every interface)."
    )


def test_a_zmq_subscriber_receives_each_line_as_one_message():
    zmq = pytest.importorskip("zmq")
    url = f"zmq+tcp://127.0.0.1:{free_port()}"
    pub = ZmqPublisher(url)
    sub = zmq.Context.instance().socket(zmq.SUB)
    sub.setsockopt(zmq.SUBSCRIBE, b"")
    sub.setsockopt(zmq.RCVTIMEO, 100)
    sub.connect(url.removeprefix("zmq+"))
    try:
        got = None
        deadline = time.monotonic() + 10
        while got is None and time.monotonic() < deadline:  # a subscriber joins a moment after it connects
            pub.publish(LINE)
            try:
                got = sub.recv()
            except zmq.Again:
                pass
        assert got is not None and json.loads(got) == json.loads(LINE)
        pub.publish(EVENT)
        rest: list[str] = []
        while EVENT not in rest and time.monotonic() < deadline + 10:  # lines still in flight, then the event
            try:
                rest.append(sub.recv().decode())
            except zmq.Again:
                pass
        assert rest[-1] == EVENT and set(rest) <= {LINE, EVENT}
    finally:
        sub.close(0)
        pub.close()


def test_a_zmq_port_in_use():
    pytest.importorskip("zmq")
    port = free_port()
    first = ZmqPublisher(f"zmq+tcp://127.0.0.1:{port}")
    try:
        with pytest.raises(ConfigError) as exc:
            ZmqPublisher(f"zmq+tcp://127.0.0.1:{port}")
    finally:
        first.close()
    assert str(exc.value) == (
        f"Cannot publish on zmq+tcp://127.0.0.1:{port}: the port is in use; choose another port or stop the "
        "program holding it."
    )


def test_an_lsl_inlet_reads_the_estimates_and_the_events():
    pylsl = pytest.importorskip("pylsl")
    name = f"labcli-test-{time.time_ns()}"
    outlet = LslOutlet(name, ["theta1_deg", "Fx_N", "Fy_N"], 10.0)
    try:
        found = pylsl.resolve_byprop("name", name, timeout=10)
        events = pylsl.resolve_byprop("name", f"{name}-events", timeout=10)
        if not found or not events:
            pytest.skip("LSL cannot resolve streams on this machine (no multicast)")
        inlet, markers = pylsl.StreamInlet(found[0]), pylsl.StreamInlet(events[0])
        inlet.open_stream(timeout=10)
        markers.open_stream(timeout=10)
        info = inlet.info(timeout=10)
        ch = info.desc().child("channels").child("channel")
        labels = []
        while not ch.empty():
            labels.append((ch.child_value("label"), ch.child_value("unit")))
            ch = ch.next_sibling()
        assert labels == [("theta1_deg", "deg"), ("theta1_deg_se", "deg"), ("Fx_N", "N"), ("Fx_N_se", "N"),
                          ("Fy_N", "N"), ("Fy_N_se", "N")]  # fmt: skip
        sample = None
        deadline = time.monotonic() + 10
        while sample is None and time.monotonic() < deadline:
            outlet.publish(LINE)
            outlet.publish(EVENT)
            sample, _ = inlet.pull_sample(timeout=0.2)
        assert sample is not None
        assert sample[:4] == [1.5, 0.2, -0.25, 0.1] and all(math.isnan(v) for v in sample[4:])  # Fy: not reported
        marker, _ = markers.pull_sample(timeout=5)
        assert marker is not None and json.loads(marker[0]) == json.loads(EVENT)
    finally:
        outlet.close()


def test_sense_publishes_on_zeromq_the_lines_its_file_has():
    """The real command: a subscriber's messages are the JSON lines file's, from when it joined."""
    zmq = pytest.importorskip("zmq")
    import pathlib
    import tempfile

    root = pathlib.Path(__file__).resolve().parents[2]
    url = f"zmq+tcp://127.0.0.1:{free_port()}"
    sub = zmq.Context.instance().socket(zmq.SUB)
    sub.setsockopt(zmq.SUBSCRIBE, b"")
    sub.setsockopt(zmq.RCVTIMEO, 20000)
    sub.connect(url.removeprefix("zmq+"))  # before the command binds: ZeroMQ reconnects until it does
    with tempfile.TemporaryDirectory() as tmp:
        out = pathlib.Path(tmp) / "out.jsonl"
        proc = subprocess.Popen(
            [sys.executable, "-m", "labcli", "sense", "--port", "sim://?seed=1&clock=wall", "--model",
             str(root / "sample_runs" / "force.model.json"), "--seconds", "3", "--publish", url, "--jsonl", str(out)],
            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
        )  # fmt: skip
        got: list[str] = []
        try:
            while True:
                got.append(sub.recv().decode())
                sub.setsockopt(zmq.RCVTIMEO, 3000)  # once the stream runs, silence means it ended
        except zmq.Again:
            pass
        finally:
            sub.close(0)
            err = proc.communicate(timeout=60)[1]
        assert proc.returncode == 0, err
        assert f"Publishing JSON lines on {url}." in err
        written = out.read_text().splitlines()
    assert len(got) >= 10 and got == written[-len(got) :]
