"""Notes on a run and on its trials: ``labcli note``, ``n`` at the review; kept in the run file,
shown by ``inspect``, written by ``export``; nothing else in the file changes."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pandas as pd
from click.testing import CliRunner

from labcli.cli import cli
from labcli.core.store import RunFile

ROOT = Path(__file__).resolve().parents[2]
SAMPLE = ROOT / "sample_runs" / "trials.csv"
PORT = "sim://?seed=8&clock=virtual&ideal=1"


def small_run(tmp_path: Path, rows: int = 6) -> Path:
    table = tmp_path / "t.csv"
    pd.read_csv(SAMPLE, keep_default_na=False).head(rows).to_csv(table, index=False)
    run = tmp_path / "run.h5"
    r = CliRunner().invoke(cli, ["import", str(table), "-o", str(run), "--protocol", "takuma2014"])
    assert r.exit_code == 0, r.output
    return run


def test_a_note_on_the_run_and_on_a_trial_is_kept_shown_and_exported(tmp_path):
    run = small_run(tmp_path)
    runner = CliRunner()
    before = runner.invoke(cli, ["export", str(run), "-o", str(tmp_path / "before.csv")])
    assert before.exit_code == 0
    with RunFile.open(run) as rf:
        table_before = rf.records.table()
    r = runner.invoke(cli, ["note", str(run), "valve 2 replaced before trial 4"])
    assert r.exit_code == 0, r.output
    assert r.output.startswith(f"{run}: note on the run kept (")
    r = runner.invoke(cli, ["note", str(run), "--trial", "3", "the weight  swung,\nredone by hand"])
    assert r.exit_code == 0 and r.output.startswith(f"{run}: note on trial 3 kept (")
    listed = runner.invoke(cli, ["note", str(run)])
    lines = listed.output.splitlines()
    assert [line.split("  ", 1)[1] for line in lines] == [
        "run: valve 2 replaced before trial 4",
        "trial 3: the weight swung, redone by hand",
    ]
    shown = runner.invoke(cli, ["inspect", str(run)])
    assert "  note        valve 2 replaced before trial 4 (" in shown.output
    assert "  note        trial 3: the weight swung, redone by hand (" in shown.output
    as_json = json.loads(runner.invoke(cli, ["inspect", str(run), "--json"]).output)
    assert [(n["about"], n["text"]) for n in as_json["notes"]] == [
        ("the run", "valve 2 replaced before trial 4"),
        ("trial 3", "the weight swung, redone by hand"),
    ]
    # The run still verifies, and its records are as they were.
    assert runner.invoke(cli, ["inspect", str(run), "--verify"]).exit_code == 0
    with RunFile.open(run) as rf:
        pd.testing.assert_frame_equal(rf.records.table(), table_before)
    out = tmp_path / "after.csv"
    assert runner.invoke(cli, ["export", str(run), "-o", str(out)]).exit_code == 0
    df = pd.read_csv(out, keep_default_na=False)
    assert df["note"].tolist() == ["", "", "the weight swung, redone by hand", "", "", ""]
    old = pd.read_csv(tmp_path / "before.csv", keep_default_na=False)
    pd.testing.assert_frame_equal(df.drop(columns="note"), old)
    sidecar = json.loads(Path(str(out) + ".json").read_text())
    assert sidecar["labcli"]["provenance"]["notes"] == ["valve 2 replaced before trial 4"]
    # The exported table imports again, its notes a column of it.
    again = tmp_path / "again.h5"
    assert runner.invoke(cli, ["import", str(out), "-o", str(again), "--protocol", "takuma2014"]).exit_code == 0


def test_notes_refused_in_one_sentence(tmp_path):
    run = small_run(tmp_path)
    runner = CliRunner()
    r = runner.invoke(cli, ["note", str(run), "--trial", "99", "x"])
    assert r.exit_code == 1
    assert r.output == f"Error: {run} has no complete trial 99, so the note was not added.\n"
    r = runner.invoke(cli, ["note", str(run), "   "])
    assert r.output == "Error: a note needs some text; nothing was added.\n"
    r = runner.invoke(cli, ["note", str(run), "x" * 2001])
    assert r.output == "Error: a note holds at most 2000 bytes, and this one has 2001; nothing was added.\n"
    assert runner.invoke(cli, ["note", str(run)]).output == (
        f'{run} has no notes; add one with: labcli note {run} "..."\n'
    )
    missing = tmp_path / "missing.h5"
    r = runner.invoke(cli, ["note", str(missing), "x"])
    assert r.output == f"Error: {missing} does not exist; check the path.\n"
    v1 = tmp_path / "v1.h5"
    shutil.copy(ROOT / "tests" / "data" / "v1" / "force.h5", v1)
    r = runner.invoke(cli, ["note", str(v1), "an old run"])  # opened for writing, a version 1 file is upgraded
    assert r.exit_code == 0, r.output
    assert runner.invoke(cli, ["note", str(v1)]).output.endswith("  run: an old run\n")


def test_n_at_the_review_notes_the_trial(tmp_path):
    plan = tmp_path / "plan.csv"
    plan.write_text("trial,set,mass_g,direction_deg\n1,fit,200,-60\n2,fit,500,30\n3,fit,300,90\n")
    run = tmp_path / "run.h5"
    setup, trial = "", "\n\n"  # the simulated board supplies and holds the air by command
    # Trial 1: n, a note, then accept.  Trial 2: a note, redo, accept (the note stays with it).
    # Trial 3: a note, then skip (the note becomes the run's, naming the trial).
    answers = (
        setup
        + trial
        + "n\nfirst one\na\n"
        + trial
        + "n\nthe weight swung\nr\n"
        + trial
        + "a\n"
        + trial
        + "n\npulley jammed\ns\n"
    )
    r = CliRunner().invoke(cli, ["acquire", str(run), "--port", PORT, "--plan", str(plan)], input=answers)
    assert r.exit_code == 0, r.output
    assert "Accept [a], redo [r], skip [s], note [n] or quit [q]? (a): n" in r.output
    assert "Note on this trial (one line; Enter for none):" in r.output
    with RunFile.open(run) as rf:
        notes = rf.notes.all()
        assert rf.records.ids() == [1, 2]
    assert [(n["record"], n["text"]) for n in notes] == [
        (1, "first one"),
        (2, "the weight swung"),
        (None, "trial 3 (skipped): pulley jammed"),
    ]
