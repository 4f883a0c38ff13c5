"""``labcli fit --form`` and the two forms side by side in ``labcli validate`` (CliRunner)."""

from __future__ import annotations

import json
from pathlib import Path

import pandas as pd
import pytest
from click.testing import CliRunner

from labcli.cli import cli
from labcli.papers.takuma2014.models.synthetic import paper_trials
from labcli.papers.takuma2014.tables import write_trial_csv


@pytest.fixture()
def csv(tmp_path: Path) -> Path:
    table = pd.concat(
        [paper_trials(90, seed=1), paper_trials(18, seed=2, set_name="validation", start_id=91)], ignore_index=True
    )
    p = tmp_path / "trials.csv"
    write_trial_csv(table, p)
    return p


def run(*args: object):
    return CliRunner().invoke(cli, [str(a) for a in args])


def test_fit_defaults_to_the_posture_form_and_validate_shows_both_forms(csv: Path) -> None:
    r = run("fit", csv)
    assert r.exit_code == 0, r.output
    assert "Load torque  tau = J(theta0 + dtheta)^T F" in r.output
    model = json.loads((csv.parent / "trials.model.json").read_text())
    # The table lists the torque terms the fit kept, the pressure drops first.
    assert model["torque_terms"][:4] == ["dP_L1", "dP_R1", "dP_L2", "dP_R2"]
    assert all(f" {t} " in r.output for t in model["torque_terms"])
    assert model["form"] == "posture" and model["schema"] == "labcli-takuma-model"
    assert model["fit_stats"]["n"] == 90 and model["limits"]["Fy"] == 1.0
    r = run("validate", csv, "--json")
    assert r.exit_code == 0, r.output
    d = json.loads(r.output)
    assert d["form"] == "posture" and list(d["forms"]) == ["posture", "paper"]
    # The data follow Eqs. 34-37 (their cos-products at deflections of 5-25 deg): the paper form
    # fits them to the noise; the torque route's linear moment arms do not (its standard errors
    # are over the 1 N limit on every held-out fit trial), so the forces take the paper's route,
    # chosen on the fit trials, and report what it reports.
    assert d["forms"]["paper"]["Fx"]["rmse"] < 0.5
    assert d["routes"]["Fx"] == d["routes"]["Fy"] == "paper" and model["routes"] == d["routes"]
    assert model["fit_stats"]["routes_cv"]["Fx"]["reported_posture"] == 0
    for q in ("Fx", "Fy"):
        assert d["metrics"][q]["n"] == d["forms"]["paper"][q]["n"] == 18
        # The forms table's paper form fits the potentiometers' play (none in these data: its fitted
        # width is noise), the posture form's paper route the labels as read: nearly the same fit.
        assert d["metrics"][q]["rmse"] == pytest.approx(d["forms"]["paper"][q]["rmse"], rel=0.02)
    for t in d["trials"]:
        for q in ("Fx", "Fy"):
            assert (t["calculated"][q] is None) == (t["standard_error"][q] > 1.0), t
    r = run("validate", csv)
    assert "Both forms on the same validation trials" in r.output
    said = " ".join(r.output.split())
    assert "Routes (chosen by cross-validation on the fit trials): theta1 " in said
    assert "Fx paper's Eq. 36, Fy paper's Eq. 37." in said


def test_fit_form_paper_keeps_eqs_34_37(csv: Path) -> None:
    r = run("fit", csv, "--form", "paper", "--json")
    assert r.exit_code == 0, r.output
    d = json.loads(r.output)
    assert d["model"]["form"] == "paper" and d["paper_coefficients"]["beta_theta2_R2"] == -2.972
    r = run("validate", csv, "--json")
    assert json.loads(r.output)["form"] == "paper"


def test_max_amplification_belongs_to_the_paper_form(csv: Path) -> None:
    r = run("fit", csv, "--max-amplification", "50")
    assert r.exit_code == 1
    assert r.output == (
        "Error: --max-amplification is the paper form's cut near theta2 = 0; the posture form "
        "flags by standard error ([sensing] in the protocol), so add --form paper or leave it out.\n"
    )
    assert run("fit", csv, "--form", "paper", "--max-amplification", "50").exit_code == 0


def test_an_unknown_form_is_refused(csv: Path) -> None:
    r = run("fit", csv, "--form", "exact")
    assert r.exit_code == 2 and "'exact' is not one of 'posture', 'paper'" in r.output
