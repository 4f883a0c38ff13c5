"""Hardware in the loop: the rig firmware on a simulated ATmega328P, its sensors driven by the physics rig.

The compiled firmware (``firmware/build/labcli_rig.elf``) runs on simavr inside
a small harness (``firmware/hil/harness.c``, built next to the ELF as
``labcli_hil``).  :class:`HilLink` starts the harness and is its only partner:

* **Time.**  The AVR's simulated clock is the master.  The harness runs the
  AVR only as far as it has voltages for its six analog inputs; the link sends
  them in batches of ``batch_ms`` one-millisecond slices, each slice's value
  the rig's sample at the slice's end, taken with the rig's own
  ``samples(n, 1000 Hz)``.  So the rig's clock advances with the AVR's, a few
  milliseconds ahead of it (at most ``IN_FLIGHT`` batches), and an operator
  action on the rig (``hang_weight`` ...) acts at the AVR time the rig has
  reached.  Only the link moves the rig's clock while it runs: a
  ``rig.advance()`` from elsewhere would put the rig ahead of the board.
  Between slices the harness interpolates linearly; at each ADC conversion it
  adds the ADC's own noise (``adc_noise_lsb``) and applies the ATmega328P's
  transfer function (see the harness).
* **Pace.**  ``pacing="wall"``: simulated time follows the wall clock, at most
  ``lead_s`` ahead, as a board on a desk does (``labcli sim --pty --firmware``,
  ``sim://?firmware=...&clock=wall``).  ``pacing="demand"``: as fast as simavr
  goes, but only while someone wants bytes (:meth:`HilLink.demand`), so
  simulated time stands still while the host is busy elsewhere: the virtual
  clock of ``sim://``.
* **Bytes.**  What the firmware sends goes to ``on_bytes`` (device to host);
  :meth:`HilLink.write` sends host bytes to the AVR's UART.

* **Valves.**  The harness reports every write of the firmware to PORTB and PORTD; the
  link reads the valves' coils off them (:data:`VALVE_PINS`, the map of
  ``firmware/src/config.h``) and sets the rig's valves (``rig.set_valves``) when they
  change, a fixed :data:`VALVE_LAG_BATCHES` batches (90 ms of simulated time at the default
  ``batch_ms``) after the firmware switched them, at that very slice: the most the rig can be
  ahead of the AVR, so the change always lies in the rig's future.  Set when the write is
  read instead, a valve would act up to that much later by the pump's luck: under load a
  supply the board held for 60 ms could give the rig none at all.

``record=True`` keeps every fed sample (``fed()``: AVR time in microseconds
and the rig's counts) so tests can hold the firmware's frames against the rig;
``pins()`` always lists every port write (AVR time, port, value).
The rig must have the firmware's six channels, in its order (``FIRMWARE_CHANNELS``: the
reference rig's names, compiled into the firmware); the ``sim://`` mode whose rig has them
is found through the registry, like any ``mode=``.
"""

from __future__ import annotations

import os
import select
import struct
import subprocess
import threading
import time
from collections import deque
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from ...errors import DeviceError
from . import make_rig, modes

FIRMWARE_CHANNELS = ("P_L1", "P_R1", "P_L2", "P_R2", "POT1", "POT2")  # A0..A5
# Each chamber's coils (firmware/src/config.h): port, inlet bit, exhaust bit; and the main supply valve.
VALVE_PINS = (("D", 2, 3), ("D", 4, 5), ("D", 6, 7), ("B", 0, 1))
MAIN_SUPPLY_PIN = ("B", 2)
HARNESS_NAME = "labcli_hil"
BUILD_HINT = (
    "build it with `make -C firmware` (needs gcc-avr, avr-libc, simavr, libsimavr-dev and libelf-dev: "
    "apt-get install gcc-avr avr-libc binutils-avr simavr libsimavr-dev libelf-dev)"
)
SLICE_MS = 1
IN_FLIGHT = {"wall": 3, "demand": 8}  # batches the harness may hold beyond the one it runs
VALVE_LAG_BATCHES = max(IN_FLIGHT.values()) + 1  # a valve acts on the rig this long after its pin moved
VREF = 5.0
ADC_MAX = 4095  # the rig's counts are the protocol's: V = counts * 5 / 4095
START_TIMEOUT_S = 10.0
CPU_HZ = 16_000_000  # the harness's default --freq
_HEAD = struct.Struct("<cI")
_SLICE_CYCLES = CPU_HZ * SLICE_MS // 1000


class FirmwareSimError(DeviceError):
    """The simulated board could not be started or stopped working (one sentence)."""


def find_harness(elf: Path) -> Path:
    """The harness built next to ``elf``, or :class:`FirmwareSimError` saying how to build it."""
    if not elf.is_file():
        raise FirmwareSimError(f"No firmware at {elf}: {BUILD_HINT}.")
    harness = elf.with_name(HARNESS_NAME)
    if not os.access(harness, os.X_OK):
        raise FirmwareSimError(f"No simulator harness next to {elf} ({harness}): {BUILD_HINT}.")
    return harness


def _wrong_rig(rig: Any) -> FirmwareSimError:
    """The rig lacks the firmware's channels: say which ``sim://`` mode has them (builds each rig once)."""
    fits = [m for m in modes() if tuple(make_rig(m).channels) == FIRMWARE_CHANNELS]
    advice = f"run it with mode={' or mode='.join(fits)}" if fits else "no installed simulated rig has them"
    return FirmwareSimError(
        f"The firmware reads {','.join(FIRMWARE_CHANNELS)} on A0-A5, but the simulated rig "
        f"{rig.device} has channels {','.join(rig.channels)}: {advice}."
    )


class HilLink:
    """One run of the firmware on simavr, fed by ``rig`` (see the module docstring)."""

    def __init__(
        self,
        rig: Any,
        elf: str | os.PathLike,
        *,
        pacing: str = "wall",
        seed: int = 0,
        adc_noise_lsb: float = 0.5,
        on_bytes: Callable[[bytes], None] | None = None,
        record: bool = False,
        batch_ms: int = 10,
        lead_s: float = 0.02,
    ) -> None:
        if pacing not in ("wall", "demand"):
            raise ValueError("pacing is 'wall' or 'demand'")
        if tuple(rig.channels) != FIRMWARE_CHANNELS:
            raise _wrong_rig(rig)
        self.elf = Path(elf)
        harness = find_harness(self.elf)
        self.rig = rig
        self.pacing = pacing
        self._in_flight = IN_FLIGHT[pacing]
        self.on_bytes = on_bytes or (lambda data: None)
        self.batch = int(batch_ms) // SLICE_MS  # slices per 'V' message
        self._batch_s = self.batch * SLICE_MS * 1e-3
        self.lead_s = float(lead_s)
        self.rig_t0 = float(rig.time_s)  # rig time at the AVR's power-up
        self.uart = ""  # the harness's report of the baud rate the firmware set
        self.error: str | None = None
        self.exited = threading.Event()
        self._batches_sent = 0
        self._batches_done = 0
        self._horizon_s = 0.0
        self._record: list[tuple[np.ndarray, np.ndarray]] | None = [] if record else None
        self._ports = {"B": 0, "D": 0}
        self._pins: list[tuple[float, str, int]] = []
        self.valve_states: tuple[str, ...] = ("hold",) * len(VALVE_PINS)  # the pins at power-up
        # The rig's valve changes still to come: (the slice after which they act, the states).
        self._valves_due: deque[tuple[int, list[str]]] = deque()
        self._valve_lag = VALVE_LAG_BATCHES * self.batch  # slices
        self._stderr: deque[str] = deque(maxlen=20)
        self._write_lock = threading.Lock()
        self._stop = threading.Event()
        self._wake_lock = threading.Lock()
        self._wake_r, self._wake_w = os.pipe()
        self._proc = subprocess.Popen(
            [
                str(harness),
                "--channels",
                str(len(FIRMWARE_CHANNELS)),
                "--slice-us",
                str(SLICE_MS * 1000),
                "--seed",
                str(int(seed)),
                "--adc-noise-lsb",
                repr(float(adc_noise_lsb)),
                str(self.elf),
            ],
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            bufsize=0,
        )
        stdin, stdout, stderr = self._proc.stdin, self._proc.stdout, self._proc.stderr
        if stdin is None or stdout is None or stderr is None:  # all three were asked for as PIPE
            raise RuntimeError("the simavr harness started without its pipes")
        self._pipe_in, self._pipe_out, self._pipe_err = stdin, stdout, stderr
        self._out = stdout.fileno()
        self._buf = bytearray()
        threading.Thread(target=self._drain_stderr, name="labcli-hil-stderr", daemon=True).start()
        try:
            self._await_hello()
        except BaseException:
            self.stop()
            raise
        self._wall0 = time.monotonic()
        self._thread = threading.Thread(target=self._run, name="labcli-hil", daemon=True)
        self._thread.start()

    # ------------------------------------------------------------ public

    @property
    def avr_time_s(self) -> float:
        """Simulated time the AVR has run to, s since its power-up."""
        return self._batches_done * self._batch_s

    @property
    def rig_time_s(self) -> float:
        """Simulated time the rig has been sampled to, s since the AVR's power-up (the AVR's plus what is in flight)."""
        return self._batches_sent * self._batch_s

    def write(self, data: bytes) -> None:
        """Send host bytes to the AVR's UART."""
        if data:
            self._send(b"R", bytes(data))

    def demand(self, seconds: float) -> None:
        """Let simulated time run ``seconds`` beyond what was already granted (``pacing="demand"``)."""
        sent_s = self._batches_sent * self._batch_s
        horizon = sent_s + float(seconds)
        if horizon > self._horizon_s:
            self._horizon_s = horizon
            self._wake()

    def _wake(self) -> None:
        with self._wake_lock:  # never write to the pipe's number once stop() closed it
            if self._wake_w >= 0:
                os.write(self._wake_w, b"x")

    def fed(self) -> tuple[np.ndarray, np.ndarray]:
        """With ``record=True``: (AVR time of each fed sample, us (n,); the rig's counts (n, 6))."""
        if self._record is None:
            raise ValueError("HilLink(record=True) keeps the fed samples")
        parts = list(self._record)
        if not parts:
            return np.zeros(0, np.int64), np.zeros((0, len(FIRMWARE_CHANNELS)), np.int64)
        return np.concatenate([p[0] for p in parts]), np.concatenate([p[1] for p in parts])

    def pins(self) -> list[tuple[float, str, int]]:
        """Every write of the firmware to PORTB or PORTD: (AVR time s, ``"B"`` or ``"D"``, value)."""
        return list(self._pins)

    def failure(self) -> str:
        """Why the simulation ended, as one sentence."""
        return self._ended()

    def stop(self, timeout: float = 2.0) -> None:
        """Stop the harness (the AVR loses power); idempotent."""
        if self._pipe_out.closed:
            return
        self._stop.set()
        self._wake()
        thread = getattr(self, "_thread", None)
        if thread is not None and thread is not threading.current_thread():
            thread.join(timeout)
        try:
            self._send(b"Q", b"")
            self._pipe_in.close()
        except (OSError, ValueError):
            pass  # the harness has already gone
        try:
            self._proc.wait(timeout)
        except subprocess.TimeoutExpired:
            self._proc.kill()
            self._proc.wait()
        self._pipe_out.close()
        with self._wake_lock:
            if self._wake_w >= 0:
                os.close(self._wake_r)
                os.close(self._wake_w)
                self._wake_r = self._wake_w = -1
        self.exited.set()

    # ------------------------------------------------------------ harness I/O

    def _send(self, kind: bytes, payload: bytes) -> None:
        data = memoryview(_HEAD.pack(kind, len(payload)) + payload)
        with self._write_lock:
            fd = self._pipe_in.fileno()
            while data:
                data = data[os.write(fd, data) :]

    def _drain_stderr(self) -> None:
        for line in self._pipe_err:
            self._stderr.append(line.decode("utf-8", "replace").rstrip())

    def _await_hello(self) -> None:
        deadline = time.monotonic() + START_TIMEOUT_S
        while True:
            for kind, payload in self._messages():
                if kind == b"H":
                    return
                if kind == b"E":
                    self.error = payload.decode("utf-8", "replace")
            left = deadline - time.monotonic()
            if left <= 0 or not self._read_some(left):
                raise FirmwareSimError(self._ended(starting=True))

    def _read_some(self, timeout: float | None) -> bool:
        """Read what the harness sent (waiting up to ``timeout``); False when it has exited."""
        ready, _, _ = select.select([self._out, self._wake_r], [], [], timeout)
        if self._wake_r in ready:
            os.read(self._wake_r, 4096)
        if self._out in ready:
            data = os.read(self._out, 65536)
            if not data:
                return False
            self._buf += data
        return True

    def _messages(self):
        buf = self._buf
        pos = 0
        while len(buf) - pos >= _HEAD.size:
            kind, n = _HEAD.unpack_from(buf, pos)
            if len(buf) - pos - _HEAD.size < n:
                break
            yield kind, bytes(buf[pos + _HEAD.size : pos + _HEAD.size + n])
            pos += _HEAD.size + n
        del buf[:pos]

    def _ended(self, starting: bool = False) -> str:
        what = "did not start" if starting else "stopped"
        why = self.error or (self._stderr[-1] if self._stderr else "no message")
        return f"The simulated board running {self.elf.name} {what}: {why.rstrip('.')}."

    # ------------------------------------------------------------ the pump

    def _run(self) -> None:
        try:
            while not self._stop.is_set():
                self._grant()
                if not self._read_some(self._wait_s()):
                    break
                for kind, payload in self._messages():
                    self._handle(kind, payload)
        except (OSError, ValueError):
            pass  # pipes closed under us: stopping
        finally:
            self.exited.set()

    def _handle(self, kind: bytes, payload: bytes) -> None:
        if kind == b"U":
            self.on_bytes(payload)
        elif kind == b"T":
            self._batches_done += 1
        elif kind == b"B":
            self.uart = payload.decode("ascii", "replace")
        elif kind == b"P":
            self._port_write(payload)
        elif kind == b"E":
            self.error = payload.decode("utf-8", "replace")

    def _port_write(self, payload: bytes) -> None:
        cycle, port, value = struct.unpack("<QcB", payload)
        name = port.decode("ascii")
        self._ports[name] = value
        self._pins.append((cycle / CPU_HZ, name, value))
        main = self._ports[MAIN_SUPPLY_PIN[0]] >> MAIN_SUPPLY_PIN[1] & 1
        states = []
        for p, inlet, exhaust in VALVE_PINS:
            bits = self._ports[p]
            states.append("vent" if bits >> exhaust & 1 else "supply" if bits >> inlet & 1 and main else "hold")
        if tuple(states) != self.valve_states:
            self.valve_states = tuple(states)
            if hasattr(self.rig, "set_valves"):
                # The write's slice (rounded up), plus the lag: never before the rig's clock.
                at = -(-cycle // _SLICE_CYCLES) + self._valve_lag
                self._valves_due.append((max(at, self._batches_sent * self.batch), states))

    def _may_send(self) -> bool:
        if self._batches_sent - self._batches_done > self._in_flight:
            return False
        start_s = self._batches_sent * self._batch_s
        if self.pacing == "wall":
            return start_s <= time.monotonic() - self._wall0 + self.lead_s
        return start_s < self._horizon_s

    def _wait_s(self) -> float | None:
        if self.pacing == "wall" and self._batches_sent - self._batches_done <= self._in_flight:
            start_s = self._batches_sent * self._batch_s
            return max(0.0, start_s - self.lead_s - (time.monotonic() - self._wall0))
        return None  # a harness message or a demand() wakes us

    def _grant(self) -> None:
        while self._may_send():
            counts = self._next_counts()
            volts = (np.asarray(counts, np.float32) * np.float32(VREF / ADC_MAX)).astype("<f4")
            self._send(b"V", volts.tobytes())
            if self._record is not None:
                first = self._batches_sent * self.batch
                t_us = (first + np.arange(1, self.batch + 1, dtype=np.int64)) * SLICE_MS * 1000
                self._record.append((t_us, np.asarray(counts, np.int64)))
            self._batches_sent += 1

    def _next_counts(self) -> np.ndarray:
        """The rig's counts over the next batch's slices, each valve change made after its own slice."""
        done = self._batches_sent * self.batch
        end = done + self.batch
        parts = []
        while self._valves_due and self._valves_due[0][0] < end:
            at, states = self._valves_due.popleft()
            if at > done:
                parts.append(self.rig.samples(at - done, 1000.0 / SLICE_MS)[1])
                done = at
            self.rig.set_valves(states)
        parts.append(self.rig.samples(end - done, 1000.0 / SLICE_MS)[1])
        return parts[0] if len(parts) == 1 else np.concatenate(parts)
