"""``labcli runs DIR``: one row per run file under DIR (table and JSON), what checks out and what
does not, and nothing under DIR changed."""

from __future__ import annotations

import hashlib
import json
import shutil
from pathlib import Path

import h5py
import pandas as pd
import pytest
from click.testing import CliRunner

from labcli.cli import cli

ROOT = Path(__file__).resolve().parents[2]
SAMPLE = ROOT / "sample_runs"


def digest(folder: Path) -> dict[str, str]:
    return {
        str(p.relative_to(folder)): hashlib.sha256(p.read_bytes()).hexdigest() for p in folder.rglob("*") if p.is_file()
    }


@pytest.fixture
def lab(tmp_path: Path) -> Path:
    """A folder as a lab keeps one: two runs, a nested short run split and noted, a damaged copy, a stray .h5."""
    lab = tmp_path / "lab"
    (lab / "week2").mkdir(parents=True)
    shutil.copy(SAMPLE / "force.h5", lab / "force.h5")
    shutil.copy(SAMPLE / "pushes.h5", lab / "pushes.h5")
    table = tmp_path / "t.csv"
    pd.read_csv(SAMPLE / "trials.csv", keep_default_na=False).head(12).assign(set="").to_csv(table, index=False)
    runner = CliRunner()
    short = lab / "week2" / "short.h5"
    assert (
        runner.invoke(
            cli, ["import", str(table), "-o", str(short), "--protocol", "takuma2014", "--operator", "kim"]
        ).exit_code
        == 0
    )
    assert runner.invoke(cli, ["split", str(short)]).exit_code == 0
    assert runner.invoke(cli, ["note", str(short), "bench test"]).exit_code == 0
    damaged = lab / "week2" / "damaged.h5"
    shutil.copy(SAMPLE / "force.h5", damaged)
    with h5py.File(damaged, "a") as f:  # an attribute changed behind labcli's back
        f["entry"].attrs.modify("operator", "mallory")
    (lab / "notes.h5").write_text("not an HDF5 file")
    return lab


def test_the_catalogue_lists_every_run_and_changes_nothing(lab):
    before = digest(lab)
    r = CliRunner().invoke(cli, ["runs", str(lab), "--json"])  # what a file's open warns is in its row
    assert r.exit_code == 0, r.output
    rows = {e["file"]: e for e in json.loads(r.output)}
    assert list(rows) == ["force.h5", "notes.h5", "pushes.h5", "week2/damaged.h5", "week2/short.h5"]
    force = rows["force.h5"]
    assert (force["kind"], force["protocol"], force["rig"], force["status"]) == (
        "force",
        "takuma2014",
        "mckibben-2dof-sim 1.1",
        "ok",
    )
    assert (force["complete"], force["planned"], force["models"]) == (108, 108, ["takuma2014"])
    assert force["split"]["fit"] == 90 and force["split"]["validation"] == 18 and len(force["uid"]) == 36
    assert rows["pushes.h5"]["records"] == "pushes" and rows["pushes.h5"]["complete"] == 60
    short = rows["week2/short.h5"]
    assert (short["operator"], short["complete"], short["planned"], short["notes"]) == ("kim", 12, None, 1)
    assert (short["split"]["fit"], short["split"]["validation"], short["imported"]) == (10, 2, True)
    assert rows["week2/damaged.h5"]["status"] == "damaged"
    assert rows["week2/damaged.h5"]["problem"].startswith("the run's metadata (the attributes")
    assert "do not match their checksum" in rows["week2/damaged.h5"]["problem"]
    stray = rows["notes.h5"]
    assert stray["status"] == "not a run" and stray["problem"] == (
        "is not an HDF5 file; run files are written by 'labcli acquire' or 'labcli import'."
    )
    assert digest(lab) == before


def test_the_table_has_a_row_per_run_and_says_what_is_wrong(lab):
    r = CliRunner(env={"COLUMNS": "250"}).invoke(cli, ["runs", str(lab)])
    assert r.exit_code == 0, r.output
    lines = r.output.splitlines()
    assert lines[0] == f"5 run files under {lab}"
    header = lines[1].split()
    assert header[:3] == ["file", "uid", "kind"] and header[-1] == "status"
    short = next(line for line in lines if line.startswith(" week2/short.h5"))
    assert "12 trials" in short and " 10/2 " in short and " kim " in short and short.rstrip().endswith("ok")
    assert " 108/108 trials " in next(line for line in lines if line.startswith(" force.h5"))
    assert any(line.startswith("week2/damaged.h5: ") and "checksum" in line for line in lines)


def test_verify_reads_every_window(tmp_path):
    lab = tmp_path / "lab"
    lab.mkdir()
    shutil.copy(SAMPLE / "force.h5", lab / "force.h5")
    r = CliRunner().invoke(cli, ["runs", str(lab), "--verify", "--json"])
    assert r.exit_code == 0 and json.loads(r.output)[0]["status"] == "verified"


def test_a_folder_that_is_not_one_is_refused(tmp_path):
    r = CliRunner().invoke(cli, ["runs", str(tmp_path / "nowhere")])
    assert r.exit_code == 1
    assert r.output == f"Error: {tmp_path / 'nowhere'} does not exist; give the folder whose run files to list.\n"
    empty = CliRunner().invoke(cli, ["runs", str(tmp_path)])
    assert empty.exit_code == 0 and empty.output == f"No run files (.h5, .hdf5) under {tmp_path}.\n"
