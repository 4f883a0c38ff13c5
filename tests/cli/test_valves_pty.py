"""The board's valves with the host in another process: a killed host never leaves the chambers supplying.

``labcli acquire`` runs on the simulated rig served on a pty (wall clock), as on hardware; the
session supplies the chambers by command, and the host is killed with SIGKILL while they fill.
The board holds them by itself once they have been supplied for its ``supply_max_s`` (60 s by
default, 1 s here), with a ``VALVE`` event of cause ``timeout``.  A host killed after the hold
leaves them holding.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from labcli.core.sim.pty import serve_pty

ROOT = Path(__file__).resolve().parents[2]
HELD = ("hold",) * 4


def acquire(tmp_path: Path, port: str) -> subprocess.Popen:
    env = dict(os.environ, COLUMNS="300", PYTHONUNBUFFERED="1")
    (tmp_path / "plan.csv").write_text("trial,set,mass_g,direction_deg\n1,fit,200,-60\n")
    return subprocess.Popen(
        [
            sys.executable,
            "-m",
            "labcli",
            "acquire",
            str(tmp_path / "run.h5"),
            "--port",
            port,
            "--plan",
            str(tmp_path / "plan.csv"),
        ],
        cwd=ROOT,
        env=env,
        stdin=subprocess.PIPE,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )


def wait_for(what, timeout: float = 30.0) -> None:
    deadline = time.monotonic() + timeout
    while not what():
        if time.monotonic() > deadline:
            raise AssertionError("timed out")
        time.sleep(0.02)


@pytest.fixture
def rig_on_pty():
    server = serve_pty(seed=11, tau=0.1, ideal=True)
    try:
        yield server
    finally:
        server.stop()


def test_a_host_killed_while_the_chambers_fill_leaves_them_held_by_the_board(tmp_path, rig_on_pty):
    board, rig = rig_on_pty.firmware.board, rig_on_pty.rig
    board.supply_max_s = 1.0
    proc = acquire(tmp_path, rig_on_pty.path)
    try:
        # The supply's settling takes five seconds at least (the shipped protocol): kill within it.
        wait_for(lambda: rig.valve_states == ("supply",) * 4 and rig_on_pty.firmware.streaming)
        proc.send_signal(signal.SIGKILL)
        proc.wait(10)
        killed_at = rig.time_s
        assert rig.valve_states == ("supply",) * 4  # the host did not get to hold them
        wait_for(lambda: rig.valve_states == HELD, timeout=10.0)
        assert rig.true_state()["valves"] == "closed"
        assert rig.time_s - killed_at <= board.supply_max_s + 0.5
    finally:
        if proc.poll() is None:
            proc.kill()


def test_a_host_killed_after_the_hold_leaves_the_chambers_holding(tmp_path, rig_on_pty):
    rig = rig_on_pty.rig
    proc = acquire(tmp_path, rig_on_pty.path)
    try:
        wait_for(lambda: rig.valve_states == HELD and rig.true_state()["pressures_MPa"].min() > 0.2)
        proc.send_signal(signal.SIGKILL)
        proc.wait(10)
        time.sleep(1.0)
        assert rig.valve_states == HELD and rig.true_state()["valves"] == "closed"
    finally:
        if proc.poll() is None:
            proc.kill()
