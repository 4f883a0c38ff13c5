"""``labcli acquire`` forgives what people do at the rig: an Enter too many, a mistyped load,
a direction past 180 deg, a key pressed while the rig settles, a resumed run's operator."""

from __future__ import annotations

import io
import math
import os

import pytest
from click.testing import CliRunner
from rich.console import Console

from labcli.cli import cli
from labcli.core.acquisition import acquire as run_acquisition
from labcli.core.store import RunFile
from labcli.core.ui import RichUI, UnattendedUI, settle_keys
from labcli.papers.takuma2014.records import load_trials
from labcli.papers.takuma2014.session import G, parse_direction_deg, parse_load_change

IDEAL = "sim://?seed=8&clock=virtual&ideal=1"
SETUP = ""  # no air prompts: the simulated board supplies and holds the air by command
END = "End the run here with {} stored? y ends it, Enter goes on:"


def no_plan(path, answers):
    return CliRunner().invoke(cli, ["acquire", str(path), "--port", IDEAL, "--no-plan"], input=answers)


def test_an_empty_mass_asks_before_it_ends_the_run(tmp_path):
    path = tmp_path / "run.h5"
    # Enter at the first mass (a slip: Enter goes on), then a load, then Enter and y.
    answers = SETUP + "\n" + "\n" + "250\n45\n" + "\n\na\n" + "\n" + "y\n"
    result = no_plan(path, answers)
    assert result.exit_code == 0, result.output
    assert END.format("0 trials") in result.output
    assert END.format("1 trial") in result.output
    assert f"Session complete: 1 trial stored in {path}" in result.output
    assert load_trials(path)["trial"].tolist() == [1]


def test_a_redone_trial_takes_a_retyped_load(tmp_path):
    path = tmp_path / "run.h5"
    offer = " (or type another mass in g and direction in deg, e.g. 300 90)"
    # 250 g at 45 deg hung and reviewed, redone; at its hang prompt 300 g at 90 deg is typed instead.
    answers = SETUP + "250\n45\n" + "\n\nr\n" + "300 90\n" + "\n\na\n" + "\ny\n"
    result = no_plan(path, answers)
    assert result.exit_code == 0, result.output
    assert f"Trial 1/108: hang 250 g, pulley direction 45 deg, then press Enter{offer}" in result.output
    assert f"Trial 1/108: hang 300 g, pulley direction 90 deg, then press Enter{offer}" in result.output
    df = load_trials(path)
    assert df["trial"].tolist() == [1]
    assert df["mass_g"].tolist() == pytest.approx([300.0])
    assert df["Fx_N"].iloc[0] == pytest.approx(0.0, abs=1e-12)
    assert df["Fy_N"].iloc[0] == pytest.approx(0.3 * G)


def test_directions_wrap_as_the_docs_say(tmp_path):
    assert parse_direction_deg("270") == pytest.approx(math.radians(-90))
    assert parse_direction_deg("-270 deg") == pytest.approx(math.radians(90))
    assert parse_direction_deg("540") == pytest.approx(math.pi)
    assert parse_direction_deg("180") == pytest.approx(math.pi)  # in range: kept as typed
    assert parse_direction_deg("270", -90, 90) == pytest.approx(math.radians(-90))
    with pytest.raises(
        ValueError,
        match=r"^The direction must be from -90 deg to 90 deg \(or a whole turn from there\), got 180 deg\.$",
    ):
        parse_direction_deg("180", -90, 90)
    assert parse_load_change("300 g 270 deg", 0.0, (1, 2000), (-180, 180)).direction_rad == pytest.approx(
        math.radians(-90)
    )
    assert parse_load_change("400", 0.5, (1, 2000), (-180, 180)).direction_rad == 0.5  # the direction kept
    with pytest.raises(ValueError, match=r"^'heavy' is not a mass: type a number of grams, e\.g\. 200 g\.$"):
        parse_load_change("heavy 90", 0.0, (1, 2000), (-180, 180))
    path = tmp_path / "run.h5"
    result = no_plan(path, SETUP + "200\n270\n" + "\n\na\n" + "\ny\n")
    assert result.exit_code == 0, result.output
    assert "Trial 1/108: hang 200 g, pulley direction -90 deg, then press Enter" in result.output
    df = load_trials(path)
    assert df["direction_deg"].tolist() == pytest.approx([-90.0])
    assert df["Fy_N"].iloc[0] == pytest.approx(-0.2 * G)


def test_q_and_r_pressed_on_a_terminal_are_read_as_single_keys():
    master, slave = os.openpty()
    with os.fdopen(slave, "r") as stream:
        with settle_keys(stream) as key:
            assert key() is None
            os.write(master, b"x")  # another key: dropped
            assert key() is None
            os.write(master, b"r")
            assert key() == "redo"
            os.write(master, b"q")
            assert key() == "quit"
        # RichUI's settling status hands the key to the engine the same way.
        ui = RichUI(console=Console(file=io.StringIO()), stdin=stream)
        with ui.settling("load", None) as show:
            os.write(master, b"q")
            assert show(None) == "quit"
    os.close(master)


def test_a_piped_answer_is_never_taken_for_a_settle_key():
    with settle_keys(io.StringIO("q\n")) as key:
        assert key() is None


class KeyAtSettle(UnattendedUI):
    """Acts out the prompts; presses ``key`` once during the first wait labelled ``label``."""

    def __init__(self, label, key):
        super().__init__(console=Console(file=io.StringIO(), width=200))
        self.label, self.key, self.pressed = label, key, False

    def settling(self, label, criteria):
        import contextlib

        @contextlib.contextmanager
        def cm():
            def show(status):
                if label == self.label and not self.pressed:
                    self.pressed = True
                    return self.key
                return None

            yield show

        return cm()


def plan_file(tmp_path):
    plan = tmp_path / "plan.csv"
    plan.write_text("trial,set,mass_g,direction_deg\n1,fit,200,-60\n2,fit,500,30\n")
    return plan


def test_q_during_a_settle_quits_at_once(tmp_path):
    path = tmp_path / "run.h5"
    outcome = run_acquisition(
        path, IDEAL, protocol="takuma2014", plan=plan_file(tmp_path), ui=KeyAtSettle("load", "quit")
    )
    assert outcome.status == "quit" and outcome.stored == 0
    assert outcome.message.startswith("Stopped at your request during trial 1, which was not stored; 0 trials stored")


def test_r_during_a_settle_redoes_the_trial(tmp_path):
    path = tmp_path / "run.h5"
    ui = KeyAtSettle("load", "redo")
    seen = []
    outcome = run_acquisition(
        path,
        IDEAL,
        protocol="takuma2014",
        plan=plan_file(tmp_path),
        ui=ui,
        subscribers=(lambda s, r: seen.append((s, r)),),
    )
    assert outcome.status == "finished" and outcome.stored == 2
    hangs = [s.text for s, _ in seen if type(s).__name__ == "Prompt" and "hang 200 g" in s.text]
    assert len(hangs) == 2  # trial 1's load prompted again after the redo
    with RunFile.open(path) as run:
        assert run.records.ids() == [1, 2]


def test_a_resumed_session_keeps_its_operator(tmp_path):
    path = tmp_path / "run.h5"
    plan = plan_file(tmp_path)
    runner = CliRunner()
    first = runner.invoke(
        cli,
        ["acquire", str(path), "--port", IDEAL, "--plan", str(plan), "--operator", "kim"],
        input=SETUP + "\n\na\nq\n",
    )
    assert first.exit_code == 0, first.output
    again = runner.invoke(cli, ["acquire", str(path), "--port", IDEAL, "--resume"], input=SETUP + "\n\na\n")
    assert again.exit_code == 0, again.output
    assert "Operator kim, as the run recorded (--operator names another)." in again.output
    with RunFile.open(path) as run:
        assert [s["operator"] for s in run.sessions.all()] == ["kim", "kim"]
    other = runner.invoke(cli, ["acquire", str(path), "--port", IDEAL, "--resume", "--operator", "lee"])
    assert other.exit_code == 0 and "nothing to resume" in other.output
