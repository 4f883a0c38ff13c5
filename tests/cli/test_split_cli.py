"""``labcli split`` does what ``fit``'s advice promises: a trial CSV gets its set column, a short
run gets sizes in the protocol's proportion (said), and one trial is "1 completed trial"."""

from __future__ import annotations

import json
from pathlib import Path

import pandas as pd
from click.testing import CliRunner

from labcli.cli import cli
from labcli.core.store import RunFile

SAMPLE = Path(__file__).resolve().parents[2] / "sample_runs" / "trials.csv"


def unsplit_csv(tmp_path: Path, rows: int) -> Path:
    df = pd.read_csv(SAMPLE, keep_default_na=False).head(rows)
    df["set"] = ""
    path = tmp_path / "t.csv"
    df.to_csv(path, index=False)
    return path


def test_fit_advises_split_on_a_csv_and_split_fills_its_set_column(tmp_path):
    table = unsplit_csv(tmp_path, 40)
    runner = CliRunner()
    refused = runner.invoke(cli, ["fit", str(table), "-o", str(tmp_path / "m.json")])
    assert refused.exit_code == 1
    assert "assign trials with `labcli split`" in refused.output
    before = pd.read_csv(table, keep_default_na=False)
    done = runner.invoke(cli, ["split", str(table)])
    assert done.exit_code == 0, done.output
    assert done.output == (
        f"{table} -> {table} (its set column): 33 fit, 7 validation, 0 unassigned of 40 completed trials "
        "(sequential). The protocol's 90 fit + 18 validation need 108 trials and there are 40, so the sizes "
        "keep its proportion (--fit and --validation choose others).\n"
    )
    after = pd.read_csv(table, keep_default_na=False)
    assert after["set"].tolist() == ["fit"] * 33 + ["validation"] * 7
    # Nothing else in the table changed.
    pd.testing.assert_frame_equal(after.drop(columns="set"), before.drop(columns="set"))
    fitted = runner.invoke(cli, ["fit", str(table), "-o", str(tmp_path / "m.json")])
    assert fitted.exit_code == 0, fitted.output
    assert json.loads((tmp_path / "m.json").read_text())


def test_split_of_a_csv_to_another_file_leaves_the_csv(tmp_path):
    table = unsplit_csv(tmp_path, 12)
    text = table.read_text()
    out = tmp_path / "split.csv"
    done = CliRunner().invoke(cli, ["split", str(table), "--fit", "9", "-o", str(out)])
    assert done.exit_code == 0, done.output
    assert "9 fit, 3 validation, 0 unassigned of 12 completed trials (sequential). 3 validation: the trials" in (
        done.output
    )
    assert table.read_text() == text
    assert pd.read_csv(out, keep_default_na=False)["set"].tolist() == ["fit"] * 9 + ["validation"] * 3


def test_a_short_run_is_split_in_the_protocols_proportion(tmp_path):
    table = unsplit_csv(tmp_path, 12)
    run = tmp_path / "r.h5"
    runner = CliRunner()
    assert runner.invoke(cli, ["import", str(table), "-o", str(run), "--protocol", "takuma2014"]).exit_code == 0
    done = runner.invoke(cli, ["split", str(run)])
    assert done.exit_code == 0, done.output
    assert done.output.startswith(f"{run}: 10 fit, 2 validation, 0 unassigned of 12 completed trials (sequential).")
    assert "need 108 trials and there are 12" in done.output
    with RunFile.open(run) as rf:
        s = rf.split.get()
    assert s["fit"] == list(range(1, 11)) and s["validation"] == [11, 12]
    # A run file carries its protocol: --protocol and -o are for tables.
    refused = runner.invoke(cli, ["split", str(run), "-o", str(tmp_path / "x.csv")])
    assert refused.exit_code == 1
    assert refused.output == (
        f"Error: {run} is a run file, which carries its protocol and keeps its split: drop --protocol and -o.\n"
    )


def test_one_trial_is_one_completed_trial(tmp_path):
    table = unsplit_csv(tmp_path, 1)
    run = tmp_path / "one.h5"
    runner = CliRunner()
    assert runner.invoke(cli, ["import", str(table), "-o", str(run), "--protocol", "takuma2014"]).exit_code == 0
    done = runner.invoke(cli, ["split", str(run), "--fit", "1", "--validation", "0"])
    assert done.output == f"{run}: 1 fit, 0 validation, 0 unassigned of 1 completed trial (sequential).\n"
    short = runner.invoke(cli, ["split", str(run)])
    assert short.exit_code == 1
    assert short.output == f"Error: {run} has 1 completed trial; a split needs at least 2 (1 fit, 1 validation).\n"
    too_many = runner.invoke(cli, ["split", str(run), "--fit", "2", "--validation", "0"])
    assert too_many.output == (
        f"Error: {run}: the run has 1 completed trial, fewer than the 2 asked for (2 fit + 0 validation).\n"
    )


def test_verify_counts_one_raw_window_in_the_singular(tmp_path):
    import numpy as np

    from labcli.core.protocol import load_protocol
    from labcli.core.window import Window

    run = tmp_path / "w.h5"
    proto = load_protocol("takuma2014")
    si = np.tile([0.3, 0.3, 0.3, 0.3, 0.0, 0.0], (10, 1))
    w = Window.of(
        np.arange(10), proto.calibration.to_counts(si), si, t_us=np.arange(10) * 5000, t_s=np.arange(10) * 0.005
    )
    with RunFile.create(run, protocol=proto) as rf:
        rf.records.write(
            {
                "trial": 1,
                "P0_MPa": np.full(4, 0.3),
                "P_MPa": np.full(4, 0.31),
                "theta_rad": np.zeros(2),
                "force_N": np.array([1.0, 0.0]),
                "raw": {"load": w},
            }
        )
    r = CliRunner().invoke(cli, ["inspect", str(run), "--verify"])
    assert r.exit_code == 0, r.output
    assert r.output == f"{run}: 1 trial and 1 raw window check out.\n"
