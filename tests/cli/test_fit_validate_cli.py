"""``labcli fit`` and ``labcli validate`` on trial CSVs and run files (CliRunner)."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from click.testing import CliRunner

from labcli.cli import cli
from labcli.papers.takuma2014.models.synthetic import paper_trials
from labcli.papers.takuma2014.models.takuma import COEFFICIENT_NAMES, PAPER_COEFFICIENTS
from labcli.papers.takuma2014.tables import write_trial_csv


@pytest.fixture(scope="module")
def table() -> pd.DataFrame:
    fit = paper_trials(90, seed=1)
    val = paper_trials(18, seed=2, set_name="validation", start_id=91)
    near = paper_trials(2, seed=3, set_name="validation", start_id=109, theta2_values_deg=[0.6, -1.2])
    near_fit = paper_trials(1, seed=4, set_name="fit", start_id=111, theta2_values_deg=[1.0])
    return pd.concat([fit, val, near, near_fit], ignore_index=True)


@pytest.fixture()
def csv(tmp_path: Path, table: pd.DataFrame) -> Path:
    p = tmp_path / "trials.csv"
    write_trial_csv(table, p)
    return p


def run(*args: str):
    return CliRunner().invoke(cli, [str(a) for a in args])


def test_fit_prints_coefficients_beside_the_paper_and_writes_the_model(csv: Path) -> None:
    r = run("fit", csv, "--form", "paper")
    assert r.exit_code == 0, r.output
    out = r.output
    assert "Eq. 34  sin(theta1)" in out and "Eq. 37  Fy" in out and "paper 3.3" in out
    # the paper's values are printed in the paper column, beta_theta2_R2 as listed (-2.972)
    for value in ("-2201.03", "-642.995", "-2.972", "-75.906"):
        assert value in out
    assert "beta_theta2R2 = -2.972 as listed" in out
    assert "trial 111: singular Jacobian: |theta2| = 1.00 deg, Fy amplification 28" in out
    assert "coefficients in N m/MPa" in out and " deg;" in out
    model = json.loads((csv.parent / "trials.model.json").read_text())
    assert model["schema"] == "labcli-takuma-model" and model["protocol"] == "takuma2014"
    assert model["geometry"] == {"h1": 0.355, "h2": 0.13, "h3": 0.065, "r1": 0.075, "r2": 0.035}
    for name in COEFFICIENT_NAMES:
        se = model["standard_errors"][name]
        assert abs(model["coefficients"][name] - PAPER_COEFFICIENTS[name]) < 5 * se, name
    assert model["fit_stats"]["Fy"]["n"] == 90 and model["fit_stats"]["Fx"]["n"] == 91


def test_fit_json_output(csv: Path, tmp_path: Path) -> None:
    out_path = tmp_path / "m.json"
    r = run("fit", csv, "--form", "paper", "-o", out_path, "--json")
    assert r.exit_code == 0, r.output
    d = json.loads(r.output)
    assert d["model_path"] == str(out_path) and d["recorded_in_run"] is False
    assert d["paper_coefficients"]["beta_theta2_R2"] == -2.972
    assert d["model"] == json.loads(out_path.read_text())
    assert d["model"]["excluded_trials"]["Fy"][0]["trial"] == 111


def test_validate_reports_metrics_flags_and_figure(csv: Path, tmp_path: Path) -> None:
    assert run("fit", csv, "--form", "paper").exit_code == 0
    png = tmp_path / "fig7.png"
    r = run("validate", csv, "--plot", png)
    assert r.exit_code == 0, r.output
    assert "pressure-only" in r.output and "theta1 (deg)" in r.output and "Fy (N)" in r.output
    assert ("trial 109: Fy = — (theta2 too close to 0 for this force component (Jacobian near singular))") in r.output
    assert f"Figure 7 written to {png}." in r.output
    assert png.read_bytes()[:4] == b"\x89PNG"
    for line in r.output.splitlines():
        assert "nan" not in line.lower().split() and "inf" not in line.lower().split()


@pytest.mark.parametrize("mode", ["pressure-only", "measured-angles"])
def test_validate_json(csv: Path, table: pd.DataFrame, mode: str) -> None:
    assert run("fit", csv, "--form", "paper").exit_code == 0
    r = run("validate", csv, "--mode", mode, "--json")
    assert r.exit_code == 0, r.output
    d = json.loads(r.output)
    assert d["mode"] == mode and d["units"] == {"theta1": "deg", "theta2": "deg", "Fx": "N", "Fy": "N"}
    assert [t["trial"] for t in d["trials"]] == list(range(91, 111))
    m = d["metrics"]
    assert m["Fy"]["n"] == 18 and m["Fy"]["n_flagged"] == 2 and m["theta2"]["n"] == 20
    assert m["Fx"]["n"] == 20 and m["Fx"]["n_flagged"] == 0
    # 12-bit rounding: angles to a tenth of a degree, forces to about a newton
    assert m["theta1"]["rmse"] < 0.1 and m["theta2"]["rmse"] < 0.2
    assert m["Fx"]["rmse"] < 1.5 and m["Fy"]["rmse"] < 1.5
    rows = {t["trial"]: t for t in d["trials"]}
    assert rows[109]["calculated"]["Fy"] is None and rows[109]["flags"][0]["flag"] == "singular-jacobian"
    assert rows[109]["calculated"]["Fx"] is not None
    obs = table.set_index("trial")
    assert rows[95]["observed"]["Fy"] == obs.loc[95, "Fy_N"]
    errs = [t["calculated"]["theta1"] - t["observed"]["theta1"] for t in d["trials"]]
    assert math.sqrt(np.mean(np.square(errs))) == pytest.approx(m["theta1"]["rmse"], rel=1e-12)


def test_fit_and_validate_on_a_run_file_record_the_model(tmp_path: Path, table: pd.DataFrame) -> None:
    from labcli.core.protocol import load_protocol
    from labcli.core.store import RunFile

    path = tmp_path / "run.h5"
    with RunFile.create(path, protocol=load_protocol("takuma2014"), operator="test") as rf:
        for _, r in table.iterrows():
            rf.records.write(
                {
                    "trial": int(r.trial),
                    "P0_MPa": r[["P_L10", "P_R10", "P_L20", "P_R20"]].to_numpy(float),
                    "P_MPa": r[["P_L1", "P_R1", "P_L2", "P_R2"]].to_numpy(float),
                    "theta_rad": np.radians(r[["theta1_deg", "theta2_deg"]].to_numpy(float)),
                    "force_N": r[["Fx_N", "Fy_N"]].to_numpy(float),
                }
            )
        rf.split.set(table.trial[table.set == "fit"], table.trial[table.set == "validation"])
    r = run("fit", path, "--form", "paper")
    assert r.exit_code == 0, r.output
    assert f"recorded in {path} under /models/takuma2014" in r.output
    saved = (tmp_path / "run.model.json").read_text()
    with RunFile.open(path) as rf:
        assert rf.models.all()["takuma2014"] == saved
    r = run("validate", path, "--json")
    assert r.exit_code == 0, r.output
    assert json.loads(r.output)["metrics"]["theta1"]["n"] == 20
    r = run("fit", path, "--form", "paper", "--protocol", "other")
    assert r.exit_code == 1
    assert r.output == (
        f"Error: {path} was recorded with protocol 'takuma2014'; --protocol applies to "
        "trial CSV files only, so leave it out for a run file.\n"
    )


# ----------------------------------------------------------------------------- errors


def test_validate_without_a_model_file(csv: Path) -> None:
    r = run("validate", csv)
    assert r.exit_code == 1
    assert r.output == (
        f"Error: The model file {csv.parent / 'trials.model.json'} does not exist; write one with `labcli fit`.\n"
    )


def test_validate_with_a_model_of_another_protocol(csv: Path, tmp_path: Path) -> None:
    assert run("fit", csv, "--form", "paper").exit_code == 0
    mpath = csv.parent / "trials.model.json"
    d = json.loads(mpath.read_text())
    d["protocol"] = "rig-b"
    other = tmp_path / "other.json"
    other.write_text(json.dumps(d))
    r = run("validate", csv, "--model", other)
    assert r.exit_code == 1
    assert r.output == (
        f"Error: The model file {other} was fitted for protocol 'rig-b' but {csv} uses "
        "protocol 'takuma2014'; fit a model on a run of this protocol.\n"
    )


def test_validate_with_no_validation_trials(tmp_path: Path, table: pd.DataFrame) -> None:
    p = tmp_path / "fitonly.csv"
    write_trial_csv(table[table.set == "fit"], p)
    assert run("fit", p, "--form", "paper").exit_code == 0
    r = run("validate", p)
    assert r.exit_code == 1
    assert r.output == (
        f"Error: {p} has no validation trials (no row with set = 'validation'); assign "
        "trials with `labcli split` (or fill the `set` column).\n"
    )


def test_fit_with_too_few_trials(tmp_path: Path, table: pd.DataFrame) -> None:
    p = tmp_path / "few.csv"
    write_trial_csv(table.head(5), p)
    r = run("fit", p, "--form", "paper")
    assert r.exit_code == 1
    assert r.output == (
        f"Error: The Fx equation needs at least 7 usable fit trials for its 6 "
        f"coefficients, but {p} has 5; record more fit trials.\n"
    )


def test_bad_plot_extension_and_missing_run(csv: Path, tmp_path: Path) -> None:
    assert run("fit", csv, "--form", "paper").exit_code == 0
    r = run("validate", csv, "--plot", tmp_path / "fig.jpg")
    assert r.exit_code == 1
    assert r.output == f"Error: The plot file {tmp_path / 'fig.jpg'} must end in .png, .pdf or .svg.\n"
    r = run("fit", tmp_path / "nothing.csv", "--form", "paper")
    assert r.exit_code == 1
    assert r.output == (f"Error: {tmp_path / 'nothing.csv'} does not exist; pass a run file (.h5) or a trial CSV.\n")
