"""Building the rig firmware for the tests, and skipping when its tools are not installed.

The firmware tests need tools that pip does not install: make and a C compiler
for the host tests of the protocol code, gcc-avr and avr-libc for the firmware
itself, simavr (libsimavr-dev, libelf-dev) for the hardware-in-the-loop tests.
Without them those tests skip, the install line as the reason, so the README's
test command passes on a machine with only Python.

``LABCLI_FIRMWARE_TOOLS`` overrides the detection of the AVR tools: ``absent``
behaves as a machine without them (to see the skips), ``required`` fails
instead of skipping (CI, which installs them).  make and the C compiler are
looked up on PATH like any program.

Each build goes into its own folder under pytest's temporary directory, never
into ``firmware/build``, and must be free of compiler warnings;
``tests/conftest.py`` builds the firmware and its simavr harness once per
session as the fixture ``firmware_elf``.
"""

from __future__ import annotations

import os
import shutil
import subprocess
from functools import cache
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
FIRMWARE = ROOT / "firmware"
HOST_INSTALL = "apt-get install make gcc"
AVR_INSTALL = "apt-get install gcc-avr avr-libc binutils-avr simavr libsimavr-dev libelf-dev"


def _mode() -> str:
    return os.environ.get("LABCLI_FIRMWARE_TOOLS", "detect")


def _run_ok(cmd: list[str], stdin: str = "") -> bool:
    try:
        return subprocess.run(cmd, input=stdin, capture_output=True, text=True, timeout=60).returncode == 0
    except (OSError, subprocess.TimeoutExpired):
        return False


@cache
def _have_host() -> bool:
    return bool(shutil.which("make") and shutil.which("cc"))


@cache
def _have_avr() -> bool:
    return (
        _have_host()
        and all(shutil.which(t) for t in ("avr-gcc", "avr-objcopy", "avr-size"))
        and _run_ok(["avr-gcc", "-mmcu=atmega328p", "-E", "-x", "c", "-"], "#include <avr/io.h>\n")
    )


@cache
def _have_simavr() -> bool:
    return _have_avr() and _run_ok(
        ["cc", "-x", "c", "-fsyntax-only", "-I/usr/include/simavr", "-"], "#include <sim_avr.h>\n#include <libelf.h>\n"
    )


def _need(have: bool, what: str, install: str) -> None:
    mode = _mode()
    if not have:
        if mode == "required":
            pytest.fail(f"{what} required (LABCLI_FIRMWARE_TOOLS=required) but not installed: {install}")
        pytest.skip(f"needs {what}: {install}")


def need_host_compiler() -> None:
    _need(_have_host(), "make and a C compiler", HOST_INSTALL)


def need_avr_tools() -> None:
    _need(_mode() != "absent" and _have_avr(), "the AVR toolchain", AVR_INSTALL)


def need_simavr() -> None:
    _need(_mode() != "absent" and _have_simavr(), "the AVR toolchain and simavr", AVR_INSTALL)


def make(build: Path, *targets: str, defs: str = "", baud: int | None = None, model: Path | None = None) -> str:
    """``make -C firmware BUILD=build targets``; its output, asserted free of compiler warnings.

    ``model``: a header from ``labcli export-model`` (``MODEL=``), for the estimates on the chip."""
    cmd = ["make", "-C", str(FIRMWARE), f"BUILD={build}", *targets]
    if defs:
        cmd.append(f"DEFS={defs}")
    if baud is not None:
        cmd.append(f"BAUD={baud}")
    if model is not None:
        cmd.append(f"MODEL={Path(model).resolve()}")
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=300)
    out = proc.stdout + proc.stderr
    assert proc.returncode == 0, out
    assert "warning" not in out.lower(), out
    return out
