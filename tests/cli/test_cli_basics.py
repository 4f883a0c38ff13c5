"""The package entry points and the promise that start-up stays light."""

from __future__ import annotations

import json
import subprocess
import sys

from click.testing import CliRunner

import labcli
from labcli.cli import COMMANDS, cli

HEAVY = ("scipy", "pandas", "h5py", "matplotlib", "numpy", "rich", "serial")


def test_version_matches_package():
    result = CliRunner().invoke(cli, ["--version"])
    assert result.exit_code == 0
    assert result.output.strip() == f"labcli, version {labcli.__version__}"


def test_help_lists_every_command_with_its_summary():
    result = CliRunner().invoke(cli, ["--help"])
    assert result.exit_code == 0
    for name, (_, _, short) in COMMANDS.items():
        assert name in result.output
        assert short[:30] in result.output


def test_every_command_module_loads_and_has_help():
    runner = CliRunner()
    for name in COMMANDS:
        result = runner.invoke(cli, [name, "--help"], prog_name="labcli")
        assert result.exit_code == 0, (name, result.output)
        assert "Usage: labcli " + name in result.output.replace("\n", " ")


def test_unknown_command_is_one_clear_line():
    result = CliRunner().invoke(cli, ["fitt"])
    assert result.exit_code == 2
    assert "No such command 'fitt'" in result.output
    assert "Traceback" not in result.output


def test_help_imports_no_heavy_module():
    code = (
        "import sys, json\n"
        "from labcli.cli import cli\n"
        "try:\n    cli(['--help'], prog_name='labcli')\n"
        "except SystemExit:\n    pass\n"
        f"print(json.dumps([m for m in {HEAVY!r} if m in sys.modules]))\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    loaded = json.loads(out.stdout.strip().splitlines()[-1])
    assert loaded == []


def test_python_dash_m_runs_the_same_cli():
    out = subprocess.run([sys.executable, "-m", "labcli", "--version"], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == f"labcli, version {labcli.__version__}"
