"""`labcli fit`'s posture form with the sleeves' friction terms read from the history of loads
(PostureModel(friction=True), the default; `--no-friction-terms` leaves them out), on a run taken
as `labcli acquire` takes it."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from labcli.cli import cli
from labcli.papers.takuma2014.analyses import friction_of
from labcli.papers.takuma2014.models.posture import FRICTION_TERMS, PostureModel

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))


@pytest.fixture(scope="module")
def acquired_csv(tmp_path_factory):
    """The straight protocol on the kind rig, tuning seed 2, 15 s waits and the chambers supplied
    again past the drift limit (sensing_accuracy.trials' defaults), as a trial CSV."""
    from sensing_accuracy import trials

    _, table = trials("takuma2014", 2)
    path = tmp_path_factory.mktemp("friction") / "trials.csv"
    table.to_csv(path, index=False)
    return path, table


def _fit(csv: Path, out: Path, *extra: str) -> PostureModel:
    result = CliRunner().invoke(cli, ["fit", str(csv), "-o", str(out), *extra])
    assert result.exit_code == 0, result.output
    return PostureModel.from_dict(json.loads(out.read_text()))


def test_the_friction_terms_take_up_the_sleeves_hysteresis(acquired_csv, tmp_path) -> None:
    """Offered the terms (the default), the fit keeps one (the rig has sleeve friction), the model
    file names it, and the validation trials' Fx, predicted with each trial's motion into its
    baseline, comes out at least a fifth lower than the posture form's without them
    (`--no-friction-terms`; 0.204 against 0.295 N on this seed); `--friction-terms` is the default."""
    csv, table = acquired_csv
    plain = _fit(csv, tmp_path / "plain.json", "--no-friction-terms")
    terms = _fit(csv, tmp_path / "terms.json")
    assert not set(plain.torque_terms) & set(FRICTION_TERMS)
    assert set(terms.torque_terms) & set(FRICTION_TERMS)
    asked = _fit(csv, tmp_path / "asked.json", "--friction-terms")
    assert asked.torque_coefficients == terms.torque_coefficients
    val = table[table["set"] == "validation"]

    def rmse(model: PostureModel) -> float:
        return float(np.sqrt(np.mean((model.predict_table(val)["Fx_N"] - val["Fx_N"].to_numpy()) ** 2)))

    assert rmse(terms) < 0.8 * rmse(plain)
    # The angles do not use the terms.
    np.testing.assert_allclose(terms.predict_table(val)["theta2_rad"], plain.predict_table(val)["theta2_rad"])


def test_the_terms_are_offered_only_when_asked_and_a_relieved_run_keeps_its_own(tmp_path) -> None:
    from labcli.core.protocol import load_protocol

    shipped = load_protocol("takuma2014")
    assert friction_of(shipped) is False and friction_of(shipped, True) is True
    path = tmp_path / "p.toml"
    path.write_text(
        shipped.text.replace(
            "rate_hz = 200.0\n", "rate_hz = 200.0\nfriction_relief_s = 3.0\nfriction_relief_vent_s = 2.0\n"
        )
    )
    relieved = load_protocol(str(path))
    assert friction_of(relieved, True) == "relieved"
    # --no-friction-terms on a relieved run: the plain posture form, the one the board computes.
    assert friction_of(relieved, False) is False


def test_the_paper_form_refuses_the_friction_terms_in_a_sentence(acquired_csv, tmp_path) -> None:
    csv, _ = acquired_csv
    out = tmp_path / "m.json"
    result = CliRunner().invoke(cli, ["fit", str(csv), "-o", str(out), "--form", "paper", "--friction-terms"])
    assert result.exit_code != 0 and "Traceback" not in result.output
    assert "--friction-terms are the posture form's" in result.output and not out.exists()


def test_asking_for_both_fits_is_refused_in_a_sentence(acquired_csv, tmp_path) -> None:
    csv, _ = acquired_csv
    out = tmp_path / "m.json"
    result = CliRunner().invoke(cli, ["fit", str(csv), "-o", str(out), "--friction-terms", "--no-friction-terms"])
    assert result.exit_code == 1
    assert result.output == (
        "Error: --friction-terms and --no-friction-terms ask for opposite fits; give one of them.\n"
    )
    assert not out.exists()
