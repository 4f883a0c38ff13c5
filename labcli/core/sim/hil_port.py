"""``sim://?firmware=ELF``: the rig firmware on simavr behind pyserial's ``Serial`` API.

The URL handler (:mod:`labcli.core.sim.protocol_sim`) hands a ``sim://``
URL with a ``firmware`` option to :class:`HilSerial`: the bytes are the
compiled firmware's, from its UART on the simulated ATmega328P, and
``port.rig`` is the physics rig whose sensors drive its analog inputs, so
``labcli acquire --unattended`` works the rig while the firmware measures it.

* ``clock=virtual`` (the default): simulated time runs as fast as simavr
  goes while the host waits for bytes, and stands still while it does not
  (see :class:`labcli.core.sim.hil.HilLink`, ``pacing="demand"``);
* ``clock=wall``: simulated time follows the wall clock, like a board.

``mode`` picks the rig as for ``sim://`` (it must have the firmware's
channels); ``seed``, ``noise``, ``drift`` and ``tau`` shape it as there;
``rate`` and ``faults`` belong to the firmware model and are refused: the
firmware powers up at its own rate and takes RATE from the host, and its link
is what its UART makes.  Reopening the port powers the board up again (as a
DTR reset does); the rig, being physical, stays as it was.
"""

from __future__ import annotations

import threading
import time

from serial.serialutil import PortNotOpenError, SerialException, to_bytes

from .hil import HilLink
from .port import SimulatedPort
from .url import firmware_options

DEMAND_S = 0.05  # simulated time a waiting read lets run at a time (clock=virtual)
POLL_S = 0.05


class HilSerial(SimulatedPort):
    """The firmware on simavr as a serial port (see module docstring)."""

    record_feed = False  # keep every sample fed to the board, ``port.link.fed()`` (for tests)

    def __init__(self, *args, **kwargs) -> None:
        self.link: HilLink | None = None
        self._rx = bytearray()
        self._cond = threading.Condition()
        super().__init__(*args, **kwargs)

    # ------------------------------------------------------------ open/close

    def open(self) -> None:
        opts = self._open_rig()
        pacing = "wall" if opts["clock"] == "wall" else "demand"
        self._rx.clear()
        self.link = HilLink(
            self.rig,
            opts["firmware"],
            pacing=pacing,
            seed=opts["seed"],
            on_bytes=self._on_bytes,
            record=self.record_feed,
        )
        self.is_open = True

    def close(self) -> None:
        # The link stays (stopped) for a look at what it fed; reopening starts a new one.
        if self.link is not None:
            self.link.stop()
        with self._cond:
            self.is_open = False
            self._cond.notify_all()
        super().close()

    def from_url(self, url: str) -> dict:
        return firmware_options(url)

    # ------------------------------------------------------------ I/O

    def _on_bytes(self, data: bytes) -> None:
        with self._cond:
            self._rx += data
            self._cond.notify_all()

    def _check(self) -> HilLink:
        if not self.is_open or self.link is None:
            raise PortNotOpenError()
        if self.link.exited.is_set():
            raise SerialException(f"the simulated board stopped: {self.link.error or 'no message'}")
        return self.link

    @property
    def in_waiting(self) -> int:
        link = self._check()
        if link.pacing == "demand":
            link.demand(DEMAND_S)
        return len(self._rx)

    def read(self, size: int = 1) -> bytes:
        link = self._check()
        if size <= 0:
            return b""
        deadline = None if self._timeout is None else time.monotonic() + self._timeout
        with self._cond:
            while len(self._rx) < size:
                if link.pacing == "demand":
                    link.demand(DEMAND_S)
                wait = POLL_S if deadline is None else min(POLL_S, deadline - time.monotonic())
                if wait <= 0:
                    break
                self._cond.wait(wait)
                self._check()
            data = bytes(self._rx[:size])
            del self._rx[:size]
            return data

    def write(self, data) -> int:
        link = self._check()
        data = to_bytes(data)
        link.write(data)
        return len(data)

    def reset_input_buffer(self) -> None:
        if not self.is_open:
            raise PortNotOpenError()
        with self._cond:
            self._rx.clear()

    def flush(self) -> None:
        # Writes reach the harness at once; a closed port has nothing to flush (io's close calls this).
        if self.is_open:
            self._check()
