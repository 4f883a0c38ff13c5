"""The rig vanishes mid-trial and comes back: what the experimenter is told, what the file keeps.

A real unplug closes the port; coming back is a new open of the same port
name.  Over ``sim://`` the unplug is the port's ``unplug()`` and coming back is
a new open of the same URL (a fresh simulated rig, as after a power cycle);
over a pseudo-terminal the server is stopped and a new one started behind the
same path (a symlink, as ``/dev/serial/by-id/...`` is for a USB adapter).

Unattended runs end with one sentence holding the exact resume command; that
command continues and completes the run.  Attended runs ask for the rig, open
the port again and redo the setup and the interrupted trial from its
baseline.  Either way the trial in progress is never stored half, and every
trial stored before is byte-identical afterwards (datasets and attributes).
"""

from __future__ import annotations

import io
import os
import shlex
from collections import deque
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from click.testing import CliRunner
from rich.console import Console
from support.records import stored_trials

from labcli.cli import cli
from labcli.core.acquisition import acquire
from labcli.core.device import Device
from labcli.core.protocol import load_protocol
from labcli.core.sim.pty import serve_pty
from labcli.core.store import RunFile
from labcli.core.ui import RichUI
from labcli.errors import DeviceDisconnected
from labcli.papers.takuma2014.session import CloseValves, HangWeight, Prompt, RemoveWeight, SupplyAir

SEED = 5
# A 1.0 board: the experimenter supplies and closes the valves (the prompts this file counts);
# LOSE_AT_START counts the stream's STARTs of that session.
PORT = f"sim://?seed={SEED}&clock=virtual&fw=1.0"
PLAN = (
    "trial,set,mass_g,direction_deg\n1,fit,200,-60\n2,fit,500,30\n3,fit,300,150\n"
    "4,fit,800,0\n5,validation,400,90\n6,validation,600,-150\n"
)
# START commands before the loss: setup check, air supply, then baseline and load of
# trials 1 and 2, then trial 3's baseline; the 8th START begins trial 3's loaded wait.
LOSE_AT_START = 8


# ---------------------------------------------------------------- building blocks


def trial_data(path: Path, attrs: bool = True) -> dict[int, dict[str, Any]]:
    """Every complete trial's arrays and values (dtype, shape, bytes) and, optionally, its metadata."""
    return stored_trials(path, attrs)


def datasets_only(data: dict[int, dict[str, Any]]) -> dict[int, dict[str, Any]]:
    return {t: {k: v for k, v in d.items() if not k.startswith("@")} for t, d in data.items()}


def hang(ser: Any) -> None:
    """The firmware hangs: it still answers commands but sends no more data lines."""
    fw = ser.firmware
    answer = fw.command

    def hung(line):
        reply = answer(line)
        fw.streaming = False
        return reply

    fw.command = hung
    fw.streaming = False


def lose_rig_at_start(monkeypatch, n: int, lose=lambda ser: ser.unplug()) -> list[Device]:
    """Unplug (or otherwise ``lose``) the first opened sim:// port right after its ``n``-th START.

    Returns the devices opened, in order."""
    real_open = Device.open.__func__
    opened: list[Device] = []

    def spy(cls, port, **kw):
        dev = real_open(cls, port, **kw)
        opened.append(dev)
        if len(opened) == 1:
            ser, write, starts = dev.serial, dev.serial.write, [0]

            def counting_write(data):
                written = write(data)
                if bytes(data).startswith(b"START"):
                    starts[0] += 1
                    if starts[0] == n:
                        lose(ser)
                return written

            ser.write = counting_write
        return dev

    monkeypatch.setattr(Device, "open", classmethod(spy))
    return opened


class Answers:
    """stdin for RichUI: Enter (accept the default) unless the test queued something else."""

    def __init__(self) -> None:
        self.queue: deque[str] = deque()

    def readline(self) -> str:
        return (self.queue.popleft() if self.queue else "") + "\n"

    def isatty(self) -> bool:
        return False


class Person(RichUI):
    """An experimenter at the rig: does what each prompt says with the rig's hooks, then presses Enter.

    ``on_prompt(person, step)`` runs first; ``rig`` is whichever rig is plugged in now.
    """

    def __init__(self, rig: Any = None, on_prompt=None) -> None:
        self.out = io.StringIO()
        self.answers = Answers()
        super().__init__(console=Console(file=self.out, width=400, highlight=False), stdin=self.answers)
        self.rig = rig
        self.on_prompt = on_prompt
        self.prompts: list[str] = []

    def prompt(self, step: Prompt) -> None:
        self.prompts.append(step.text)
        if self.on_prompt is not None:
            self.on_prompt(self, step)
        if self.rig is not None:
            act(self.rig, step.action)
        super().prompt(step)

    @property
    def text(self) -> str:
        return " ".join(self.out.getvalue().split())


def act(rig: Any, action: Any) -> None:
    if isinstance(action, SupplyAir):
        rig.supply_air()
    elif isinstance(action, CloseValves):
        rig.close_valves()
    elif isinstance(action, HangWeight):
        rig.hang_weight(action.mass_kg, action.direction_rad)
    elif isinstance(action, RemoveWeight):
        rig.remove_weight()


def assert_run_complete(path: Path, n: int, fit: list[int], validation: list[int]) -> None:
    with RunFile.open(path) as run:
        assert run.records.ids() == list(range(1, n + 1))
        assert run.records.incomplete_ids() == []
        split = run.split.get()
        assert split["strategy"] == "plan"
        assert split["fit"] == fit and split["validation"] == validation


@pytest.fixture(scope="module")
def plan_file(tmp_path_factory) -> Path:
    p = tmp_path_factory.mktemp("plan") / "plan.csv"
    p.write_text(PLAN)
    return p


@pytest.fixture(scope="module")
def reference(tmp_path_factory, plan_file) -> dict[int, dict[str, Any]]:
    """The same seed and plan, never interrupted."""
    path = tmp_path_factory.mktemp("ref") / "ref.h5"
    result = CliRunner().invoke(cli, ["acquire", str(path), "--port", PORT, "--plan", str(plan_file), "--unattended"])
    assert result.exit_code == 0, result.output
    return datasets_only(trial_data(path))


@pytest.fixture(scope="module")
def lost_and_resumed(tmp_path_factory, plan_file):
    """Unattended over sim://: the rig is lost in trial 3, then the printed command resumes the run."""
    mp = pytest.MonkeyPatch()
    path = tmp_path_factory.mktemp("lost") / "run.h5"
    try:
        lose_rig_at_start(mp, LOSE_AT_START)
        lost = CliRunner().invoke(cli, ["acquire", str(path), "--port", PORT, "--plan", str(plan_file), "--unattended"])
    finally:
        mp.undo()
    with RunFile.open(path) as run:
        state = (run.records.ids(), run.records.incomplete_ids(), run.split.get())
    before = trial_data(path)
    command = lost.output.rsplit("resume with: ", 1)[-1].strip()
    resumed = CliRunner().invoke(cli, shlex.split(command)[1:])
    return {
        "path": path,
        "lost": lost,
        "state": state,
        "before": before,
        "command": command,
        "resumed": resumed,
        "after": trial_data(path),
    }


# ---------------------------------------------------------------- unattended: exit, then resume


def test_unattended_loss_is_one_sentence_with_the_resume_command(lost_and_resumed, reference):
    r = lost_and_resumed
    path = r["path"]
    assert r["lost"].exit_code == 1
    assert r["lost"].output.splitlines()[-1] + "\n" == (
        f"Error: The rig on {PORT} was disconnected during trial 3; that trial was not stored and the "
        f"2 completed trials in {path} are unchanged. Check the cable and power, then resume with: "
        f"labcli acquire {path} --port '{PORT}' --resume --unattended\n"
    )
    completed, incomplete, split = r["state"]
    assert completed == [1, 2] and incomplete == [] and split is None  # nothing of trial 3, no split yet
    # What was stored is what an uninterrupted run of the same seed stores, to the byte.
    assert datasets_only(r["before"]) == {t: reference[t] for t in (1, 2)}


def test_the_printed_command_completes_the_run_and_leaves_earlier_trials_untouched(lost_and_resumed):
    r = lost_and_resumed
    path = r["path"]
    assert r["resumed"].exit_code == 0, r["resumed"].output
    assert f"Session complete: 6 trials stored in {path} (4 this session, " in r["resumed"].output
    assert_run_complete(path, 6, [1, 2, 3, 4], [5, 6])
    after = r["after"]
    for t in (1, 2):
        assert after[t] == r["before"][t]  # datasets and attributes, byte for byte
    # Trial 3 was measured whole in the resumed session: both windows full, from its own baseline.
    with RunFile.open(path) as run:
        rec = run.records.read(3)
    for name in ("baseline", "load"):
        seq = rec["raw"][name].seq.astype(np.int64)
        assert len(seq) == 200 and np.all(np.diff(seq) == 1)


# ---------------------------------------------------------------- attended: wait for the rig


def test_attended_run_waits_for_the_rig_and_redoes_the_trial_from_its_baseline(
    tmp_path, monkeypatch, plan_file, reference, lost_and_resumed
):
    path = tmp_path / "run.h5"
    opened = lose_rig_at_start(monkeypatch, LOSE_AT_START)
    person = Person()
    outcome = acquire(path, PORT, protocol="takuma2014", plan=plan_file, ui=person)
    assert outcome.status == "finished", person.out.getvalue()
    assert outcome.message.startswith(f"Session complete: 6 trials stored in {path} (6 this session, ")
    assert len(opened) == 2  # the port was opened again, by its name
    text = person.text
    assert (
        f"Warning: The rig on {PORT} was disconnected during trial 3, which was not stored; it will be "
        "redone from its baseline once the rig is back."
    ) in text
    assert f"Rig lost on {PORT}; reconnect it and press Enter to retry (q to quit):" in text
    # The setup is redone (the rig was power-cycled), then trial 3 from its baseline.
    assert person.prompts.count("Supply compressed air to the four actuators, then press Enter") == 2
    assert sum(p.startswith("Trial 3/6 (fit): hang 300 g") for p in person.prompts) == 2
    assert sum(p.startswith("Trial 2/6 (fit): hang 500 g") for p in person.prompts) == 1
    assert_run_complete(path, 6, [1, 2, 3, 4], [5, 6])
    got = datasets_only(trial_data(path))
    assert {t: got[t] for t in (1, 2)} == {t: reference[t] for t in (1, 2)}
    # After the reconnection the run is exactly a resumed run: same rig, same setup, same trials.
    resumed = datasets_only(lost_and_resumed["after"])
    assert {t: got[t] for t in range(3, 7)} == {t: resumed[t] for t in range(3, 7)}
    assert got[3] != reference[3]  # not the uninterrupted run's trial 3: it was measured anew


def test_attended_run_waits_for_a_silent_rig_too(tmp_path, monkeypatch, plan_file, lost_and_resumed):
    path = tmp_path / "run.h5"
    opened = lose_rig_at_start(monkeypatch, LOSE_AT_START, lose=hang)
    person = Person()
    outcome = acquire(path, PORT, protocol="takuma2014", plan=plan_file, ui=person, device_timeout=0.3)
    assert outcome.status == "finished", person.out.getvalue()
    assert len(opened) == 2
    assert (
        f"Warning: The rig on {PORT} stopped sending data during trial 3, which was not stored; it will be "
        "redone from its baseline once the rig is back."
    ) in person.text
    assert_run_complete(path, 6, [1, 2, 3, 4], [5, 6])
    got = datasets_only(trial_data(path))
    resumed = datasets_only(lost_and_resumed["after"])
    assert got == resumed  # trials 1-2 as first recorded, 3-6 as after any reconnection


def test_attended_run_stopped_at_the_reconnect_prompt_says_how_to_resume(tmp_path, monkeypatch, plan_file):
    path = tmp_path / "run.h5"
    lose_rig_at_start(monkeypatch, LOSE_AT_START)

    def stop_when_lost(person, step):
        if step.text.startswith("Rig lost on "):
            person.answers.queue.append("q")

    person = Person(on_prompt=stop_when_lost)
    with pytest.raises(DeviceDisconnected) as e:
        acquire(path, PORT, protocol="takuma2014", plan=plan_file, ui=person)
    assert str(e.value) == (
        f"The rig on {PORT} was disconnected during trial 3; that trial was not stored and the "
        f"2 completed trials in {path} are unchanged. Check the cable and power, then resume with: "
        f"labcli acquire {path} --port '{PORT}' --resume"
    )
    with RunFile.open(path) as run:
        assert run.records.ids() == [1, 2] and run.records.incomplete_ids() == []


def test_a_rig_lost_during_the_setup_check_of_a_new_run_leaves_no_file(tmp_path, monkeypatch, plan_file):
    path = tmp_path / "run.h5"
    lose_rig_at_start(monkeypatch, 1)
    result = CliRunner().invoke(cli, ["acquire", str(path), "--port", PORT, "--plan", str(plan_file), "--unattended"])
    assert result.exit_code == 1
    assert result.output == (
        f"Error: The rig on {PORT} was disconnected during the setup, before anything was written to "
        f"{path}. Check the cable and power, then run the same command again.\n"
    )
    assert not path.exists() and not Path(str(path) + ".creating").exists()


# ---------------------------------------------------------------- a pseudo-terminal: server stopped, new one started


class PlugSocket:
    """A stable port name (symlink) for whichever pty server is plugged in."""

    def __init__(self, tmp_path: Path) -> None:
        self.path = str(tmp_path / "ttyRIG")
        self.server = None

    def plug(self):
        # The ideal rig: what is tested is the reconnection; on the wall clock the default
        # rig's heat would hold each load for seconds past this protocol's short timeout.
        self.server = serve_pty(seed=11, tau=0.1, ideal=True)
        os.symlink(self.server.path, self.path)
        return self.server

    def unplug(self) -> None:
        os.unlink(self.path)
        self.server.stop()
        self.server = None

    def close(self) -> None:
        if self.server is not None:
            self.server.stop()


def quick_protocol(tmp_path: Path) -> Path:
    """The shipped protocol with short settling and capture windows: a trial takes about a second."""
    import re

    text = load_protocol("takuma2014").text
    # Limits for the short window: its 0.02 s block means (4 samples) carry about twice the noise
    # of the shipped 0.1 s ones, which one count would not leave still for long.
    for key, value in (
        ("window_s", "0.2"),
        ("hold_s", "0.2"),
        ("timeout_s", "20.0"),
        ("capture_s", "0.2"),
        ("pressure_spread_MPa", "0.001"),
        ("angle_spread_deg", "0.3"),
    ):
        text, n = re.subn(rf"(?m)^{key} = .*$", f"{key} = {value}", text)
        assert n == 1
    path = tmp_path / "quick.toml"
    path.write_text(text)
    (tmp_path / "plan.csv").write_text("trial,set,mass_g,direction_deg\n1,fit,200,-60\n2,validation,500,30\n")
    return path


@pytest.fixture
def socket(tmp_path):
    s = PlugSocket(tmp_path)
    try:
        yield s
    finally:
        s.close()


def test_pty_rig_replugged_while_the_run_waits(tmp_path, socket):
    proto = quick_protocol(tmp_path)
    path = tmp_path / "run.h5"
    socket.plug()
    events: list[str] = []

    def hands(person, step):
        if step.text.startswith("Trial 2/2 (validation): hang") and "unplugged" not in events:
            act(socket.server.rig, step.action)
            socket.unplug()  # the cable comes out while trial 2 settles under its load
            events.append("unplugged")
        elif step.text.startswith("Rig lost on "):
            if "retried" not in events:
                events.append("retried")  # Enter before the rig is back: told so, asked again
            else:
                person.rig = socket.plug().rig
                events.append("replugged")
        person.rig = socket.server.rig if socket.server is not None else None

    person = Person(socket.server.rig, on_prompt=hands)
    outcome = acquire(path, socket.path, protocol=str(proto), plan=tmp_path / "plan.csv", ui=person, valves="hand")
    assert outcome.status == "finished", person.out.getvalue()
    assert events == ["unplugged", "retried", "replugged"]
    text = person.text
    assert (
        f"Warning: The rig on {socket.path} was disconnected during trial 2, which was not stored; it will "
        "be redone from its baseline once the rig is back."
    ) in text
    assert (
        f"Warning: Cannot open serial port {socket.path}: no such device. Check the cable and run "
        "`labcli ports` to list ports."
    ) in text
    assert text.count(f"Rig lost on {socket.path}; reconnect it and press Enter to retry (q to quit):") == 2
    assert_run_complete(path, 2, [1], [2])
    with RunFile.open(path) as run:
        df = run.records.table()
        seq = run.records.read(2)["raw"]["load"].seq.astype(np.int64)
    assert len(seq) >= 40 and np.all(np.diff(seq) == 1)  # 0.2 s at 200 Hz, whole, from the new rig
    # The person hung what the prompts said on whichever rig was plugged in: the joints bent as
    # the paper-scale rig bends under 200 g at -60 deg and 500 g at 30 deg (0.27 and 1.12 deg).
    assert df["theta1_deg"].abs().to_numpy() == pytest.approx([0.27, 1.12], abs=0.1)


def test_pty_rig_lost_then_resumed_by_the_printed_command_on_a_new_server(tmp_path, socket):
    proto = quick_protocol(tmp_path)
    path = tmp_path / "run.h5"
    socket.plug()

    def hands(person, step):
        if step.text.startswith("Trial 2/2 (validation): hang"):
            act(socket.server.rig, step.action)
            socket.unplug()
        elif step.text.startswith("Rig lost on "):
            person.answers.queue.append("q")  # not coming back today
        person.rig = socket.server.rig if socket.server is not None else None

    person = Person(socket.server.rig, on_prompt=hands)
    with pytest.raises(DeviceDisconnected) as e:
        acquire(path, socket.path, protocol=str(proto), plan=tmp_path / "plan.csv", ui=person, valves="hand")
    command = f"labcli acquire {path} --port {socket.path} --resume"
    assert str(e.value) == (
        f"The rig on {socket.path} was disconnected during trial 2; that trial was not stored and the "
        f"1 completed trial in {path} is unchanged. Check the cable and power, then resume with: {command}"
    )
    before = trial_data(path)
    assert list(before) == [1]

    # Another day, another server behind the same name: the printed command continues the run.
    server = socket.plug()
    args = shlex.split(command)[2:]
    person = Person(server.rig)
    outcome = acquire(args[0], args[2], resume=True, ui=person)
    assert outcome.status == "finished", person.out.getvalue()
    assert outcome.message.startswith(f"Session complete: 2 trials stored in {path} (1 this session, ")
    assert trial_data(path)[1] == before[1]
    assert_run_complete(path, 2, [1], [2])
