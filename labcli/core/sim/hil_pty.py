"""Serve the rig firmware, running on simavr, on a pseudo-terminal (``labcli sim --pty --firmware ELF``).

The same shape as :class:`labcli.core.sim.pty.PtyServer` (``path``, ``rig``,
``stop()``, ``wait()``, ``request_stop()``, ``operate()``), so whatever drives the rig of
``labcli sim --pty`` drives this one the same way.  Simulated time follows the
wall clock; the bytes on the pty are the firmware's own, from its UART.

    server = serve_firmware_pty("firmware/build/labcli_rig.elf", seed=1)
    print(server.path)            # open with pyserial, minicom, labcli ...
    server.rig.supply_air()
    server.stop()

A real board resets when the port is opened (DTR); this one keeps running,
as a board with the auto-reset disabled does.  Bytes nobody reads pile up in
the pty and, past ``MAX_PENDING``, are dropped as a UART would drop them.
"""

from __future__ import annotations

import errno
import os
import select
import threading
import tty

from . import make_rig
from .console import execute
from .hil import HilLink

POLL_S = 0.005
MAX_PENDING = 1 << 20


class HilPtyServer:
    """A running pty server for the firmware on simavr: ``path``, ``rig``, ``link``, ``stop()``."""

    faults = None  # the link's faults are whatever the firmware and its UART make

    def __init__(self, rig, elf, *, seed: int = 0, adc_noise_lsb: float = 0.5, record: bool = False) -> None:
        self.rig = rig
        self.dropped_bytes = 0
        self._out = bytearray()
        self._out_lock = threading.Lock()
        self._stop = threading.Event()
        self._master, self._slave = os.openpty()
        try:
            tty.setraw(self._slave)
            os.set_blocking(self._master, False)
            self.path = os.ttyname(self._slave)
            self.link = HilLink(
                rig,
                elf,
                pacing="wall",
                seed=seed,
                adc_noise_lsb=adc_noise_lsb,
                on_bytes=self._from_device,
                record=record,
            )
        except BaseException:
            self._close_fds()
            raise
        self._thread = threading.Thread(target=self._run, name="labcli-hil-pty", daemon=True)
        self._thread.start()

    def operate(self, line: str) -> str:
        """Act on one operator console line (:mod:`.console`); returns the reply.

        The link keeps the rig's clock with the wall clock, so ``wait`` just lets wall time pass.
        """
        reply = execute(self.rig, line, idle_wait=self._stop.wait)  # a stop request ends a wait at once
        if reply == "ok quit":
            self.request_stop()
        return reply

    def request_stop(self) -> None:
        """Ask the server to stop (safe from a signal handler)."""
        self._stop.set()

    def wait(self, timeout: float | None = None) -> bool:
        """Block until stopped (or ``timeout``); True if stopped.  A board that stopped ends it too."""
        stopped = self._stop.wait(timeout)
        if not stopped and self.link.exited.is_set():
            self._stop.set()
            return True
        return stopped

    @property
    def error(self) -> str | None:
        """Why the simulated board stopped by itself (one sentence), or None."""
        if self._stop.is_set() and not self.link.exited.is_set():
            return None
        return self.link.failure() if self.link.exited.is_set() and self.link.error else None

    def stop(self, timeout: float = 2.0) -> None:
        """Stop serving, power the simulated board off and close the pseudo-terminal."""
        self._stop.set()
        self._thread.join(timeout)
        self.link.stop()
        self._close_fds()

    def __enter__(self) -> HilPtyServer:
        return self

    def __exit__(self, *exc) -> None:
        self.stop()

    def _close_fds(self) -> None:
        for fd in (self._master, self._slave):
            try:
                os.close(fd)
            except OSError:
                pass

    def _from_device(self, data: bytes) -> None:
        with self._out_lock:
            self._out += data
            if len(self._out) > MAX_PENDING:
                self.dropped_bytes += len(self._out)
                self._out.clear()

    def _run(self) -> None:
        while not self._stop.is_set():
            try:
                readable, _, _ = select.select([self._master], [], [], POLL_S)
            except (OSError, ValueError):
                return
            if readable:
                try:
                    data = os.read(self._master, 4096)
                except BlockingIOError:
                    data = b""
                except OSError as e:  # EIO: no client has the pty open right now
                    if e.errno != errno.EIO:
                        return
                    data = b""
                if data:
                    self.link.write(data)
            with self._out_lock:
                if self._out:
                    try:
                        del self._out[: os.write(self._master, self._out)]
                    except BlockingIOError:
                        pass
                    except OSError:
                        return


def serve_firmware_pty(
    elf,
    *,
    seed: int = 0,
    noise: float = 1.0,
    drift: float | None = None,
    tau: float = 0.7,
    mode: str | None = None,
    rig=None,
    adc_noise_lsb: float = 0.5,
    record: bool = False,
    **rig_options,
) -> HilPtyServer:
    """Serve the firmware ``elf`` on simavr on a new pty, fed by the rig of ``mode`` (None: the default rig).

    ``record`` keeps every sample fed to the board (``server.link.fed()``); ``rig_options``
    are the rig's own (its paper's ``sim_options``, parsed).

    Raises :class:`~labcli.core.sim.hil.FirmwareSimError` (one sentence) when the
    firmware or its harness is missing, the rig lacks the firmware's channels or the
    simulated board does not start.
    """
    if rig is None:
        rig = make_rig(mode, seed=seed, noise=noise, drift=drift, tau_s=tau, **rig_options)
    return HilPtyServer(rig, elf, seed=seed, adc_noise_lsb=adc_noise_lsb, record=record)
