"""The whole-column reader agrees with the cell-by-cell one: same table, or it steps aside.

:func:`labcli.core.table_fast.read_fast` may decline a file (None), and the cell-by-cell
reader then decides; what it may never do is give a table that reader would refuse, or a
table that differs from the one it gives, in a value, a type or a column.
"""

from __future__ import annotations

from pathlib import Path

import pandas as pd
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from labcli.core import table_fast
from labcli.core.tables import PRESSURE_SPAN_MPA, _read
from labcli.errors import ConfigError
from labcli.papers.rpam2015.tables import JOINT_POINTS
from labcli.papers.takuma2014.tables import PLAN, PUSH, TRIAL

HEADER = "trial,set,P_L10,P_R10,P_L20,P_R20,P_L1,P_R1,P_L2,P_R2,theta1_deg,theta2_deg,Fx_N,Fy_N,mass_g,direction_deg"
ROW = "1,fit,0.2,0.2,0.25,0.25,0.21,0.19,0.26,0.24,1.5,-2.0,0.98,0.0,100,0"


def both(path: Path, spec=TRIAL):
    """(fast table or None, slow table or the error's text)."""
    fast = table_fast.read_fast(path, spec, PRESSURE_SPAN_MPA, None)
    try:
        slow = _read(path, spec, PRESSURE_SPAN_MPA)
    except ConfigError as exc:
        slow = str(exc)
    return fast, slow


def agree(path: Path, spec=TRIAL) -> pd.DataFrame | None:
    fast, slow = both(path, spec)
    if fast is not None:
        assert isinstance(slow, pd.DataFrame), f"the fast reader took a table the rules refuse: {slow}"
        pd.testing.assert_frame_equal(fast, slow)
    return fast


def put(tmp_path: Path, text: str, name: str = "t.csv") -> Path:
    p = tmp_path / name
    p.write_bytes(text.encode("utf-8"))
    return p


def test_a_clean_table_is_read_whole_column(tmp_path: Path) -> None:
    rows = [ROW.replace("1,fit", f"{i},fit", 1) for i in range(1, 6)]
    df = agree(put(tmp_path, HEADER + ",note\n" + "\n".join(r + ",n" for r in rows) + "\n"))
    assert df is not None and df["trial"].tolist() == [1, 2, 3, 4, 5] and df["note"].tolist() == ["n"] * 5


@pytest.mark.parametrize(
    "text",
    [
        f"{HEADER}\n{ROW.rsplit(',', 2)[0]}\n",  # short row: the two optional cells missing
        f"{HEADER}\n{ROW},5\n",  # long first row (pandas would shift it)
        f"{HEADER}\n{ROW}\n{ROW.replace('1,fit', '2,fit', 1)},5\n",  # long later row
        f"{HEADER}\n{ROW.replace(',0.98,', ',True,')}\n",  # pandas reads True as 1.0
        f"{HEADER}\n{ROW.replace(',100,0', ',100,false')}\n",
        f"{HEADER}\n{ROW.replace(',100,0', ',nan,nan')}\n",  # text NaN where an empty cell is allowed
        f"{HEADER}\n{ROW.replace(',100,0', ',inf,0')}\n",
        HEADER + "\n" + ROW.replace(",fit,", ',"fit",') + "\n",  # quoting
        f"{HEADER}\n{ROW.replace(',fit,', ', fit,')}\n",  # spaces around a set
        f"{HEADER}\r{ROW}\r",  # old Mac line ends
        f"\n{HEADER}\n{ROW}\n",  # blank line before the header
        f"{HEADER},\n{ROW},\n",  # an unnamed trailing column
        f"{HEADER}\n{ROW}\n{ROW}\n",  # a repeated id
        f"{HEADER}\n{ROW.replace(',1.5,', ',1e400,')}\n",
        f"{HEADER}\n{ROW.replace(',1.5,', ',400,')}\n",  # beyond a joint angle
        f"{HEADER}\n{ROW.replace(',100,0', ',100,')}\n",  # a pair half given
        f"{HEADER}\n{ROW.replace('1,fit', '3.5,fit', 1)}\n",  # an id that is not an integer
        HEADER + "\n" + ROW.replace(",fit,", ",a\x00b,") + "\n",
    ],
)
def test_anything_the_rules_might_judge_otherwise_goes_cell_by_cell(tmp_path: Path, text: str) -> None:
    p = put(tmp_path, text)
    assert table_fast.read_fast(p, TRIAL, PRESSURE_SPAN_MPA, None) is None
    agree(p)


@pytest.mark.parametrize(
    "text",
    [
        f"\ufeff{HEADER}\r\n{ROW}\r\n",
        f"{HEADER}\n{ROW}\n\n\n{ROW.replace('1,fit', '2,fit', 1)}\n\n",
        f"{HEADER}\n{ROW}",
        f"{HEADER}\n",
        f" trial ,{HEADER[6:]}\n{ROW}\n",
        f"{HEADER}\n{ROW.replace(',100,0', ',,')}\n",
        f"{HEADER}\n{ROW.replace(',100,0', ',100,200')}\n",  # a direction, wrapped to -160
        f"{HEADER}\n{ROW.replace('1,fit', '3.0,fit', 1)}\n",  # an integer id written as a number
    ],
)
def test_clean_variants_are_read_whole_column_and_agree(tmp_path: Path, text: str) -> None:
    df = agree(put(tmp_path, text))
    assert df is not None


def test_a_direction_is_wrapped_the_same_way(tmp_path: Path) -> None:
    df = agree(put(tmp_path, f"{HEADER}\n{ROW.replace(',100,0', ',100,200')}\n"))
    assert df["direction_deg"].tolist() == [-160.0]


def test_blocks_join_lines_split_between_them(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(table_fast, "BLOCK", 7)
    rows = [ROW.replace("1,fit", f"{i},validation", 1) for i in range(1, 40)]
    df = agree(put(tmp_path, HEADER + "\n" + "\n".join(rows) + "\n"))
    assert df is not None and len(df) == 39
    p = put(tmp_path, HEADER + "\n" + "\n".join(rows[:20] + [rows[20].rsplit(",", 1)[0]] + rows[21:]) + "\n")
    assert table_fast.read_fast(p, TRIAL, PRESSURE_SPAN_MPA, None) is None
    p = tmp_path / "cut.csv"
    p.write_bytes((HEADER + ",note\n" + ROW + ",é\n").encode()[:-2] + b"\n")  # half of a two-byte letter
    assert table_fast.read_fast(p, TRIAL, PRESSURE_SPAN_MPA, None) is None
    with pytest.raises(ConfigError, match="is not UTF-8 text"):
        _read(p, TRIAL, PRESSURE_SPAN_MPA)


# --------------------------------------------------------------------------- properties

NUMBER_TEXT = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True).map(repr),
    st.floats(min_value=-200, max_value=200).map(lambda v: f"{v:.3f}"),
    st.integers(-10, 10**6).map(str),
    st.sampled_from(
        [
            "",
            " ",
            "0",
            "1",
            "-0",
            "1.",
            ".5",
            "1e3",
            "+2",
            " 0.5",
            "0.5 ",
            "True",
            "false",
            "nan",
            "NaN",
            "inf",
            "-Infinity",
            "1e400",
            "0x10",
            "1_000",
            "NA",
            "null",
            "fit",
            "validation",
            "x",
        ]
    ),
)
TEXT = st.text(alphabet=st.characters(blacklist_categories=("Cs",)), max_size=6)
CELL = st.one_of(NUMBER_TEXT, NUMBER_TEXT, TEXT)


@st.composite
def near_tables(draw, spec) -> str:
    names = [c for c, _, p in spec.columns if p == "required" or draw(st.booleans())]
    names += draw(st.lists(st.sampled_from(["note", "T_degC", *spec.names]), max_size=2))
    names = draw(st.permutations(names))
    n = draw(st.integers(0, 5))
    lines = [",".join(names)]
    for i in range(n):
        cells = []
        for c in names:
            kind = dict((a, k) for a, k, _ in spec.columns).get(c, "text")
            if kind == "id":
                cells.append(draw(st.one_of(st.just(str(i)), NUMBER_TEXT)))
            elif kind.startswith("set"):
                cells.append(draw(st.sampled_from(["fit", "validation", "", " fit", "train"])))
            elif kind == "pressure":
                cells.append(draw(st.one_of(st.floats(0.001, 1.0).map(repr), NUMBER_TEXT)))
            else:
                cells.append(draw(CELL))
        if draw(st.integers(0, 6)) == 0:
            cells = cells[: draw(st.integers(0, len(cells)))] or cells + ["9"]
        lines.append(",".join(cells))
    if draw(st.booleans()):
        lines.insert(draw(st.integers(1, len(lines))), "")
    return "\n".join(lines) + draw(st.sampled_from(["\n", "", "\n\n"]))


@settings(max_examples=250, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(data=st.data())
def test_the_two_readers_never_disagree(tmp_path: Path, data) -> None:
    spec = data.draw(st.sampled_from([TRIAL, PUSH, PLAN, JOINT_POINTS]))
    text = data.draw(near_tables(spec))
    p = tmp_path / "t.csv"
    p.write_text(text, encoding="utf-8", newline="")
    agree(p, spec)


def test_cells_of_a_table_are_read_whole_column_or_refused_alike(tmp_path: Path) -> None:
    """Random damage to good rows: both outcomes occur, and the readers agree on each."""
    import random

    fast = refused = 0
    rnd = random.Random(5)
    for _ in range(120):
        cells = [ROW.split(",") for _ in range(3)]
        for r, row in enumerate(cells):
            row[0] = str(r)
            if rnd.random() < 0.3:
                row[rnd.randrange(len(row))] = rnd.choice(["x", "", "True", "1e400", "400", " 7", "-0", "1.0"])
        got = agree(put(tmp_path, HEADER + "\n" + "\n".join(",".join(r) for r in cells) + "\n"))
        fast += got is not None
        refused += got is None
    assert fast > 20 and refused > 20, (fast, refused)


def test_the_words_true_and_false_inside_a_name_or_a_cell_keep_the_whole_column_read(tmp_path: Path) -> None:
    # pandas turns a whole cell true/false into 1/0; a column named true_stiffness_N_per_m or an
    # object called falsework is no such cell, and must not send a million rows cell by cell.
    text = f"{HEADER},true_stiffness_N_per_m,note\n{ROW},420.0,falsework\n{ROW.replace('1,fit', '2,fit', 1)},,untrue\n"
    df = agree(put(tmp_path, text))
    assert df is not None and df["note"].tolist() == ["falsework", "untrue"]
    for cell in ("true", " FALSE", "True "):
        p = put(tmp_path, f"{HEADER},true_stiffness_N_per_m,note\n{ROW},420.0,{cell}\n", "w.csv")
        assert table_fast.read_fast(p, TRIAL, PRESSURE_SPAN_MPA, None) is None
        agree(p)


@given(
    st.lists(
        st.lists(
            st.sampled_from(["true", "false", " true", "true\t", "untrue", "falsework", "1.5", "", "x"]), max_size=4
        ),
        max_size=80,
    ),
    st.sampled_from(["\n", "\r\n"]),
)
@settings(max_examples=300)
def test_a_whole_true_or_false_cell_is_found_as_the_pattern_over_the_block_finds_it(rows, eol):
    # The lines holding either word are tried one by one, or the whole block past 64 of them.
    low = ("name,true_stiffness_N_per_m" + eol + "".join(",".join(r) + eol for r in rows)).encode()
    assert table_fast._boolean_cell(low) == (table_fast._BOOLEAN_CELL.search(low) is not None)


@given(
    st.lists(
        st.sampled_from(["a", "b,c", ",", "1.5", "\n", "\r\n", "\r", "\n\n", '"', "true", "é", "\x00"]), max_size=60
    ),
    st.integers(1, 17),
)
@settings(max_examples=300, suppress_health_check=[HealthCheck.function_scoped_fixture])
def test_the_scan_reads_the_same_whatever_the_blocks(tmp_path: Path, monkeypatch: pytest.MonkeyPatch, parts, block):
    # The scan reads blocks into one buffer and moves each unfinished line to its start: a file
    # cut anywhere (inside a line, between a carriage return and its line break, inside a
    # two-byte letter) scans as it does in one block.
    p = tmp_path / "s.csv"
    p.write_bytes("".join(["h,i\n", *parts]).encode("utf-8"))
    monkeypatch.setattr(table_fast, "BLOCK", 1 << 22)
    whole = table_fast._scan(p)
    monkeypatch.setattr(table_fast, "BLOCK", block)
    assert table_fast._scan(p) == whole


@pytest.mark.parametrize("block", [4, 5, 1 << 22])
def test_a_longer_first_line_is_refused_when_the_header_ends_a_block(tmp_path: Path, monkeypatch, block) -> None:
    # pandas takes a longer first data line as an index column; here the separators add up (a
    # short line makes up for it), so only the first line's own count can tell.  With the
    # header ending a block, that count was once taken on the line after it.
    p = put(tmp_path, "a,b\n1,2,3\n5,6\n4\n")
    monkeypatch.setattr(table_fast, "BLOCK", block)
    assert table_fast._scan(p) is None
    assert table_fast._scan(put(tmp_path, "a,b\n1,2\n5,6\n4,3\n", "good.csv")) == ["a", "b"]


@given(st.lists(st.sampled_from(["a", "1,2", ",", "\n", "\r\n", "\r", "\n\n", "\n\r\n", " "]), max_size=80))
@settings(max_examples=400)
def test_separators_and_lines_are_counted_as_one_line_at_a_time_counts_them(parts):
    # Whole lines (each ending in a line break), as the scan hands them over: the count with no
    # blank line among them (the bytes' own count) and with some (line ends whole-array) is the
    # count line by line.
    text = "".join(parts)
    text = text[: text.rfind("\n") + 1]
    data = bytearray(text.encode())
    lines = [line.removesuffix("\r") for line in text.split("\n")[:-1]]
    expected = (text.count(","), sum(1 for line in lines if line))
    assert table_fast._count(data, len(data)) == expected
