"""rPAM acquisition: the stretch test and the joint map run unattended on ``sim://?mode=rpam``.

The runs go through the same engine, run file and commands as a real rig; the simulated
rig's truth (its true stretch correction, its posture at each capture) is the yardstick.
"""

from __future__ import annotations

import io
import json
import math
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from rich.console import Console
from scipy import stats

from labcli.cli import cli
from labcli.core.acquisition import acquire
from labcli.core.protocol import load_protocol
from labcli.core.store import RunFile
from labcli.core.ui import UnattendedUI
from labcli.errors import ConfigError, StoreError
from labcli.papers.rpam2015.session import acquisition_protocol, rpam_session
from labcli.papers.rpam2015.sim.rig import RpamRig
from labcli.papers.takuma2014.session import Baseline, Capture, Prompt

SHIPPED = Path(__file__).resolve().parents[3] / "protocols" / "rpam2015.toml"
CHI2_999 = float(stats.chi2.ppf(0.999, 4))
# Sensor noise per sample, rms (labcli.papers.rpam2015.sim.rig): 0.7 count of 0.0733 mm, 0.7 count of 0.083 deg.
LEN_NOISE_M = 0.7 * 0.300 / 4095
POT_NOISE_DEG = 0.7 * 340 / 4095


def quiet_ui() -> UnattendedUI:
    return UnattendedUI(console=Console(file=io.StringIO(), width=200))


def small_protocol(tmp_path: Path, *, name: str = "rpam-small", **replace: str) -> Path:
    """The shipped protocol with 3 pressures per payload and a 3 x 3 joint map (plus edits)."""
    text = SHIPPED.read_text(encoding="utf-8")
    edits = {
        'name = "rpam2015"': f'name = "{name}"',
        "pressure_count = 20": "pressure_count = 3",
        "Pa_count = 11": "Pa_count = 3",
        "Pb_count = 11": "Pb_count = 3",
        **replace,
    }
    for old, new in edits.items():
        assert text.count(old) == 1, old
        text = text.replace(old, new)
    path = tmp_path / f"{name}.toml"
    path.write_text(text, encoding="utf-8")
    return path


class Recorder:
    """Every prompt's text and the rig's truth at each baseline and capture."""

    def __init__(self) -> None:
        self.prompts: list[str] = []
        self.rig = None
        self.baselines: list[dict] = []
        self.captures: list[dict] = []

    def __call__(self, step, reply) -> None:
        if isinstance(step, Prompt):
            self.prompts.append(step.text)
        elif isinstance(step, Baseline):
            self.baselines.append(self.rig.true_state())
        elif isinstance(step, Capture):
            self.captures.append(self.rig.true_state())


def run_experiment(path: Path, experiment: str, seed: int, protocol: str = "rpam2015") -> Recorder:
    rec = Recorder()
    import labcli.core.device as device

    original = device.Device.__dict__["open"]
    opened = device.Device.open

    def grab(*a, **k):  # the rig behind the port, for its truth
        dev = opened(*a, **k)
        rec.rig = dev.rig
        return dev

    device.Device.open = staticmethod(grab)
    try:
        outcome = acquire(
            path,
            f"sim://?mode=rpam&seed={seed}&clock=virtual",
            protocol=protocol,
            experiment=experiment,
            unattended=True,
            ui=quiet_ui(),
            subscribers=(rec,),
        )
    finally:
        device.Device.open = original
    assert outcome.status == "finished", outcome.message
    return rec


@pytest.fixture(scope="module")
def stretch_run(tmp_path_factory):
    path = tmp_path_factory.mktemp("stretch") / "stretch.h5"
    return path, run_experiment(path, "stretch", seed=3)


@pytest.fixture(scope="module")
def joint_run(tmp_path_factory):
    path = tmp_path_factory.mktemp("joint") / "joint.h5"
    return path, run_experiment(path, "joint", seed=3)


# --------------------------------------------------------------------------- stretch test


def test_stretch_points_are_what_the_rig_did(stretch_run):
    path, rec = stretch_run
    with RunFile.open(path) as run:
        assert run.kind == "rpam-stretch" and run.attrs["device"] == "rpam-joint-sim"
        table = run.records.table()
        summary = run.summary()
    assert list(table.columns[:6]) == ["point", "mass_g", "P_A", "P_B", "L_m", "lambda"]
    assert table["point"].tolist() == list(range(1, 121)) and summary["records"] == "points"
    # The prompts, as a person at the stand reads them: payload x pressure, grams and kPa.
    assert rec.prompts[0].startswith("Take actuator A off the joint and hang it on the stretch stand")
    assert (
        "Point 7/120 (stretch): leave actuator A without a payload, set P_A = 60 kPa, then press Enter" in rec.prompts
    )
    assert "Point 27/120 (stretch): hang 100 g on actuator A, set P_A = 60 kPa, then press Enter" in rec.prompts
    assert rec.prompts[-1] == "Take the payload off actuator A and vent it, then press Enter"
    truth_L = np.array([s["length_m"] for s in rec.captures])
    truth_p = np.array([s["pressures_MPa"][0] for s in rec.captures])
    np.testing.assert_array_equal(table["mass_g"], [s["payload_kg"] * 1e3 for s in rec.captures])
    np.testing.assert_array_equal(table["set_mass_g"], table["mass_g"])
    # A 0.5 s capture averages 50 samples: a tenth of a count of the draw wire, of the sensor.
    assert np.max(np.abs(table["L_m"] - truth_L)) < 6 * LEN_NOISE_M / math.sqrt(50) + 0.5 * 0.3 / 4095
    assert np.max(np.abs(table["P_A"] - truth_p)) < 0.5e-3
    np.testing.assert_allclose(table["lambda"], table["L_m"] / 0.07, rtol=1e-12)
    # Settled from the data: every point is read within a few lag constants, none timed out.
    assert summary["settle"]["timeout_accepted"] == 0 and summary["settle"]["max_s"] < 10.0


def test_labcli_fit_recovers_the_rigs_true_correction(stretch_run, tmp_path):
    path, rec = stretch_run
    plot = tmp_path / "fig6.png"
    result = CliRunner().invoke(
        cli, ["fit", str(path), "-o", str(tmp_path / "s.json"), "--plot", str(plot), "--json", "--record"]
    )
    assert result.exit_code == 0, result.output
    out = json.loads(result.output)
    m = out["fit"]["model"]
    truth = np.asarray(rec.rig.true_stretch_coefficients_N["A"])
    assert np.allclose(truth, RpamRig(seed=3).true_stretch_coefficients_N["A"])
    d = np.asarray(m["coefficients_N"]) - truth
    # The truth lies inside the fit's joint 99.9 % region; the protocol's default does not.
    assert d @ np.linalg.solve(np.asarray(m["covariance_N2"]), d) < CHI2_999
    default = np.asarray(m["coefficients_N"]) - np.asarray(out["fit"]["default_coefficients_N"])
    assert default @ np.linalg.solve(np.asarray(m["covariance_N2"]), default) > 100 * CHI2_999
    assert m["n_points"] == 120 and m["r2"] > 0.999
    assert plot.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    with RunFile.open(path) as run:
        assert json.loads(run.models.all()["rpam2015-stretch"]) == json.loads((tmp_path / "s.json").read_text())


# --------------------------------------------------------------------------- joint map


def test_joint_points_are_deflections_from_the_vented_baseline(joint_run):
    path, rec = joint_run
    with RunFile.open(path) as run:
        table = run.records.table()
    assert len(table) == 121 and list(table.columns[:4]) == ["point", "P_A", "P_B", "alpha_deg"]
    assert "Point 12/121 (joint map): set P_A = 50.7 kPa and P_B = 41 kPa, then press Enter" in rec.prompts
    assert (
        "Point 12/121 (joint map): vent both actuators (P_A = P_B = 0 kPa) for the baseline, then press Enter"
        in rec.prompts
    )
    base = np.array([s["alpha_rad"] for s in rec.baselines])
    cap = np.array([s["alpha_rad"] for s in rec.captures])
    # The potentiometer's offset (0.5 deg rms) cancels: what is stored is the true deflection.
    err = table["alpha_deg"] - np.degrees(cap - base)
    assert np.max(np.abs(err)) < 6 * POT_NOISE_DEG * math.sqrt(2 / 50) + 0.1
    assert abs(math.degrees(rec.rig.pot_offset_rad)) > 0.05
    np.testing.assert_allclose(table["P_A0"], 0.0, atol=1e-3)
    np.testing.assert_allclose(
        table[["P_A", "P_B"]].to_numpy(), table[["set_P_A_kPa", "set_P_B_kPa"]].to_numpy() * 1e-3, atol=1e-3
    )


def test_labcli_validate_with_the_fitted_correction_beats_the_model_without(stretch_run, joint_run, tmp_path):
    model = tmp_path / "stretch.model.json"
    runner = CliRunner()
    assert runner.invoke(cli, ["fit", str(stretch_run[0]), "-o", str(model)]).exit_code == 0
    fig = tmp_path / "fig8.png"
    result = runner.invoke(cli, ["validate", str(joint_run[0]), "--model", str(model), "--plot", str(fig), "--json"])
    assert result.exit_code == 0, result.output
    s = json.loads(result.output)["summary"]
    assert json.loads(result.output)["correction"]["source"] == "fit"
    assert s["with"]["rmse_deg"] < 3.0 < 8.0 < s["without"]["rmse_deg"]
    assert s["with"]["rmse_all_deg"] < s["without"]["rmse_all_deg"] / 4
    assert s["with"]["max_abs_error_deg"] < s["without"]["max_abs_error_deg"]
    assert fig.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and fig.stat().st_size > 50_000
    text = runner.invoke(cli, ["validate", str(joint_run[0]), "--model", str(model)]).output
    assert f"from the stretch fit in {model}." in text and "Figure 8" not in text


# --------------------------------------------------------------------------- resume, errors, settling


def test_an_interrupted_joint_map_resumes_where_it_stopped(tmp_path):
    proto = small_protocol(tmp_path)
    path = tmp_path / "joint.h5"
    port = "sim://?mode=rpam&seed=5&clock=virtual"
    captures = []

    def interrupt_in_point_5(step, reply):
        if isinstance(step, Capture):
            captures.append(1)
            if len(captures) == 5:
                raise KeyboardInterrupt

    outcome = acquire(
        path,
        port,
        protocol=str(proto),
        experiment="joint",
        unattended=True,
        ui=quiet_ui(),
        subscribers=(interrupt_in_point_5,),
    )
    assert outcome.status == "interrupted" and outcome.exit_code == 130
    assert outcome.message == (
        f"Interrupted during point 5, which was discarded; 4 points stored in {path} are safe. "
        f"Resume with: labcli acquire {path} --port '{port}' --resume --unattended"
    )
    runner = CliRunner()
    result = runner.invoke(cli, ["acquire", str(path), "--port", port, "--resume", "--unattended"])
    assert result.exit_code == 0, result.output
    assert result.output.endswith(
        f"Session complete: 9 points stored in {path} (5 this session, " + result.output.rsplit("this session, ", 1)[1]
    )
    with RunFile.open(path) as run:
        assert run.records.ids() == list(range(1, 10)) and run.records.incomplete_ids() == []
        table = run.records.table()
    assert table["set_P_A_kPa"].tolist() == [41.0] * 3 + [89.5] * 3 + [138.0] * 3
    again = runner.invoke(cli, ["acquire", str(path), "--port", port, "--resume"])
    assert again.output == f"All 9 points of the joint map are already stored in {path}; nothing to resume.\n"
    other = runner.invoke(cli, ["acquire", str(path), "--port", port, "--resume", "--experiment", "stretch"])
    assert other.output == (
        f"Error: {path} records the joint experiment, not stretch; drop --experiment to resume it.\n"
    )


@pytest.mark.parametrize(
    "args, message",
    [
        (
            [],
            "Protocol rpam2015 holds two experiments: choose one with --experiment stretch (the stretch test, "
            "Figs. 5-6) or --experiment joint (the joint map, Fig. 8).",
        ),
        (
            ["--experiment", "stretch", "--plan", "plan.csv"],
            "--plan and --no-plan apply to force protocols; an rPAM experiment runs the grid of its protocol's "
            "[experiments] table.",
        ),
    ],
)
def test_acquire_rpam_errors(tmp_path, args, message):
    result = CliRunner().invoke(
        cli,
        [
            "acquire",
            str(tmp_path / "r.h5"),
            "--protocol",
            "rpam2015",
            "--port",
            "sim://?mode=rpam&clock=virtual",
            "--unattended",
            *args,
        ],
    )
    assert result.exit_code == 1 and result.output == f"Error: {message}\n"
    assert not (tmp_path / "r.h5").exists()


def test_experiment_with_a_force_protocol_is_refused(tmp_path):
    result = CliRunner().invoke(
        cli,
        ["acquire", str(tmp_path / "r.h5"), "--experiment", "joint", "--port", "sim://?clock=virtual", "--unattended"],
    )
    assert result.output == (
        "Error: --experiment picks one experiment of an rPAM protocol; takuma2014 is of kind "
        "'force', so leave --experiment out.\n"
    )


def test_the_mckibben_rig_fails_the_rpam_setup_check(tmp_path):
    result = CliRunner().invoke(
        cli,
        [
            "acquire",
            str(tmp_path / "r.h5"),
            "--protocol",
            "rpam2015",
            "--experiment",
            "joint",
            "--port",
            "sim://?clock=virtual",
            "--unattended",
        ],
    )
    assert result.output == (
        "Error: The device on sim://?clock=virtual is 'mckibben-2dof-sim', but protocol rpam2015 is for "
        "'rpam-joint': connect that rig, or pass the matching --protocol.\n"
    )
    assert not (tmp_path / "r.h5").exists()


def test_the_length_is_judged_for_settling(tmp_path):
    # A length limit below the draw wire's own noise can never be met: every point times out.
    proto = small_protocol(
        tmp_path,
        name="rpam-strict",
        **{"settle_spread_mm = 0.15": "settle_spread_mm = 0.001", "timeout_s = 30.0": "timeout_s = 12.0"},
    )
    path = tmp_path / "s.h5"
    outcome = acquire(
        path,
        "sim://?mode=rpam&seed=2&clock=virtual",
        protocol=str(proto),
        experiment="stretch",
        unattended=True,
        ui=quiet_ui(),
    )
    assert outcome.status == "finished"
    with RunFile.open(path) as run:
        s = run.summary()["settle"]
    assert s["timeout_accepted"] == 18 == s["n"]
    # The same protocol with the shipped limit settles every point from the data.
    loose = small_protocol(tmp_path, name="rpam-loose", **{"timeout_s = 30.0": "timeout_s = 12.0"})
    acquire(
        tmp_path / "l.h5",
        "sim://?mode=rpam&seed=2&clock=virtual",
        protocol=str(loose),
        experiment="stretch",
        unattended=True,
        ui=quiet_ui(),
    )
    with RunFile.open(tmp_path / "l.h5") as run:
        assert run.summary()["settle"]["timeout_accepted"] == 0


def test_session_steps_without_a_rig():
    proto = acquisition_protocol(load_protocol("rpam2015"), "joint")
    assert proto.kind == "rpam-joint" and len(proto.settings.points) == 121
    assert proto.settling.length_spread_m == pytest.approx(1.5e-4)
    assert proto.calibration.units == ("MPa", "MPa", "rad", "m") and proto.device.matches("rpam-joint-sim")
    gen = rpam_session(proto, completed=range(1, 121))
    steps = [next(gen), gen.send(None), gen.send(None)]
    assert [type(s).__name__ for s in steps] == ["SetupCheck", "Prompt", "BeginTrial"]
    assert steps[2].label == "Point 121/121 (joint map)" and steps[2].index == 121
    with pytest.raises(ConfigError, match="must be stretch or joint, not 'both'"):
        acquisition_protocol(load_protocol("rpam2015"), "both")


def test_store_refuses_points_of_the_other_experiment(tmp_path):
    proto = acquisition_protocol(load_protocol("rpam2015"), "stretch")
    with RunFile.create(tmp_path / "s.h5", protocol=proto) as run:
        with pytest.raises(StoreError) as e:
            run.records.write({"point": 1, "experiment": "joint", "P_MPa": [0.1, 0.0], "alpha_rad": 0.1})
        assert str(e.value) == f"point 1: a joint point cannot go into {tmp_path / 's.h5'}, a rpam-stretch run."
        with pytest.raises(StoreError) as e:
            run.records.write({"point": 1, "experiment": "stretch", "P_MPa": [0.1, 0.0], "mass_kg": 0.1, "L_m": 0.1})
        assert str(e.value) == "point 1 record lacks a finite 'lambda', which a stretch point needs."
        run.records.write(
            {
                "point": 2,
                "experiment": "stretch",
                "P_MPa": [0.1, 0.0],
                "mass_kg": 0.25,
                "L_m": 0.1,
                "lambda": 0.1 / 0.07,
                "plan": {"mass_g": 250.0, "P_A_kPa": 100.0},
            }
        )
        t = run.records.table()
        assert run.records.ids() == [2]
    assert t.to_dict("records") == [
        {
            "point": 2,
            "mass_g": 250.0,
            "P_A": 0.1,
            "P_B": 0.0,
            "L_m": 0.1,
            "lambda": 0.1 / 0.07,
            "set_mass_g": 250.0,
            "set_P_A_kPa": 100.0,
        }
    ]
