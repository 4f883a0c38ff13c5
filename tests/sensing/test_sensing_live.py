"""The live pieces on their own: the TCP publisher's clients, the stream loop's stops, the view's traces."""

from __future__ import annotations

import json
import socket
import time

import numpy as np
import pytest
from support.sensing import LinearModel

from labcli.core.device import Device
from labcli.core.protocol import load_protocol
from labcli.core.rolling import spark
from labcli.errors import ConfigError, DeviceDisconnected
from labcli.sensing import Estimator
from labcli.sensing.live import line_of, run
from labcli.sensing.publish import JsonLines, TcpPublisher, parse_tcp
from labcli.sensing.results import Estimate, Event


def read_lines(sock: socket.socket, n: int, timeout: float = 5.0) -> list[str]:
    sock.settimeout(timeout)
    buf = b""
    while buf.count(b"\n") < n:
        chunk = sock.recv(65536)
        if not chunk:
            break
        buf += chunk
    return buf.decode().splitlines()


def settle(pub: TcpPublisher, clients: int, timeout: float = 5.0) -> None:
    end = time.monotonic() + timeout
    while pub.clients != clients and time.monotonic() < end:
        pub.poll()
        time.sleep(0.01)
    assert pub.clients == clients


def test_every_client_gets_every_line_and_one_that_leaves_is_named_once():
    notes: list[str] = []
    pub = TcpPublisher("tcp://127.0.0.1:0", notice=notes.append)
    try:
        a = socket.create_connection(("127.0.0.1", pub.port))
        b = socket.create_connection(("127.0.0.1", pub.port))
        settle(pub, 2)
        for i in range(3):
            pub.publish(json.dumps({"seq": i}))
        assert read_lines(a, 3) == read_lines(b, 3) == ['{"seq": 0}', '{"seq": 1}', '{"seq": 2}']
        name = f"127.0.0.1:{b.getsockname()[1]}"
        b.close()
        settle(pub, 1)
        pub.publish('{"seq": 3}')
        assert read_lines(a, 1) == ['{"seq": 3}']
        assert notes.count(f"Client {name} disconnected; publishing to the others goes on.") == 1
        assert sum(n.endswith(f"connected to {pub.url}.") for n in notes) == 2
    finally:
        pub.close()
    assert a.recv(10) == b""  # closing the publisher ends the clients' stream
    a.close()


def test_a_client_that_stops_reading_is_dropped_not_waited_for():
    notes: list[str] = []
    pub = TcpPublisher("tcp://127.0.0.1:0", notice=notes.append, max_backlog=64 * 1024)
    try:
        c = socket.socket()
        c.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
        c.connect(("127.0.0.1", pub.port))
        settle(pub, 1)
        line = json.dumps({"pad": "x" * 1000})
        t0 = time.perf_counter()
        for _ in range(20000):  # 20 MB to a client that reads nothing
            pub.publish(line)
            if not pub.clients:
                break
        assert time.perf_counter() - t0 < 5.0  # never blocked on it
        assert pub.clients == 0
        assert notes[-1].endswith("fell more than 64 KB behind; publishing to the others goes on.")
        c.close()
    finally:
        pub.close()


def test_parse_tcp_and_a_port_in_use():
    assert parse_tcp("tcp://127.0.0.1:5555") == ("127.0.0.1", 5555)
    assert parse_tcp("tcp://[::1]:0") == ("::1", 0)
    first = TcpPublisher("tcp://127.0.0.1:0")
    try:
        with pytest.raises(ConfigError, match="the port is in use"):
            TcpPublisher(f"tcp://127.0.0.1:{first.port}")
    finally:
        first.close()


def test_json_lines_are_flushed_per_line(tmp_path):
    out = JsonLines.to(str(tmp_path / "a.jsonl"))
    out.publish('{"a": 1}')
    assert (tmp_path / "a.jsonl").read_text() == '{"a": 1}\n'  # before close: a kill loses no line written
    out.close()
    with pytest.raises(ConfigError, match="Cannot write the JSON lines to"):
        JsonLines.to(str(tmp_path / "no" / "such" / "dir.jsonl"))


def test_a_line_is_the_items_json_and_the_host_time():
    e = Estimate(7, 1.25, "idle", {"x": 0.01, "f": 2.0}, {"x": 0.001, "f": 0.1}, {"x": "rad", "f": "N"}, ("transient",))
    obj = json.loads(line_of(e))
    assert obj["seq"] == 7 and obj["x_deg"] == pytest.approx(0.572958, abs=1e-6) and obj["f_N_se"] == 0.1
    assert obj["flags"] == ["transient"] and abs(obj["t_host_s"] - time.time()) < 5
    ev = json.loads(line_of(Event("load", 1.0, 1.2, 9)))
    assert ev["event"] == "load" and ev["t_device_s"] == 1.0


def test_an_estimates_line_is_what_json_dumps_writes_of_its_fields_character_for_character():
    rng = np.random.default_rng(5)

    def pick() -> float:
        """A number as estimates hold them: any size, and the ones json and rounding treat specially."""
        return float(rng.choice(odd)) if rng.random() < 0.3 else float(rng.normal(0, 10.0 ** rng.integers(-8, 6)))

    odd = [0.0, -0.0, 1e-7, -4.9999995e-7, 123456.0000005, 1e21, 2.5e-300, np.nan, np.inf, -np.inf]
    units = {"theta1": "rad", "Fx": "N", "P": "MPa", "L": "m", "w": "au"}
    flags = [(), ("transient",), ("out-of-range", "unobservable:Fx", 'caf\u00e9 "q"')]
    for i in range(300):
        e = Estimate(
            int(rng.integers(0, 2**40)),
            pick(),
            ("idle", "loading", "caf\u00e9")[i % 3],
            {q: pick() for q in units},
            {q: pick() for q in units},
            units,
            flags[i % 3],
        )
        t_host = round(1.7e9 + rng.random() * 1e8, 6)
        expected = json.dumps({**e.as_json(), "t_host_s": t_host}, separators=(", ", ": "), allow_nan=False)
        assert e.json_line(t_host) == expected


class Sink:
    def __init__(self) -> None:
        self.lines: list[str] = []

    def publish(self, line: str) -> None:
        self.lines.append(line)

    def close(self) -> None:
        pass


def test_the_loop_stops_on_the_rigs_clock_and_publishes_every_nth_estimate():
    sink = Sink()
    with Device.open("sim://?seed=2&clock=virtual") as dev:
        est = Estimator(LinearModel(), calibration=load_protocol("takuma2014").calibration, channels=dev.info.channels)
        dev.set_rate(200)
        summary = run(dev, est, [sink], seconds=5.0, every=4)
    assert summary.stopped == "seconds"
    assert summary.frames == 1001  # 0 to 5 s of the rig's clock, both ends: no frame past it
    assert summary.device_s == pytest.approx(5.0)
    assert summary.estimates == 50 and summary.published == 13  # estimates 0, 4, ..., 48
    assert len(sink.lines) == 13 and len(summary.latency_s) == 13
    assert not dev.streaming


def test_latency_runs_from_the_frames_bytes_reaching_the_host_not_from_read_returning():
    """A read that parses slowly (a long burst): its parsing counts, as the controller waits for it."""
    sink = Sink()
    with Device.open("sim://?seed=2&clock=virtual") as dev:
        est = Estimator(LinearModel(), calibration=load_protocol("takuma2014").calibration, channels=dev.info.channels)
        dev.set_rate(200)
        real_read, stamps = dev.read, []

        def read_then_parse_slowly(timeout: float = 1.0):
            batch = real_read(timeout)
            stamps.append(dev.arrived)
            time.sleep(0.02)  # bytes in hand, frames not yet handed over
            return batch

        dev.read = read_then_parse_slowly
        summary = run(dev, est, [sink], seconds=2.0)
    assert all(isinstance(t, float) for t in stamps)
    assert len(summary.latency_s) == 20 and min(summary.latency_s) >= 0.02


def test_an_unplugged_rig_stops_the_loop_with_its_sentence_and_the_summary_so_far():
    sink = Sink()
    with Device.open("sim://?seed=2&clock=virtual") as dev:
        est = Estimator(LinearModel(), calibration=load_protocol("takuma2014").calibration, channels=dev.info.channels)
        seen = []

        def unplug_after_a_while(frames, items):
            seen.append(len(frames))
            if sum(seen) > 400:
                dev.serial.unplug()

        with pytest.raises(DeviceDisconnected) as exc:
            run(dev, est, [sink], seconds=60.0, on_batch=unplug_after_a_while)
    assert "sim://?seed=2&clock=virtual" in str(exc.value)
    assert exc.value.summary.stopped == "error" and exc.value.summary.frames > 400


def test_spark_scales_each_trace_to_its_own_range():
    assert spark([0, 1, 2, 3, 4, 5, 6, 7], 8) == "▁▂▃▄▅▆▇█"
    assert spark([5, 5, 5], 4) == " ▁▁▁"
    assert spark([], 3) == "   "
    assert len(spark(np.arange(1000.0), 30)) == 30


def test_the_live_view_plots_the_pressures_with_monitors_rolling_widget():
    """The view's pressure traces are the shared widget's (labcli/core/rolling.py): each channel's
    range over the window is that of its frames' means per tenth of a second of device time."""
    from rich.console import Console

    from labcli.core import rolling
    from labcli.sensing import view as view_module
    from labcli.sensing.inputs import DeviceClock
    from labcli.sensing.view import LiveView

    assert view_module.spark is rolling.spark  # no second copy of the widget
    frames = []
    with Device.open("sim://?seed=3&clock=virtual") as dev:
        est = Estimator(LinearModel(), calibration=load_protocol("takuma2014").calibration, channels=dev.info.channels)
        view = LiveView(est, "rig", window_s=5.0)

        def both(batch, items):
            frames.append(batch)
            view.take(batch, items)

        run(dev, est, [], seconds=3.0, on_batch=both)
    t = DeviceClock().seconds(np.concatenate([f.t_us for f in frames]))
    kpa = est.inputs.si(np.concatenate([f.values for f in frames]))[:, : est.inputs.n_pressures] * 1e3
    bins = np.floor(t / 0.1).astype(int)
    console = Console(width=200, record=True)
    console.print(view.render(plain=True))
    text = console.export_text()
    assert "last 5 s" in text
    for j, name in enumerate(view.names):
        means = np.array([kpa[bins == b, j].mean() for b in np.unique(bins)])
        line = next(line for line in text.splitlines() if line.strip().startswith(name))
        assert f"{means.min():.2f}..{means.max():.2f} kPa" in line, (line, means.min(), means.max())
