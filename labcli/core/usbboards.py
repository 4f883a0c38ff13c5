"""Which board a serial port looks like, by its USB vendor and product id, and whether it is a labcli rig.

``labcli ports`` lists every port with the board its USB ids name (an Uno, a Nano, a Mega, a
CH340 or FTDI adapter...) and, with ``--probe``, opens each and asks ``ID?``: a port whose
board answers in the wire protocol is a labcli rig, named with its device, firmware and
protocol version.  Opening a port resets an Uno-class board (DTR), so probing is asked for, not
done by default, and waits for the bootloader like ``Device.open``.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from typing import Any

# (vendor id, product id) -> what it is.  USB ids from the vendors' own lists (Arduino's boards.txt,
# WCH, FTDI, Silicon Labs, Prolific); a clone board carries its bridge's ids, not the board's.
ARDUINO_VIDS = (0x2341, 0x2A03)
BOARDS: dict[tuple[int, int], str] = {
    **{(v, 0x0043): "Arduino Uno R3" for v in ARDUINO_VIDS},
    (0x2341, 0x0001): "Arduino Uno",
    (0x2341, 0x0243): "Arduino Uno (Genuino)",
    **{(v, 0x0042): "Arduino Mega 2560 R3" for v in ARDUINO_VIDS},
    (0x2341, 0x0010): "Arduino Mega 2560",
    (0x2341, 0x003F): "Arduino Mega ADK",
    (0x2341, 0x0044): "Arduino Mega ADK R3",
    (0x2341, 0x8036): "Arduino Leonardo",
    (0x2341, 0x8037): "Arduino Micro",
    (0x2341, 0x0058): "Arduino Nano Every",
    (0x2341, 0x0069): "Arduino Uno R4 Minima",
    (0x2341, 0x1002): "Arduino Uno R4 WiFi",
    (0x1A86, 0x7523): "CH340 USB-serial (Nano and Uno clones)",
    (0x1A86, 0x5523): "CH341 USB-serial",
    (0x1A86, 0x55D4): "CH9102 USB-serial (Nano clones)",
    (0x0403, 0x6001): "FTDI FT232R USB-serial (Arduino Nano, Duemilanove, adapters)",
    (0x0403, 0x6015): "FTDI FT231X USB-serial",
    (0x0403, 0x6014): "FTDI FT232H USB-serial",
    (0x0403, 0x6010): "FTDI FT2232 USB-serial",
    (0x10C4, 0xEA60): "Silicon Labs CP210x USB-serial",
    (0x067B, 0x2303): "Prolific PL2303 USB-serial",
}
# Boards whose bootloader the reference firmware is flashed through (labcli flash's default).
UNO_CLASS = {"Arduino Uno R3", "Arduino Uno", "Arduino Uno (Genuino)"}


def board_name(vid: int | None, pid: int | None) -> str:
    """What a port's USB ids name; "" when it has none (a built-in UART, a pty) or they are unknown."""
    if vid is None or pid is None:
        return ""
    known = BOARDS.get((vid, pid))
    if known:
        return known
    if vid in ARDUINO_VIDS:
        return f"Arduino board (USB id {vid:04x}:{pid:04x})"
    return ""


@dataclass(frozen=True)
class PortRow:
    """One line of ``labcli ports``."""

    device: str
    description: str
    hwid: str
    board: str
    rig: str = ""  # after a probe: "labcli rig: ..." or why not


def rows_of(ports: Iterable[Any]) -> list[PortRow]:
    """pyserial's ``list_ports.comports()`` entries as rows, in device order."""
    rows = []
    for p in sorted(ports, key=lambda p: p.device):
        rows.append(
            PortRow(
                p.device,
                p.description or "n/a",
                p.hwid or "n/a",
                board_name(getattr(p, "vid", None), getattr(p, "pid", None)),
            )
        )
    return rows


def probe(port: str, *, timeout: float = 1.0, boot_wait: float = 2.0) -> str:
    """Open ``port``, ask ``ID?`` (and ``CAPS?``) and say what answered, as one short phrase."""
    from ..errors import LabcliError
    from .device import Device

    try:
        with Device.open(port, timeout=timeout, boot_wait=boot_wait) as dev:
            info, caps = dev.info, dev.caps
    except LabcliError as e:
        text = str(e)
        if "No answer to ID?" in text:
            return "no answer to ID?"
        if "not the labcli wire protocol" in text:
            return "answers, but not in the labcli wire protocol"
        return text.split(":", 1)[-1].split(";")[0].split(". ")[0].strip().rstrip(".")
    assert info is not None
    return f"labcli rig: {info.device} firmware {info.firmware}, wire protocol {caps.protocol}"


def probe_all(rows: Sequence[PortRow], *, boot_wait: float = 2.0, timeout: float = 1.0) -> list[PortRow]:
    """Every row probed at once (each board waits for its own bootloader); sim ptys without a boot wait."""

    def one(row: PortRow) -> PortRow:
        wait = 0.0 if row.hwid.startswith("sim") else boot_wait
        return PortRow(
            row.device, row.description, row.hwid, row.board, probe(row.device, timeout=timeout, boot_wait=wait)
        )

    if not rows:
        return []
    with ThreadPoolExecutor(max_workers=min(8, len(rows))) as pool:
        return list(pool.map(one, rows))
