"""labcli split / export / import / inspect through the command line."""

from __future__ import annotations

import json
import math

import h5py
import numpy as np
import pytest
from click.testing import CliRunner
from support.records import FakeDevice, make_record

import labcli
from labcli.cli import cli
from labcli.core.protocol import load_protocol
from labcli.core.store import RunFile


def invoke(*args):
    return CliRunner().invoke(cli, [str(a) for a in args])


def make_run(path, n=30, protocol=None, drift=False):
    with RunFile.create(
        str(path),
        protocol=protocol or load_protocol("takuma2014"),
        device_info=FakeDevice(),
        port="sim://?seed=1",
        operator="ada",
    ) as run:
        for i in range(1, n + 1):
            rec = make_record(i)
            if drift:
                rec["P0_MPa"] = np.array([0.2 + 0.0002 * i, 0.25, 0.2, 0.3 - 0.0004 * i])
            run.records.write(rec)
    return str(path)


@pytest.fixture
def run_path(tmp_path):
    return make_run(tmp_path / "run.h5")


# ------------------------------------------------------------------ split


def test_split_sequential(run_path):
    res = invoke("split", run_path, "--fit", 20, "--validation", 6)
    assert res.exit_code == 0, res.output
    assert res.output == f"{run_path}: 20 fit, 6 validation, 4 unassigned of 30 completed trials (sequential).\n"
    with RunFile.open(run_path) as run:
        s = run.split.get()
        assert s["fit"] == list(range(1, 21)) and s["validation"] == list(range(21, 27))
        assert s["strategy"] == "sequential" and s["seed"] is None
        assert run.records.table()["set"].tolist() == ["fit"] * 20 + ["validation"] * 6 + [""] * 4


def test_split_random_is_reproducible(run_path, tmp_path):
    other = make_run(tmp_path / "other.h5")
    for p in (run_path, other):
        res = invoke("split", p, "--fit", 20, "--validation", 6, "--strategy", "random", "--seed", 11)
        assert res.exit_code == 0 and "(random, seed 11)." in res.output
    with RunFile.open(run_path) as a, RunFile.open(other) as b:
        assert (
            a.split.get()["fit"] == b.split.get()["fit"] and a.split.get()["validation"] == b.split.get()["validation"]
        )
        assert a.split.get()["fit"] != list(range(1, 21))
        assert a.split.get()["seed"] == 11


def test_split_defaults_from_the_runs_protocol(tmp_path):
    path = make_run(tmp_path / "big.h5", n=110)
    res = invoke("split", path)
    assert res.exit_code == 0
    assert res.output == f"{path}: 90 fit, 18 validation, 2 unassigned of 110 completed trials (sequential).\n"


def test_split_more_than_completed(run_path):
    res = invoke("split", run_path, "--fit", 90, "--validation", 18)
    assert res.exit_code == 1
    assert res.output == (
        f"Error: {run_path}: the run has 30 completed trials, fewer than the 108 asked for (90 fit + 18 validation).\n"
    )


def test_split_missing_file(tmp_path):
    res = invoke("split", tmp_path / "none.h5", "--fit", 1, "--validation", 1)
    assert res.exit_code == 1
    assert res.output == f"Error: {tmp_path / 'none.h5'} does not exist; check the path.\n"


# ------------------------------------------------------------------ export / import


def test_export_import_export_is_byte_identical(run_path, tmp_path):
    assert invoke("split", run_path, "--fit", 20, "--validation", 6).exit_code == 0
    first, second = tmp_path / "a.csv", tmp_path / "b.csv"
    res = invoke("export", run_path, "-o", first)
    assert res.exit_code == 0 and res.output == f"Wrote 30 trials from {run_path} to {first}.\n"
    imported = tmp_path / "imp.h5"
    res = invoke("import", first, "-o", imported, "--protocol", "takuma2014")
    assert res.exit_code == 0
    assert res.output == f"Imported 30 trials from {first} into {imported} (split: 20 fit, 6 validation).\n"
    assert invoke("export", imported, "-o", second).exit_code == 0
    assert first.read_bytes() == second.read_bytes()
    header = first.read_text().splitlines()[0]
    assert header == (
        "trial,set,P_L10,P_R10,P_L20,P_R20,P_L1,P_R1,P_L2,P_R2,theta1_deg,theta2_deg,Fx_N,Fy_N,"
        "mass_g,direction_deg,theta1_0_deg,theta2_0_deg"
    )
    with RunFile.open(str(imported)) as run:
        assert run.attrs["imported"] is True and run.attrs["source"] == "a.csv"
        assert run.attrs["protocol"] == "takuma2014" and run.protocol_text == load_protocol("takuma2014").text
        assert run.records.read(7)["raw"] == {}
        # SI inside: degrees and grams came back as rad and kg
        rec = make_record(7)
        assert run.records.read(7)["theta_rad"][0] == pytest.approx(rec["theta_rad"][0], rel=1e-11)
        assert run.records.read(7)["mass_kg"] == pytest.approx(rec["mass_kg"], rel=1e-12)
    with h5py.File(str(imported), "r") as f:
        assert f["entry/trials/theta"].attrs["units"] == b"rad"


def test_round_trip_keeps_extra_columns(tmp_path):
    src = tmp_path / "in.csv"
    src.write_text(
        "trial,set,P_L10,P_R10,P_L20,P_R20,P_L1,P_R1,P_L2,P_R2,theta1_deg,theta2_deg,Fx_N,Fy_N,note,rep\n"
        "1,fit,0.2,0.2,0.2,0.2,0.21,0.19,0.2,0.2,1.5,-2.25,0.0,-1.96133,first,1\n"
        "2,validation,0.2,0.2,0.2,0.2,0.22,0.18,0.2,0.2,3.0,-4.5,0.0,-3.92266,,2\n"
    )
    out = tmp_path / "run.h5"
    assert invoke("import", src, "-o", out, "--protocol", "takuma2014").exit_code == 0
    back = tmp_path / "back.csv"
    assert invoke("export", out, "-o", back).exit_code == 0
    assert back.read_text() == src.read_text()


def test_import_bad_row_reports_row_and_column(tmp_path):
    src = tmp_path / "bad.csv"
    src.write_text(
        "trial,set,P_L10,P_R10,P_L20,P_R20,P_L1,P_R1,P_L2,P_R2,theta1_deg,theta2_deg,Fx_N,Fy_N\n"
        "1,fit,0.2,0.2,0.2,0.2,0.21,0.19,0.2,0.2,1.5,-2.25,0.0,-1.96\n"
        "2,fit,0.2,0.2,0.2,abc,0.22,0.18,0.2,0.2,3.0,-4.5,0.0,-3.92\n"
    )
    out = tmp_path / "run.h5"
    res = invoke("import", src, "-o", out, "--protocol", "takuma2014")
    assert res.exit_code == 1
    assert f"{src}:row 3, column P_R20: 'abc' is not a number." in res.output
    assert res.output.startswith("Error: ")
    assert "Traceback" not in res.output
    assert not out.exists()


def test_import_refuses_overwrite(run_path, tmp_path):
    csv = tmp_path / "t.csv"
    assert invoke("export", run_path, "-o", csv).exit_code == 0
    res = invoke("import", csv, "-o", run_path, "--protocol", "takuma2014")
    assert res.exit_code == 1
    assert res.output == f"Error: {run_path} already exists; use --force to overwrite it.\n"
    with RunFile.open(run_path) as run:  # untouched, raw windows still there
        assert run.records.read(3)["raw"]["load"].counts.shape == (50, 6)
    res = invoke("import", csv, "-o", run_path, "--protocol", "takuma2014", "--force")
    assert res.exit_code == 0
    with RunFile.open(run_path) as run:
        assert run.attrs["imported"] is True


def test_push_run_export_import(tmp_path):
    proto = load_protocol("takuma2014-stiffness")
    path = str(tmp_path / "push.h5")
    rec = make_record(1)
    with RunFile.create(path, protocol=proto, device_info=FakeDevice()) as run:
        for i, (obj, phi) in enumerate([("pet-1", None), ("can-al-1", math.radians(12.5)), ("can-steel-1", 0.0)]):
            run.records.write(
                {
                    "push": i + 1,
                    "object": obj,
                    "R_m": 0.033,
                    "d_m": 0.004 + 0.001 * i,
                    "phi_rad": phi,
                    "category": "" if i == 0 else "hard",
                    "P0_MPa": rec["P0_MPa"],
                    "P_MPa": rec["P_MPa"],
                    "raw": rec["raw"],
                    "settle": rec["settle"],
                }
            )
    a, b = tmp_path / "a.csv", tmp_path / "b.csv"
    res = invoke("export", path, "-o", a)
    assert res.exit_code == 0 and res.output == f"Wrote 3 pushes from {path} to {a}.\n"
    lines = a.read_text().splitlines()
    assert lines[0] == "push,object,R_m,d_m,phi_deg,P_L10,P_R10,P_L20,P_R20,P_L1,P_R1,P_L2,P_R2,category"
    assert lines[1].split(",")[4] == "" and lines[2].split(",")[4] == "12.5"
    imported = tmp_path / "imp.h5"
    assert invoke("import", a, "-o", imported, "--protocol", "takuma2014-stiffness").exit_code == 0
    assert invoke("export", imported, "-o", b).exit_code == 0
    assert a.read_bytes() == b.read_bytes()


def test_load_trials_api_reads_run_files(run_path, tmp_path):
    df = labcli.load_trials(run_path)
    assert len(df) == 30 and df["trial"].tolist() == list(range(1, 31))
    assert df.loc[0, "theta1_deg"] == pytest.approx(math.degrees(make_record(1)["theta_rad"][0]))
    csv = tmp_path / "t.csv"
    assert invoke("export", run_path, "-o", csv).exit_code == 0
    assert labcli.load_trials(csv).equals(df)


def test_rest_posture_and_wrapped_direction_round_trip(tmp_path):
    """theta1_0_deg/theta2_0_deg are stored as pot0 (rad) and come back; a direction of 200 deg comes back -160."""
    header = (
        "trial,set,P_L10,P_R10,P_L20,P_R20,P_L1,P_R1,P_L2,P_R2,theta1_deg,theta2_deg,Fx_N,Fy_N,"
        "mass_g,direction_deg,theta1_0_deg,theta2_0_deg"
    )
    rows = [
        "1,fit,0.2,0.2,0.25,0.25,0.21,0.19,0.26,0.24,1.5,-2,0.98,0,100,200,12.5,-30",
        "2,validation,0.2,0.2,0.25,0.25,0.21,0.19,0.26,0.24,1.5,-2,0.98,0,100,-90,,",
        "3,fit,0.2,0.2,0.25,0.25,0.21,0.19,0.26,0.24,1.5,-2,0.98,0,100,270,0,170",
    ]
    src, run, out = tmp_path / "t.csv", tmp_path / "t.h5", tmp_path / "out.csv"
    src.write_text("\n".join([header, *rows]) + "\n")
    assert invoke("import", src, "-o", run, "--protocol", "takuma2014").exit_code == 0
    with RunFile.open(run) as f:
        assert np.allclose(f.records.read(1)["pot0_rad"], [math.radians(12.5), math.radians(-30)], rtol=1e-15)
        assert "pot0_rad" not in f.records.read(2)
    df = labcli.load_trials(run)
    assert df["theta1_0_deg"].tolist()[::2] == [12.5, 0.0] and df["theta2_0_deg"].tolist()[::2] == [-30.0, 170.0]
    assert math.isnan(df.loc[1, "theta1_0_deg"]) and math.isnan(df.loc[1, "theta2_0_deg"])
    assert df["direction_deg"].tolist() == [-160.0, -90.0, -90.0]  # 270 and -90 are the same direction
    assert invoke("export", run, "-o", out).exit_code == 0
    assert out.read_text().splitlines()[1].endswith(",100.0,-160.0,12.5,-30.0")
    assert labcli.load_trials(out).equals(df)


# ------------------------------------------------------------------ inspect


def test_inspect_numbers(tmp_path):
    path = make_run(tmp_path / "d.h5", n=30, drift=True)
    from unittest import mock

    from labcli.core.store import columns

    # An interrupted trial, as a kill between writing its row and committing it leaves it.
    with RunFile.open(path, "a") as run, mock.patch.object(columns.Table, "commit", side_effect=KeyboardInterrupt):
        with pytest.raises(KeyboardInterrupt):
            run.records.write(make_record(31))
    assert invoke("split", path, "--fit", 20, "--validation", 6).exit_code == 0
    res = invoke("inspect", path, "--json")
    assert res.exit_code == 0
    s = json.loads(res.output)
    assert (s["complete"], s["incomplete"], s["incomplete_ids"]) == (30, 1, [31])
    assert s["split"] == {"strategy": "sequential", "seed": None, "fit": 20, "validation": 6, "unassigned": 4}
    d = s["baseline_drift"]
    assert d["P_L1"]["slope_kPa_per_trial"] == pytest.approx(0.2)
    assert d["P_R2"]["slope_kPa_per_trial"] == pytest.approx(-0.4)
    assert d["P_R2"]["max_deviation_kPa"] == pytest.approx(29 * 0.4)
    assert d["P_R1"]["slope_kPa_per_trial"] == pytest.approx(0.0, abs=1e-12)
    times = [2.0 + (i % 4) for i in range(1, 31)]
    assert s["settle"]["median_s"] == float(np.median(times)) and s["settle"]["max_s"] == 5.0
    assert s["settle"]["timeout_ids"] == [4, 9, 14, 19, 24, 29]
    assert (s["device"], s["firmware"], s["operator"], s["protocol"]) == ("mckibben-2dof", "1.0", "ada", "takuma2014")

    res = invoke("inspect", path)
    assert res.exit_code == 0
    out = res.output
    assert "  trials      30 complete, 1 incomplete (31)\n" in out
    assert "  split       20 fit, 6 validation, 4 unassigned (sequential)\n" in out
    assert (
        "  settling    median 3.50 s, max 5.00 s over 30 trials; 6 accepted on timeout (4, 9, 14, 19, 24, 29)\n"
    ) in out
    assert ("    P_R2  first 0.2996 MPa, last 0.2880 MPa, slope -0.400 kPa/trial, max deviation 11.600 kPa\n") in out


def test_inspect_errors(tmp_path):
    other = tmp_path / "other.h5"
    with h5py.File(other, "w") as f:
        f.attrs["schema"] = "something-else"
    res = invoke("inspect", other)
    assert res.exit_code == 1
    assert res.output == (
        f"Error: {other} is an HDF5 file but not a labcli run file (schema 'something-else', expected 'labcli-run').\n"
    )
    text = tmp_path / "notes.txt"
    text.write_text("hello\n")
    res = invoke("inspect", text)
    assert res.exit_code == 1
    assert res.output == (
        f"Error: {text} is not an HDF5 file; run files are written by 'labcli acquire' or 'labcli import'.\n"
    )


def test_inspect_imported_run_without_settle_times(tmp_path):
    src = tmp_path / "in.csv"
    src.write_text(
        "trial,set,P_L10,P_R10,P_L20,P_R20,P_L1,P_R1,P_L2,P_R2,theta1_deg,theta2_deg,Fx_N,Fy_N\n"
        "1,fit,0.2,0.2,0.2,0.2,0.21,0.19,0.2,0.2,1.5,-2.25,0.0,-1.96\n"
        "2,,0.201,0.2,0.2,0.2,0.22,0.18,0.2,0.2,3.0,-4.5,0.0,-3.92\n"
    )
    out = tmp_path / "run.h5"
    assert invoke("import", src, "-o", out, "--protocol", "takuma2014").exit_code == 0
    res = invoke("inspect", out)
    assert res.exit_code == 0
    assert "  settling    no settle times recorded\n" in res.output
    assert "  split       1 fit, 0 validation, 1 unassigned (imported)\n" in res.output
    assert (
        "    P_L1  first 0.2000 MPa, last 0.2010 MPa, slope +1.000 kPa/trial, max deviation 1.000 kPa\n" in res.output
    )


# ------------------------------------------------------------------ with the acquisition engine


def test_acquired_run_on_the_simulated_rig(tmp_path):
    plan = tmp_path / "plan.csv"
    plan.write_text("trial,set,mass_g,direction_deg\n1,fit,200,0\n2,fit,300,45\n3,validation,100,90\n")
    run = tmp_path / "run.h5"
    res = invoke("acquire", run, "--port", "sim://?seed=2", "--unattended", "--plan", plan)
    assert res.exit_code == 0, res.output
    s = json.loads(invoke("inspect", run, "--json").output)
    assert (s["complete"], s["incomplete"], s["planned"]) == (3, 0, 3)
    assert s["split"] == {"strategy": "plan", "seed": None, "fit": 2, "validation": 1, "unassigned": 0}
    assert s["device"] and s["port"] == "sim://?seed=2"
    df = labcli.load_trials(run)
    assert df["set"].tolist() == ["fit", "fit", "validation"]
    assert df["mass_g"].tolist() == [200.0, 300.0, 100.0] and df["direction_deg"].tolist() == [0.0, 45.0, 90.0]
    g = 9.80665
    assert df.loc[1, "Fx_N"] == pytest.approx(0.3 * g * math.cos(math.pi / 4), rel=1e-12)
    assert df.loc[2, "Fy_N"] == pytest.approx(0.1 * g, rel=1e-12)
    with RunFile.open(str(run)) as rf:
        t = rf.records.read(2)
        load = t["raw"]["load"]
        assert load.counts.dtype == np.int32 and load.counts.shape[1] == 6 and len(load.seq) > 10
        # SI values are the protocol's calibration of the counts as sent
        np.testing.assert_allclose(load.si, rf_cal(rf, load.counts), rtol=0, atol=1e-12)
        # the summary pressures are the means of the windows
        np.testing.assert_allclose(t["P_MPa"], load.si[:, :4].mean(axis=0), rtol=1e-12)
        assert np.all(np.diff(load.t_s) > 0) and np.all(np.diff(load.seq.astype(np.int64)) == 1)
        assert t["accepted"] in ("auto", "timeout") and t["settle"]["load"]["criterion"]
    res = invoke("acquire", run, "--port", "sim://?seed=2", "--unattended", "--plan", plan)
    assert res.exit_code == 1
    assert "already exists" in res.output


def rf_cal(rf, counts):
    cal = rf.calibration()
    return counts * cal["gain"] + cal["offset"]


from hypothesis import HealthCheck, given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402

_deg = st.floats(-180, 180, allow_nan=False)
_direction = st.floats(-180, 180, exclude_min=True)  # -180 is read as 180, the same direction
_mpa = st.floats(0.01, 0.99, allow_nan=False)
_row = st.tuples(
    st.lists(_mpa, min_size=8, max_size=8),
    _deg,
    _deg,
    st.floats(-50, 50, allow_nan=False),
    st.floats(0.001, 5000),
    _direction,
)


@settings(max_examples=15, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(rows=st.lists(_row, min_size=1, max_size=3))
def test_any_table_round_trips_byte_identical(tmp_path_factory, rows):
    """Any table, once in a run file, exports to bytes that survive import -> export exactly."""
    import pandas as pd

    from labcli.papers.takuma2014.tables import read_trial_csv, write_trial_csv

    d = tmp_path_factory.mktemp("rt")
    df = pd.DataFrame(
        {
            "trial": list(range(1, len(rows) + 1)),
            "set": ["fit"] * len(rows),
            **{
                c: [r[0][j] for r in rows]
                for j, c in enumerate(["P_L10", "P_R10", "P_L20", "P_R20", "P_L1", "P_R1", "P_L2", "P_R2"])
            },
            "theta1_deg": [r[1] for r in rows],
            "theta2_deg": [r[2] for r in rows],
            "Fx_N": [r[3] for r in rows],
            "Fy_N": [-r[3] for r in rows],
            "mass_g": [r[4] for r in rows],
            "direction_deg": [r[5] for r in rows],
        }
    )
    source = d / "source.csv"
    write_trial_csv(df, source)
    assert invoke("import", source, "-o", d / "r1.h5", "--protocol", "takuma2014").exit_code == 0
    assert invoke("export", d / "r1.h5", "-o", d / "a.csv").exit_code == 0
    assert invoke("import", d / "a.csv", "-o", d / "r2.h5", "--protocol", "takuma2014").exit_code == 0
    assert invoke("export", d / "r2.h5", "-o", d / "b.csv").exit_code == 0
    assert (d / "b.csv").read_bytes() == (d / "a.csv").read_bytes()
    # degrees and grams went through rad and kg: what comes out is what went in to 12 digits
    back = read_trial_csv(d / "a.csv")
    for c in ("theta1_deg", "theta2_deg", "mass_g"):
        np.testing.assert_allclose(back[c], df[c], rtol=1e-11, atol=1e-300)
    # a direction is the same direction: within 1e-9 deg of -180 it is kept to 12 digits, -180, and reads 180
    turn = (back["direction_deg"] - df["direction_deg"] + 180.0) % 360.0 - 180.0
    np.testing.assert_allclose(turn, 0.0, atol=1e-9)
    for c in ("P_L10", "P_R2", "Fx_N", "Fy_N"):
        assert back[c].tolist() == df[c].tolist()  # stored as given: exact
