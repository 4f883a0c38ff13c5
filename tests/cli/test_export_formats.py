"""labcli export as CSV with its sidecar, parquet, Excel and MATLAB; --all-columns; load_trials' units and provenance."""

from __future__ import annotations

import json
import sys

import numpy as np
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


# ------------------------------------------------------------------ formats by extension, --all-columns


@pytest.fixture
def flagged_run(tmp_path):
    """Three trials, the second accepted over a warning (a flag) after its load timed out."""
    from support.records import FakeDevice, make_record

    from labcli.core.protocol import load_protocol
    from labcli.core.store import RunFile

    path = tmp_path / "flagged.h5"
    with RunFile.create(
        str(path), protocol=load_protocol("takuma2014"), device_info=FakeDevice(), operator="ada"
    ) as run:
        for i in (1, 2, 3):
            rec = make_record(i)
            if i == 2:
                rec = {**rec, "accepted": "operator", "flags": ["The load never settled; accepted by the operator."]}
            run.records.write(rec)
    return str(path)


def test_all_columns_add_flags_times_and_settling_and_import_takes_them_back(flagged_run, tmp_path):
    a, b, run2 = tmp_path / "a.csv", tmp_path / "b.csv", tmp_path / "back.h5"
    assert invoke("export", flagged_run, "-o", a, "--all-columns").exit_code == 0
    df = labcli.load_trials(a)
    assert df["flags"].tolist() == ["", "The load never settled; accepted by the operator.", ""]
    assert df["accepted"].tolist() == ["auto", "operator", "auto"]
    assert df["started"][0] == "2024-05-01T09:01:00Z" and df["loaded_settle_time_s"].tolist() == [3.0, 4.0, 5.0]
    meta = json.loads((tmp_path / "a.csv.json").read_text())
    units = {f["name"]: f.get("unit") for f in meta["schema"]["fields"]}
    assert units["loaded_settle_time_s"] == "s" and units["baseline_pressure_spread_MPa"] == "MPa"
    assert invoke("import", a, "-o", run2, "--protocol", "takuma2014").exit_code == 0
    assert invoke("export", run2, "-o", b, "--all-columns").exit_code == 0
    assert a.read_bytes() == b.read_bytes()
    plain = tmp_path / "plain.csv"
    assert invoke("export", flagged_run, "-o", plain).exit_code == 0
    assert "flags" not in plain.read_text().splitlines()[0].split(",")  # the exchange table unless asked


def test_xlsx_is_a_workbook_with_units_and_provenance(flagged_run, tmp_path):
    openpyxl = pytest.importorskip("openpyxl", reason="openpyxl is not installed (pip install 'labcli[xlsx]')")
    out = tmp_path / "trials.xlsx"
    res = invoke("export", flagged_run, "-o", out, "--all-columns")
    assert res.exit_code == 0 and res.output == f"Wrote 3 trials from {flagged_run} to {out}.\n"
    wb = openpyxl.load_workbook(out)
    assert wb.sheetnames == ["trials", "provenance"]
    ws = wb["trials"]
    rows = [[c.value for c in row] for row in ws.iter_rows()]
    df = labcli.load_trials(flagged_run)
    assert rows[0][: len(df.columns)] == list(df.columns) and "flags" in rows[0]
    assert rows[1][rows[0].index("P_L1")] == "MPa" and rows[1][rows[0].index("theta1_deg")] == "deg"
    assert rows[1][rows[0].index("trial")] is None and ws.freeze_panes == "A3"
    assert len(rows) == 2 + 3
    for j, c in enumerate(df.columns):  # numbers as numbers (openpyxl writes 16 significant digits), text as text
        got = [r[j] for r in rows[2:]]
        want = df[c].tolist()
        assert got == (
            [None if v == "" else v for v in want] if df[c].dtype == object else pytest.approx(want, rel=1e-15)
        ), c
    assert rows[2 + 1][rows[0].index("flags")] == "The load never settled; accepted by the operator."
    prov = dict(r for r in wb["provenance"].iter_rows(values_only=True))
    assert prov["protocol"] == "takuma2014" and prov["file"] == "flagged.h5" and prov["operator"] == "ada"
    assert prov["versions.labcli"] == labcli.__version__


def test_mat_round_trip(flagged_run, tmp_path):
    import scipy.io

    out = tmp_path / "trials.mat"
    res = invoke("export", flagged_run, "-o", out, "--all-columns")
    assert res.exit_code == 0 and res.output == f"Wrote 3 trials from {flagged_run} to {out}.\n"
    m = scipy.io.loadmat(out, simplify_cells=True)
    df = labcli.load_trials(flagged_run)
    t = m["trials"]
    assert list(m["columns"]) == list(df.columns) + [c for c in list(m["columns"]) if c not in df.columns]
    for c in df.columns:
        if df[c].dtype == object:
            assert [str(x) if len(x) else "" for x in t[c]] == df[c].tolist(), c
        else:
            np.testing.assert_array_equal(t[c], df[c].to_numpy(), err_msg=c)  # bit for bit
    assert t["flags"][1] == "The load never settled; accepted by the operator."
    assert t["loaded_settle_time_s"].tolist() == [3.0, 4.0, 5.0]
    assert m["units"]["P_L1"] == "MPa" and m["units"]["loaded_settle_time_s"] == "s"
    assert m["provenance"]["protocol"] == "takuma2014" and m["provenance"]["versions_labcli"] == labcli.__version__


def test_an_unknown_extension_is_refused_in_one_sentence(run_path, tmp_path):
    for name, what in (
        ("t.txt", "the extension .txt, which names no format labcli writes"),
        ("trials", "no extension to name its format"),
    ):
        out = tmp_path / name
        res = invoke("export", run_path, "-o", out)
        assert res.exit_code == 1
        assert res.output == f"Error: {out} has {what}; end it in .csv, .parquet, .xlsx or .mat, or give --format.\n"
        assert not out.exists() and list(tmp_path.iterdir()) == [tmp_path / "run.h5"]
    out = tmp_path / "t.txt"
    assert invoke("export", run_path, "-o", out, "--format", "csv").exit_code == 0
    assert out.read_text().startswith("trial,set,")


def test_xlsx_without_openpyxl_is_one_sentence(run_path, tmp_path, monkeypatch):
    monkeypatch.setitem(sys.modules, "openpyxl", None)
    out = tmp_path / "t.xlsx"
    res = invoke("export", run_path, "-o", out)
    assert res.exit_code == 1
    assert res.output == (
        "Error: writing .xlsx needs openpyxl, which is not installed; install it with pip install 'labcli[xlsx]'.\n"
    )
    assert not out.exists()


def test_parquet_all_columns_round_trip(flagged_run, tmp_path):
    pytest.importorskip("pyarrow")
    out = tmp_path / "t.parquet"
    assert invoke("export", flagged_run, "-o", out, "--all-columns").exit_code == 0
    back = table_meta.read_parquet(out)
    assert back["flags"].tolist()[1] == "The load never settled; accepted by the operator."
    assert back.attrs["units"]["loaded_settle_time_s"] == "s"
