"""Every table labcli prints stays whole at 80 columns, and plain when stdout is not a terminal."""

from __future__ import annotations

import io
import re
from pathlib import Path

import pandas as pd
import pytest
from click.testing import CliRunner

from labcli.cli import cli
from labcli.core.report import print_table
from labcli.papers.takuma2014.models.synthetic import paper_trials
from labcli.papers.takuma2014.tables import write_trial_csv

BOX = re.compile("[\u2500-\u257f]")  # box-drawing characters
CUT_NUMBER = re.compile(r"[0-9.+\-]\u2026")  # a number cut short: "0.009…", "+0.00…", "18…"


def run80(*args):
    return CliRunner(env={"COLUMNS": "80"}).invoke(cli, [str(a) for a in args])


@pytest.fixture(scope="module")
def world(tmp_path_factory) -> Path:
    d = tmp_path_factory.mktemp("t80")
    table = pd.concat(
        [paper_trials(30, seed=1), paper_trials(8, seed=2, set_name="validation", start_id=31)], ignore_index=True
    )
    write_trial_csv(table, d / "trials.csv")
    assert run80("import", d / "trials.csv", "-o", d / "run.h5", "--protocol", "takuma2014").exit_code == 0
    return d


def assert_whole_and_plain(text: str) -> None:
    assert text.strip()
    assert not BOX.search(text), "box drawing in piped output"
    assert not CUT_NUMBER.search(text), "a number cut short"


@pytest.mark.parametrize(
    "args",
    [
        ("fit", "{d}/run.h5"),
        ("validate", "{d}/run.h5"),
        ("validate", "{d}/run.h5", "--mode", "measured-angles"),
        ("inspect", "{d}/run.h5"),
    ],
)
def test_force_reports_piped_at_80_columns(world: Path, args) -> None:
    if args[0] != "fit":
        assert run80("fit", world / "run.h5").exit_code == 0
    r = run80(*(a.format(d=world) for a in args))
    assert r.exit_code == 0, r.output
    assert_whole_and_plain(r.stdout)


def test_every_validation_number_of_the_json_is_printed_in_full(world: Path) -> None:
    import json

    assert run80("fit", world / "run.h5").exit_code == 0
    data = json.loads(run80("validate", world / "run.h5", "--json").stdout)
    text = run80("validate", world / "run.h5").stdout
    for q, m in data["metrics"].items():
        if m["rmse"] is None:  # no trial reported for q: its row shows a dash, never a number
            assert "—" in text, q
            continue
        assert f"{m['rmse']:.3g}" in text and f"{m['bias']:+.2g}" in text, q


def test_optimize_piped_at_80_columns() -> None:
    r = run80("optimize", "--seed", "1")
    assert r.exit_code == 0, r.output
    assert_whole_and_plain(r.stdout)
    assert max(len(line) for line in r.stdout.splitlines() if line.startswith("  ")) <= 80


def test_a_wide_table_on_an_80_column_terminal_is_split_not_cut() -> None:
    from rich import box
    from rich.console import Console
    from rich.table import Table

    out = io.StringIO()
    con = Console(file=out, width=80, force_terminal=True, color_system=None)
    t = Table(title="wide", box=box.SIMPLE_HEAD)
    names = ["object"] + [f"quantity {i} [N/m]" for i in range(8)]
    for n in names:
        t.add_column(n, justify="right")
    values = [[f"petbottle-{r}"] + [f"{1234.5678 * (r + 1) * (i + 1):.4f}" for i in range(8)] for r in range(3)]
    for row in values:
        t.add_row(*row)
    print_table(con, t)
    text = out.getvalue()
    assert "\u2026" not in text
    assert max(len(line) for line in text.splitlines()) <= 80
    for row in values:
        for v in row:
            assert v in text  # every cell whole
    assert text.count("petbottle-0") >= 2  # the row's name repeats in each column group
    assert BOX.search(text)  # a terminal keeps its rules


def test_piped_tables_lose_their_box_but_not_their_cells() -> None:
    from rich import box
    from rich.console import Console
    from rich.table import Table

    out = io.StringIO()
    con = Console(file=out, width=80)  # a StringIO is not a terminal
    t = Table(box=box.SIMPLE_HEAD)
    t.add_column("a")
    t.add_column("b")
    t.add_row("1.2345", "-0.00935")
    print_table(con, t)
    assert not BOX.search(out.getvalue()) and "-0.00935" in out.getvalue()
