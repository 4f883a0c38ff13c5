"""rPAM point tables through ``labcli export``, ``labcli import`` and ``labcli inspect``.

Runs of the stretch test and of the joint map are recorded on ``sim://?mode=rpam`` with a
small grid; the yardstick is the run file's own point table (``RunFile.point_table``),
the protocol's grid, and the fit of the stretch correction, which must not change when
the run goes through a CSV file and back.
"""

from __future__ import annotations

import io
import json
import math
from pathlib import Path
from unittest import mock

import h5py
import numpy as np
import pandas as pd
import pytest
from click.testing import CliRunner
from rich.console import Console

from labcli.cli import cli
from labcli.core.acquisition import acquire
from labcli.core.protocol import load_protocol
from labcli.core.store import RunFile, columns, import_table
from labcli.core.tables import TableError
from labcli.core.ui import UnattendedUI
from labcli.errors import ConfigError
from labcli.papers.rpam2015.session import acquisition_protocol
from labcli.papers.rpam2015.tables import read_point_csv

SHIPPED = Path(__file__).resolve().parents[3] / "protocols" / "rpam2015.toml"
STRETCH_HEADER = "point,mass_g,P_A,P_B,L_m,lambda,set_mass_g,set_P_A_kPa,set_P_B_kPa"
JOINT_HEADER = "point,P_A,P_B,alpha_deg,P_A0,P_B0,L_m,set_P_A_kPa,set_P_B_kPa"
TABLE_HEAD = "has 1 problem (rows counted as a spreadsheet shows them, the header included):"


def small_protocol(folder: Path) -> Path:
    """The shipped protocol with 4 pressures per payload (24 points) and a 3 x 3 joint map."""
    text = SHIPPED.read_text(encoding="utf-8")
    for old, new in {
        'name = "rpam2015"': 'name = "rpam-small"',
        "pressure_count = 20": "pressure_count = 4",
        "Pa_count = 11": "Pa_count = 3",
        "Pb_count = 11": "Pb_count = 3",
    }.items():
        assert text.count(old) == 1, old
        text = text.replace(old, new)
    path = folder / "rpam-small.toml"
    path.write_text(text, encoding="utf-8")
    return path


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    d = tmp_path_factory.mktemp("rpam-tables")
    proto = small_protocol(d)
    out = {"dir": d, "protocol": proto}
    for experiment in ("stretch", "joint"):
        path = d / f"{experiment}.h5"
        outcome = acquire(
            path,
            "sim://?mode=rpam&seed=5&clock=virtual",
            protocol=str(proto),
            experiment=experiment,
            unattended=True,
            ui=UnattendedUI(console=Console(file=io.StringIO())),
        )
        assert outcome.status == "finished", outcome.message
        out[experiment] = path
    return out


def invoke(*args):
    return CliRunner().invoke(cli, [str(a) for a in args])


def kpa(p_MPa: float) -> str:
    """A pressure as inspect prints it: kPa to 0.1, a vented sensor's -0.0 shown as 0.0."""
    return f"{round(p_MPa * 1e3, 1) + 0.0:.1f}"


def table_of(path: Path) -> pd.DataFrame:
    with RunFile.open(path) as run:
        return run.records.table()


# --------------------------------------------------------------------------- export


@pytest.mark.parametrize(
    "experiment, header, n, title",
    [("stretch", STRETCH_HEADER, 24, "stretch test"), ("joint", JOINT_HEADER, 9, "joint map")],
)
def test_export_writes_every_point_of_the_run(runs, tmp_path, experiment, header, n, title):
    csv = tmp_path / f"{experiment}.csv"
    r = invoke("export", runs[experiment], "-o", csv)
    assert r.exit_code == 0, r.output
    assert r.output == f"Wrote {n} points of the {title} from {runs[experiment]} to {csv}.\n"
    lines = csv.read_text().splitlines()
    assert lines[0] == header and len(lines) == n + 1
    # Every value as the run file gives it: the CSV reads back to the point table exactly.
    back = pd.read_csv(csv)
    want = table_of(runs[experiment])
    assert list(back.columns) == list(want.columns)
    for c in want.columns:
        np.testing.assert_array_equal(back[c].to_numpy(dtype=float), want[c].to_numpy(dtype=float), err_msg=c)


@pytest.mark.parametrize("experiment", ["stretch", "joint"])
def test_export_import_export_is_byte_identical(runs, tmp_path, experiment):
    first, second, imported = tmp_path / "a.csv", tmp_path / "b.csv", tmp_path / "imp.h5"
    assert invoke("export", runs[experiment], "-o", first).exit_code == 0
    r = invoke("import", first, "-o", imported, "--protocol", runs["protocol"], "--experiment", experiment)
    assert r.exit_code == 0, r.output
    n = 24 if experiment == "stretch" else 9
    title = "stretch test" if experiment == "stretch" else "joint map"
    assert r.output == f"Imported {n} points of the {title} from {first} into {imported}.\n"
    with RunFile.open(imported) as run:
        assert run.kind == f"rpam-{experiment}" and run.attrs["imported"] and run.attrs["protocol"] == "rpam-small"
        assert run.records.ids() == list(range(1, n + 1))
    assert invoke("export", imported, "-o", second).exit_code == 0
    assert first.read_bytes() == second.read_bytes()


def test_an_imported_stretch_test_fits_exactly_as_the_recorded_one(runs, tmp_path):
    csv, imported = tmp_path / "s.csv", tmp_path / "s.h5"
    assert invoke("export", runs["stretch"], "-o", csv).exit_code == 0
    assert (
        invoke("import", csv, "-o", imported, "--protocol", runs["protocol"], "--experiment", "stretch").exit_code == 0
    )
    fits = []
    for run in (runs["stretch"], imported):
        r = invoke("fit", run, "-o", tmp_path / f"{Path(run).stem}.json", "--json")
        assert r.exit_code == 0, r.output
        fits.append(json.loads(r.output)["fit"]["model"])
    assert fits[0]["coefficients_N"] == fits[1]["coefficients_N"]
    assert fits[0]["covariance_N2"] == fits[1]["covariance_N2"] and fits[1]["n_points"] == 24


def test_an_imported_joint_map_validates_as_the_recorded_one(runs, tmp_path):
    csv, imported = tmp_path / "j.csv", tmp_path / "j.h5"
    assert invoke("export", runs["joint"], "-o", csv).exit_code == 0
    assert invoke("import", csv, "-o", imported, "--protocol", runs["protocol"], "--experiment", "joint").exit_code == 0
    results = []
    for run in (runs["joint"], imported):
        r = invoke("validate", run, "--json")
        assert r.exit_code == 0, r.output
        results.append(json.loads(r.output))
    # Every number of the comparison (RMSE, toggles, per-point errors) is the same.
    a, b = (
        json.dumps(r, sort_keys=True).replace(str(p), "RUN")
        for r, p in zip(results, (runs["joint"], imported), strict=False)
    )
    assert a == b and "rmse" in a


# --------------------------------------------------------------------------- import of hand-made tables


def test_a_stretch_table_without_lambda_gets_it_from_the_protocols_rest_length(tmp_path):
    csv = tmp_path / "s.csv"
    csv.write_text("point,mass_g,P_A,P_B,L_m,note\n1,100,0.05,0.0,0.091,first\n2,200,0.1,-0.0002,0.105,\n")
    out = tmp_path / "s.h5"
    r = invoke("import", csv, "-o", out, "--protocol", "rpam2015", "--experiment", "stretch")
    assert r.exit_code == 0, r.output
    t = table_of(out)
    # L0 = 0.07 m in rpam2015.toml; the payload is stored in kg and shown in g.
    assert t["lambda"].tolist() == [0.091 / 0.07, 0.105 / 0.07]
    assert t["mass_g"].tolist() == [100.0, 200.0] and t["P_B"].tolist() == [0.0, -0.0002]
    assert t["note"].tolist() == ["first", ""]  # a column labcli does not know is kept
    assert "set_mass_g" not in t.columns
    with h5py.File(out) as f:
        row = list(f["entry/points/point"][:]).index(1)
        assert f["entry/points/mass"][row] == pytest.approx(0.1, rel=1e-15)
        assert f["entry/points/mass"].attrs["units"] == b"kg"


def test_a_joint_table_without_baseline_or_length_keeps_what_it_has(tmp_path):
    csv = tmp_path / "j.csv"
    csv.write_text("point,P_A,P_B,alpha_deg\n3,0.041,0.138,-30.5\n4,0.138,0.041,30.25\n")
    out = tmp_path / "j.h5"
    assert invoke("import", csv, "-o", out, "--protocol", "rpam2015", "--experiment", "joint").exit_code == 0
    t = table_of(out)
    assert t["point"].tolist() == [3, 4] and t["alpha_deg"].tolist() == [-30.5, 30.25]
    assert t[["P_A0", "P_B0", "L_m"]].isna().all().all()
    again = tmp_path / "again.csv"
    assert invoke("export", out, "-o", again).exit_code == 0
    assert again.read_text() == csv.read_text()  # empty optional columns stay out of the file
    with h5py.File(out) as f:
        assert f["entry/points/alpha"][list(f["entry/points/point"][:]).index(3)] == math.radians(-30.5)


@pytest.mark.parametrize(
    "experiment, text, problem",
    [
        (
            "joint",
            "point,P_A,P_B,alpha_deg,P_A0\n1,0.05,0.05,1.0,0.0\n",
            "j.csv:row 1, column P_B0: is missing from the header but P_A0 is there; give both columns or neither.",
        ),
        (
            "stretch",
            "point,mass_g,P_A,P_B,L_m\n1,-100,0.05,0.0,0.09\n",
            "j.csv:row 2, column mass_g: -100 must be 0 or more.",
        ),
        (
            "stretch",
            "point,mass_g,P_A,P_B,L_m\n1000000,100,0.05,0.0,0.09\n",
            "j.csv:row 2, column point: 1000000 is outside the point ids a run file holds, 0 to 999999.",
        ),
        (
            "joint",
            "point,P_A,P_B,alpha_deg,note\n1,0.05,0.05,1.0,a\x00b\n",
            "j.csv:row 2, column note: holds a NUL character, which a run file cannot store; remove it.",
        ),
        ("joint", "point,P_A,P_B,alpha_deg\n1,0.05,high,1.0\n", "j.csv:row 2, column P_B: 'high' is not a number."),
    ],
)
def test_bad_point_tables_are_refused_by_row_and_column(tmp_path, monkeypatch, experiment, text, problem):
    monkeypatch.chdir(tmp_path)
    Path("j.csv").write_text(text)
    r = invoke("import", "j.csv", "-o", "j.h5", "--protocol", "rpam2015", "--experiment", experiment)
    assert r.exit_code == 1 and r.output == f"Error: j.csv {TABLE_HEAD}\n{problem}\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["j.csv"]


def test_experiment_with_a_force_protocol_is_refused(tmp_path):
    r = invoke(
        "import", tmp_path / "x.csv", "-o", tmp_path / "x.h5", "--protocol", "takuma2014", "--experiment", "joint"
    )
    assert r.exit_code == 1 and r.output == (
        "Error: --experiment picks one experiment of an rPAM protocol; "
        "takuma2014 is of kind 'force', so leave --experiment out.\n"
    )


def test_read_point_csv_names_the_experiments(tmp_path):
    with pytest.raises(ConfigError) as e:
        read_point_csv(tmp_path / "x.csv", "bend")
    assert str(e.value) == "an rPAM point table is of experiment stretch or joint, not 'bend'."
    (tmp_path / "x.csv").write_text("point,P_A,P_B,alpha_deg\n1,0.05,0.05,1.0\n")
    with pytest.raises(TableError):
        read_point_csv(tmp_path / "x.csv", "stretch")


# --------------------------------------------------------------------------- NUL in a table given from Python


def test_import_table_refuses_nul_before_making_a_file(tmp_path):
    df = pd.DataFrame(
        {
            "trial": [1, 2],
            "set": ["fit", "fit"],
            **{c: [0.2, 0.2] for c in ("P_L10", "P_R10", "P_L20", "P_R20", "P_L1", "P_R1", "P_L2", "P_R2")},
            "theta1_deg": [1.0, 2.0],
            "theta2_deg": [0.5, 0.5],
            "Fx_N": [0.0, 0.0],
            "Fy_N": [-1.0, -2.0],
            "note": ["ok", "x\x00y"],
        }
    )
    proto = load_protocol("takuma2014")
    with pytest.raises(ConfigError) as e:
        import_table(df, tmp_path / "r.h5", protocol=proto)
    assert str(e.value) == "trial 2, column note: holds a NUL character, which a run file cannot store; remove it."
    df = df.rename(columns={"note": "no\x00te"}).assign(**{"no\x00te": ["a", "b"]})
    with pytest.raises(ConfigError) as e:
        import_table(df, tmp_path / "r.h5", protocol=proto)
    assert str(e.value) == (
        "the column name 'no\\x00te' holds a NUL character, which a run file cannot store; rename the column."
    )
    assert list(tmp_path.iterdir()) == []


# --------------------------------------------------------------------------- inspect


def test_inspect_shows_the_experiment_its_coverage_and_settling(runs):
    r = invoke("inspect", runs["stretch"])
    assert r.exit_code == 0, r.output
    t = table_of(runs["stretch"])
    with RunFile.open(runs["stretch"]) as run:
        s = run.summary()
    lines = r.output.splitlines()
    assert lines[5:9] == [
        "  experiment  stretch test",
        "  points      24 of 24 planned complete, 0 incomplete",
        f"  pressures   P_A {kpa(t['P_A'].min())} to {kpa(t['P_A'].max())} kPa, "
        f"P_B {kpa(t['P_B'].min())} to {kpa(t['P_B'].max())} kPa (measured)",
        f"  payloads    0, 100, 200, 300, 1000, 1300 g; stretch lambda {t['lambda'].min():.3f} to "
        f"{t['lambda'].max():.3f} (L / L0)",
    ]
    st = s["settle"]
    assert lines[9] == (
        f"  settling    median {st['median_s']:.2f} s, max {st['max_s']:.2f} s over 24 points; 0 accepted on timeout"
    )
    # The payloads are the protocol's; the pressure sweep reaches its top, 190 kPa, within the sensor's noise.
    assert s["rpam"]["payloads_g"] == [0.0, 100.0, 200.0, 300.0, 1000.0, 1300.0]
    assert s["rpam"]["P_A_kPa"][1] == pytest.approx(190.0, abs=0.5)
    assert not any(line.startswith(("  split", "  baseline drift")) for line in lines)


def test_inspect_a_joint_map_cut_short(runs, tmp_path):
    """Four points of nine written, a fifth begun: the rest of the grid is named."""
    proto = acquisition_protocol(load_protocol(str(runs["protocol"])), "joint")
    path = tmp_path / "cut.h5"
    full = table_of(runs["joint"])
    with RunFile.create(path, protocol=proto, port="sim://") as run:
        for row in full.head(4).itertuples():
            run.records.write(
                {
                    "point": row.point,
                    "experiment": "joint",
                    "P_MPa": [row.P_A, row.P_B],
                    "alpha_rad": math.radians(row.alpha_deg),
                    "settle": {"load": {"settle_time_s": 2.5}},
                }
            )
        # what a kill during the fifth write leaves: its row written, never committed
        with mock.patch.object(columns.Table, "commit", side_effect=KeyboardInterrupt):
            with pytest.raises(KeyboardInterrupt):
                run.records.write({"point": 5, "experiment": "joint", "P_MPa": [0.01, 0.01], "alpha_rad": 0.0})
    r = invoke("inspect", path)
    assert r.exit_code == 0, r.output
    lines = r.output.splitlines()
    assert lines[5:10] == [
        "  experiment  joint map",
        "  points      4 of 9 planned complete, 1 incomplete (5)",
        "  to record   5 points (5, 6, 7, 8, 9); labcli acquire --resume records them",
        f"  pressures   P_A {kpa(full['P_A'][:4].min())} to {kpa(full['P_A'][:4].max())} kPa, "
        f"P_B {kpa(full['P_B'][:4].min())} to {kpa(full['P_B'][:4].max())} kPa (measured)",
        f"  deflection  alpha {full['alpha_deg'][:4].min():+.1f} to {full['alpha_deg'][:4].max():+.1f} deg "
        "from the vented baseline",
    ]
    assert lines[10] == "  settling    median 2.50 s, max 2.50 s over 4 points; 0 accepted on timeout"
    s = json.loads(invoke("inspect", path, "--json").output)
    assert s["rpam"]["missing_ids"] == [5, 6, 7, 8, 9] and s["incomplete_ids"] == [5]
    assert s["split"] is None and s["baseline_drift"] is None


def test_inspect_an_imported_point_table_claims_no_grid(tmp_path):
    csv = tmp_path / "j.csv"
    csv.write_text("point,P_A,P_B,alpha_deg\n1,0.05,0.1,-12.0\n2,0.1,0.05,12.5\n")
    out = tmp_path / "j.h5"
    assert invoke("import", csv, "-o", out, "--protocol", "rpam2015", "--experiment", "joint").exit_code == 0
    lines = invoke("inspect", out).output.splitlines()
    assert lines[1] == "  kind        rpam-joint, protocol rpam2015, imported from a table"
    assert lines[4:9] == [
        "  experiment  joint map",
        "  points      2 complete, 0 incomplete",
        "  pressures   P_A 50.0 to 100.0 kPa, P_B 50.0 to 100.0 kPa (measured)",
        "  deflection  alpha -12.0 to +12.5 deg from the vented baseline",
        "  settling    no settle times recorded",
    ]
