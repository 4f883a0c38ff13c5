"""`labcli flash` (avrdude) and `labcli ports` (which board each port is, which is a labcli rig).

avrdude is faked on PATH by a script that records its arguments, and, where the AVR tools are
installed, the real avrdude writes the firmware to an Uno's bootloader emulated on a
pseudo-terminal (tests/support/stk500.py) and reads it back to verify.  The ports are pyserial's
listing faked, their devices pseudo-terminals served by the test firmware of
tests/support/firmware.py.
"""

from __future__ import annotations

import os
import shutil
import stat
import subprocess
from pathlib import Path
from types import SimpleNamespace

import pytest
from click.testing import CliRunner
from support.firmware import REFERENCE_CHANNELS, FakeFirmware
from support.stk500 import Bootloader

from labcli.cli import cli
from labcli.core.usbboards import board_name

INSTALL = "install it with `apt-get install avrdude` (the Debian and Ubuntu package avrdude)"


def fake_avrdude(folder: Path, *, exit_code: int = 0, stderr: str = "avrdude done.  Thank you.") -> Path:
    """An avrdude on PATH that writes its arguments, one a line, to ``folder/args``."""
    folder.mkdir(exist_ok=True)
    tool = folder / "avrdude"
    tool.write_text(
        f'#!/bin/sh\nfor a in "$@"; do echo "$a"; done > "{folder / "args"}"\necho \'{stderr}\' >&2\nexit {exit_code}\n'
    )
    tool.chmod(tool.stat().st_mode | stat.S_IXUSR)
    return tool


@pytest.fixture
def elf(tmp_path: Path) -> Path:
    """A file with an AVR ELF header (machine 83), enough for labcli's check; avrdude is fake."""
    image = tmp_path / "labcli_rig.elf"
    head = bytearray(b"\x7fELF\x01\x01\x01" + bytes(9))
    head += (2).to_bytes(2, "little") + (83).to_bytes(2, "little")
    image.write_bytes(bytes(head) + bytes(100))
    return image


def invoke(*args: object, path: str | None = None):
    env = {"PATH": path} if path is not None else None
    return CliRunner().invoke(cli, [str(a) for a in args], env=env)


def test_flash_runs_avrdude_then_asks_the_board(elf, tmp_path, monkeypatch):
    tools = tmp_path / "bin"
    fake_avrdude(tools)
    monkeypatch.setenv("PATH", f"{tools}{os.pathsep}{os.environ['PATH']}")
    with FakeFirmware(firmware="1.0-avr", device="mckibben-2dof") as fw:
        result = invoke("flash", elf, "--port", fw.port)
    assert result.exit_code == 0, result.output
    args = (tools / "args").read_text().splitlines()
    assert args == ["-p", "m328p", "-c", "arduino", "-P", fw.port, "-b", "115200", "-U", f"flash:w:{elf}:e"]
    assert result.output.splitlines() == [
        f"Wrote {elf} to the board on {fw.port} (avrdude {' '.join(args)}).",
        f"The board answers: mckibben-2dof firmware 1.0-avr, wire protocol 1.0; channels {', '.join(REFERENCE_CHANNELS)}.",
    ]
    assert fw.commands[:2] == ["ID?", "STOP"] and "CAPS?" in fw.commands


def test_flash_takes_a_hex_file_and_an_isp_programmer(tmp_path, monkeypatch):
    tools = tmp_path / "bin"
    fake_avrdude(tools)
    monkeypatch.setenv("PATH", f"{tools}{os.pathsep}{os.environ['PATH']}")
    image = tmp_path / "rig.hex"
    image.write_text(":100000000C9434000C9446000C9446000C9446006A\n:00000001FF\n")
    port = tmp_path / "ttyUSB9"
    port.touch()
    result = invoke("flash", image, "--port", port, "--programmer", "usbasp", "--upload-baud", "19200", "--no-check")
    assert result.exit_code == 0, result.output
    assert (tools / "args").read_text().splitlines()[-2:] == ["-U", f"flash:w:{image}:i"]
    assert "-c\nusbasp\n" in (tools / "args").read_text()
    assert result.output.count("\n") == 1  # no ID? asked


@pytest.mark.parametrize(
    "setup, message",
    [
        ("no-avrdude", f"Error: avrdude, which writes firmware onto the board, is not installed; {INSTALL}."),
        ("no-image", "Error: No firmware image at {image}; build one with `make -C firmware`."),
        (
            "not-avr",
            "Error: {image} is an ELF file for another processor, not AVR firmware; pass "
            "firmware/build/labcli_rig.elf from `make -C firmware`.",
        ),
        (
            "text",
            "Error: {image} is neither an ELF nor an Intel HEX file; pass the .elf or .hex file "
            "`make -C firmware` writes.",
        ),
        (
            "sim",
            "Error: sim:// is not a serial port: flash writes a real board. The firmware runs on simavr "
            "without flashing: labcli sim --pty --firmware ELF, or --port 'sim://?firmware=ELF'.",
        ),
        ("no-port", "Error: No serial port {port}; check the cable and run `labcli ports` to find the board."),
        (
            "fails",
            "Error: avrdude did not write labcli_rig.elf to the board on {port} (stk500_recv(): programmer is "
            "not responding); check the port, the programmer (an Uno's bootloader is `arduino`, at 115200 baud) and "
            "that nothing else holds the port.",
        ),
    ],
)
def test_flash_says_what_went_wrong_in_one_sentence(setup, message, elf, tmp_path):
    tools = tmp_path / "bin"
    fake_avrdude(
        tools, exit_code=1 if setup == "fails" else 0, stderr="avrdude: stk500_recv(): programmer is not responding"
    )
    path = f"{tools}{os.pathsep}/usr/bin{os.pathsep}/bin"
    image, port = elf, tmp_path / "ttyACM7"
    port.touch()
    if setup == "no-avrdude":
        path = str(tmp_path / "empty")
    elif setup == "no-image":
        image = tmp_path / "missing.elf"
    elif setup == "not-avr":
        image = Path(shutil.which("true") or "/bin/true")
    elif setup == "text":
        image = tmp_path / "notes.txt"
        image.write_text("firmware\n")
    elif setup == "no-port":
        port = tmp_path / "ttyACM8"
    result = invoke("flash", image, "--port", "sim://" if setup == "sim" else port, path=path)
    assert result.exit_code == 1
    assert result.output == message.format(image=image, port=port) + "\n"


def test_the_real_avrdude_writes_the_firmware_to_a_bootloader(firmware_elf, tmp_path):
    """avrdude itself takes labcli's command line and writes and verifies the image (no board)."""
    if shutil.which("avrdude") is None:
        pytest.skip("needs avrdude: apt-get install avrdude")
    hexfile = firmware_elf.with_suffix(".hex")
    image = tmp_path / "image.bin"
    subprocess.run(["avr-objcopy", "-O", "binary", "-R", ".eeprom", str(firmware_elf), str(image)], check=True)
    want = image.read_bytes()
    for source in (firmware_elf, hexfile):
        with Bootloader() as boot:
            result = invoke("flash", source, "--port", boot.port, "--no-check")
            assert result.exit_code == 0, result.output
            assert boot.flash[: len(want)] == want and boot.written >= len(want)
            assert 0x64 in boot.commands and 0x74 in boot.commands  # written, then read back to verify


# ---------------------------------------------------------------- ports


@pytest.mark.parametrize(
    "vid, pid, name",
    [
        (0x2341, 0x0043, "Arduino Uno R3"),
        (0x2A03, 0x0043, "Arduino Uno R3"),
        (0x2341, 0x0042, "Arduino Mega 2560 R3"),
        (0x1A86, 0x7523, "CH340 USB-serial (Nano and Uno clones)"),
        (0x0403, 0x6001, "FTDI FT232R USB-serial (Arduino Nano, Duemilanove, adapters)"),
        (0x2341, 0x7777, "Arduino board (USB id 2341:7777)"),
        (0x1234, 0x5678, ""),
        (None, None, ""),
    ],
)
def test_boards_are_named_by_their_usb_ids(vid, pid, name):
    assert board_name(vid, pid) == name


def test_ports_names_the_boards_and_probe_finds_the_rig(monkeypatch, tmp_path):
    from serial.tools import list_ports

    monkeypatch.setenv("LABCLI_RUNTIME_DIR", str(tmp_path))
    with FakeFirmware(device="mckibben-2dof", firmware="1.0-avr") as rig, FakeFirmware(silent=True) as mute:
        fake = [
            SimpleNamespace(
                device=rig.port, description="USB2.0-Serial", hwid="USB VID:PID=1A86:7523", vid=0x1A86, pid=0x7523
            ),
            SimpleNamespace(
                device=mute.port, description="Arduino Uno", hwid="USB VID:PID=2341:0043", vid=0x2341, pid=0x0043
            ),
        ]
        monkeypatch.setattr(list_ports, "comports", lambda: fake)
        plain = invoke("ports")
        probed = invoke("ports", "--probe", "--boot-wait", "0")
    assert plain.exit_code == 0 and probed.exit_code == 0, probed.output
    rows = sorted([(rig.port, "CH340 USB-serial (Nano and Uno clones)"), (mute.port, "Arduino Uno R3")])
    assert [line.split("  ")[0].strip() for line in plain.output.splitlines()[1:]] == [r[0] for r in rows]
    for dev, board in rows:
        line = next(x for x in probed.output.splitlines() if x.startswith(dev))
        assert board in line
        if dev == rig.port:
            assert "labcli rig: mckibben-2dof firmware 1.0-avr, wire protocol 1.0" in line
        else:
            assert "no answer to ID?" in line
    assert probed.output.splitlines()[0].split() == ["DEVICE", "BOARD", "ID?", "DESCRIPTION", "HWID"]
