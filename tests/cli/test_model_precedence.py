"""``fit -o M.json`` writes only M.json unless --record; validate applies one precedence:
an explicit --model, else the model the run records in force, else RUN.model.json beside it."""

from __future__ import annotations

import hashlib
import json
import shutil
from pathlib import Path

import pandas as pd
import pytest
from click.testing import CliRunner

from labcli.cli import cli
from labcli.core.store import RunFile

SAMPLE = Path(__file__).resolve().parents[2] / "sample_runs"


def run(*args: object):
    return CliRunner().invoke(cli, [str(a) for a in args])


def sha(p: Path) -> str:
    return hashlib.sha256(p.read_bytes()).hexdigest()


@pytest.fixture
def force(tmp_path: Path) -> Path:
    path = tmp_path / "force.h5"
    shutil.copy(SAMPLE / "force.h5", path)
    return path


def test_fit_with_o_writes_only_that_file(force: Path, tmp_path: Path) -> None:
    before = sha(force)
    out = tmp_path / "x.json"
    r = run("fit", force, "--form", "paper", "-o", out)
    assert r.exit_code == 0, r.output
    assert f"Model written to {out}." in r.output and "recorded in" not in r.output
    assert sha(force) == before  # the run file is not touched
    assert not (tmp_path / "force.model.json").exists()
    assert json.loads(out.read_text())["protocol"] == "takuma2014"
    r = run("fit", force, "--form", "paper", "-o", out, "--json")
    assert json.loads(r.output)["recorded_in_run"] is False
    # --record keeps it in the run as well, as the model in force.
    r = run("fit", force, "--form", "paper", "-o", out, "--record")
    assert r.exit_code == 0 and f"Model written to {out} and recorded in {force} under /models/takuma2014." in r.output
    with RunFile.open(force) as rf:
        assert rf.models.get("takuma2014") == out.read_text()


def test_record_on_a_table_is_refused(tmp_path: Path) -> None:
    table = tmp_path / "t.csv"
    shutil.copy(SAMPLE / "trials.csv", table)
    r = run("fit", table, "-o", tmp_path / "m.json", "--record")
    assert r.exit_code == 1
    assert r.output == (
        f"Error: --record keeps the model in a run file, and {table} is a table; leave --record out "
        "(the model goes to the file -o names).\n"
    )
    assert not (tmp_path / "m.json").exists()


def test_validate_prefers_the_model_the_run_records_over_the_sidecar(force: Path, tmp_path: Path) -> None:
    # The posture form beside the run and in it; then the paper form recorded with -o and --record.
    assert run("fit", force).exit_code == 0
    side = tmp_path / "force.model.json"
    assert json.loads(side.read_text())["form"] == "posture"
    paper = tmp_path / "paper.json"
    assert run("fit", force, "--form", "paper", "-o", paper, "--record").exit_code == 0
    r = run("validate", force, "--json")
    assert r.exit_code == 0, r.output
    assert json.loads(r.output)["model"] == f"{force}:/models/takuma2014"
    by_record = json.loads(r.output)["metrics"]
    by_paper = json.loads(run("validate", force, "--model", paper, "--json").output)["metrics"]
    assert by_record == by_paper  # the paper form, which the run records, not the posture sidecar
    by_side = json.loads(run("validate", force, "--model", side, "--json").output)
    assert by_side["model"] == str(side) and by_side["metrics"] != by_record  # an explicit --model wins


def test_a_run_that_records_no_model_uses_the_sidecar(tmp_path: Path) -> None:
    table = tmp_path / "t.csv"
    pd.read_csv(SAMPLE / "trials.csv", keep_default_na=False).to_csv(table, index=False)
    imported = tmp_path / "imp.h5"
    assert run("import", table, "-o", imported, "--protocol", "takuma2014").exit_code == 0
    r = run("validate", imported)
    assert r.exit_code == 1
    assert r.output == (
        f"Error: {imported} records no model under /models/takuma2014 and the model file "
        f"{tmp_path / 'imp.model.json'} does not exist; write one with `labcli fit {imported}`.\n"
    )
    side = tmp_path / "imp.model.json"
    assert run("fit", imported, "-o", side).exit_code == 0  # written beside it, not recorded
    with RunFile.open(imported) as rf:
        assert rf.models.names() == []
    r = run("validate", imported, "--json")
    assert r.exit_code == 0, r.output
    assert json.loads(r.output)["model"] == str(side)
