"""Trial, push and plan CSV tables: checks, exact messages, byte-exact round trips."""

from __future__ import annotations

import csv
import io
import math
import re
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from labcli.core.store import runfile
from labcli.core.tables import MAX_LISTED, TableError
from labcli.errors import ConfigError
from labcli.papers.takuma2014.records import load_pushes, load_trials
from labcli.papers.takuma2014.tables import (
    PUSH,
    REST,
    TRIAL,
    load_plan,
    read_push_csv,
    read_trial_csv,
    write_plan_csv,
    write_push_csv,
    write_trial_csv,
)

HEADER = "trial,set,P_L10,P_R10,P_L20,P_R20,P_L1,P_R1,P_L2,P_R2,theta1_deg,theta2_deg,Fx_N,Fy_N,mass_g,direction_deg"
GOOD_ROW = "1,fit,0.2,0.2,0.25,0.25,0.21,0.19,0.26,0.24,1.5,-2.0,0.98,0.0,100,0"
PUSH_HEADER = "push,object,R_m,d_m,phi_deg,P_L10,P_R10,P_L20,P_R20,P_L1,P_R1,P_L2,P_R2,category"


def put(tmp_path: Path, text: str, name: str = "trials.csv") -> Path:
    p = tmp_path / name
    p.write_bytes(text.encode("utf-8"))
    return p


def problems_of(fn, path: Path) -> str:
    with pytest.raises(ConfigError) as exc:
        fn(path)
    return str(exc.value)


# ---------------------------------------------------------------- reading


def test_reads_a_valid_trial_table_with_types(tmp_path: Path) -> None:
    p = put(
        tmp_path,
        f"{HEADER},note\n{GOOD_ROW},first\n" + GOOD_ROW.replace("1,fit", "2,", 1).replace(",100,0", ",,") + ",\n",
    )
    df = read_trial_csv(p)
    assert list(df.columns) == list(TRIAL.names) + ["note"]
    assert df["trial"].dtype == np.int64 and df["trial"].tolist() == [1, 2]
    assert df["set"].tolist() == ["fit", ""]
    assert df["P_L1"].tolist() == [0.21, 0.21] and df["P_L1"].dtype == np.float64
    assert df["mass_g"].iloc[0] == 100.0 and math.isnan(df["mass_g"].iloc[1])
    assert math.isnan(df["direction_deg"].iloc[1])
    assert df["note"].tolist() == ["first", ""]


def test_every_problem_is_reported_with_row_and_column(tmp_path: Path) -> None:
    rows = [
        GOOD_ROW,
        "2,train,0.2,0,0.25,0.25,0.21,1.19,0.26,0.24,1.5,-2.0,x,0.0,100,",
        GOOD_ROW.replace("1,fit", "1,validation", 1).replace(",0.0,100,0", ",nan,-5,0"),
    ]
    p = put(tmp_path, HEADER + "\n" + "\n".join(rows) + "\n")
    assert problems_of(read_trial_csv, p) == "\n".join(
        [
            f"{p} has 8 problems (rows counted as a spreadsheet shows them, the header included):",
            f"{p}:row 3, column set: 'train' must be fit, validation or empty (unassigned).",
            f"{p}:row 3, column P_R10: 0 MPa is not a positive gauge pressure.",
            f"{p}:row 3, column P_R1: 1.19 MPa is outside the sensor span 0 to 1 MPa.",
            f"{p}:row 3, column Fx_N: 'x' is not a number.",
            f"{p}:row 3, column direction_deg: is empty but mass_g is given; give both or neither.",
            f"{p}:row 4, column Fy_N: 'nan' is not a number.",
            f"{p}:row 4, column mass_g: -5 must be greater than 0.",
            f"{p}:row 4, column trial: trial 1 is already used on row 2.",
        ]
    )


def test_problems_are_collected_in_a_table_error(tmp_path: Path) -> None:
    p = put(tmp_path, HEADER + "\n" + GOOD_ROW.replace("0.21", "2.1", 1) + "\n")
    with pytest.raises(TableError) as exc:
        read_trial_csv(p)
    assert exc.value.problems == [f"{p}:row 2, column P_L1: 2.1 MPa is outside the sensor span 0 to 1 MPa."]
    assert str(exc.value).startswith(f"{p} has 1 problem (rows")


def test_missing_columns_and_one_sided_pair(tmp_path: Path) -> None:
    header = HEADER.replace(",theta2_deg", "").replace(",direction_deg", "")
    row = GOOD_ROW.replace(",-2.0", "").rsplit(",", 1)[0]
    p = put(tmp_path, f"{header}\n{row}\n")
    assert problems_of(read_trial_csv, p).splitlines()[1:] == [
        f"{p}:row 1, column theta2_deg: required column is missing from the header.",
        f"{p}:row 1, column direction_deg: is missing from the header but mass_g is there; give both columns or neither.",
    ]


def test_set_and_optional_columns_may_be_absent(tmp_path: Path) -> None:
    header = ",".join(c for c in HEADER.split(",") if c not in ("set", "mass_g", "direction_deg"))
    row = ",".join(v for i, v in enumerate(GOOD_ROW.split(",")) if i not in (1, 14, 15))
    df = read_trial_csv(put(tmp_path, f"{header}\n{row}\n"))
    assert df["set"].tolist() == [""]
    assert math.isnan(df["mass_g"].iloc[0]) and math.isnan(df["direction_deg"].iloc[0])
    assert list(df.columns) == list(TRIAL.names)


def test_ragged_rows_and_unnamed_columns(tmp_path: Path) -> None:
    # A trailing separator on every line (spreadsheet export) is harmless.
    df = read_trial_csv(put(tmp_path, f"{HEADER},\n{GOOD_ROW},\n{GOOD_ROW.replace('1,fit', '2,fit', 1)},,\n"))
    assert len(df) == 2 and list(df.columns) == list(TRIAL.names)
    p = put(tmp_path, f"{HEADER},\n{GOOD_ROW},oops\n{GOOD_ROW[:20]}\n")
    assert problems_of(read_trial_csv, p).splitlines()[1:] == [
        f"{p}:row 1, column 17: has values but no name in the header.",
        f"{p}:row 3: has 6 values but the header has 17 columns.",
    ]


def test_duplicate_header_names(tmp_path: Path) -> None:
    p = put(tmp_path, f"{HEADER},Fx_N\n{GOOD_ROW},1.0\n")
    assert problems_of(read_trial_csv, p).splitlines()[1:] == [
        f"{p}:row 1, column Fx_N: appears twice in the header (columns 13 and 17)."
    ]


def test_blank_lines_keep_spreadsheet_row_numbers(tmp_path: Path) -> None:
    p = put(tmp_path, f"{HEADER}\n\n{GOOD_ROW}\n\n{GOOD_ROW.replace('0.21', '-1', 1)}\n\n")
    assert problems_of(read_trial_csv, p).splitlines()[1:] == [
        f"{p}:row 5, column P_L1: -1 MPa is not a positive gauge pressure.",
        f"{p}:row 5, column trial: trial 1 is already used on row 3.",
    ]


def test_bom_crlf_and_spaces_are_accepted(tmp_path: Path) -> None:
    text = "\ufeff" + HEADER.replace(",", ", ") + "\r\n" + GOOD_ROW.replace(",", " , ") + "\r\n"
    df = read_trial_csv(put(tmp_path, text))
    assert df["trial"].tolist() == [1] and df["set"].tolist() == ["fit"] and df["Fx_N"].tolist() == [0.98]


def test_whole_file_errors(tmp_path: Path) -> None:
    assert (
        problems_of(read_trial_csv, tmp_path / "none.csv") == f"{tmp_path / 'none.csv'} does not exist; check the path."
    )
    p = put(tmp_path, "\n\n")
    assert problems_of(read_trial_csv, p) == (
        f"{p} has no header row; the first line must name the columns (trial, P_L10, P_R10, P_L20, P_R20, "
        "P_L1, P_R1, P_L2, P_R2, theta1_deg, theta2_deg, Fx_N, Fy_N)."
    )
    p = tmp_path / "latin.csv"
    p.write_bytes(b"trial,obj\xe9t\n")
    assert problems_of(read_trial_csv, p) == f"{p} is not UTF-8 text (bad byte at offset 9); save it as CSV UTF-8."
    p = put(tmp_path, HEADER.replace(",", ";") + "\n" + GOOD_ROW.replace(",", ";") + "\n")
    assert (
        problems_of(read_trial_csv, p)
        .splitlines()[1]
        .endswith(
            "required column is missing from the header (the header is one column: is the file separated by ';' "
            "or tabs instead of commas?)."
        )
    )
    p = put(tmp_path, f'{HEADER}\n1,"fit\n')
    assert problems_of(read_trial_csv, p).startswith(f"{p}:row 2: not valid CSV (")
    assert problems_of(read_trial_csv, tmp_path) == f"{tmp_path} is a folder, not a CSV file."


def test_integer_ids(tmp_path: Path) -> None:
    df = read_trial_csv(put(tmp_path, HEADER + "\n" + GOOD_ROW.replace("1,fit", "3.0,fit", 1) + "\n"))
    assert df["trial"].tolist() == [3]
    p = put(tmp_path, HEADER + "\n" + GOOD_ROW.replace("1,fit", "3.5,fit", 1) + "\n")
    assert problems_of(read_trial_csv, p).splitlines()[1] == f"{p}:row 2, column trial: '3.5' is not an integer id."
    p = put(tmp_path, HEADER + "\n" + GOOD_ROW.replace("1,fit", ",fit", 1) + "\n")
    assert problems_of(read_trial_csv, p).splitlines()[1] == (
        f"{p}:row 2, column trial: is empty; an integer id is required."
    )


def test_long_error_lists_are_capped_but_counted(tmp_path: Path) -> None:
    n = MAX_LISTED + 50
    rows = [GOOD_ROW.replace("1,fit", f"{i},fitt", 1) for i in range(n)]
    p = put(tmp_path, HEADER + "\n" + "\n".join(rows) + "\n")
    with pytest.raises(TableError) as exc:
        read_trial_csv(p)
    lines = str(exc.value).splitlines()
    assert lines[0].startswith(f"{p} has {n} problems")
    assert len(lines) == MAX_LISTED + 2 and lines[-1] == "... and 50 more."
    assert len(exc.value.problems) == n


def test_push_table(tmp_path: Path) -> None:
    good = "1,pet-1,0.033,0.01,,0.2,0.2,0.2,0.2,0.21,0.19,0.2,0.2,soft"
    df = read_push_csv(put(tmp_path, f"{PUSH_HEADER},true_stiffness_N_per_m\n{good},350.0\n", "pushes.csv"))
    assert df["object"].tolist() == ["pet-1"] and math.isnan(df["phi_deg"].iloc[0])
    assert df["true_stiffness_N_per_m"].dtype == np.float64
    bad = "2, ,0,-0.001,x,0.2,0.2,0.2,0.2,0.21,0.19,0.2,0.2,"
    p = put(tmp_path, f"{PUSH_HEADER}\n{good}\n{bad}\n", "pushes.csv")
    assert problems_of(read_push_csv, p).splitlines()[1:] == [
        f"{p}:row 3, column object: is empty; an object name is required.",
        f"{p}:row 3, column R_m: 0 must be greater than 0.",
        f"{p}:row 3, column d_m: -0.001 must be 0 or more.",
        f"{p}:row 3, column phi_deg: 'x' is not a number.",
    ]


def test_extra_columns_become_numbers_only_when_nothing_is_lost(tmp_path: Path) -> None:
    p = put(
        tmp_path, f"{HEADER},a,b,c,d\n{GOOD_ROW},007,1.50,1.5,3\n{GOOD_ROW.replace('1,fit', '2,fit', 1)},8,2.0,,4\n"
    )
    df = read_trial_csv(p)
    assert df["a"].tolist() == ["007", "8"]  # a leading zero is kept as text
    assert df["b"].tolist() == ["1.50", "2.0"]
    assert df["c"].dtype == np.float64 and df["c"].iloc[0] == 1.5 and math.isnan(df["c"].iloc[1])
    assert df["d"].dtype == np.int64
    out = tmp_path / "out.csv"
    write_trial_csv(df, out)
    assert out.read_text().splitlines()[1].endswith(",007,1.50,1.5,3")


# ---------------------------------------------------------------- plan


def test_plan_errors_name_row_and_column(tmp_path: Path) -> None:
    text = "trial,set,mass_g,direction_deg\n1,fit,50,0\n2,,50,0\n3,validation,2500,200\n4,fit,0,x\n"
    p = put(tmp_path, text, "plan.csv")
    with pytest.raises(TableError) as exc:
        load_plan(p, mass_range_g=(1, 2000), direction_range_deg=(-90, 90))
    assert exc.value.problems == [
        f"{p}:row 3, column set: '' must be fit or validation.",
        f"{p}:row 4, column mass_g: 2500 g is outside the protocol's range 1 to 2000 g.",
        f"{p}:row 4, column direction_deg: -160 deg is outside the protocol's range -90 to 90 deg.",
        f"{p}:row 5, column mass_g: 0 must be greater than 0.",
        f"{p}:row 5, column direction_deg: 'x' is not a number.",
    ]
    assert len(load_plan(put(tmp_path, text.split("2,,")[0], "ok.csv"))) == 1


def test_a_plan_direction_is_any_angle_wrapped(tmp_path: Path) -> None:
    text = "trial,set,mass_g,direction_deg\n1,fit,50,200\n2,fit,50,270\n3,fit,50,-90\n4,fit,50,540\n5,fit,50,-180\n"
    plan = load_plan(put(tmp_path, text, "plan.csv"), direction_range_deg=(-180, 180))
    assert plan["direction_deg"].tolist() == [-160.0, -90.0, -90.0, 180.0, 180.0]  # (-180, 180]
    p = put(tmp_path, "trial,set,mass_g,direction_deg\n1,fit,50,721\n", "far.csv")
    assert problems_of(load_plan, p).splitlines()[1:] == [
        f"{p}:row 2, column direction_deg: 721 deg is outside the range of a direction, -720 to 720 deg."
    ]


def test_plan_round_trip(tmp_path: Path) -> None:
    plan = load_plan(Path(__file__).resolve().parents[2] / "protocols" / "takuma2014-plan.csv")
    a, b = tmp_path / "a.csv", tmp_path / "b.csv"
    write_plan_csv(plan, a)
    write_plan_csv(load_plan(a), b)
    assert a.read_bytes() == b.read_bytes()
    pd.testing.assert_frame_equal(load_plan(b), plan)


# ---------------------------------------------------------------- writing


def _trial_frame(n: int = 3) -> pd.DataFrame:
    rng = np.random.default_rng(3)
    df = pd.DataFrame({"trial": np.arange(1, n + 1), "set": ["fit"] * (n - 1) + ["validation"]})
    for c in ("P_L10", "P_R10", "P_L20", "P_R20", "P_L1", "P_R1", "P_L2", "P_R2"):
        df[c] = rng.uniform(0.1, 0.4, n)
    for c in ("theta1_deg", "theta2_deg", "Fx_N", "Fy_N"):
        df[c] = rng.normal(0, 3, n)
    return df


def test_export_order_is_standard_then_extras(tmp_path: Path) -> None:
    df = _trial_frame()
    df.insert(0, "operator_note", ["a", "b", "c"])
    df = df[list(reversed(df.columns))]
    out = tmp_path / "t.csv"
    write_trial_csv(df, out)
    header = out.read_text().splitlines()[0].split(",")
    optional = ("mass_g", "direction_deg", "theta1_0_deg", "theta2_0_deg")
    assert header == [c for c in TRIAL.names if c not in optional] + ["operator_note"]
    # optional columns appear once they carry values
    df["mass_g"] = [100.0, 200.0, 50.0]
    df["direction_deg"] = [0.0, 90.0, -30.0]
    write_trial_csv(df, out)
    assert out.read_text().splitlines()[0].split(",") == list(TRIAL.names[:-2]) + ["operator_note"]
    df["theta2_0_deg"] = [0.5, -1.0, 2.0]
    df["theta1_0_deg"] = [10.0, 0.0, -3.25]
    write_trial_csv(df, out)
    assert out.read_text().splitlines()[0].split(",") == list(TRIAL.names) + ["operator_note"]


def test_floats_are_written_repr_exact(tmp_path: Path) -> None:
    df = _trial_frame(1)
    df["Fx_N"] = [0.1 + 0.2]
    df["theta1_deg"] = [-1e-300]
    out = tmp_path / "t.csv"
    write_trial_csv(df, out)
    row = dict(zip(*[r.split(",") for r in out.read_text().splitlines()], strict=False))
    assert row["Fx_N"] == "0.30000000000000004" and row["theta1_deg"] == "-1e-300"
    back = read_trial_csv(out)
    assert back["Fx_N"].iloc[0] == 0.1 + 0.2


def test_writing_an_invalid_table_fails_and_keeps_the_old_file(tmp_path: Path) -> None:
    out = tmp_path / "t.csv"
    out.write_text("precious\n")
    df = _trial_frame()
    df.loc[1, "P_L1"] = 1.5
    with pytest.raises(ConfigError) as exc:
        write_trial_csv(df, out)
    assert str(exc.value).splitlines()[1] == f"{out}:row 3, column P_L1: 1.5 MPa is outside the sensor span 0 to 1 MPa."
    assert out.read_text() == "precious\n"
    assert [p.name for p in tmp_path.iterdir()] == ["t.csv"]  # no temporary file left
    with pytest.raises(ConfigError) as exc:
        write_trial_csv(_trial_frame().drop(columns=["Fy_N", "P_L1"]), out)
    assert str(exc.value) == f"Cannot write {out}: the trial table has no column P_L1, Fy_N."
    with pytest.raises(ConfigError) as exc:
        write_trial_csv(_trial_frame(), tmp_path / "no" / "such" / "t.csv")
    assert str(exc.value).startswith(f"Cannot write {tmp_path / 'no' / 'such' / 't.csv'}: ")


def test_integer_valued_float_ids_are_written_as_integers(tmp_path: Path) -> None:
    df = _trial_frame()
    df["trial"] = df["trial"].astype(float)
    out = tmp_path / "t.csv"
    write_trial_csv(df, out)
    assert [r.split(",")[0] for r in out.read_text().splitlines()] == ["trial", "1", "2", "3"]


# ---------------------------------------------------------------- run files


def test_h5_paths_go_to_the_run_file(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    calls = []

    class FakeRun:
        @classmethod
        def open(cls, path):
            calls.append(("open", str(path)))
            return cls()

        @property
        def records(self):
            return self

        def table(self, kind):
            calls.append(("table", kind.kind))
            return pd.DataFrame({kind.id_column: [1]})

        def __enter__(self):
            return self

        def __exit__(self, *exc):
            calls.append("close")

    monkeypatch.setattr(runfile, "RunFile", FakeRun)
    assert load_trials(tmp_path / "run.h5")["trial"].tolist() == [1]
    assert load_pushes(tmp_path / "run.H5")["push"].tolist() == [1]
    assert calls == [
        ("open", str(tmp_path / "run.h5")),
        ("table", "force"),
        "close",
        ("open", str(tmp_path / "run.H5")),
        ("table", "push"),
        "close",
    ]
    p = put(tmp_path, f"{HEADER}\n{GOOD_ROW}\n")
    assert load_trials(p)["trial"].tolist() == [1]


# ---------------------------------------------------------------- properties

SAFE_TEXT = st.text(alphabet=st.characters(blacklist_categories=("Cs",)), max_size=12)
NOTE = st.text(alphabet="abc ,\"'\n\r;\t-é", max_size=8).map(lambda s: "n" + s)
PRESSURE = st.floats(min_value=0.0, max_value=1.0, exclude_min=True, allow_nan=False)
ANY_FLOAT = st.floats(allow_nan=False, allow_infinity=False)
ANGLE = st.floats(min_value=-180, max_value=180)
DIRECTION = st.floats(min_value=-180, max_value=180, exclude_min=True)  # -180 reads back as 180
FORCE = st.floats(min_value=-1000, max_value=1000)


def _rest_posture(draw, df: pd.DataFrame, n: int) -> None:
    """The optional rest posture (both columns or neither; per row both cells or neither)."""
    if draw(st.booleans()):
        pairs = draw(st.lists(st.one_of(st.none(), st.tuples(ANGLE, ANGLE)), min_size=n, max_size=n))
        df["theta1_0_deg"] = pd.Series([math.nan if p is None else p[0] for p in pairs], dtype="float64")
        df["theta2_0_deg"] = pd.Series([math.nan if p is None else p[1] for p in pairs], dtype="float64")


@st.composite
def trial_tables(draw) -> pd.DataFrame:
    n = draw(st.integers(0, 8))
    ids = draw(st.lists(st.integers(-(2**62), 2**62), min_size=n, max_size=n, unique=True))
    df = pd.DataFrame({"trial": pd.Series(ids, dtype="int64")})
    df["set"] = pd.Series(
        draw(st.lists(st.sampled_from(["fit", "validation", ""]), min_size=n, max_size=n)), dtype=object
    )
    for c in ("P_L10", "P_R10", "P_L20", "P_R20", "P_L1", "P_R1", "P_L2", "P_R2"):
        df[c] = pd.Series(draw(st.lists(PRESSURE, min_size=n, max_size=n)), dtype="float64")
    for c, values in (("theta1_deg", ANGLE), ("theta2_deg", ANGLE), ("Fx_N", FORCE), ("Fy_N", FORCE)):
        df[c] = pd.Series(draw(st.lists(values, min_size=n, max_size=n)), dtype="float64")
    pairs = draw(
        st.lists(
            st.one_of(st.none(), st.tuples(st.floats(min_value=1e-3, max_value=1e5), DIRECTION)), min_size=n, max_size=n
        )
    )
    df["mass_g"] = pd.Series([math.nan if p is None else p[0] for p in pairs], dtype="float64")
    df["direction_deg"] = pd.Series([math.nan if p is None else p[1] for p in pairs], dtype="float64")
    _rest_posture(draw, df, n)
    if draw(st.booleans()):
        df["temperature_C"] = pd.Series(
            draw(st.lists(st.one_of(ANY_FLOAT, st.just(math.nan)), min_size=n, max_size=n)), dtype="float64"
        )
    if draw(st.booleans()):
        df["note"] = pd.Series(draw(st.lists(NOTE, min_size=n, max_size=n)), dtype=object)
    return df


@st.composite
def push_tables(draw) -> pd.DataFrame:
    n = draw(st.integers(0, 8))
    ids = draw(st.lists(st.integers(0, 10**9), min_size=n, max_size=n, unique=True))
    df = pd.DataFrame({"push": pd.Series(ids, dtype="int64")})
    df["object"] = pd.Series(draw(st.lists(NOTE, min_size=n, max_size=n)), dtype=object)
    df["R_m"] = pd.Series(
        draw(st.lists(st.floats(min_value=1e-6, max_value=1.0), min_size=n, max_size=n)), dtype="float64"
    )
    df["d_m"] = pd.Series(
        draw(st.lists(st.floats(min_value=0.0, max_value=0.1), min_size=n, max_size=n)), dtype="float64"
    )
    df["phi_deg"] = pd.Series(
        draw(st.lists(st.one_of(DIRECTION, st.just(math.nan)), min_size=n, max_size=n)), dtype="float64"
    )
    for c in ("P_L10", "P_R10", "P_L20", "P_R20", "P_L1", "P_R1", "P_L2", "P_R2"):
        df[c] = pd.Series(draw(st.lists(PRESSURE, min_size=n, max_size=n)), dtype="float64")
    df["category"] = pd.Series(
        draw(st.lists(st.sampled_from(["", "soft", "hard", "can, steel"]), min_size=n, max_size=n)), dtype=object
    )
    _rest_posture(draw, df, n)
    if draw(st.booleans()):
        df["true_stiffness_N_per_m"] = pd.Series(
            draw(st.lists(st.floats(min_value=0, max_value=1e6), min_size=n, max_size=n)), dtype="float64"
        )
    return df


def _canonical(df: pd.DataFrame, names: tuple[str, ...], optional: tuple[str, ...], empty_text: str) -> pd.DataFrame:
    """What a reader returns for ``df``: optional columns always present, empty ones empty."""
    out = df.copy()
    for c in optional:
        if c not in out.columns:
            out[c] = pd.Series(
                [empty_text if c == "category" else math.nan] * len(out), dtype=object if c == "category" else "float64"
            )
    for c in out.columns:
        if c not in names and not any(v == v and v != "" for v in out[c]):
            out[c] = pd.Series([math.nan] * len(out), dtype="float64")  # an empty column has no type
    return out[list(names) + [c for c in df.columns if c not in names]].reset_index(drop=True)


@settings(max_examples=100, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(df=trial_tables())
def test_valid_trial_tables_round_trip_exactly(tmp_path: Path, df: pd.DataFrame) -> None:
    a, b = tmp_path / "a.csv", tmp_path / "b.csv"
    write_trial_csv(df, a)
    back = read_trial_csv(a)
    pd.testing.assert_frame_equal(back, _canonical(df, TRIAL.names, ("mass_g", "direction_deg", *REST), ""))
    write_trial_csv(back, b)
    assert a.read_bytes() == b.read_bytes()


@settings(max_examples=100, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(df=push_tables())
def test_valid_push_tables_round_trip_exactly(tmp_path: Path, df: pd.DataFrame) -> None:
    a, b = tmp_path / "a.csv", tmp_path / "b.csv"
    write_push_csv(df, a)
    back = read_push_csv(a)
    pd.testing.assert_frame_equal(back, _canonical(df, PUSH.names, ("category", *REST), ""))
    write_push_csv(back, b)
    assert a.read_bytes() == b.read_bytes()


CELL = st.one_of(
    SAFE_TEXT,
    st.sampled_from(["", "fit", "validation", "0.2", "1", "-3", "1e400", "nan", "inf", " 0.5 ", "2.0", "0"]),
    st.floats().map(repr),
    st.integers().map(str),
)
NAME = st.one_of(st.sampled_from(list(TRIAL.names) + list(PUSH.names)), SAFE_TEXT)
PROBLEM_LINE = re.compile(r"^.+:row \d+(, column .+)?: .+\.$|^\.\.\. and \d+ more\.$", re.S)


def _check_outcome(fn, path: Path) -> None:
    try:
        df = fn(path)
    except TableError as exc:
        lines = str(exc).split("\n")
        assert lines[0].startswith(f"{path} has {len(exc.problems)} problem")
        for line in exc.problems:
            assert line.startswith(f"{path}:row ") and PROBLEM_LINE.match(line), line
    except ConfigError as exc:
        assert str(exc).strip() and str(path) in str(exc)
    else:
        assert isinstance(df, pd.DataFrame)


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(
    header=st.one_of(st.just(list(TRIAL.names)), st.just(list(PUSH.names)), st.lists(NAME, max_size=16)),
    rows=st.lists(st.lists(CELL, max_size=18), max_size=6),
)
def test_arbitrary_rows_never_crash_the_readers(tmp_path: Path, header: list[str], rows: list[list[str]]) -> None:
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(header)
    w.writerows(rows)
    p = tmp_path / "x.csv"
    p.write_text(buf.getvalue(), encoding="utf-8")
    for fn in (read_trial_csv, read_push_csv, load_plan):
        _check_outcome(fn, p)


@settings(max_examples=200, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(data=st.binary(max_size=300))
def test_arbitrary_bytes_never_crash_the_readers(tmp_path: Path, data: bytes) -> None:
    p = tmp_path / "x.csv"
    p.write_bytes(data)
    for fn in (read_trial_csv, read_push_csv, load_plan):
        _check_outcome(fn, p)
