"""``labcli demo --protocol rpam2015`` and the rPAM branches of ``labcli fit`` / ``labcli validate`` (CliRunner)."""

from __future__ import annotations

import io
import json
from pathlib import Path

import pytest
from click.testing import CliRunner
from rich.console import Console

from labcli.cli import cli
from labcli.core.acquisition import acquire
from labcli.core.ui import UnattendedUI

SHIPPED = Path(__file__).resolve().parents[2] / "protocols" / "rpam2015.toml"
PNG = b"\x89PNG\r\n\x1a\n"


def small_protocol(folder: Path, name: str, **replace: str) -> Path:
    text = SHIPPED.read_text(encoding="utf-8")
    edits = {
        'name = "rpam2015"': f'name = "{name}"',
        "pressure_count = 20": "pressure_count = 4",
        "Pa_count = 11": "Pa_count = 3",
        "Pb_count = 11": "Pb_count = 3",
        **replace,
    }
    for old, new in edits.items():
        assert text.count(old) == 1, old
        text = text.replace(old, new)
    path = folder / f"{name}.toml"
    path.write_text(text, encoding="utf-8")
    return path


def run(path: Path, protocol: Path, experiment: str) -> Path:
    outcome = acquire(
        path,
        "sim://?mode=rpam&seed=4&clock=virtual",
        protocol=str(protocol),
        experiment=experiment,
        unattended=True,
        ui=UnattendedUI(console=Console(file=io.StringIO())),
    )
    assert outcome.status == "finished", outcome.message
    return path


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    d = tmp_path_factory.mktemp("rpam")
    proto = small_protocol(d, "rpam-small")
    return {"stretch": run(d / "stretch.h5", proto, "stretch"), "joint": run(d / "joint.h5", proto, "joint"), "dir": d}


def invoke(*args: str):
    return CliRunner().invoke(cli, [str(a) for a in args])


# --------------------------------------------------------------------------- demo


def test_demo_runs_the_rpam_chain_and_reports_it(tmp_path):
    out = tmp_path / "demo"
    result = invoke("demo", out, "--protocol", "rpam2015", "--seed", "2")
    assert result.exit_code == 0, result.output
    text = result.output
    assert text.startswith(
        "labcli demo --protocol rpam2015 on the simulated rPAM rig (seed 2): "
        "120 stretch-test points, 121 joint-map points, "
    )
    for needle in (
        "Eq. 7 stretch correction F_stretch(lambda) fitted on 120 points",
        "rig's truth (N)",
        "Joint map against the model (Fig. 8)",
        "Link optimisation (Section IV) at Pa = 96 kPa, Pb = 41 kPa with the fitted F_stretch",
        str(out / "fig8-joint-map.png"),
    ):
        assert needle in text
    s = json.loads((out / "rpam-summary.json").read_text())
    # The fit finds the simulated rig's own correction, within its uncertainty (99.9 % limit 18.5).
    assert s["stretch"]["chi2_4dof"] < 18.47 and s["stretch"]["n_points"] == 120
    jm = s["joint_map"]
    # (Near equal high pressures the joint may sit on either stop, the paper's "toggle between two
    # extreme states": a point or two there can be far off, so the balanced-points RMSE is compared
    # with the uncorrected model's, and the all-points RMSE carries the margin.)
    assert jm["with_fitted"]["rmse_deg"] < jm["without"]["rmse_deg"] and jm["without"]["rmse_deg"] > 8.0
    assert jm["with_fitted"]["rmse_all_deg"] < jm["without"]["rmse_all_deg"] / 4
    assert jm["with_fitted"]["n_toggle"] < jm["without"]["n_toggle"] - 20
    # With the fitted correction the optimiser still returns a joint that holds, clear of the
    # toggle, and the paper's design is evaluated beside it.
    o = s["optimum"]
    assert o["stiffness_Nm_per_rad"] >= o["min_stiffness_Nm_per_rad"] > 0
    assert o["toggle_deg"] - o["alpha_deg"] >= 1.0 and o["L_a_m"] <= 0.14 + 1e-12
    assert abs(o["rounded"]["alpha_deg"] - o["alpha_deg"]) <= 0.5 and o["rounded"]["feasible"]
    assert o["paper"]["L2_m"] == 0.1048 and "Link optimisation" in text and "paper's design" in text
    # Both readings of the force through the chain: the stand follows the derived force, so the
    # paper reading explains its stretch test and its joint map worse, and each optimum is its own.
    r = s["readings"]
    assert r["derived"]["optimum"]["alpha_deg"] == pytest.approx(o["alpha_deg"], abs=1e-9)
    assert r["paper"]["stretch_rmse_N"] > 3 * r["derived"]["stretch_rmse_N"]
    assert r["paper"]["joint_map_with_fitted"]["rmse_deg"] > r["derived"]["joint_map_with_fitted"]["rmse_deg"]
    assert r["paper"]["optimum"]["min_stiffness_Nm_per_rad"] == 0.2
    assert "Both readings of the actuator force (--force)" in text
    # The joint-map check on a stand of each reading (the protocol's F_stretch, which the stands
    # scale by a seeded factor): each model finds its own stand's map within 1-2 deg and misses
    # the other's by several times that (seed 2: 0.97 / 4.78 and 1.68 / 5.61 deg), so it can fail.
    by = s["joint_map_by_stand"]
    for stand, other in (("derived", "paper"), ("paper", "derived")):
        own, cross = by[stand][stand]["rmse_deg"], by[stand][other]["rmse_deg"]
        assert own < 2.5 and cross > 4.0 and cross > 2.5 * own
    assert "The joint-map check on a stand of each reading" in text
    assert (out / "joint-paper-stand.h5").is_file()
    # The lab's actuator fitted to the stretch test: the stand's (the protocol's) within 3 s.e.
    act = s["actuator"]["parameters"]
    assert act["mu_1"]["determined"] and act["radius_m"]["determined"]
    assert all(abs(r["deviation_in_se"]) < 3 for r in act.values())
    for name in ("fig6-stretch.png", "fig8-joint-map.png"):
        assert (out / name).read_bytes()[:8] == PNG
    assert (out / "joint-map.csv").read_text().splitlines()[0].startswith("point,P_A,P_B,alpha_deg,")
    again = invoke("demo", out, "--protocol", "rpam2015")
    assert again.exit_code == 1 and again.output == (
        f"Error: {out} already holds rPAM demo output (stretch.h5, stretch.model.json, fig6-stretch.png, ...); "
        "pass --force to overwrite it or choose another directory.\n"
    )


def test_demo_refuses_an_unknown_protocol(tmp_path):
    result = invoke("demo", tmp_path, "--protocol", "rpam2016")
    assert result.exit_code == 2 and "'rpam2016' is not one of 'takuma2014', 'rpam2015'" in result.output


# --------------------------------------------------------------------------- fit / validate


def test_fit_prints_the_cubic_with_units_and_records_it(runs):
    result = invoke("fit", runs["stretch"])
    assert result.exit_code == 0, result.output
    model = runs["dir"] / "stretch.model.json"
    assert "c3" in result.output and "24 points (20 degrees of freedom)" in result.output
    assert result.output.rstrip().endswith(
        f"Model written to {model} and recorded in {runs['stretch']} under /models/rpam-small-stretch; "
        f"compare a joint map with it: labcli validate JOINT.h5 --model {model}"
    )
    assert json.loads(model.read_text())["kind"] == "rpam-stretch-fit"


def test_validate_without_a_stretch_model_uses_the_protocols_own(runs):
    result = invoke("validate", runs["joint"])
    assert result.exit_code == 0, result.output
    assert (
        "F_stretch coefficients c0..c3 = [+8, -14, +4, +2] N, from the protocol's [stretch_correction] "
        "(no --model given)." in result.output
    )


def test_validate_needs_a_stretch_model_when_the_protocol_has_none(tmp_path):
    proto = small_protocol(
        tmp_path, "rpam-nocorr", **{"coefficients_N = [8.0, -14.0, 4.0, 2.0]": "coefficients_N = [0.0, 0.0, 0.0, 0.0]"}
    )
    joint = run(tmp_path / "joint.h5", proto, "joint")
    result = invoke("validate", joint)
    assert result.exit_code == 1 and result.output == (
        f"Error: {joint}'s protocol has no stretch correction (its coefficients are all 0 N), so the model with "
        "and without it would agree; fit one to a stretch-test run with labcli fit STRETCH.h5 and pass it with "
        "--model STRETCH.model.json.\n"
    )


def _takuma_model(tmp_path: Path) -> Path:
    p = tmp_path / "takuma.model.json"
    p.write_text(json.dumps({"kind": "takuma2014-regression", "coefficients": {}}))
    return p


@pytest.mark.parametrize(
    "args, message",
    [
        (
            lambda r, t: ["fit", r["joint"]],
            lambda r, t: (
                f"{r['joint']} is a joint-map run (kind rpam-joint); labcli fit fits the stretch correction to a "
                "stretch-test run (labcli acquire --experiment stretch), and labcli validate compares a joint map "
                "with the model."
            ),
        ),
        (
            lambda r, t: ["validate", r["stretch"]],
            lambda r, t: (
                f"{r['stretch']} is a stretch-test run (kind rpam-stretch); labcli validate compares a joint-map "
                f"run with the model: fit this one with labcli fit {r['stretch']} and pass the model it writes to "
                "labcli validate JOINT.h5 --model."
            ),
        ),
        (
            lambda r, t: ["validate", r["joint"], "--model", t / "none.json"],
            lambda r, t: (
                f"Model file {t / 'none.json'} does not exist; fit the stretch test first with labcli fit "
                "STRETCH.h5, which writes STRETCH.model.json."
            ),
        ),
        (
            lambda r, t: ["validate", r["joint"], "--model", _takuma_model(t)],
            lambda r, t: (
                f"Model file {t / 'takuma.model.json'} is not a stretch fit (kind 'takuma2014-regression'); a "
                "joint map is compared with the stretch correction labcli fit writes for a stretch-test run."
            ),
        ),
        (
            lambda r, t: ["validate", r["joint"], "--mode", "measured-angles"],
            lambda r, t: (
                f"--mode is an option of takuma2014 runs; {r['joint']} is a run of kind rpam-joint (rpam2015)."
            ),
        ),
        (
            lambda r, t: ["fit", r["stretch"], "--max-amplification", "50"],
            lambda r, t: (
                f"--max-amplification is an option of takuma2014 runs; {r['stretch']} is a run of kind "
                "rpam-stretch (rpam2015)."
            ),
        ),
        (
            lambda r, t: ["fit", r["stretch"], "--protocol", "rpam2015"],
            lambda r, t: (
                f"{r['stretch']} was recorded with protocol 'rpam-small'; --protocol applies to trial CSV "
                "files only, so leave it out for a run file."
            ),
        ),
        (
            lambda r, t: ["fit", r["stretch"], "--plot", t / "fig.jpg"],
            lambda r, t: f"The plot file {t / 'fig.jpg'} must end in .png, .pdf or .svg.",
        ),
    ],
)
def test_rpam_fit_and_validate_errors(runs, tmp_path, args, message):
    result = invoke(*args(runs, tmp_path))
    assert result.exit_code == 1 and result.output == f"Error: {message(runs, tmp_path)}\n"


def test_plot_on_a_force_table_is_refused_in_the_core_sentence(tmp_path):
    csv = tmp_path / "t.csv"
    csv.write_text("trial,set\n")
    result = invoke("fit", csv, "--plot", tmp_path / "f.png")
    # The core's one sentence for an option another paper declares (not a per-paper refusal).
    assert result.output == f"Error: --plot is an option of rpam2015 runs; labcli fit reads {csv} with takuma2014.\n"


# --------------------------------------------------------------------------- --set on an analysis


def test_set_changes_the_model_for_this_analysis_only(runs):
    base = json.loads(invoke("validate", runs["joint"], "--json").output)
    before = runs["joint"].read_bytes()
    # A wall twice as thick makes the actuators stiffer: the model's angles change, the
    # measured ones do not, and the run file keeps its own protocol.
    thick = invoke("validate", runs["joint"], "--json", "--set", "actuator.A0_m2=4.147e-4")
    assert thick.exit_code == 0, thick.output
    changed = json.loads(thick.output)
    assert changed["summary"]["with"]["rmse_all_deg"] != pytest.approx(base["summary"]["with"]["rmse_all_deg"])
    assert runs["joint"].read_bytes() == before
    again = json.loads(invoke("validate", runs["joint"], "--json").output)
    assert again["summary"] == base["summary"]


def test_set_with_an_unknown_key_names_the_choices(runs):
    result = invoke("fit", runs["stretch"], "--set", "actuator.L0_mm=0.08")
    assert result.exit_code == 1
    assert result.output == (
        "Error: Unknown protocol key 'actuator.L0_mm' in --set; keys under actuator: "
        "A0_m2, L0_m, force_reading, n_turns, prestretch, thread_length_m.\n"
    )


def test_set_is_refused_on_a_force_run(tmp_path):
    from labcli.papers.takuma2014.models.synthetic import paper_trials
    from labcli.papers.takuma2014.tables import write_trial_csv

    csv = tmp_path / "trials.csv"
    write_trial_csv(paper_trials(20, noise=False), csv)
    for cmd in ("fit", "validate"):
        result = invoke(cmd, csv, "--set", "actuator.L0_m=0.08")
        assert result.exit_code == 1
        assert (
            result.output == f"Error: --set is an option of rpam2015 runs; labcli {cmd} reads {csv} with takuma2014.\n"
        )


@pytest.mark.parametrize("args", [("fit", "stretch"), ("validate", "joint")])
def test_rpam_reports_stay_whole_and_plain_at_80_columns(runs, args, tmp_path):
    import re
    import shutil

    run = tmp_path / runs[args[1]].name
    shutil.copy(runs[args[1]], run)  # fit records its model: work on a copy
    result = CliRunner(env={"COLUMNS": "80"}).invoke(cli, [args[0], str(run)])
    assert result.exit_code == 0, result.output
    assert not re.search("[\u2500-\u257f]", result.output), "box drawing in piped output"
    assert not re.search(r"[0-9.+\-]\u2026", result.output), "a number cut short"


# --------------------------------------------------------------------------- --force (the reading of the actuator force)


def test_force_reading_is_chosen_recorded_and_kept_with_its_fit(runs, tmp_path):
    paper_model = tmp_path / "stretch-paper.model.json"
    fitted = invoke("fit", runs["stretch"], "--force", "paper", "-o", paper_model)
    assert fitted.exit_code == 0, fitted.output
    d = json.loads(paper_model.read_text())
    assert d["force_reading"] == "paper"
    # The correction is what the reading leaves unexplained: under the paper reading it differs.
    derived_model = tmp_path / "stretch-derived.model.json"
    assert invoke("fit", runs["stretch"], "-o", derived_model).exit_code == 0
    dd = json.loads(derived_model.read_text())
    assert dd["force_reading"] == "derived"
    assert d["model"]["coefficients_N"] != pytest.approx(dd["model"]["coefficients_N"], abs=0.1)
    # validate follows the fit's reading, and records it.
    v = invoke("validate", runs["joint"], "--model", paper_model, "--json")
    assert v.exit_code == 0, v.output
    vd = json.loads(v.output)
    assert vd["force_reading"] == "paper" and vd["actuator"]["force_reading"] == "paper"
    plain = json.loads(invoke("validate", runs["joint"], "--json").output)
    assert plain["force_reading"] == "derived"
    assert (
        json.loads(invoke("validate", runs["joint"], "--json", "--force", "paper").output)["force_reading"] == "paper"
    )
    # A fit made under one reading is not compared under the other.
    wrong = invoke("validate", runs["joint"], "--model", paper_model, "--force", "derived")
    assert wrong.exit_code == 1 and wrong.output == (
        "Error: The stretch fit was made with the paper force reading, so its correction belongs to it; "
        "compare with --force paper, or fit the stretch test again with --force derived.\n"
    )


def test_force_is_refused_on_a_force_run_and_checked_on_an_rpam_run(runs, tmp_path):
    from labcli.papers.takuma2014.models.synthetic import paper_trials
    from labcli.papers.takuma2014.tables import write_trial_csv

    csv = tmp_path / "trials.csv"
    write_trial_csv(paper_trials(20, noise=False), csv)
    for cmd in ("fit", "validate"):
        result = invoke(cmd, csv, "--force", "paper")
        assert result.exit_code == 1
        # The core's one sentence for another paper's option (no per-paper refusal tables).
        assert (
            result.output
            == f"Error: --force is an option of rpam2015 runs; labcli {cmd} reads {csv} with takuma2014.\n"
        )
    from labcli.papers.rpam2015.actuator import FORCE_READINGS
    from labcli.papers.rpam2015.options import FORCE_READINGS as DECLARED

    assert DECLARED == FORCE_READINGS  # the declaration imports nothing heavy, so it repeats them
    bad = invoke("fit", runs["stretch"], "--force", "printed")
    assert bad.exit_code == 2 and "'printed' is not one of 'derived', 'paper'" in bad.output
