"""Tables whose values contradict their units: refused or warned in one sentence naming the column."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from click.testing import CliRunner

from labcli.cli import cli
from labcli.core.tables import TableError
from labcli.errors import LabcliWarning
from labcli.papers.takuma2014.records import load_pushes, load_trials
from labcli.papers.takuma2014.tables import write_push_csv, write_trial_csv
from labcli.papers.takuma2014.units import G, check_units, unit_findings

ROOT = Path(__file__).resolve().parents[3]


@pytest.fixture(scope="module")
def trials() -> pd.DataFrame:
    """The sample run's 108 trials: forces m g (cos d, sin d) in N, degrees, gauge MPa."""
    return load_trials(ROOT / "sample_runs" / "trials.csv")


def _with_forces(t: pd.DataFrame, fx: np.ndarray, fy: np.ndarray) -> pd.DataFrame:
    t = t.copy()
    t["Fx_N"], t["Fy_N"] = fx, fy
    return t


def _load(t: pd.DataFrame) -> tuple[np.ndarray, np.ndarray]:
    d = np.radians(t["direction_deg"].to_numpy())
    w = t["mass_g"].to_numpy() / 1000.0 * G
    return w * np.cos(d), w * np.sin(d)


def test_the_sample_runs_and_the_test_tables_raise_nothing(trials: pd.DataFrame) -> None:
    assert unit_findings(trials) == []
    assert unit_findings(load_pushes(ROOT / "sample_runs" / "pushes.csv")) == []
    ex, ey = _load(trials)
    assert np.allclose(trials["Fx_N"], ex, atol=1e-6) and np.allclose(trials["Fy_N"], ey, atol=1e-6)


def test_a_pulley_that_loses_a_few_percent_is_not_a_unit_mistake(trials: pd.DataFrame) -> None:
    ex, ey = _load(trials)
    assert unit_findings(_with_forces(trials, 0.96 * ex, 0.96 * ey)) == []


@pytest.mark.parametrize(
    ("make", "phrase"),
    [
        (lambda ex, ey: (ex * 1000 / G, ey * 1000 / G), "gram-force"),
        (lambda ex, ey: (ex / G, ey / G), "kilogram-force"),
        (lambda ex, ey: (ey, ex), "Fx and Fy are swapped"),
        (lambda ex, ey: (-ex, -ey), "both signs are flipped"),
        (lambda ex, ey: (-ex, ey), "Fx's sign is flipped"),
        (lambda ex, ey: (ex, -ey), "Fy's sign is flipped"),
    ],
)
def test_a_force_slip_is_refused_naming_the_columns_and_the_slip(
    trials: pd.DataFrame, tmp_path: Path, make, phrase: str
) -> None:
    fx, fy = make(*_load(trials))
    path = tmp_path / "t.csv"
    write_trial_csv(_with_forces(trials, fx, fy), path)
    with pytest.raises(TableError) as e:
        load_trials(path)
    msg = str(e.value)
    assert "Fx_N and Fy_N contradict mass_g and direction_deg" in msg and phrase in msg
    assert str(path) in msg


def test_grams_force_needs_most_rows_to_be_refused(trials: pd.DataFrame) -> None:
    """Three rows in gram-force among 108 in newtons: not the table's unit, nothing said."""
    ex, ey = _load(trials)
    fx, fy = ex.copy(), ey.copy()
    fx[:3], fy[:3] = ex[:3] * 1000 / G, ey[:3] * 1000 / G
    assert unit_findings(_with_forces(trials, fx, fy)) == []


def test_forces_unrelated_to_the_loads_are_warned(trials: pd.DataFrame) -> None:
    rng = np.random.default_rng(0)
    t = _with_forces(trials, rng.normal(0, 5, len(trials)), rng.normal(0, 5, len(trials)))
    with pytest.warns(LabcliWarning, match=r"Fx_N and Fy_N differ from the pulley load .* on \d+ of 108 rows"):
        check_units(t, "t.csv")


def test_deflections_in_radians_are_warned_in_one_sentence(trials: pd.DataFrame, tmp_path: Path) -> None:
    t = trials.copy()
    t["theta1_deg"], t["theta2_deg"] = np.radians(t["theta1_deg"]), np.radians(t["theta2_deg"])
    path = tmp_path / "t.csv"
    write_trial_csv(t, path)
    with pytest.warns(LabcliWarning) as w:
        load_trials(path)
    (msg,) = [str(x.message) for x in w]
    assert msg.startswith(f"{path}: theta1_deg and theta2_deg look like radians")
    assert "\n" not in msg
    # The same deflections in degrees say nothing; a stiff rig that deflects a fifth of a degree neither.
    assert unit_findings(trials) == []
    t["theta1_deg"], t["theta2_deg"] = np.clip(trials["theta1_deg"], -0.25, 0.25), trials["theta2_deg"] * 0.05
    assert unit_findings(t) == []


def test_absolute_pressures_at_rest_are_warned(trials: pd.DataFrame) -> None:
    """An unpressurised rig read in absolute pressure: every baseline near 0.101 MPa."""
    t = trials.copy()
    rng = np.random.default_rng(1)
    for c in ("P_L10", "P_R10", "P_L20", "P_R20", "P_L1", "P_R1", "P_L2", "P_R2"):
        t[c] = 0.101325 + rng.normal(0, 0.002, len(t))
    with pytest.warns(LabcliWarning, match=r"t.csv: P_L10, P_R10, P_L20 and P_R20 look like absolute pressures"):
        check_units(t, "t.csv")
    t["P_L10"] = 0.3  # one chamber pressurised: not a rig at rest
    assert [f for f in unit_findings(t) if "absolute" in f.sentence] == []


def test_push_tables_are_checked_too(tmp_path: Path) -> None:
    pushes = load_pushes(ROOT / "sample_runs" / "pushes.csv")
    for c in ("P_L10", "P_R10", "P_L20", "P_R20"):
        pushes[c] = 0.1 + 0.001 * np.arange(len(pushes)) / len(pushes)
    path = tmp_path / "p.csv"
    write_push_csv(pushes, path)
    with pytest.warns(LabcliWarning, match="look like absolute pressures"):
        load_pushes(path)


def test_fit_refuses_a_gram_force_table_in_one_sentence(trials: pd.DataFrame, tmp_path: Path) -> None:
    ex, ey = _load(trials)
    path = tmp_path / "grams.csv"
    write_trial_csv(_with_forces(trials, ex * 1000 / G, ey * 1000 / G), path)
    r = CliRunner().invoke(cli, ["fit", str(path), "-o", str(tmp_path / "m.json")])
    assert r.exit_code == 1, r.output
    assert "Traceback" not in r.output
    assert "gram-force" in r.output and "Fx_N and Fy_N" in r.output
    assert not (tmp_path / "m.json").exists()
    assert math.isclose(float(trials["mass_g"].iloc[0]) / 1000 * G, math.hypot(ex[0], ey[0]))
