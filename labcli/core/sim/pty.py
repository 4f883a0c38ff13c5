"""Serve the simulated rig's firmware on a pseudo-terminal, paced by the wall clock.

Any program that opens the printed ``/dev/pts/N`` sees a serial device
speaking the rig wire protocol, exactly as it would see a USB bridge::

    server = serve_pty(seed=1, rate=200)
    print(server.path)           # open this with pyserial, minicom, labcli ...
    server.rig.hang_weight(0.2, 0.0)
    server.stop()

The server runs in a daemon thread.  The slave side is put in raw mode (no
echo, no line discipline) and kept open by the server, so the path stays
valid while clients come and go; frames written while nobody reads pile up in
the pty's buffer and, once it is full, are dropped as a real UART would.

``serve_pty(..., faults="checksum:0.01,stall:0.001@0.5")`` makes the link
noisy (:mod:`labcli.core.sim.faults`); ``server.faults`` holds the ground truth.

``server.operate("hang 500 30")`` acts on the rig as the operator's console
(:mod:`labcli.core.sim.console`) does, at the rig's present time; ``labcli sim
--pty`` feeds it the lines typed on its standard input.
"""

from __future__ import annotations

import errno
import os
import select
import threading
import time
import tty

from . import make_rig
from .console import execute
from .faults import FaultInjector, FaultSpec
from .firmware import Firmware

POLL_S = 0.005
MAX_BACKLOG = 1 << 20  # bytes queued for a host that does not read, about 20000 frames


class PtyServer:
    """A running pty server: ``path``, ``rig``, ``firmware``, ``faults`` (or None), ``stop()``."""

    def __init__(self, rig, rate_hz: float = 200.0, faults: FaultInjector | None = None) -> None:
        self.rig = rig
        self.faults = faults
        self.firmware = Firmware(rig, rate_hz, faults=faults)
        self.dropped_frames = 0
        self._master, self._slave = os.openpty()
        tty.setraw(self._slave)
        os.set_blocking(self._master, False)
        self.path = os.ttyname(self._slave)
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="labcli-sim-pty", daemon=True)
        self._out = bytearray(self.firmware.banner())
        self._t0 = time.monotonic() - rig.time_s  # wall time at the rig's time zero
        self._thread.start()

    def operate(self, line: str) -> str:
        """Act on one operator console line (:mod:`.console`); returns the reply.

        An idle rig's clock is first brought up to the wall clock (a streaming
        one is kept there by the frames), so the action happens now.
        """
        with self.rig._lock:
            self._sync()
            reply = execute(self.rig, line, idle_wait=self._wait)
        if reply == "ok quit":
            self.request_stop()
        return reply

    def _sync(self) -> None:
        if not self.firmware.streaming:
            self.rig.advance_to(time.monotonic() - self._t0)

    def _wait(self, seconds: float) -> None:
        """Let ``seconds`` of wall time pass (the rig's clock follows the wall here)."""
        self.rig._lock.release()
        try:
            self._stop.wait(seconds)  # not time.sleep: Ctrl-C or SIGTERM (request_stop) ends the wait at once
        finally:
            self.rig._lock.acquire()
        self._sync()

    def request_stop(self) -> None:
        """Ask the serving thread to stop (safe from a signal handler)."""
        self._stop.set()

    def stop(self, timeout: float = 2.0) -> None:
        """Stop serving and close the pseudo-terminal."""
        self._stop.set()
        self._thread.join(timeout)
        for fd in (self._master, self._slave):
            try:
                os.close(fd)
            except OSError:
                pass

    def wait(self, timeout: float | None = None) -> bool:
        """Block until stopped (or ``timeout``); True if stopped."""
        return self._stop.wait(timeout)

    def __enter__(self) -> PtyServer:
        return self

    def __exit__(self, *exc) -> None:
        self.stop()

    # ------------------------------------------------------------ loop

    def _run(self) -> None:
        fw = self.firmware
        t0 = self._t0
        pace_t0, sent = time.monotonic(), 0
        while not self._stop.is_set():
            try:
                readable, _, _ = select.select([self._master], [], [], POLL_S)
            except (OSError, ValueError):
                return
            now = time.monotonic()
            if readable:
                try:
                    data = os.read(self._master, 4096)
                except BlockingIOError:
                    data = b""
                except OSError as e:  # EIO: no slave open at this instant
                    if e.errno != errno.EIO:
                        return
                    data = b""
                if data:
                    was_streaming, old_rate = fw.streaming, fw.rate_hz
                    if not was_streaming:
                        self.rig.advance_to(now - t0)
                    self._out += fw.receive(data)
                    if fw.streaming and (not was_streaming or fw.rate_hz != old_rate):
                        pace_t0, sent = now, 0
            if not fw.streaming:
                # The board's own checks go on with nobody asking (a host killed while it supplied).
                self._out += fw.idle(now - t0)
            if fw.streaming:
                due = int((now - pace_t0) * fw.stream_hz) - sent
                if due > 0:
                    sent += due
                    self._queue_frames(fw.frames(due))
                    stall = fw.take_stall()
                    if stall is not None:
                        # The firmware hung: the frames it did not make fall due a stall later.
                        sent -= stall[1]
                        pace_t0 += stall[0]
            if self._out:
                try:
                    n = os.write(self._master, self._out)
                    del self._out[:n]
                except BlockingIOError:
                    pass
                except OSError:
                    return

    def _queue_frames(self, frames: bytes) -> None:
        """Queue new frames for the host, or drop them whole while the backlog is full.

        A firmware whose UART cannot keep up drops the frames it makes, never what it
        already queued, and never its replies to commands: so ``OK STOP`` still reaches
        a host that fell behind (the sequence numbers show the gap).
        """
        if len(self._out) + len(frames) > MAX_BACKLOG:
            self.dropped_frames += frames.count(b"$D")
        else:
            self._out += frames


def serve_pty(
    seed: int = 0,
    rate: float = 200.0,
    noise: float = 1.0,
    drift: float | None = None,
    tau: float = 0.7,
    mode: str | None = None,
    rig=None,
    faults: FaultSpec | str | dict | None = None,
    **rig_options,
) -> PtyServer:
    """Start serving a simulated rig on a new pseudo-terminal; returns the running server.

    ``faults`` (a :class:`~labcli.core.sim.faults.FaultSpec`, its text form or a
    dict) makes the link noisy, drawn from ``seed``; FaultSpecError if malformed.
    ``rig_options`` are the rig's own (its paper's ``sim_options``, parsed).
    """
    spec = FaultSpec.from_data(faults)
    if rig is None:
        rig = make_rig(mode, seed=seed, noise=noise, drift=drift, tau_s=tau, **rig_options)
    injector = FaultInjector(spec, seed=seed, n_channels=len(rig.channels)) if spec.active else None
    return PtyServer(rig, rate, faults=injector)
