"""``labcli sense --record``: the frames, estimates and events of a live session in a run file that
verifies, exports, holds exactly what was published, and survives a SIGKILL losing at most a second."""

from __future__ import annotations

import json
import math
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from labcli.cli import cli
from labcli.core.store import RunFile
from labcli.errors import StoreError

ROOT = Path(__file__).resolve().parents[2]
MODEL = ROOT / "sample_runs" / "force.model.json"
SCRIPT = ROOT / "docs" / "sensing-example.toml"
PORT = f"sim://?seed=1&clock=virtual&script={SCRIPT}"


def test_the_run_file_holds_every_frame_estimate_and_event_as_published(tmp_path):
    run_path, lines_path = tmp_path / "session.h5", tmp_path / "session.jsonl"
    args = ["sense", "--port", PORT, "--model", str(MODEL), "--seconds", "40"]
    result = CliRunner().invoke(cli, [*args, "--jsonl", str(lines_path), "--record", str(run_path)])
    assert result.exit_code == 0, result.output
    lines = [json.loads(line) for line in lines_path.read_text().splitlines()]
    with RunFile.open(run_path) as run:
        assert run.kind == "sense"
        ids = run.records.ids()
        records = [run.records.read(i) for i in ids]
    assert len(records) == len(lines) == 403  # 400 estimates and load, settled, release
    for rec, line in zip(records, lines, strict=True):
        if "event" in line:
            assert rec["item"] == line["event"] and round(rec["t_device_s"], 6) == line["t_device_s"]
            assert rec["data"]["t_detected_s"] == line["t_detected_s"]
            continue
        assert rec["item"] == "estimate" and rec["state"] == line["state"] and rec["seq"] == line["seq"]
        for got, key in zip(
            [*np.degrees(rec["theta_rad"]), *rec["force_N"]], ("theta1_deg", "theta2_deg", "Fx_N", "Fy_N"), strict=True
        ):
            assert math.isclose(got, line[key], abs_tol=1e-5), (key, got, line[key])
        assert sorted(rec["flags"]) == sorted(line["flags"])
    # The raw windows tile the stream: every frame of every block, once, in order.
    windows = [r["raw"]["load"] for r in records if r["item"] == "estimate"]
    seq = np.concatenate([w.seq for w in windows])
    assert seq.tolist() == list(range(8000))
    assert all(
        w.seq[-1] == r["seq"] for w, r in zip(windows, (r for r in records if r["item"] == "estimate"), strict=True)
    )
    assert np.allclose(np.concatenate([w.t_s for w in windows])[[0, -1]], [1 / 200.0, 8000 / 200.0], atol=1e-6)


def test_inspect_verify_and_export_read_the_session(tmp_path):
    run_path = tmp_path / "s.h5"
    runner = CliRunner()
    result = runner.invoke(
        cli, ["sense", "--port", PORT, "--model", str(MODEL), "--seconds", "40", "--record", str(run_path)]
    )
    assert result.exit_code == 0, result.output
    verify = runner.invoke(cli, ["inspect", str(run_path), "--verify"])
    assert verify.exit_code == 0
    assert verify.output == f"{run_path}: 403 records (estimates and events) and 400 raw windows check out.\n"
    shown = runner.invoke(cli, ["inspect", str(run_path)])
    assert "  kind        sense, protocol takuma2014" in shown.output
    assert "  session     400 estimates over 39.9 s of the rig's clock; 1 load, 1 settled, 1 release" in shown.output
    out = tmp_path / "s.csv"
    exported = runner.invoke(cli, ["export", str(run_path), "-o", str(out)])
    assert exported.exit_code == 0, exported.output
    rows = out.read_text().splitlines()
    assert rows[0] == (
        "record,item,seq,t_device_s,state,theta1_deg,theta1_deg_se,theta2_deg,theta2_deg_se,Fx_N,Fx_N_se,"
        "Fy_N,Fy_N_se,flags,data"
    )
    assert [r.split(",")[1] for r in rows[1:] if ",estimate," not in r] == ["load", "settled", "release"]


def test_a_record_file_that_exists_is_refused_before_the_rig_is_opened(tmp_path):
    run_path = tmp_path / "s.h5"
    run_path.write_bytes(b"keep me")
    result = CliRunner().invoke(
        cli, ["sense", "--port", "sim://?clock=virtual", "--model", str(MODEL), "--record", str(run_path)]
    )
    assert result.exit_code == 1
    assert result.output == f"Error: {run_path} already exists; choose a new file name for the session's run file.\n"
    assert run_path.read_bytes() == b"keep me"


def test_a_sigkill_mid_session_loses_at_most_the_last_second(tmp_path):
    run_path, lines_path = tmp_path / "s.h5", tmp_path / "s.jsonl"
    proc = subprocess.Popen(
        [sys.executable, "-m", "labcli", "sense", "--port", "sim://?seed=1&clock=wall", "--model", str(MODEL),
         "--seconds", "60", "--jsonl", str(lines_path), "--record", str(run_path)],
        stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
    )  # fmt: skip
    try:
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline:  # until 3 s of estimates were published
            if lines_path.exists() and len(lines_path.read_text().splitlines()) >= 30:
                break
            time.sleep(0.05)
        proc.send_signal(signal.SIGKILL)
    finally:
        proc.wait(timeout=30)
    assert proc.returncode == -signal.SIGKILL
    published = [json.loads(line) for line in lines_path.read_text().splitlines() if line.endswith("}")]
    verify = CliRunner().invoke(cli, ["inspect", str(run_path), "--verify"])
    assert verify.exit_code == 0, verify.output
    with RunFile.open(run_path) as run:
        kept = [run.records.read(i) for i in run.records.ids()]
    assert kept, "nothing committed in 3 s"
    # What the file holds is what was published, in order, and it reaches to within a second of the end.
    assert [round(r["t_device_s"], 6) for r in kept] == [p["t_device_s"] for p in published[: len(kept)]]
    assert published[-1]["t_device_s"] - kept[-1]["t_device_s"] <= 1.1


def test_a_stalled_rig_ends_in_one_sentence_and_a_run_file_that_verifies(tmp_path):
    run_path, lines_path = tmp_path / "s.h5", tmp_path / "s.jsonl"
    port = "sim://?seed=1&clock=wall&faults=stall:0.001@3"  # a 3 s silence after a few seconds of estimates
    result = CliRunner().invoke(
        cli,
        ["sense", "--port", port, "--model", str(MODEL), "--timeout", "0.5", "--jsonl", str(lines_path),
         "--record", str(run_path)],
    )  # fmt: skip
    assert result.exit_code == 1
    assert result.stderr.splitlines()[-1] == (
        f"Error: No data from {port} for 0.5 s while streaming. Check the cable and that the rig is powered."
    )
    assert "Traceback" not in result.output
    verify = CliRunner().invoke(cli, ["inspect", str(run_path), "--verify"])
    assert verify.exit_code == 0, verify.output
    published = [json.loads(line) for line in lines_path.read_text().splitlines()]
    with RunFile.open(run_path) as run:
        kept = [run.records.read(i) for i in run.records.ids()]
    # Everything published before the rig went quiet is in the file, in order (the error's stop commits it).
    assert published and [round(r["t_device_s"], 6) for r in kept] == [p["t_device_s"] for p in published]


ESTIMATE = {
    "item": "estimate",
    "seq": 19,
    "t_device_s": 0.1,
    "state": "free",
    "theta_rad": [0.1, 0.2],
    "theta_se_rad": [0.01, 0.02],
    "force_N": [1.0, 2.0],
    "force_se_N": [0.1, 0.2],
}


def sense_run(path: Path) -> RunFile:
    from labcli.core.protocol import load_protocol

    return RunFile.create(path, protocol=load_protocol("takuma2014"), kind="sense", port="sim://")


def test_an_infinite_standard_error_is_stored_and_exported_as_an_empty_cell(tmp_path):
    """The JSON lines publish an infinite standard error as null; the run's table holds an empty cell,
    so the run exports (the table refused 'inf', and the whole run with it)."""
    with sense_run(tmp_path / "s.h5") as run:
        run.records.write_many(
            [
                {**ESTIMATE, "record": 1, "theta_se_rad": [0.01, math.inf], "force_se_N": [math.inf, 0.2]},
                {"record": 2, "item": "load", "seq": 39, "t_device_s": 0.2, "data": {"t_detected_s": 0.2}},
            ]
        )
    result = CliRunner().invoke(cli, ["export", str(tmp_path / "s.h5"), "-o", str(tmp_path / "s.csv")])
    assert result.exit_code == 0, result.output
    header, first, *_ = (tmp_path / "s.csv").read_text().splitlines()
    row = dict(zip(header.split(","), first.split(","), strict=False))
    assert (row["theta2_deg_se"], row["Fx_N_se"]) == ("", "")
    assert math.isclose(float(row["theta1_deg_se"]), math.degrees(0.01), rel_tol=1e-11) and row["Fy_N_se"] == "0.2"
    with RunFile.open(tmp_path / "s.h5") as run:
        assert run.records.read(1)["force_se_N"][0] == math.inf  # the run file keeps what was estimated


def test_a_sense_batch_goes_through_its_table_before_anything_is_written(tmp_path, monkeypatch):
    """As acquire's trials do: every record of a batch is checked against the sense table's own
    bounds (what export and import hold a sense table to), as one table; one refused, none stored."""
    from labcli.core import tables

    real = tables.frame_problems
    seen = []

    def refuse_the_second(df, spec, *args):
        seen.append(len(df))
        assert real(df, spec, *args) == []
        return [(1, "Fx_N", "1e+99 N is not a force the rig can measure")]

    path = tmp_path / "s.h5"
    with sense_run(path) as run:
        run.records.write_many([{**ESTIMATE, "record": 1}])
        monkeypatch.setattr(tables, "frame_problems", refuse_the_second)
        batch = [{**ESTIMATE, "record": i, "seq": 20 * i - 1} for i in (2, 3, 4)]
        with pytest.raises(StoreError) as refused:
            run.records.write_many(batch)
        assert run.records.ids() == [1]
    assert seen == [3]  # one table for the batch
    assert str(refused.value) == (
        "record 3 was not stored: column Fx_N: 1e+99 N is not a force the rig can measure, which a sense "
        "table cannot hold (the rig or its link is not measuring)."
    )
    with RunFile.open(path) as run:
        assert run.records.ids() == [1]
