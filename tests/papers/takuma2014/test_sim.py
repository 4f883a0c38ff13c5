"""The simulated rig: dynamics, sensors, firmware, the sim:// port and the pty server."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time

import numpy as np
import pytest
import serial
from click.testing import CliRunner

from labcli.core.sim import register
from labcli.core.sim.firmware import Firmware
from labcli.core.wire import Frame, parse_line
from labcli.papers.takuma2014.sim import physics as ph
from labcli.papers.takuma2014.sim.nonideal import NonIdeal
from labcli.papers.takuma2014.sim.rig import SimRig

register()


def CAL_P(c):
    return (np.asarray(c) * 5.0 / 4095 - 1.0) / 4.0  # reference calibration, MPa


def CAL_DEG(c):
    return (np.asarray(c) - 2048) * 340 / 4095


EXPECTED_FORM = (
    "sim://[?seed=N][&rate=HZ][&noise=X][&drift=X][&clock=virtual|wall][&tau=S][&ratefactor=X]"
    "[&mode=mckibben|rpam][&faults=KIND:RATE[@X],...][&fw=1.0|1.1][&firmware=ELF][&experiment=joint|stretch]"
    "[&nominal=0|1][&reading=derived|paper][&ideal=0|1][&friction=X][&leak=X][&thermal=X][&backlash=X][&links=X][&contact=X][&pulley=X]"
    "[&potscale=X][&potlin=X][&repeat=X][&supply=MPA[,MPA,MPA,MPA]][&design=paper|thin][&realism=literature|kind]"
    "[&valves=ok|open][&valve_c=X][&valve_b=X][&flow=orifice|lag][&script=FILE]"
)


def settled_rig(**kw) -> SimRig:
    """The ideal rig (the physics tests below hold the ideal model), pressurised and closed.

    The non-idealities have their own tests (tests/papers/takuma2014/test_nonideal.py).
    """
    kw.setdefault("nonideal", NonIdeal.ideal())
    rig = SimRig(**kw)
    rig.supply_air()
    rig.advance(10)
    rig.close_valves()
    rig.advance(10)
    return rig


def boyle_amount(rig: SimRig, state: dict) -> np.ndarray:
    p = rig.params
    L = ph.actuator_lengths(state["theta_rad"], p)
    return (state["pressures_MPa"] * 1e6 + ph.P_ATM) * (ph.mckibben_volume(L, p.b, p.n) + p.V_dead)


def frames_of(data: bytes) -> list[Frame]:
    return [f for f in (parse_line(x) for x in data.split(b"\n")) if isinstance(f, Frame)]


# ---------------------------------------------------------------- rig


def test_rig_starts_vented_and_supply_reaches_regulator_pressure():
    # The sensors without their repeatability, drift, gain and linearity errors: their counts exact.
    exact = NonIdeal(repeat=0.0, drift=0.0, potscale=0.0, potlin=0.0)
    rig = SimRig(seed=2, variation=False, noise=0, nonideal=exact)
    assert rig.true_state()["pressures_MPa"] == pytest.approx([0] * 4)
    _, counts = rig.samples(5, 100)
    assert np.all(counts[:, :4] == 819)  # 1.0 V at 0 MPa gauge
    rig.supply_air()
    rig.advance(15)
    st = rig.true_state()
    assert st["valves"] == "open"
    assert st["pressures_MPa"] == pytest.approx([0.3] * 4, abs=1e-6)
    assert st["theta_rad"] == pytest.approx([0, 0], abs=1e-9)
    _, counts = rig.samples(3, 100)
    assert CAL_P(counts[:, :4]) == pytest.approx(0.3, abs=0.5 * 5 / 4095 / 4)
    assert np.all(counts[:, 4:] == 2048)


def test_zero_load_gives_zero_deflection_and_baseline_pressures():
    rig = settled_rig(seed=4)
    base = rig.true_state()
    rig.hang_weight(0.0, 0.3)
    rig.advance(10)
    st = rig.true_state()
    assert st["theta_rad"] == pytest.approx(base["theta_rad"], abs=1e-12)
    assert st["pressures_MPa"] == pytest.approx(base["pressures_MPa"], abs=1e-12)


def test_boyle_invariant_holds_after_closing_through_loads_and_transients():
    rig = settled_rig(seed=5)
    n0 = boyle_amount(rig, rig.true_state())
    for action in (
        lambda: rig.hang_weight(0.8, np.radians(160)),
        rig.remove_weight,
        lambda: rig.push_object(0.03, 0.008, 0.2, 1500.0),
    ):
        action()
        for dt in (0.1, 0.4, 5.0):
            rig.advance(dt)
            assert boyle_amount(rig, rig.true_state()) == pytest.approx(n0, rel=1e-12)
    st = rig.true_state()
    assert np.linalg.norm(st["force_N"]) > 1.0


def test_unload_returns_to_the_baseline():
    rig = settled_rig(seed=6)
    base = rig.true_state()
    rig.hang_weight(1.0, 0.0)
    rig.advance(5)
    assert abs(rig.true_state()["theta_rad"][0] - base["theta_rad"][0]) > np.radians(1)
    rig.remove_weight()
    rig.advance(20)
    st = rig.true_state()
    assert st["theta_rad"] == pytest.approx(base["theta_rad"], abs=1e-9)
    assert st["pressures_MPa"] == pytest.approx(base["pressures_MPa"], abs=1e-9)


def test_first_order_lag_reaches_63_percent_at_tau():
    rig = settled_rig(seed=8, tau_s=0.8)
    th0 = rig.true_state()["theta_rad"]
    rig.hang_weight(0.4, np.radians(200))
    st = rig.true_state()
    tau, target = st["tau_s"], st["target_theta_rad"]
    assert 0.5 <= tau <= 1.2 and tau != 0.8  # seeded jitter around the nominal
    rig.advance(tau)
    frac = (rig.true_state()["theta_rad"] - th0) / (target - th0)
    assert frac == pytest.approx([1 - np.exp(-1)] * 2, abs=1e-12)
    rig.advance(9 * tau)
    frac = (rig.true_state()["theta_rad"] - th0) / (target - th0)
    assert frac == pytest.approx([1 - np.exp(-10)] * 2, abs=1e-12)


def test_pot_counts_track_angles_and_pressures_track_boyle_in_counts():
    rig = settled_rig(seed=9, noise=0)
    _, c0 = rig.samples(1, 200)
    rig.hang_weight(1.0, np.pi)
    rig.advance(10)
    _, c1 = rig.samples(1, 200)
    st = rig.true_state()
    dtheta_deg = CAL_DEG(c1[0, 4:]) - CAL_DEG(c0[0, 4:])
    base_theta = np.degrees(rig.true_state()["theta_rad"])
    assert dtheta_deg[0] > 1  # pulled to the left: counter-clockwise
    # Deflection read from the pots within one count of the truth.
    rig2 = settled_rig(seed=9, noise=0)
    d_true = base_theta - np.degrees(rig2.true_state()["theta_rad"])
    assert dtheta_deg == pytest.approx(d_true, abs=340 / 4095)
    assert CAL_P(c1[0, :4]) == pytest.approx(st["pressures_MPa"] + rig.sensor_offset_MPa, abs=5 / 4095 / 4)
    assert c1[0, 1] > c0[0, 1] and c1[0, 0] < c0[0, 0]  # R1 stretched: up; L1 shortened: down


def test_noise_statistics_and_quantisation():
    rig = settled_rig(seed=10, noise=1.0)
    _, counts = rig.samples(40000, 1000)
    assert counts.dtype == np.int64
    sd = counts.std(axis=0)
    # Gaussian noise plus rounding: sqrt(0.5^2 + 1/12) and sqrt(0.7^2 + 1/12), within 10 %.
    assert sd[:4] == pytest.approx([np.sqrt(0.25 + 1 / 12)] * 4, rel=0.1)
    assert sd[4:] == pytest.approx([np.sqrt(0.49 + 1 / 12)] * 2, rel=0.1)
    ideal = rig.ideal_counts(*rig._state_at(np.array([rig.time_s])), np.array([rig.time_s]))[0]
    assert counts.mean(axis=0) == pytest.approx(ideal, abs=0.03)
    quiet = settled_rig(seed=10, noise=0.0)
    _, c = quiet.samples(100, 1000)
    assert np.all(c == c[0]) and np.all(c[0] == np.rint(ideal))


def test_counts_clip_to_the_12_bit_range():
    rig = SimRig(seed=1, noise=3.0, variation=False)
    rig.supply_air(1.0)  # 5 V: the top of the ADC
    rig.advance(20)
    _, counts = rig.samples(2000, 1000)
    assert counts[:, :4].max() == 4095
    assert np.all((counts >= 0) & (counts <= 4095))
    assert (counts[:, :4] == 4095).mean() > 0.4


def test_samples_are_timed_and_vectorised():
    rig = SimRig(seed=0)
    t_us, counts = rig.samples(100_000, 2000)
    assert counts.shape == (100_000, 6)
    assert np.all(np.diff(t_us) == 500)
    assert t_us[0] == 500 and rig.time_s == pytest.approx(50.0)


def test_seeded_determinism():
    def run(seed):
        rig = settled_rig(seed=seed, drift=1.0)
        rig.hang_weight(0.3, 1.0)
        a = rig.samples(500, 200)[1]
        rig.push_object(0.04, 0.005, 0.0, 900.0)
        return np.vstack([a, rig.samples(500, 200)[1]])

    assert np.array_equal(run(21), run(21))
    assert not np.array_equal(run(21), run(22))


def test_drift_moves_readings_slowly_and_does_not_touch_the_air():
    # Sensor zero drift only; the chambers' leak is its own switch (tests/papers/takuma2014/test_nonideal.py).
    rig = settled_rig(seed=12, drift=1.0, noise=0)
    p0 = rig.true_state()["pressures_MPa"]
    rig.advance(600)
    assert rig.true_state()["pressures_MPa"] == pytest.approx(p0, abs=1e-12)
    still = settled_rig(seed=12, drift=0.0, noise=0)
    q0 = still.true_state()["pressures_MPa"]
    still.advance(600)
    assert still.true_state()["pressures_MPa"] == pytest.approx(q0, abs=1e-12)
    # Sensor zero drift: a few counts over minutes, starting from zero.
    t = np.array([0.0, 60.0, 1200.0])
    theta, pr = still._state_at(np.full(3, still.time_s))
    drifting = settled_rig(seed=12, drift=1.0, noise=0)
    off = drifting.ideal_counts(theta, pr, t) - still.ideal_counts(theta, pr, t)
    assert off[0] == pytest.approx(np.zeros(6), abs=1e-12)
    assert 0.2 < np.abs(off[2]).max() < 6.5


def test_unreachable_load_is_a_clear_error():
    rig = settled_rig(seed=1)
    with pytest.raises(ValueError, match="no static equilibrium with 800000 g hanging at 0 deg"):
        rig.hang_weight(800.0, 0.0)


# ---------------------------------------------------------------- firmware


def test_firmware_replies():
    fw = Firmware(SimRig(seed=0), 200)
    assert fw.receive(b"ID?\n") == b"ID,mckibben-2dof-sim,1.1,P_L1,P_R1,P_L2,P_R2,POT1,POT2\n"
    assert fw.receive(b"RATE 500\r\n") == b"OK RATE 500\n"
    assert fw.receive(b"RATE 0\n") == b"ERR RATE must be within 1..50000 Hz, got 0\n"
    # Up to the stream reader's measured limit (tests/benchmarks/bench_link.py), not beyond.
    assert fw.receive(b"RATE 50000\n") == b"OK RATE 50000\n"
    assert fw.receive(b"RATE 50001\n") == b"ERR RATE must be within 1..50000 Hz, got 50001\n"
    assert fw.rate_hz == 50000
    assert fw.receive(b"RATE fast\n") == b"ERR RATE needs a number of Hz, got 'fast'\n"
    assert fw.receive(b"HELLO\n") == b"ERR unknown command 'HELLO'\n"
    assert fw.receive(b"STA") == b""  # partial line waits for its newline
    assert fw.receive(b"RT\n").startswith(b"OK START\n#")
    assert fw.receive(b"STOP\n") == b"OK STOP\n"


def test_firmware_seq_and_time_wrap_at_2_32():
    rig = SimRig(seed=0)
    fw = Firmware(rig, 1000)
    fw.receive(b"START\n")
    fw.seq = (1 << 32) - 2
    rig.advance_to(((1 << 32) - 2500) / 1e6)
    fr = frames_of(fw.frames(5))
    assert [f.seq for f in fr] == [(1 << 32) - 2, (1 << 32) - 1, 0, 1, 2]
    t = [f.t_us for f in fr]
    assert t[0] > t[1] or t[1] > t[2]  # wrapped within these frames
    assert all((b - a) % (1 << 32) == 1000 for a, b in zip(t, t[1:], strict=False))


@pytest.mark.parametrize("n", [1, 63, 64, 3000])
def test_block_formatting_is_byte_identical_to_the_wire_codec(n):
    from labcli.core.sim.firmware import format_frames
    from labcli.core.wire import format_frame

    rng = np.random.default_rng(n)
    seq = rng.integers(0, 1 << 32, n)
    t_us = rng.integers(0, 1 << 32, n)
    values = rng.integers(0, 4096, (n, 6))
    values[0] = 0
    seq[-1] = 0
    want = b"".join(
        format_frame(int(a), int(b), [int(v) for v in row]) for a, b, row in zip(seq, t_us, values, strict=False)
    )
    assert format_frames(seq, t_us, values) == want


# ---------------------------------------------------------------- sim:// port


def test_url_rejects_unknown_option_with_the_accepted_form():
    with pytest.raises(serial.SerialException) as e:
        serial.serial_for_url("sim://?sped=3")
    assert str(e.value) == f"unknown option 'sped' in sim:// URL; expected {EXPECTED_FORM}"
    assert isinstance(e.value, ValueError)


@pytest.mark.parametrize(
    "url,message",
    [
        ("sim://?seed=abc", "option 'seed' in sim:// URL must be a whole number >= 0, got 'abc'"),
        ("sim://?rate=60000", "option 'rate' in sim:// URL must be a number of Hz within 1..50000, got '60000'"),
        ("sim://?clock=fast", "option 'clock' in sim:// URL must be 'virtual' or 'wall', got 'fast'"),
        ("sim://?noise=-1", "option 'noise' in sim:// URL must be a number >= 0, got '-1'"),
        ("sim://?seed=1&seed=2", "option 'seed' given twice in sim:// URL"),
        ("sim://rig1", "unexpected 'rig1' in sim:// URL"),
    ],
)
def test_url_rejects_malformed_values(url, message):
    with pytest.raises(ValueError) as e:
        serial.serial_for_url(url)
    assert str(e.value) == f"{message}; expected {EXPECTED_FORM}"


def test_protocol_over_sim_url():
    port = serial.serial_for_url("sim://?seed=3&rate=250&noise=1", timeout=1.0)
    assert port.readline() == b"#mckibben-2dof-sim 1.1 ready, 6 channels\n"
    port.write(b"ID?\n")
    assert port.read(port.in_waiting) == b"ID,mckibben-2dof-sim,1.1,P_L1,P_R1,P_L2,P_R2,POT1,POT2\n"
    port.write(b"RATE 100\n")
    assert port.readline() == b"OK RATE 100\n"
    port.rig.supply_air()
    port.write(b"START\n")
    data = port.read(40_000)
    assert len(data) == 40_000  # the virtual clock never starves a read
    assert data.startswith(b"OK START\n#streaming 6 channels at 100 Hz\n$D,0,")
    fr = frames_of(data)
    assert len(fr) > 500
    assert [f.seq for f in fr] == list(range(len(fr)))
    assert set(np.diff([f.t_us for f in fr])) == {10_000}
    p_late = CAL_P([f.values[:4] for f in fr[-50:]]).mean(axis=0)
    assert p_late == pytest.approx([0.3] * 4, abs=0.006)  # regulator reached, sensor offsets aside
    port.write(b"STOP\n")
    tail = port.read(port.in_waiting)
    assert tail.endswith(b"OK STOP\n")
    assert port.in_waiting == 0
    port.close()


def test_virtual_clock_runs_long_protocols_and_buffer_resets():
    port = serial.serial_for_url("sim://?seed=1&rate=1000", timeout=0.5)
    port.write(b"START\n")
    assert port.in_waiting > 0
    t0 = port.rig.time_s
    got = 0
    while got < 12_000_000:  # several minutes of device time
        got += len(port.read(1 << 16))
    assert port.rig.time_s - t0 > 240
    port.reset_input_buffer()
    nxt = port.read(400)
    line = nxt.split(b"\n")[1]
    assert isinstance(parse_line(line), Frame)
    port.close()
    with pytest.raises(serial.PortNotOpenError):
        port.read(1)


def test_virtual_port_has_no_stale_backlog_when_the_operator_acts():
    port = serial.serial_for_url("sim://?seed=2&rate=200&noise=0&ideal=1", timeout=0.5)
    port.rig.supply_air()
    port.write(b"START\n")
    seen = port.read(port.in_waiting)
    for _ in range(20):
        seen += port.read(port.in_waiting)
    t_hook = port.rig.time_s
    last_seen = frames_of(seen)[-1].t_us / 1e6
    assert -1e-6 <= t_hook - last_seen <= 3 / 200 + 1e-6  # at most a few frames on their way
    port.rig.hang_weight(1.0, 0.0)
    after = frames_of(seen[seen.rfind(b"\n") + 1 :] + port.read(4000))
    before_hook = [f for f in after if f.t_us / 1e6 <= t_hook + 1e-6]
    assert before_hook == after[: len(before_hook)] and len(before_hook) <= 3
    pots = np.array([f.values[4] for f in after[len(before_hook) :]])
    assert pots[-1] < pots[0] - 10  # every later frame shows the arm moving


def test_idle_virtual_port_waits_its_timeout_and_the_device_clock_runs_meanwhile():
    port = serial.serial_for_url("sim://", timeout=0.3)
    port.reset_input_buffer()
    t = time.monotonic()
    assert port.read(10) == b""
    waited = time.monotonic() - t
    assert waited >= 0.29
    assert port.rig.time_s == pytest.approx(waited, abs=0.05)
    port.write(b"ID?\n")
    assert port.read(5) == b"ID,mc"  # enough bytes: no wait


def test_wall_clock_paces_frames_and_honours_timeouts():
    port = serial.serial_for_url("sim://?clock=wall&rate=200", timeout=0.3)
    port.reset_input_buffer()
    t = time.monotonic()
    assert port.read(10) == b""
    assert time.monotonic() - t >= 0.29
    port.write(b"START\n")
    time.sleep(0.5)
    fr = frames_of(port.read(port.in_waiting))
    assert 60 <= len(fr) <= 130  # 200 Hz for about half a second
    port.write(b"STOP\n")
    port.close()


def test_unplug_fails_reads_and_writes_like_a_vanished_adapter():
    port = serial.serial_for_url("sim://?seed=1")
    port.write(b"START\n")
    port.read(100)
    port.unplug()
    for op in (lambda: port.read(10), lambda: port.write(b"STOP\n")):
        with pytest.raises(serial.SerialException, match="^device reports readiness to read but returned no data$"):
            op()
    assert port.is_open


# ---------------------------------------------------------------- pty


def reply(port) -> bytes:
    """The next line that is not a firmware log line (the boot banner may come first)."""
    while True:
        line = port.readline()
        if not line.startswith(b"#"):
            return line


@pytest.mark.skipif(not hasattr(os, "openpty"), reason="needs pseudo-terminals")
def test_protocol_over_pty():
    from labcli.core.sim.pty import serve_pty

    with serve_pty(seed=2, rate=200) as server:
        port = serial.Serial(server.path, timeout=1.0)
        port.write(b"ID?\n")
        assert reply(port) == b"ID,mckibben-2dof-sim,1.1,P_L1,P_R1,P_L2,P_R2,POT1,POT2\n"
        port.write(b"RATE 400\n")
        assert reply(port) == b"OK RATE 400\n"
        server.rig.supply_air()
        port.write(b"START\n")
        assert reply(port) == b"OK START\n"
        time.sleep(0.4)
        fr = frames_of(port.read(port.in_waiting))
        assert len(fr) > 50
        assert all(b.seq == a.seq + 1 for a, b in zip(fr, fr[1:], strict=False))
        assert set(np.diff([f.t_us for f in fr])) == {2500}
        port.write(b"STOP\n")
        time.sleep(0.1)
        assert port.read(port.in_waiting).endswith(b"OK STOP\n")
        port.write(b"BOGUS\n")
        assert reply(port) == b"ERR unknown command 'BOGUS'\n"
        port.close()


def assert_stopped_cleanly(proc: subprocess.Popen) -> None:
    """``labcli sim`` ended by itself (signal or ``quit``): exit 0 and its last line."""
    from support.procs import finish

    out, err = finish(proc)
    assert proc.returncode == 0, err
    assert out == "Simulated rig stopped.\n"


@pytest.mark.skipif(not hasattr(os, "openpty"), reason="needs pseudo-terminals")
def test_sim_command_serves_a_pty_until_sigterm():
    proc = subprocess.Popen(
        [sys.executable, "-m", "labcli", "sim", "--pty", "--seed", "4"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        cwd=os.path.dirname(os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))),
    )
    try:
        first = proc.stdout.readline()
        assert first.startswith("Simulated rig on /dev/") and first.endswith(" (Ctrl-C to stop)\n")
        path = first.split()[3]
        with serial.Serial(path, timeout=2.0) as port:
            port.write(b"ID?\n")
            assert reply(port).startswith(b"ID,mckibben-2dof-sim,1.1,")
        proc.send_signal(signal.SIGTERM)
        assert_stopped_cleanly(proc)
    finally:
        if proc.poll() is None:
            proc.kill()


def test_sim_command_without_pty_says_what_to_add():
    from labcli.commands.sim import sim

    result = CliRunner().invoke(sim, [])
    assert result.exit_code == 1
    assert result.output == (
        "Error: nothing to serve: add --pty to serve the simulated rig on a pseudo-terminal"
        " (labcli commands can use the port sim:// directly).\n"
    )


# ---------------------------------------------------------------- operator console


@pytest.mark.skipif(not hasattr(os, "openpty"), reason="needs pseudo-terminals")
def test_operator_drives_the_pty_rig_by_typing_and_the_port_shows_the_physics():
    # Two terminals, no Python: `labcli sim --pty` takes the operator's lines on stdin while a
    # serial program reads the port.  The readings must move as the physics says.
    # Without the pressure sensors' repeatability and drift, which move a reading by about 0.3 kPa
    # more than the window's noise: the port's pressures then follow the rig's to 0.5 kPa.
    quiet = ("--repeat", "0", "--drift", "0")
    proc = subprocess.Popen(
        [sys.executable, "-m", "labcli", "sim", "--pty", "--seed", "3", "--rate", "100", *quiet],
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        bufsize=1,
        cwd=os.path.dirname(os.path.dirname(os.path.abspath(__file__))),
    )

    def say(line: str) -> str:
        proc.stdin.write(line + "\n")
        proc.stdin.flush()
        return proc.stdout.readline().rstrip("\n")

    def state() -> dict:
        fields = dict(f.split("=", 1) for f in say("state").split()[1:] if "=" in f)
        return {k: np.array(v.split(","), dtype=float) for k, v in fields.items() if k in ("theta_deg", "P_MPa", "F_N")}

    try:
        path = proc.stdout.readline().split()[3]
        with serial.Serial(path, timeout=2.0) as port:
            assert say("supply").startswith("ok supply 0.300,0.300,0.300,0.300 MPa")
            assert say("wait 4").startswith("ok wait 4 s")
            assert say("close").startswith("ok close")
            port.reset_input_buffer()
            port.write(b"START\n")

            def window(seconds: float) -> np.ndarray:
                """Mean counts of the last half second of frames, reading all the while."""
                data, end = b"", time.monotonic() + seconds
                while time.monotonic() < end:
                    data += port.read(port.in_waiting or 1)
                fr = frames_of(data)
                return np.array([f.values for f in fr[-50:]], dtype=float).mean(axis=0)

            before, true0 = window(1.0), state()
            assert say("hang 1000 0").startswith("ok hang 1000 g at 0 deg")
            after, true1 = window(8.0), state()
            # The tip feels the weight less what the pulley holds back while it settles downwards.
            from labcli.papers.takuma2014.sim.nonideal import PULLEY_LOSS

            assert true1["F_N"] == pytest.approx([9.807 * (1 - PULLEY_LOSS), 0.0], abs=1e-3)
            # A pull along +x turns both joints clockwise: the left actuators stretch.
            d_true = true1["theta_deg"] - true0["theta_deg"]
            assert d_true[0] < -0.5 and d_true[1] < -0.5
            assert CAL_DEG(after[4:]) - CAL_DEG(before[4:]) == pytest.approx(d_true, abs=0.2)  # counts, backlash
            dp_true = true1["P_MPa"] - true0["P_MPa"]
            assert dp_true[0] > 0.002 and dp_true[1] < -0.002  # L1 up, R1 down (Boyle)
            assert CAL_P(after[:4]) - CAL_P(before[:4]) == pytest.approx(dp_true, abs=0.0005)
            assert say("remove").startswith("ok remove")
            assert say("push tin 3 0") == (
                "error: unknown object 'tin'; known: pet-1, pet-2, pet-3, can-al-1, can-al-2, can-steel-1"
            )
            assert say("hang heavy 0") == "error: mass must be a number, got 'heavy'; usage: hang GRAMS DEG"
            port.write(b"STOP\n")
        assert say("quit") == "ok quit"
        assert_stopped_cleanly(proc)
    finally:
        if proc.poll() is None:
            proc.kill()


def test_sim_command_refuses_a_rate_beyond_the_readers_limit():
    from labcli.cli import cli
    from labcli.commands.sim import sim
    from labcli.core.sim.firmware import RATE_MAX, RATE_MIN

    result = CliRunner().invoke(cli, ["sim", "--pty", "--rate", "60000"])
    assert result.exit_code == 2
    assert result.output.splitlines()[-1] == (
        "Error: Invalid value for '--rate': 60000.0 is not in the range 1<=x<=50000."
    )
    # The command's bounds (kept literal so that --help imports no numpy) are the firmware's.
    rate = next(p for p in sim.params if p.name == "rate")
    assert (rate.type.min, rate.type.max) == (RATE_MIN, RATE_MAX)
    assert serial.serial_for_url("sim://?rate=50000").firmware.rate_hz == RATE_MAX


@pytest.mark.skipif(not hasattr(os, "openpty"), reason="needs pseudo-terminals")
def test_a_host_that_falls_behind_loses_frames_but_still_gets_ok_stop():
    # At 50 kHz a host that stops reading fills the backlog in well under a second.  The rig
    # drops its new frames whole from then on (the sequence numbers show the gap), never what is
    # queued and never its replies: the STOP sent afterwards is answered (a host waiting for it
    # used to wait for ever once the backlog was cleared with the reply in it).
    from labcli.core.sim.pty import MAX_BACKLOG, serve_pty

    server = serve_pty(seed=1, rate=50000)
    try:
        with serial.Serial(server.path, timeout=0.2) as port:
            port.write(b"START\n")
            time.sleep(1.5)  # not reading: about 75000 frames fall due
            assert server.dropped_frames > 10000
            port.write(b"STOP\n")
            data, deadline = b"", time.monotonic() + 10.0
            while b"OK STOP\n" not in data and time.monotonic() < deadline:
                data += port.read(1 << 16)
            assert b"OK STOP\n" in data
            assert len(data) <= MAX_BACKLOG + 4096 + (1 << 16)  # the backlog, the pty's buffer, the reply
            seqs = [parse_line(line + b"\n", 6).seq for line in data.split(b"\n") if line.startswith(b"$D")]
            # Frames arrive whole and in order, with a gap where new ones were dropped (the host
            # may drain some backlog before STOP is read); every frame made was sent or counted dropped.
            assert seqs[0] == 0 and all(b > a for a, b in zip(seqs, seqs[1:], strict=False))
            assert len(seqs) + server.dropped_frames == server.firmware.count
    finally:
        server.stop()


def test_each_chambers_valve_on_its_own():
    """A held chamber keeps its air (Boyle) while the others follow the regulator or the atmosphere."""
    rig = SimRig(seed=2, nonideal=NonIdeal.ideal(), tau_s=0.3)
    rig.supply_air()
    rig.advance(3.0)
    rig.set_valves(["hold", "supply", "supply", "vent"])
    assert rig.true_state()["valves"] == "mixed" and rig.valve_states == ("hold", "supply", "supply", "vent")
    rig.advance(3.0)
    p = rig.true_state()["pressures_MPa"]
    assert abs(p[3]) < 1e-3 and np.allclose(p[1:3], 0.30, atol=1e-3)
    rig.hang_weight(0.8, 0.0)
    rig.advance(3.0)
    st = rig.true_state()
    assert np.allclose(st["pressures_MPa"][1:3], 0.30, atol=1e-3)  # open to the regulator: held at its pressure
    # The held chamber's air is what it was: P_abs (V + V_dead) unchanged as the arm moved.
    L = ph.actuator_lengths(st["theta_rad"], rig.params)
    V = ph.mckibben_volume(L, rig.params.b, rig.params.n) + rig.params.V_dead
    amount_now = (st["pressures_MPa"][0] * 1e6 + ph.P_ATM) * V[0]
    assert abs(st["pressures_MPa"][0] - 0.30) > 1e-3  # it moved with the arm
    rig.set_valves(["hold"] * 4)
    assert rig.true_state()["valves"] == "closed"
    rig.advance(1.0)
    st = rig.true_state()
    L = ph.actuator_lengths(st["theta_rad"], rig.params)
    V = ph.mckibben_volume(L, rig.params.b, rig.params.n) + rig.params.V_dead
    assert (st["pressures_MPa"][0] * 1e6 + ph.P_ATM) * V[0] == pytest.approx(amount_now, rel=1e-9)
    with pytest.raises(ValueError):
        rig.set_valves(["open"] * 4)


@pytest.mark.skipif(not hasattr(os, "openpty"), reason="needs pseudo-terminals")
@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_console_wait_is_bounded_and_a_signal_ends_it_at_once(sig):
    # `wait 1e20` traced back (time.sleep overflows) and during a wait Ctrl-C and SIGTERM were
    # ignored until it ended: a wait is at most an hour, and a stop request ends it.
    proc = subprocess.Popen(
        [sys.executable, "-m", "labcli", "sim", "--pty", "--seed", "3"],
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        bufsize=1,
    )
    try:
        assert proc.stdout.readline().startswith("Simulated rig on /dev/")
        proc.stdin.write("wait 1e20\n")
        proc.stdin.flush()
        line = proc.stdout.readline()
        while not line.startswith(("ok", "error")):  # the "Type operator actions" line on a terminal
            line = proc.stdout.readline()
        assert line == "error: seconds must be at most 3600 (an hour), got 1e+20; wait again for longer\n"
        proc.stdin.write("wait 600\n")
        proc.stdin.flush()
        time.sleep(1.0)  # inside the wait
        t0 = time.monotonic()
        proc.send_signal(sig)
        out, err = proc.communicate(timeout=20)
        assert time.monotonic() - t0 < 5.0
        assert "Traceback" not in err
        assert "Simulated rig stopped." in out
        assert proc.returncode == 0
    finally:
        if proc.poll() is None:
            proc.kill()
