"""Options every command shares are spelled and behave the same: walked over every command's parameters.

Every command that opens a port takes ``-p/--port``, ``--baud`` and ``--timeout`` alike;
``labcli sim`` and ``labcli demo`` serve the same simulated rig unless told otherwise (one
default seed, declared once).
"""

from __future__ import annotations

import importlib
import os
import time
from pathlib import Path

import click
import pytest
from click.testing import CliRunner

from labcli.cli import COMMANDS, cli
from labcli.commands import _options

MODEL = Path(__file__).resolve().parents[2] / "sample_runs" / "force.model.json"


def command(name: str) -> click.Command:
    module, attr, _ = COMMANDS[name]
    return getattr(importlib.import_module(module), attr)


def params(name: str) -> dict[str, click.Parameter]:
    ctx = click.Context(command(name))
    return {str(p.name): p for p in command(name).get_params(ctx)}


# Every command naming a port; labcli flash hands its port to avrdude (the bootloader's own
# --upload-baud, no rig link to time out), so the link's options are the others'.
NAMING_A_PORT = sorted(n for n in COMMANDS if "port" in params(n))
PORT_COMMANDS = [n for n in NAMING_A_PORT if n != "flash"]


def test_the_commands_that_open_a_port_are_found():
    assert NAMING_A_PORT == ["acquire", "flash", "monitor", "sense"]
    assert PORT_COMMANDS == ["acquire", "monitor", "sense"]


@pytest.mark.parametrize("name", NAMING_A_PORT)
def test_every_command_naming_a_port_spells_it_alike(name):
    port = params(name)["port"]
    assert sorted(port.opts) == ["--port", "-p"] and port.required


def _shape(p: click.Parameter) -> tuple:
    t = p.type
    return (
        tuple(p.opts),
        tuple(p.secondary_opts),
        type(t),
        getattr(t, "min", None),
        getattr(t, "max", None),
        getattr(t, "min_open", None),
        p.default,
        p.required,
        p.help if isinstance(p, click.Option) else None,
    )


@pytest.mark.parametrize("name", PORT_COMMANDS)
def test_port_baud_and_timeout_are_the_same_everywhere(name):
    mine, reference = params(name), params(PORT_COMMANDS[0])
    assert mine["port"].opts == ["-p", "--port"] and mine["port"].required
    for option in ("port", "baud", "timeout"):
        assert _shape(mine[option]) == _shape(reference[option]), (name, option)
    assert mine["timeout"].default == _options.TIMEOUT_S and mine["baud"].default == 115200


def required_args(name: str, tmp_path: Path) -> list[str]:
    """What a command needs besides the port to reach it: acquire its run file, sense its model."""
    return {"acquire": [str(tmp_path / "r.h5")], "sense": ["--model", str(MODEL)]}.get(name, [])


@pytest.mark.parametrize("name", PORT_COMMANDS)
@pytest.mark.parametrize(
    "args,message",
    [
        (["--timeout", "0"], "Invalid value for '--timeout': 0.0 is not in the range x>0."),
        (["--timeout", "nan"], "Invalid value for '--timeout': 'nan' is not a finite number."),
        (["--baud", "10"], "Invalid value for '--baud': 10 is not in the range 50<=x<=12000000."),
    ],
)
def test_bad_port_options_get_the_same_sentence_from_every_command(name, args, message, tmp_path):
    extra = required_args(name, tmp_path)
    result = CliRunner().invoke(cli, [name, *extra, "-p", "sim://", *args])
    assert result.exit_code == 2 and result.output.splitlines()[-1] == f"Error: {message}"


@pytest.mark.skipif(not hasattr(os, "openpty"), reason="needs pseudo-terminals")
@pytest.mark.parametrize("name", PORT_COMMANDS)
def test_the_timeout_reaches_the_link(name, tmp_path):
    # A serial port where nothing answers: each command gives up after its --timeout (plus the
    # boot wait of a serial board), and says so with the timeout it was given.
    master, slave = os.openpty()
    try:
        port = os.ttyname(slave)
        extra = required_args(name, tmp_path)
        t0 = time.monotonic()
        result = CliRunner().invoke(cli, [name, *extra, "-p", port, "--timeout", "0.3"])
        took = time.monotonic() - t0
    finally:
        os.close(master)
        os.close(slave)
    assert result.exit_code == 1
    assert f"Error: No answer to ID? from {port} within 2.3 s. " in result.output  # 0.3 s + the 2 s boot wait
    assert took < 2.0 + 0.3 + 1.5
    assert not (tmp_path / "r.h5").exists()


def test_sim_and_demo_share_one_default_seed():
    sim_seed, demo_seed = params("sim")["seed"], params("demo")["seed"]
    assert sim_seed.default == demo_seed.default == _options.SEED
    assert type(sim_seed.type) is type(demo_seed.type) and sim_seed.type.min == demo_seed.type.min == 0
