"""A push plan CSV drives the stiffness session (``labcli acquire --plan pushes.csv``) as a trial plan drives loads."""

from __future__ import annotations

import math

import pytest
from click.testing import CliRunner

from labcli.cli import cli
from labcli.papers.takuma2014.records import load_pushes

HEADER = "push,object,R_mm,d_mm,phi_deg,category,stiffness_N_per_m\n"
PORT = "sim://?seed=1&clock=virtual"


def acquire(tmp_path, rows: str, name="pp.csv"):
    (tmp_path / name).write_text(HEADER + rows)
    return CliRunner().invoke(
        cli,
        [
            "acquire",
            str(tmp_path / "p.h5"),
            "--protocol",
            "takuma2014-stiffness",
            "--plan",
            str(tmp_path / name),
            "--unattended",
            "--port",
            PORT,
        ],
    )


def test_the_plan_is_stored_as_typed_in_si_with_an_unknown_direction_kept_unknown(tmp_path):
    result = acquire(tmp_path, "1,pet-1,33,10,0,soft,300\n2,pet-1,33,12,,soft,300\n7,can-1,40,15,45,hard,3000\n")
    assert result.exit_code == 0, result.output
    df = load_pushes(tmp_path / "p.h5")
    assert df["push"].tolist() == [1, 2, 7]
    assert df["object"].tolist() == ["pet-1", "pet-1", "can-1"]
    assert df["R_m"].tolist() == pytest.approx([0.033, 0.033, 0.040])
    assert df["d_m"].tolist() == pytest.approx([0.010, 0.012, 0.015])
    assert df["phi_deg"][0] == 0.0 and math.isnan(df["phi_deg"][1]) and df["phi_deg"][2] == pytest.approx(45.0)


def test_an_object_with_two_radii_is_refused_naming_the_rows(tmp_path):
    result = acquire(tmp_path, "1,pet-1,33,10,0,soft,300\n2,pet-1,35,12,,soft,300\n")
    assert result.exit_code == 1
    assert result.output.splitlines()[-1] == (
        f"{tmp_path / 'pp.csv'}:row 3, column R_mm: 35 differs from pet-1's 33 on row 2; an object has one R_mm."
    )
    assert not (tmp_path / "p.h5").exists()
