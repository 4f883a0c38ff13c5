"""Fixtures every test may use: the command line, a quiet unattended UI, stand-ins for a run
file's protocol and rig, deterministic records, the toy paper registered for one test,
and the rig firmware built for simavr."""

from __future__ import annotations

import io
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest
from click.testing import CliRunner, Result
from support import firmware_build, records, toy

from labcli.cli import cli


@pytest.fixture
def invoke() -> Callable[..., Result]:
    """``invoke("inspect", path)``: run labcli in-process; every argument as its text."""

    def run(*args: Any, input: str | None = None) -> Result:
        return CliRunner().invoke(cli, [str(a) for a in args], input=input)

    return run


@pytest.fixture
def quiet_ui() -> Callable[[], Any]:
    """A factory of unattended UIs that print into a buffer (``ui.console.file.getvalue()``)."""
    from rich.console import Console

    from labcli.core.ui import UnattendedUI

    return lambda: UnattendedUI(console=Console(file=io.StringIO(), width=200))


@pytest.fixture
def fake_protocol() -> records.FakeProtocol:
    """A protocol stand-in for run files: kind force, the reference channels and calibration."""
    return records.FakeProtocol()


@pytest.fixture
def fake_device() -> records.FakeDevice:
    """The ``ID?`` reply of the reference rig, as a run file stores it."""
    return records.FakeDevice()


@pytest.fixture
def make_record() -> Callable[..., dict]:
    """``make_record(i, n=50)``: force trial ``i``, the same every time (:mod:`support.records`)."""
    return records.make_record


@pytest.fixture
def toy_paper(tmp_path: Path) -> Iterator[Path]:
    """The toy paper registered for one test; yields the path of its protocol file."""
    from labcli.core import registry

    registry.register(toy.ToyPaper())
    try:
        yield toy.write_protocol(tmp_path)
    finally:
        registry.unregister(toy.ToyPaper.name)


@pytest.fixture(scope="session")
def firmware_elf(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The rig firmware and its simavr harness, built once (warnings refused); skips without the tools."""
    firmware_build.need_simavr()
    build = tmp_path_factory.mktemp("firmware-hil")
    firmware_build.make(build)
    return build / "labcli_rig.elf"
