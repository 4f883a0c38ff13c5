"""One unit style in every table labcli prints: the unit in parentheses after the quantity."""

from __future__ import annotations

import re
from pathlib import Path

from click.testing import CliRunner

from labcli.cli import cli

SAMPLE = Path(__file__).resolve().parents[2] / "sample_runs"
BRACKETED = re.compile(r"\w \[(deg|N|N/m|mm|MPa|kPa|%|s|g)\]")


def test_reports_write_units_in_parentheses(tmp_path):
    runner = CliRunner(env={"COLUMNS": "200"})
    model = tmp_path / "m.json"
    outputs = [
        runner.invoke(cli, ["fit", str(SAMPLE / "trials.csv"), "-o", str(model), "--form", "paper"]),
        runner.invoke(cli, ["validate", str(SAMPLE / "trials.csv"), "--model", str(model)]),
        runner.invoke(cli, ["classify", str(SAMPLE / "pushes.csv"), "--model", str(model), "--pushes"]),
    ]
    for r in outputs:
        assert r.exit_code == 0, r.output
        assert not BRACKETED.search(r.output), BRACKETED.search(r.output)
    assert "theta1 (deg)" in outputs[1].output and "k_o (N/m)" in outputs[2].output
