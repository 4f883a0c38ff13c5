"""Every command's --help shows its examples one command a line (a continued line stays two lines)."""

from __future__ import annotations

import re

import pytest
from click.testing import CliRunner

from labcli.cli import COMMANDS, cli


@pytest.mark.parametrize("name", list(COMMANDS))
def test_example_lines_do_not_run_together(name):
    r = CliRunner(env={"COLUMNS": "200"}).invoke(cli, [name, "--help"])
    assert r.exit_code == 0, r.output
    examples = [line.strip() for line in r.output.splitlines() if line.strip().startswith("labcli ")]
    for line in examples:
        # Two lines a docstring's trailing backslash joined show as one with a run of spaces inside.
        assert not re.search(r"\S {4,}--", line), line
