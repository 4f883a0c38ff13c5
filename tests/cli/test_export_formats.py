"""labcli export as CSV with its sidecar, and as parquet; load_trials' units and provenance."""

from __future__ import annotations

import json
import sys

import pandas as pd
import pytest
from cli.test_store_commands import invoke, make_run

import labcli
from labcli.core import table_meta

PRESSURES = ("P_L10", "P_R10", "P_L20", "P_R20", "P_L1", "P_R1", "P_L2", "P_R2")


@pytest.fixture
def run_path(tmp_path):
    return make_run(tmp_path / "run.h5", n=12)


def test_load_trials_carries_units_and_the_runs_provenance(run_path):
    df = labcli.load_trials(run_path)
    units = df.attrs["units"]
    assert all(units[c] == "MPa" for c in PRESSURES)
    assert units["theta1_deg"] == units["direction_deg"] == units["theta2_0_deg"] == "deg"
    assert units["Fx_N"] == "N" and units["mass_g"] == "g" and "trial" not in units and "set" not in units
    prov = df.attrs["provenance"]
    assert prov["file"] == "run.h5" and prov["protocol"] == "takuma2014" and prov["device"] == "mckibben-2dof"
    assert prov["labcli_version"] == labcli.__version__ and prov["operator"] == "ada"
    json.dumps(df.attrs)  # plain data


def test_csv_sidecar_describes_the_table_and_load_trials_reads_it(run_path, tmp_path):
    out = tmp_path / "t.csv"
    res = invoke("export", run_path, "-o", out)
    assert res.exit_code == 0 and res.output == f"Wrote 12 trials from {run_path} to {out}.\n"
    # the CSV itself is the plain exchange table
    assert out.read_text().splitlines()[0].startswith("trial,set,P_L10,")
    meta = json.loads((tmp_path / "t.csv.json").read_text())
    assert meta["profile"] == "tabular-data-resource" and meta["path"] == "t.csv"
    assert meta["schema"]["primaryKey"] == "trial"
    fields = {f["name"]: f for f in meta["schema"]["fields"]}
    assert [f["name"] for f in meta["schema"]["fields"]] == out.read_text().splitlines()[0].split(",")
    assert fields["P_L1"] == {"name": "P_L1", "type": "number", "unit": "MPa"}
    assert fields["trial"] == {"name": "trial", "type": "integer"}
    assert meta["labcli"]["provenance"]["protocol"] == "takuma2014"
    from_run, from_csv = labcli.load_trials(run_path), labcli.load_trials(out)
    assert from_csv.attrs["units"] == from_run.attrs["units"]
    prov = dict(from_csv.attrs["provenance"])
    assert prov.pop("file") == "t.csv" and prov.pop("run_file") == "run.h5"
    assert prov == {k: v for k, v in from_run.attrs["provenance"].items() if k != "file"}


def test_a_csv_without_sidecar_still_has_units(run_path, tmp_path):
    out = tmp_path / "t.csv"
    assert invoke("export", run_path, "-o", out).exit_code == 0
    (tmp_path / "t.csv.json").write_text("{not json")
    df = labcli.load_trials(out)
    assert df.attrs["units"]["P_R2"] == "MPa" and df.attrs["provenance"] == {"file": "t.csv"}


def test_parquet_round_trip(run_path, tmp_path):
    pytest.importorskip("pyarrow")
    out = tmp_path / "t.parquet"
    res = invoke("export", run_path, "-o", out)
    assert res.exit_code == 0 and res.output == f"Wrote 12 trials from {run_path} to {out}.\n"
    back = table_meta.read_parquet(out)
    df = labcli.load_trials(run_path)
    pd.testing.assert_frame_equal(back, df)  # values bit for bit, dtypes, column order
    assert back.attrs == json.loads(json.dumps(df.attrs))
    # --format parquet whatever the name; the CSV and the parquet hold the same table
    other, csv = tmp_path / "t.bin", tmp_path / "t.csv"
    assert invoke("export", run_path, "-o", other, "--format", "parquet").exit_code == 0
    assert invoke("export", run_path, "-o", csv).exit_code == 0
    pd.testing.assert_frame_equal(table_meta.read_parquet(other), labcli.load_trials(csv))


def test_parquet_without_pyarrow_is_one_sentence(run_path, tmp_path, monkeypatch):
    monkeypatch.setitem(sys.modules, "pyarrow", None)  # import pyarrow raises ImportError
    out = tmp_path / "t.parquet"
    res = invoke("export", run_path, "-o", out)
    assert res.exit_code == 1
    assert res.output == (
        "Error: writing parquet needs pyarrow, which is not installed; install it with pip install 'labcli[parquet]'.\n"
    )
    assert not out.exists()
