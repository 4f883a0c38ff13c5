"""``labcli acquire`` end to end on the simulated rig (virtual clock): engine, run file, CLI."""

from __future__ import annotations

import io
import math

import numpy as np
import pytest
from click.testing import CliRunner
from rich.console import Console

from labcli.cli import cli
from labcli.core.acquisition import resume_command
from labcli.core.device import Device
from labcli.core.engine import RunEngine
from labcli.core.protocol import load_protocol
from labcli.core.setupcheck import check_readings
from labcli.core.simoperator import operator_for
from labcli.core.store import RunFile
from labcli.core.ui import UnattendedUI
from labcli.errors import DeviceDisconnected, DeviceTimeout
from labcli.papers.takuma2014.protocol import load_plan
from labcli.papers.takuma2014.records import load_trials
from labcli.papers.takuma2014.session import Baseline, Capture, Commit, G, HangWeight, Prompt, Window, force_session

PROTOCOL = load_protocol("takuma2014")
PLAN = load_plan(PROTOCOL)
# One count of sensor noise per sample, rms (labcli.papers.takuma2014.sim.rig): 0.5 count of 0.305 kPa, 0.7 count of 0.083 deg.
PRESSURE_NOISE_MPA = 0.5 * 5.0 / 16380
ANGLE_NOISE_DEG = 0.7 * 340 / 4095

SMALL_PLAN = (
    "trial,set,mass_g,direction_deg\n1,fit,200,-60\n2,fit,500,30\n3,validation,300,150\n4,validation,400,-150\n"
)


def quiet_ui():
    return UnattendedUI(console=Console(file=io.StringIO(), width=200))


def open_run(path, port, plan=PLAN):
    dev = Device.open(port)
    store = RunFile.create(path, protocol=PROTOCOL, device_info=dev.info, port=port, plan=plan)
    engine = RunEngine(
        dev,
        store,
        PROTOCOL,
        quiet_ui(),
        run_path=str(path),
        resume_command=resume_command(str(path), port),
        simulated_operator=operator_for(dev),
    )
    return dev, store, engine


def test_unattended_108_trials_agree_with_what_the_rig_applied(tmp_path):
    path = tmp_path / "run.h5"
    # The ideal rig: potentiometers without backlash read the true angles (the pipeline is
    # what is tested here; the non-idealities have tests/papers/takuma2014/test_nonideal.py).
    dev, store, engine = open_run(path, "sim://?seed=3&clock=virtual&ideal=1")
    rig = dev.rig
    truth, baseline = [], {}

    def record_truth(step, reply):
        if isinstance(step, Baseline):
            baseline["state"] = rig.true_state()
        elif isinstance(step, Capture):
            truth.append((baseline["state"], rig.true_state()))

    engine.subscribe(record_truth)
    outcome = engine.run(force_session(PROTOCOL, PLAN))
    store.close()
    dev.close()
    assert outcome.status == "finished" and outcome.exit_code == 0
    assert outcome.message.startswith(f"Session complete: 108 trials stored in {path} (108 this session, ")

    df = load_trials(path)
    assert list(df["trial"]) == list(range(1, 109))
    assert list(df["set"]) == ["fit"] * 90 + ["validation"] * 18
    assert len(truth) == 108
    # Deflections: potentiometer under load minus the trial's own baseline vs the rig's true angles.
    true_theta = np.degrees([s["theta_rad"] - b["theta_rad"] for b, s in truth])
    err_theta = np.abs(df[["theta1_deg", "theta2_deg"]].to_numpy() - true_theta)
    assert err_theta.max() < ANGLE_NOISE_DEG
    assert np.abs(true_theta).max() > 1.5  # the loads did bend the joints (paper scale: a few deg)
    # Pressures (the simulated sensors' zero offsets are part of what they read).
    true_p = np.array([s["pressures_MPa"] for _, s in truth]) + rig.sensor_offset_MPa
    err_p = np.abs(df[["P_L1", "P_R1", "P_L2", "P_R2"]].to_numpy() - true_p)
    assert err_p.max() < PRESSURE_NOISE_MPA
    true_p0 = np.array([b["pressures_MPa"] for b, _ in truth]) + rig.sensor_offset_MPa
    assert np.abs(df[["P_L10", "P_R10", "P_L20", "P_R20"]].to_numpy() - true_p0).max() < PRESSURE_NOISE_MPA
    # Forces: m g (cos, sin) of the plan, and exactly what the rig's pulley applied.
    true_f = np.array([s["force_N"] for _, s in truth])
    assert df[["Fx_N", "Fy_N"]].to_numpy() == pytest.approx(true_f, abs=1e-9)
    row12 = df[df["trial"] == 12].iloc[0]
    assert row12["Fx_N"] == pytest.approx(0.2 * G * math.cos(math.radians(-120)))
    assert row12["mass_g"] == 200 and row12["direction_deg"] == -120

    with RunFile.open(path) as run:
        split = run.split.get()
        assert split["strategy"] == "plan" and split["fit"] == list(range(1, 91))
        assert split["validation"] == list(range(91, 109))
        rec = run.records.read(12)
        for name in ("baseline", "load"):
            w = rec["raw"][name]
            n = len(w.seq)
            assert n == 200  # capture_s 1 s at 200 Hz
            assert np.all(np.diff(w.seq.astype(np.int64)) == 1)
            assert w.counts.shape == (n, 6) and w.si.shape == (n, 6)
            assert np.allclose(PROTOCOL.calibration.to_si(w.counts), w.si)
            assert np.allclose(np.diff(w.t_s), 0.005)
        assert rec["settle"]["load"]["settled"] is True
        assert rec["settle"]["load"]["criterion"].startswith(
            "range of 10 block means over 1 s and the tail extrapolated from 3 windows below 0.31 kPa"
        )
        assert rec["settle"]["load"]["settle_time_s"] >= 0


def test_rig_unplugged_mid_trial_leaves_the_file_as_it_was(tmp_path):
    path = tmp_path / "run.h5"
    port = "sim://?seed=5&clock=virtual"
    dev, store, engine = open_run(path, port, plan=PLAN.iloc[:6])
    snapshot = {}

    def unplug_in_trial_3(step, reply):
        if isinstance(step, Commit) and step.record["trial"] == 2:
            snapshot["table"] = store.records.table()
            snapshot["raw2"] = store.records.read(2)["raw"]["load"].counts.copy()
        if isinstance(step, Capture) and engine._trial.trial == 3:
            dev.serial.unplug()

    engine.subscribe(unplug_in_trial_3)
    with pytest.raises(DeviceDisconnected) as err:
        engine.run(force_session(PROTOCOL, PLAN.iloc[:6]))
    store.close()
    dev.close()
    assert str(err.value) == (
        f"The rig on {port} was disconnected during trial 3; that trial was not stored and the "
        f"2 completed trials in {path} are unchanged. Check the cable and power, then resume with: "
        f"labcli acquire {path} --port '{port}' --resume"
    )
    with RunFile.open(path) as run:
        assert run.records.ids() == [1, 2] and run.records.incomplete_ids() == []
        assert run.records.table().equals(snapshot["table"])
        assert np.array_equal(run.records.read(2)["raw"]["load"].counts, snapshot["raw2"])
    # The command the message gives continues the run at trial 3.
    result = CliRunner().invoke(cli, ["acquire", str(path), "--port", port, "--resume", "--unattended"])
    assert result.exit_code == 0, result.output
    assert load_trials(path)["trial"].tolist() == [1, 2, 3, 4, 5, 6]


def test_a_silent_rig_mid_trial_is_reported_with_the_resume_command(tmp_path):
    path = tmp_path / "run.h5"
    port = "sim://?seed=5&clock=virtual"
    dev = Device.open(port, timeout=0.3)  # the device's own silence limit, wall clock
    store = RunFile.create(path, protocol=PROTOCOL, device_info=dev.info, port=port, plan=PLAN.iloc[:3])
    engine = RunEngine(
        dev,
        store,
        PROTOCOL,
        quiet_ui(),
        run_path=str(path),
        resume_command=resume_command(str(path), port),
        simulated_operator=operator_for(dev),
    )

    def fall_silent_in_trial_2(step, reply):
        if isinstance(step, Prompt) and isinstance(step.action, HangWeight) and engine._trial.trial == 2:
            # The firmware hangs: it still answers commands but sends no more data lines.
            fw = dev.serial.firmware
            answer = fw.command

            def hung(line):
                reply = answer(line)
                fw.streaming = False
                return reply

            fw.command = hung
            fw.streaming = False

    engine.subscribe(fall_silent_in_trial_2)
    with pytest.raises(DeviceTimeout) as err:
        engine.run(force_session(PROTOCOL, PLAN.iloc[:3]))
    store.close()
    dev.close()
    assert str(err.value) == (
        f"The rig on {port} stopped sending data during trial 2; that trial was not stored and the "
        f"1 completed trial in {path} is unchanged. Check the cable and power, then resume with: "
        f"labcli acquire {path} --port '{port}' --resume"
    )
    assert load_trials(path)["trial"].tolist() == [1]


def test_ctrl_c_discards_the_current_trial_and_says_how_to_resume(tmp_path):
    path = tmp_path / "run.h5"
    port = "sim://?seed=6&clock=virtual"
    dev, store, engine = open_run(path, port, plan=PLAN.iloc[:5])

    def interrupt_in_trial_3(step, reply):
        if isinstance(step, Capture) and engine._trial.trial == 3:
            raise KeyboardInterrupt

    engine.subscribe(interrupt_in_trial_3)
    outcome = engine.run(force_session(PROTOCOL, PLAN.iloc[:5]))
    assert not dev.streaming
    store.close()
    dev.close()
    assert outcome.status == "interrupted" and outcome.exit_code == 130
    assert outcome.message == (
        f"Interrupted during trial 3, which was discarded; 2 trials stored in {path} are safe. "
        f"Resume with: labcli acquire {path} --port '{port}' --resume"
    )
    with RunFile.open(path) as run:
        assert run.records.ids() == [1, 2] and run.records.incomplete_ids() == []


class _CtrlCInFinaliser:
    """An object whose clean-up meets the Ctrl-C, as h5py's weakref callbacks can."""

    def __del__(self):
        raise KeyboardInterrupt


def test_ctrl_c_landing_in_a_finaliser_is_not_lost(tmp_path, capsys):
    # Python cannot raise from a finaliser: by default it prints "Exception ignored ...
    # KeyboardInterrupt" and the session runs on to the end.  The engine keeps it instead.
    path = tmp_path / "run.h5"
    port = "sim://?seed=6&clock=virtual"
    dev, store, engine = open_run(path, port, plan=PLAN.iloc[:5])

    def clean_up_in_trial_3(step, reply):
        if isinstance(step, Baseline) and engine._trial is not None and engine._trial.trial == 3:
            doomed = _CtrlCInFinaliser()
            del doomed

    engine.subscribe(clean_up_in_trial_3)
    outcome = engine.run(force_session(PROTOCOL, PLAN.iloc[:5]))
    store.close()
    dev.close()
    assert outcome.status == "interrupted" and outcome.exit_code == 130
    assert outcome.message.startswith("Interrupted during trial 3, which was discarded; 2 trials stored")
    assert "Exception ignored" not in capsys.readouterr().err
    with RunFile.open(path) as run:
        assert run.records.ids() == [1, 2]


def test_typed_session_with_redo_skip_quit_then_resume(tmp_path):
    """The prompts answered as a person types them (stdin), on the simulated rig."""
    path = tmp_path / "run.h5"
    plan = tmp_path / "plan.csv"
    plan.write_text(SMALL_PLAN)
    port = "sim://?seed=7&clock=virtual"
    setup = ""  # the simulated board supplies and holds the chambers by command: no air prompts
    trial = "\n\n"  # weight hung, weight removed
    answers = setup + trial + "r\n" + trial + "a\n" + trial + "s\n" + trial + "q\n"
    runner = CliRunner()
    result = runner.invoke(
        cli, ["acquire", str(path), "--port", port, "--plan", str(plan), "--operator", "kim"], input=answers
    )
    assert result.exit_code == 0, result.output
    out = result.output
    assert "Trial 1/4 (fit): hang 200 g, pulley direction -60 deg, then press Enter" in out
    assert out.count("Trial 1/4 (fit): hang 200 g") == 2  # redone
    assert "Trial 3/4 (validation): hang 300 g, pulley direction 150 deg, then press Enter" in out
    assert out.rstrip().endswith(
        f"Stopped at your request during trial 3, which was not stored; 1 trial stored in {path}. "
        f"Resume with: labcli acquire {path} --port '{port}' --resume"
    )
    first = load_trials(path)
    assert first["trial"].tolist() == [1]
    with RunFile.open(path) as run:
        assert run.attrs["operator"] == "kim"

    result = runner.invoke(cli, ["acquire", str(path), "--port", port, "--resume"], input=setup + (trial + "a\n") * 3)
    assert result.exit_code == 0, result.output
    assert "Trial 2/4 (fit): hang 500 g, pulley direction 30 deg, then press Enter" in result.output
    assert "Trial 1/4" not in result.output
    assert f"Session complete: 4 trials stored in {path} (3 this session, " in result.output
    df = load_trials(path)
    assert df["trial"].tolist() == [1, 2, 3, 4]
    assert df["set"].tolist() == ["fit", "fit", "validation", "validation"]
    # The first session's trial is untouched (its set came with the split at the end).
    assert df.drop(columns="set").iloc[0].equals(first.drop(columns="set").iloc[0])
    assert df["Fy_N"].tolist() == pytest.approx(
        [0.2 * G * math.sin(math.radians(-60)), 0.5 * G * 0.5, 0.3 * G * 0.5, 0.4 * G * -0.5]
    )
    result = runner.invoke(cli, ["acquire", str(path), "--port", port, "--resume"])
    assert result.exit_code == 0
    assert result.output == f"All 4 planned trials are already stored in {path}; nothing to resume.\n"


def test_typed_loads_without_a_plan_are_checked(tmp_path):
    path = tmp_path / "run.h5"
    # The simulated board supplies and holds by command: the first answers are the typed load's.
    answers = "5000\n250 g\nnorth\n45\n" + "\n\na\n" + "\ny\n"
    # The ideal rig: the check is of the typed loads; on the default rig sleeve friction and the
    # potentiometers' play hide most of a 250 g deflection (tests/test_nonideal.py has those).
    result = CliRunner().invoke(
        cli, ["acquire", str(path), "--port", "sim://?seed=8&clock=virtual&ideal=1", "--no-plan"], input=answers
    )
    assert result.exit_code == 0, result.output
    assert "The mass must be from 1 g to 2000 g, got 5000 g." in result.output
    assert "'north' is not a direction: type degrees counter-clockwise from +x, e.g. 45 deg." in result.output
    assert "Trial 1/108: hang 250 g, pulley direction 45 deg, then press Enter (or type another" in result.output
    df = load_trials(path)
    assert df["trial"].tolist() == [1] and df["set"].tolist() == [""]
    assert df["Fx_N"].iloc[0] == pytest.approx(0.25 * G / math.sqrt(2))
    # The rig did hang the weight: 250 g at 45 deg bends joint 1 of the paper-scale rig by 0.44 deg.
    assert 0.35 < df["theta1_deg"].abs().iloc[0] < 0.55


def test_existing_file_is_never_overwritten_without_force(tmp_path):
    path = tmp_path / "run.h5"
    path.write_bytes(b"precious")
    result = CliRunner().invoke(cli, ["acquire", str(path), "--port", "sim://", "--unattended"])
    assert result.exit_code == 1
    assert result.output == (
        f"Error: {path} already exists; continue it with --resume, or pass --force to overwrite it.\n"
    )
    assert path.read_bytes() == b"precious"


@pytest.mark.parametrize(
    "args, message",
    [
        (["--resume", "--force"], "--resume continues a run and --force overwrites it: give one of them, not both."),
        (["--no-plan", "--unattended"], "--unattended needs a plan to follow: drop --no-plan, or give --plan FILE."),
        (["--plan", "p.csv", "--no-plan"], "--plan and --no-plan contradict each other: give one of them."),
        (["--protocol", "nosuch"], "There is no shipped protocol named 'nosuch'; shipped protocols are "),
    ],
)
def test_contradictory_options_are_refused(tmp_path, args, message):
    result = CliRunner().invoke(cli, ["acquire", str(tmp_path / "r.h5"), "--port", "sim://", *args])
    assert result.exit_code == 1
    assert result.output.startswith("Error: " + message)
    assert not (tmp_path / "r.h5").exists()


def test_setup_check_names_the_mismatching_channels(tmp_path):
    text = PROTOCOL.text.replace(
        'channels = ["P_L1", "P_R1", "P_L2", "P_R2", "POT1", "POT2"]',
        'channels = ["P_L1", "P_R1", "P_L2", "P_R2", "POT2", "POT1"]',
    )
    proto = tmp_path / "swapped.toml"
    proto.write_text(text)
    (tmp_path / "takuma2014-plan.csv").write_text(SMALL_PLAN)
    result = CliRunner().invoke(
        cli,
        [
            "acquire",
            str(tmp_path / "r.h5"),
            "--port",
            "sim://?seed=1",
            "--protocol",
            str(proto),
            "--plan",
            str(tmp_path / "takuma2014-plan.csv"),
            "--unattended",
        ],
    )
    assert result.exit_code == 1
    assert result.output == (
        "Error: The rig on sim://?seed=1 reports channels P_L1,P_R1,P_L2,P_R2,POT1,POT2 but protocol "
        "takuma2014 expects P_L1,P_R1,P_L2,P_R2,POT2,POT1: check the firmware, or pass the matching --protocol.\n"
    )
    assert not (tmp_path / "r.h5").exists()  # a failed setup check leaves no run file


def test_setup_check_says_which_reading_is_out_of_range():
    counts = np.tile([1556, 1560, 0, 1551, 2048, 3900], (10, 1)).astype(float)  # P_L2 unplugged, POT2 at 154 deg
    si = PROTOCOL.calibration.to_si(counts)
    w = Window.of(np.arange(10), counts, si, t_us=np.arange(10) * 5000, t_s=np.arange(10) * 0.005)
    assert check_readings(w, PROTOCOL, [0, 1, 2, 3], [4, 5]) == [
        "P_L2 reads -0.250 to -0.250 MPa, outside the sensor span 0 to 1 MPa (check that sensor's cable and supply)",
        "POT2 reads 153.8 to 153.8 deg, outside the plausible -90 to 90 deg (check the potentiometer's wiring "
        "and centring)",
    ]


def test_typed_push_session_on_the_simulated_rig(tmp_path):
    """Section 4: name the object, its radius, category and its pushes' distance and direction, then ten pushes."""
    path = tmp_path / "push.h5"
    # name, R in mm, category, d in mm, phi (unknown), stiffness of the simulated object
    obj = "pet-1\n33\nsoft\n8\n?\n400\n"
    # Push 1: 10 mm along 0 deg typed instead of Enter, then Enter to push; every push: release, review.
    pushes = "10 0\n\n\n\n" + "\n\n\n" * 9
    # No air prompts: the simulated board supplies and holds by command.  The hold check after the
    # supply waits for the protocol's 12 s of quiet, which this rig (seed 9) reaches only after the
    # 45 s timeout: the experimenter presses Enter to wait longer, the default (it settles at 33 s);
    # so again when a baseline after a re-supply for the leak is slow; Enter is always the default.
    answers = "\n" + obj + pushes + "\n" * 12
    result = CliRunner().invoke(
        cli,
        # The kind rig, whose waits these answers follow (the literature's waits differently).
        [
            "acquire",
            str(path),
            "--port",
            "sim://?seed=9&clock=virtual&realism=kind",
            "--protocol",
            "takuma2014-stiffness",
        ],
        input=answers,
    )
    assert result.exit_code == 0, result.output
    assert "Push 1/10 of pet-1: push pet-1 by 10 mm along 0 deg, then press Enter" in result.output
    assert "Push 2/10 of pet-1: push pet-1 by 8 mm along an unknown direction, then press Enter" in result.output
    assert f"Session complete: 10 pushes stored in {path} (10 this session, " in result.output
    with RunFile.open(path) as run:
        df = run.records.table()
    assert df["push"].tolist() == list(range(1, 11))
    assert set(df["object"]) == {"pet-1"} and set(df["category"]) == {"soft"}
    assert df["R_m"].iloc[0] == pytest.approx(0.033) and df["d_m"].tolist() == pytest.approx([0.010] + [0.008] * 9)
    assert df["phi_deg"].iloc[0] == 0 and df["phi_deg"].iloc[1:].isna().all()
    assert df["true_stiffness_N_per_m"].tolist() == [400.0] * 10
    # Pushing the object in changes the pressures.
    dp = df[["P_L1", "P_R1", "P_L2", "P_R2"]].to_numpy() - df[["P_L10", "P_R10", "P_L20", "P_R20"]].to_numpy()
    assert np.abs(dp).max(axis=1).min() > 0.001


def test_settle_timeout_offers_wait_longer_and_accept(tmp_path):
    import re

    text = PROTOCOL.text
    for key, value in (
        ("window_s", "0.2"),
        ("hold_s", "0.2"),
        ("timeout_s", "1.0"),
        ("pressure_spread_MPa", "0.000001"),
    ):  # 1 Pa: never met, so every wait times out
        text, n = re.subn(rf"(?m)^{key} = .*$", f"{key} = {value}", text)
        assert n == 1
    proto = tmp_path / "strict.toml"
    proto.write_text(text)
    plan = tmp_path / "takuma2014-plan.csv"
    plan.write_text(SMALL_PLAN)
    path = tmp_path / "run.h5"
    answers = (
        "\n"
        + "a\n"
        + "\n"  # supply air, accept its timeout, close valves
        + "a\n"
        + "\n"
        + "w\n"
        + "a\n"
        + "\n"
        + "a\n"  # trial 1: baseline accepted, load waited then accepted
        + "q\n"
    )  # trial 2: quit at the baseline timeout
    result = CliRunner().invoke(
        cli,
        # a 1.0 board: the air supply's wait is the person's, as the answers above have it
        [
            "acquire",
            str(path),
            "--port",
            "sim://?seed=4&clock=virtual&fw=1.0",
            "--protocol",
            str(proto),
            "--plan",
            str(plan),
        ],
        input=answers,
    )
    assert result.exit_code == 0, result.output
    assert result.output.count("Accept these readings [a], wait longer [w] or redo the trial [r]? (w):") == 5
    assert "Not settled (load) after 1.0 s:" in result.output
    assert "Not settled (load) after 2.0 s:" in result.output
    assert "load: accepted without settling after 2.00 s" in result.output
    flat = " ".join(result.output.split())
    assert re.search(
        r"Not settled \(load\) after 2\.0 s: pressure spread \d+\.\d\d kPa \(limit 0\.001 kPa\), "
        r"angle spread \d\.\d{3} deg \(limit 0\.1 deg\), quiet for 0\.0 s of 0\.2 s",
        flat,
    )
    with RunFile.open(path) as run:
        assert run.records.ids() == [1]
        rec = run.records.read(1)
    load = rec["settle"]["load"]
    assert load["settled"] is False and load["accepted"] == "timeout"
    assert load["waited_s"] == pytest.approx(2.0, abs=0.05)
    assert load["criterion"].endswith("for 0.2 s (timed out, accepted)")
    assert rec["accepted"] == "timeout"


def test_unattended_push_run_pushes_the_six_reference_objects(tmp_path):
    path = tmp_path / "push.h5"
    result = CliRunner().invoke(
        cli,
        [
            "acquire",
            str(path),
            "--port",
            "sim://?seed=12&clock=virtual",
            "--protocol",
            "takuma2014-stiffness",
            "--unattended",
        ],
    )
    assert result.exit_code == 0, result.output
    assert f"Session complete: 60 pushes stored in {path} (60 this session, " in result.output
    with RunFile.open(path) as run:
        df = run.records.table()
    assert df["object"].tolist() == [
        n for n in ("pet-1", "pet-2", "pet-3", "can-al-1", "can-al-2", "can-steel-1") for _ in range(10)
    ]
    assert df.groupby("object")["category"].first().to_dict() == {
        "pet-1": "soft",
        "pet-2": "soft",
        "pet-3": "soft",
        "can-al-1": "medium",
        "can-al-2": "medium",
        "can-steel-1": "hard",
    }
    # A stiffer object pushed the same distance loads the arm more: compare the PET bottles' and
    # the aluminium cans' pressure changes per millimetre of push.
    dp = np.abs(
        df[["P_L1", "P_R1", "P_L2", "P_R2"]].to_numpy() - df[["P_L10", "P_R10", "P_L20", "P_R20"]].to_numpy()
    ).sum(axis=1) / (df["d_m"] * 1e3)
    per_object = dp.groupby(df["object"]).mean()
    assert per_object[["can-al-1", "can-al-2"]].min() > per_object[["pet-1", "pet-2", "pet-3"]].max()


def test_resume_accepts_the_plan_the_run_began_with_and_refuses_another(tmp_path):
    plan = tmp_path / "plan.csv"
    plan.write_text("trial,set,mass_g,direction_deg\n1,fit,500,-60\n2,fit,300,200\n3,validation,800,90\n")
    run = tmp_path / "run.h5"
    port = "sim://?seed=1&clock=virtual"
    r = CliRunner().invoke(cli, ["acquire", str(run), "--port", port, "--plan", str(plan), "--unattended"])
    assert r.exit_code == 0, r.output
    # The same plan again (200 deg written as -160 deg: the same direction) is the run's own.
    same = tmp_path / "same.csv"
    same.write_text("trial,set,mass_g,direction_deg\n1,fit,500,-60\n2,fit,300,-160\n3,validation,800,90\n")
    r = CliRunner().invoke(cli, ["acquire", str(run), "--port", port, "--plan", str(same), "--unattended", "--resume"])
    assert r.exit_code == 0, r.output
    assert f"All 3 planned trials are already stored in {run}; nothing to resume." in r.output
    other = tmp_path / "other.csv"
    other.write_text("trial,set,mass_g,direction_deg\n1,fit,500,-60\n2,fit,300,30\n3,validation,800,90\n")
    before = run.read_bytes()
    r = CliRunner().invoke(cli, ["acquire", str(run), "--port", port, "--plan", str(other), "--unattended", "--resume"])
    assert r.exit_code == 1
    assert r.output.endswith(
        f"Error: {other} is not the plan {run} began with; drop --plan to resume with the "
        "run's own plan, or start a new run for the new one.\n"
    )
    assert run.read_bytes() == before
