"""Arbitrary rows into ``labcli import``: a run file that round-trips, or one sentence per problem.

Rows are drawn near the trial-table format (docs/table-formats.md): mostly valid cells, with text,
empty cells, non-finite and out-of-span numbers, quotes, separators and line breaks mixed in,
columns left out or repeated, unknown extra columns, ragged rows.  The outcome is one of two:

* the table reads, the import succeeds, and the run's trial table gives back every value
  (pressures and forces exactly; angles and masses, stored in rad and kg, to the 12 significant
  digits the store keeps), with the
  extra columns kept; a second export -> import -> export is byte-identical;
* reading fails with a ConfigError whose every problem names the file, the row and (but for a
  ragged row) the column, in one sentence, and no run file is created.

Anything else (another exception, a half-written run file) fails the test.
"""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from labcli.cli import cli
from labcli.core.protocol import load_protocol
from labcli.core.store import MAX_ID, RunFile, import_table, storable_cells
from labcli.core.tables import TableError
from labcli.errors import ConfigError, StoreError
from labcli.papers.takuma2014.tables import TRIAL, read_trial_csv, write_trial_csv

STANDARD = list(TRIAL.names)
REQUIRED = [c for c, _, presence in TRIAL.columns if presence == "required"]
PRESSURES = [c for c, kind, _ in TRIAL.columns if kind == "pressure"]
EXACT = PRESSURES + ["Fx_N", "Fy_N"]
CONVERTED = ["theta1_deg", "theta2_deg", "mass_g", "direction_deg", "theta1_0_deg", "theta2_0_deg"]  # rad / kg
OPTIONAL = ("mass_g", "direction_deg", "theta1_0_deg", "theta2_0_deg")
PROTOCOL = load_protocol("takuma2014")

# NUL is left out of good text: a run file cannot store it, and the import refuses it by row and
# column (test_bad_input.py, case trial-nul-in-extra); JUNK below puts it in now and then.
TEXT = st.text(alphabet=st.characters(blacklist_categories=("Cs",), blacklist_characters="\x00"), max_size=10)
JUNK = st.one_of(
    st.sampled_from(
        [
            "",
            " ",
            "nan",
            "NaN",
            "inf",
            "-inf",
            "1e400",
            "-0",
            "0",
            "1.5",
            "-3",
            "0x10",
            "1,5",
            "1_000",
            "１２",
            "fit",
            "validation",
            "FIT",
            '"',
            "'",
            "\r",
            "\n",
            "a\nb",
            "1e-400",
            "9" * 30,
            "0.5 ",
            " 0.5",
            "a\x00b",
        ]
    ),
    TEXT,
    st.floats(allow_nan=True, allow_infinity=True).map(repr),
    st.integers(-(2**70), 2**70).map(str),
)


def good_cell(column: str, trial: int) -> st.SearchStrategy[str]:
    if column == "trial":
        return st.just(str(trial))
    if column == "set":
        return st.sampled_from(["fit", "validation", ""])
    if column in PRESSURES:
        return st.floats(min_value=1e-6, max_value=1.0).map(repr)
    if column == "mass_g":
        return st.floats(min_value=1e-3, max_value=5e3).map(repr)
    if column in ("Fx_N", "Fy_N"):
        return st.floats(min_value=-1e3, max_value=1e3, allow_subnormal=False).map(repr)
    # angles; a direction of -180 reads back as 180, the same direction
    return st.floats(min_value=-180, max_value=180, exclude_min=column == "direction_deg", allow_subnormal=False).map(
        repr
    )


@st.composite
def tables(draw, valid: bool = False) -> tuple[str, bool]:
    """CSV text of a trial table, and whether it is valid (every cell, column and id); ``valid`` forces it."""
    header = [c for c in STANDARD if c not in OPTIONAL]
    if draw(st.booleans()):
        header += ["mass_g", "direction_deg"]
    if draw(st.booleans()):
        header += ["theta1_0_deg", "theta2_0_deg"]
    names = ["note", "operator", "T_degC"] + ([] if valid else ["Fx_N", "trial"])
    extras = draw(st.lists(st.sampled_from(names), max_size=2, unique=valid))
    header += extras
    header = draw(st.permutations(header))
    if not valid and draw(st.integers(0, 9)) == 0:
        header.remove(draw(st.sampled_from(header)))  # a required column may go missing
    n = draw(st.integers(0, 6))
    damage = 0 if valid else draw(st.integers(0, 3))  # 0: every cell valid
    id_values = st.integers(0, MAX_ID) if valid or draw(st.integers(0, 3)) else st.integers(-5, 2**40)
    ids = draw(st.lists(id_values, min_size=n, max_size=n, unique=damage != 3))
    rows = []
    clean = (
        damage == 0
        and len(set(header)) == len(header)
        and set(REQUIRED) <= set(header)
        and ("mass_g" in header) == ("direction_deg" in header)
        and ("theta1_0_deg" in header) == ("theta2_0_deg" in header)
        and all(0 <= t <= MAX_ID for t in ids)
    )
    for i in range(n):
        row = []
        for c in header:
            if c in ("note", "operator"):
                row.append(draw(TEXT))
            elif c == "T_degC":
                row.append(draw(st.sampled_from(["21.5", "22", "", "warm"])))
            else:
                row.append(draw(good_cell(c, ids[i])))
        if damage and draw(st.booleans()):
            j = draw(st.integers(0, max(len(row) - 1, 0)))
            if row:
                row[j] = draw(JUNK)
        if damage == 2 and draw(st.integers(0, 4)) == 0:
            row = row[: draw(st.integers(0, len(row)))]  # ragged
        rows.append(row)
    return "".join(_line(r) for r in [header, *rows]), clean


def _line(fields: list[str]) -> str:
    # RFC 4180 quoting; csv.writer leaves a lone '\r' unquoted, which every reader takes for a line break.
    return ",".join('"' + f.replace('"', '""') + '"' if any(ch in f for ch in ',"\r\n') else f for f in fields) + "\n"


PROBLEM = re.compile(r"^(?P<file>.+?):row (?P<row>\d+)(, column (?P<col>[^:]+))?: (?P<msg>[^\n]+)\.$")


def check_outcome(text: str, folder: Path) -> None:
    src = folder / "t.csv"
    out = folder / "t.h5"
    src.write_text(text, encoding="utf-8", newline="")
    try:
        df = read_trial_csv(src)
    except TableError as e:
        lines = str(e).split("\n")
        n = len(e.problems)
        assert lines[0] == (
            f"{src} has {n} problem{'s' if n != 1 else ''} "
            "(rows counted as a spreadsheet shows them, the header included):"
        )
        for p in e.problems:
            m = PROBLEM.match(p)
            assert m and m["file"] == str(src), p
            assert m["col"] is not None or " values but the header has " in p, p
            assert "Traceback" not in p and "Error" not in p, p
        assert not out.exists()
        return
    except ConfigError as e:
        # The file as a whole (no header, not CSV): one sentence naming it.
        assert "\n" not in str(e) and str(e).startswith(str(src)) and str(e).endswith("."), str(e)
        assert not out.exists()
        return
    nul = [(i, c) for c in df.columns for i, v in enumerate(df[c]) if isinstance(v, str) and "\x00" in v]
    if nul:
        # Text a run file cannot hold: refused before any file is made, and by row and column
        # when the reader is given the store's check (as labcli import does).
        with pytest.raises(ConfigError) as e:
            import_table(df, out, protocol=PROTOCOL, source="t.csv")
        assert "holds a NUL character, which a run file cannot store" in str(e.value)
        assert not out.exists() and not Path(str(out) + ".importing").exists()
        with pytest.raises(TableError) as e:
            read_trial_csv(src, check=storable_cells)
        assert all(
            PROBLEM.match(p) and p.endswith("holds a NUL character, which a run file cannot store; remove it.")
            for p in e.value.problems
        ), e.value.problems
        assert len(e.value.problems) == len(nul)
        return
    outside = [int(t) for t in df["trial"] if not 0 <= t <= MAX_ID]
    if outside:
        # The reader takes any int64 id; a run file holds 0..MAX_ID.  import_table refuses them
        # (naming the id); the reader's id_range, which labcli import passes, names row and column.
        with pytest.raises(StoreError) as e:
            import_table(df, out, protocol=PROTOCOL, source="t.csv")
        assert str(e.value) == f"trial {outside[0]}: trial ids must be between 0 and {MAX_ID}."
        assert not out.exists() and not Path(str(out) + ".importing").exists()
        with pytest.raises(TableError) as e:
            read_trial_csv(src, id_range=(0, MAX_ID))
        assert any(
            re.fullmatch(
                rf"{re.escape(str(src))}:row \d+, column trial: -?\d+ is outside the trial ids "
                rf"a run file holds, 0 to {MAX_ID}\.",
                p,
            )
            for p in e.value.problems
        )
        return
    try:
        run = import_table(df, out, protocol=PROTOCOL, source="t.csv")
    except StoreError as e:
        # A value no rig can produce (a joint turned past a full turn): refused by the run file in
        # one sentence naming the record, the value and the range; no file is made.
        m = re.fullmatch(
            r"trial (\d+): .+ reads (\S+) (\S+), outside the physically possible (\S+) to (\S+) \3\.", str(e)
        )
        assert m, str(e)
        assert not float(m[4]) <= float(m[2]) <= float(m[5])
        assert not out.exists()
        return
    with run:
        back = run.records.table()
    assert list(back["trial"]) == list(df["trial"])
    assert list(back["set"]) == list(df["set"])
    for c in EXACT:
        assert back[c].tolist() == df[c].tolist(), c
    for c in CONVERTED:
        want = df[c].to_numpy(dtype=float)
        got = back[c].to_numpy(dtype=float) if c in back.columns else np.full(len(df), np.nan)
        if c == "direction_deg":  # a direction is kept wrapped into (-180, 180]: compare on the circle
            assert np.array_equal(np.isnan(got), np.isnan(want)), c
            both = ~np.isnan(want)
            turn = (got[both] - want[both] + 180.0) % 360.0 - 180.0
            turn = np.where(turn < -180.0 + 1e-9, turn + 360.0, turn)  # -180 and 180 are one direction
            assert np.all(np.abs(turn) <= 5e-11 * np.maximum(np.abs(want[both]), 1.0)), (c, got, want)
            continue
        np.testing.assert_allclose(got, want, rtol=5e-12 * 10, atol=0, err_msg=c)  # 12 digits kept
    extras = [c for c in df.columns if c not in STANDARD]
    if len(df):  # an extra column is kept per record: with no record there is nothing to keep
        assert [c for c in back.columns if c not in STANDARD] == extras
    for c in extras if len(df) else []:
        assert [(_same(a, b)) for a, b in zip(back[c].tolist(), df[c].tolist(), strict=False)] == [True] * len(df), c
    # From here the file is in its canonical form: export -> import -> export changes no byte.
    first, second, again = folder / "a.csv", folder / "b.csv", folder / "again.h5"
    write_trial_csv(back, first)
    with import_table(read_trial_csv(first), again, protocol=PROTOCOL, source="a.csv", force=True) as run:
        write_trial_csv(run.records.table(), second)
    assert first.read_bytes() == second.read_bytes()


def _same(a, b) -> bool:
    if isinstance(a, float) and isinstance(b, float):
        return (math.isnan(a) and math.isnan(b)) or a == b
    return a == b


@settings(
    max_examples=100, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow]
)
@given(tables())
def test_arbitrary_rows_import_or_fail_with_row_and_column(tmp_path_factory, case) -> None:
    text, _ = case
    check_outcome(text, tmp_path_factory.mktemp("fz"))


@settings(
    max_examples=40, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow]
)
@given(tables(valid=True))
def test_valid_rows_always_import(tmp_path_factory, case) -> None:
    text, clean = case
    assert clean
    folder = tmp_path_factory.mktemp("ok")
    check_outcome(text, folder)
    assert (folder / "t.h5").exists()


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.binary(max_size=300))
def test_arbitrary_bytes_are_a_table_or_one_sentence(tmp_path_factory, data: bytes) -> None:
    folder = tmp_path_factory.mktemp("bytes")
    src = folder / "t.csv"
    src.write_bytes(data)
    try:
        read_trial_csv(src)
    except TableError as e:
        assert all(PROBLEM.match(p) for p in e.problems), e.problems
    except ConfigError as e:
        assert "\n" not in str(e) and str(src) in str(e), str(e)


@settings(
    max_examples=40, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow]
)
@given(tables())
def test_the_import_command_never_crashes(tmp_path_factory, case) -> None:
    """The command itself, in process, with exceptions not caught by the runner."""
    text, clean = case
    folder = tmp_path_factory.mktemp("cli")
    src, out = folder / "t.csv", folder / "t.h5"
    src.write_text(text, encoding="utf-8", newline="")
    r = CliRunner().invoke(
        cli, ["import", str(src), "-o", str(out), "--protocol", "takuma2014"], catch_exceptions=False
    )
    if r.exit_code == 0:
        assert r.output.startswith("Imported ") and out.exists()
        assert RunFile.open(out).records.ids() is not None
    else:
        assert r.exit_code == 1 and not out.exists() and not clean
        lines = r.output.splitlines()
        assert lines[0].startswith(f"Error: {src}")
        assert all(PROBLEM.match(line) for line in lines[1:]), lines


def test_a_ragged_row_and_a_bad_cell_are_both_named(tmp_path: Path) -> None:
    header = ",".join(STANDARD[:14])
    good = "1,fit," + ",".join(["0.2"] * 8) + ",1.0,2.0,0.5,-0.5"
    bad = good.replace("1,fit", "2,fit", 1).replace(",1.0,", ",one,")
    src = tmp_path / "t.csv"
    src.write_text(f"{header}\n{good}\n{bad}\n3,fit,0.2\n")
    with pytest.raises(TableError) as e:
        read_trial_csv(src)
    assert e.value.problems == [
        f"{src}:row 3, column theta1_deg: 'one' is not a number.",
        f"{src}:row 4: has 3 values but the header has 14 columns.",
    ]


def test_an_id_a_run_file_cannot_hold_is_named_by_row_and_column(tmp_path: Path) -> None:
    header = ",".join(STANDARD[:14])
    src = tmp_path / "t.csv"
    src.write_text(
        f"{header}\n5,fit," + ",".join(["0.2"] * 8) + ",1.0,2.0,0.5,-0.5\n"
        "1000000,fit," + ",".join(["0.2"] * 8) + ",1.0,2.0,0.5,-0.5\n"
    )
    r = CliRunner().invoke(
        cli, ["import", str(src), "-o", str(tmp_path / "t.h5"), "--protocol", "takuma2014"], catch_exceptions=False
    )
    assert r.exit_code == 1 and not (tmp_path / "t.h5").exists()
    assert r.output.splitlines()[1] == (
        f"{src}:row 3, column trial: 1000000 is outside the trial ids a run file holds, 0 to 999999."
    )
