"""Writing the rig firmware onto a board with avrdude (``labcli flash``).

avrdude speaks to the board's bootloader (an Uno's, STK500 version 1: programmer ``arduino``) or
to an ISP programmer; labcli builds its command line, runs it, and turns what goes wrong into one
sentence: avrdude missing (named with its Debian package), an image that is not AVR firmware, a
port that does not exist, a board that does not answer.  After a write it opens the port and asks
``ID?`` (and ``CAPS?``), so the person sees which firmware the board now runs.

    result = flash("firmware/build/labcli_rig.elf", "/dev/ttyACM0")
    result.info.firmware            # "1.1-avr"

The image is an ELF (``make -C firmware`` writes ``build/labcli_rig.elf``) or an Intel HEX file
(``.hex``); avrdude reads either (``:e``, ``:i``).
"""

from __future__ import annotations

import os
import shutil
import subprocess
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ..errors import ConfigError, DeviceError, DeviceNotFound
from .files import read_input

AVRDUDE = "avrdude"
INSTALL_HINT = "install it with `apt-get install avrdude` (the Debian and Ubuntu package avrdude)"
EM_AVR = 83  # the ELF machine number of AVR
TIMEOUT_S = 120.0


@dataclass(frozen=True)
class FlashResult:
    """What was written where, avrdude's command line, and the board's answer afterwards."""

    image: Path
    port: str
    command: list[str]
    info: Any = None  # labcli.core.device.DeviceInfo, None when not checked
    caps: Any = None  # labcli.core.board.BoardCaps
    output: list[str] = field(default_factory=list)  # avrdude's last lines


def image_format(image: Path) -> str:
    """avrdude's format letter for ``image`` (``e`` ELF, ``i`` Intel HEX); ConfigError for anything else."""
    try:
        head = read_input(image, "a firmware image", label=f"The firmware image {image}")[:20]
    except FileNotFoundError:
        raise ConfigError(f"No firmware image at {image}; build one with `make -C firmware`.") from None
    except IsADirectoryError:
        raise ConfigError(f"{image} is a folder; pass the .elf or .hex file `make -C firmware` writes.") from None
    except OSError as e:
        raise ConfigError(f"Cannot read the firmware image {image} ({e.strerror or e}).") from None
    if head[:4] == b"\x7fELF":
        if len(head) < 20 or int.from_bytes(head[18:20], "little" if head[5] == 1 else "big") != EM_AVR:
            raise ConfigError(
                f"{image} is an ELF file for another processor, not AVR firmware; "
                "pass firmware/build/labcli_rig.elf from `make -C firmware`."
            )
        return "e"
    if head[:1] == b":":
        return "i"
    raise ConfigError(
        f"{image} is neither an ELF nor an Intel HEX file; pass the .elf or .hex file `make -C firmware` writes."
    )


def avrdude_command(
    image: Path, port: str | None, *, programmer: str = "arduino", part: str = "m328p", baud: int | None = 115200
) -> list[str]:
    """The avrdude command line that writes ``image`` (and verifies it, avrdude's default)."""
    cmd = [AVRDUDE, "-p", part, "-c", programmer]
    if port:
        cmd += ["-P", port]
    if baud:
        cmd += ["-b", str(int(baud))]
    return cmd + ["-U", f"flash:w:{image}:{image_format(image)}"]


def _avrdude_failed(image: Path, port: str, output: str) -> DeviceError:
    lines = [ln.strip() for ln in output.splitlines() if ln.strip()]
    errors = [ln for ln in lines if "error" in ln.lower() or "not" in ln.lower() or "can't" in ln.lower()]
    why = (errors or lines or ["no message"])[-1].removeprefix("avrdude:").strip().rstrip(".")
    if "ser_open" in output or "No such file" in output:
        return DeviceNotFound(
            f"avrdude could not open {port} ({why}); check the cable and run `labcli ports` to find the board."
        )
    return DeviceError(
        f"avrdude did not write {image.name} to the board on {port} ({why}); check the port, the programmer "
        "(an Uno's bootloader is `arduino`, at 115200 baud) and that nothing else holds the port."
    )


def flash(
    image: str | os.PathLike,
    port: str,
    *,
    programmer: str = "arduino",
    part: str = "m328p",
    baud: int | None = 115200,
    check: bool = True,
    boot_wait: float = 2.0,
    run: Callable[..., Any] = subprocess.run,
) -> FlashResult:
    """Write ``image`` onto the board on ``port`` with avrdude; then (``check``) ask it ``ID?``."""
    image = Path(image)
    if "://" in port:
        raise ConfigError(
            f"{port} is not a serial port: flash writes a real board. The firmware runs on simavr without "
            "flashing: labcli sim --pty --firmware ELF, or --port 'sim://?firmware=ELF'."
        )
    cmd = avrdude_command(image, port, programmer=programmer, part=part, baud=baud)
    if shutil.which(AVRDUDE) is None:
        raise ConfigError(f"avrdude, which writes firmware onto the board, is not installed; {INSTALL_HINT}.")
    if not Path(port).exists() and not port.upper().startswith("COM"):
        raise DeviceNotFound(f"No serial port {port}; check the cable and run `labcli ports` to find the board.")
    try:
        proc = run(cmd, capture_output=True, text=True, timeout=TIMEOUT_S)
    except subprocess.TimeoutExpired:
        raise DeviceError(
            f"avrdude did not finish writing to {port} within {TIMEOUT_S:g} s; unplug the board, plug it in and retry."
        ) from None
    except OSError as e:
        raise ConfigError(f"avrdude could not be started ({e.strerror or e}); {INSTALL_HINT}.") from None
    output = (proc.stdout or "") + (proc.stderr or "")
    if proc.returncode != 0:
        raise _avrdude_failed(image, port, output)
    tail = [ln for ln in output.splitlines() if ln.strip()][-3:]
    if not check:
        return FlashResult(image, port, cmd, output=tail)
    from .device import Device

    with Device.open(port, boot_wait=boot_wait) as dev:
        return FlashResult(image, port, cmd, dev.info, dev.caps, tail)
