"""An Uno's bootloader on a pseudo-terminal: the STK500 version 1 subset optiboot answers.

The real avrdude (``-c arduino``) can write a firmware image to it and read it back to verify,
with no board at all, so a test checks labcli's avrdude command line against avrdude itself and
the bytes that arrive against the image.  Written from the STK500 protocol's description
(Atmel AVR061) and optiboot's command set: every command ends with ``0x20``, every answer is
``0x14 ... 0x10``.

    with Bootloader() as boot:          # boot.port: /dev/pts/N
        run avrdude -c arduino -P boot.port -p m328p -U flash:w:app.hex:i
        boot.flash[:n]                   # the bytes written
"""

from __future__ import annotations

import os
import pty
import select
import threading
import tty

INSYNC, OK, EOP = 0x14, 0x10, 0x20
SIGNATURE = bytes([0x1E, 0x95, 0x0F])  # ATmega328P
# Parameter bytes after each command byte (before the 0x20), where fixed.
PARAMS = {0x30: 0, 0x41: 1, 0x42: 20, 0x45: 5, 0x50: 0, 0x51: 0, 0x52: 0, 0x55: 2, 0x56: 4, 0x75: 0}


class Bootloader:
    def __init__(self, flash_size: int = 32768) -> None:
        self.flash = bytearray(b"\xff" * flash_size)
        self.commands: list[int] = []
        self.written = 0
        self._address = 0  # words
        self._master, self._slave = pty.openpty()
        tty.setraw(self._slave)
        self.port = os.ttyname(self._slave)
        self._stop = threading.Event()
        self._buf = bytearray()
        self._thread = threading.Thread(target=self._run, name="stk500", daemon=True)

    def __enter__(self) -> Bootloader:
        self._thread.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self._stop.set()
        self._thread.join(2)
        for fd in (self._master, self._slave):
            os.close(fd)

    # ------------------------------------------------------------ bytes

    def _need(self, n: int) -> bytes | None:
        while len(self._buf) < n:
            if self._stop.is_set():
                return None
            ready, _, _ = select.select([self._master], [], [], 0.05)
            if ready:
                try:
                    self._buf += os.read(self._master, 4096)
                except OSError:
                    return None
        out = bytes(self._buf[:n])
        del self._buf[:n]
        return out

    def _reply(self, data: bytes = b"") -> None:
        os.write(self._master, bytes([INSYNC]) + data + bytes([OK]))

    def _run(self) -> None:
        while not self._stop.is_set():
            head = self._need(1)
            if head is None:
                return
            cmd = head[0]
            if cmd in PARAMS:
                params = self._need(PARAMS[cmd])
            elif cmd in (0x64, 0x74):  # PROG_PAGE, READ_PAGE: length (big-endian), memory type, data
                lead = self._need(3)
                if lead is None:
                    return
                n = lead[0] << 8 | lead[1]
                params = lead + (self._need(n) or b"") if cmd == 0x64 else lead
            else:
                continue  # noise before sync (avrdude drains the line first)
            eop = self._need(1)
            if params is None or eop is None:
                return
            if eop[0] != EOP:
                os.write(self._master, bytes([0x15]))  # STK_NOSYNC
                continue
            self.commands.append(cmd)
            self._answer(cmd, params)

    def _answer(self, cmd: int, params: bytes) -> None:
        if cmd == 0x41:  # GET_PARAMETER: hardware 3, software 4.4 (optiboot's)
            self._reply(bytes([{0x80: 3, 0x81: 4, 0x82: 4}.get(params[0], 3)]))
        elif cmd == 0x55:  # LOAD_ADDRESS, little-endian words
            self._address = params[0] | params[1] << 8
            self._reply()
        elif cmd == 0x56:  # UNIVERSAL (SPI passthrough): answers 0
            self._reply(b"\x00")
        elif cmd == 0x75:
            self._reply(SIGNATURE)
        elif cmd == 0x64:
            n, data = params[0] << 8 | params[1], params[3:]
            if params[2] == ord("F"):
                start = self._address * 2
                self.flash[start : start + n] = data
                self.written += n
            self._reply()
        elif cmd == 0x74:
            n, start = params[0] << 8 | params[1], self._address * 2
            self._reply(bytes(self.flash[start : start + n]) if params[2] == ord("F") else b"\xff" * n)
        else:
            self._reply()
