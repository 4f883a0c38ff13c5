"""pyserial URL handler for ``sim://``: the simulated rig as a serial port.

``serial.serial_for_url("sim://?seed=1&rate=200")`` (with ``labcli.core.sim``
in ``serial.protocol_handler_packages``, see :func:`labcli.core.sim.register`)
returns a port with the pyserial API whose other end runs the simulated
firmware (:mod:`labcli.core.sim.firmware`) over a simulated rig.

URL: ``sim://[?seed=N][&rate=HZ][&noise=X][&drift=X][&clock=virtual|wall][&tau=S][&ratefactor=X][&mode=NAME][&faults=SPEC][&fw=1.0|1.1][&firmware=ELF][&RIG_OPTION=...]``

* ``seed`` (0): seeds the actuators, sensor offsets, noise and settling times;
* ``rate`` (200): sample rate at power-up, Hz (1..50000; ``RATE`` changes it);
* ``noise`` (1): scale of the sensor noise (0.5 count pressure, 0.7 count pot rms);
* ``drift`` (the rig's own default when not given): scale of sensor zero drift;
* ``clock``: ``virtual`` (default) advances device time only as the host reads,
  so hours of protocol run in seconds: while streaming, a read never waits
  (frames are sampled when read; ``in_waiting`` offers about 1 s of device
  time, so an operator action between reads acts after the frames the host
  has seen, give or take two); while idle,
  a read short of bytes waits its timeout as on a real port and the device's
  clock runs on by the time waited.  ``wall`` paces frames by the wall clock
  like real hardware;
* ``tau`` (0.7): settling time constant after each load change, s;
* ``ratefactor`` (1): the rig streams at this many times the rate it confirms (a firmware
  timer set wrong: ``OK RATE 200`` and frames 10x as often with ``ratefactor=10``), its
  own clock stamping each frame as it is made; 0.01..100;
* ``mode`` (the default rig, mckibben): which rig model (:func:`labcli.core.sim.modes`, one per
  paper's simulated rig);
* ``fw`` (1.1): the wire protocol version the firmware model speaks; ``fw=1.0`` is a board
  without valves, pressure limit or event lines (:mod:`labcli.core.sim.valves`), to test a
  host against both;
* ``faults`` (none): a noisy link, ``KIND:RATE[@X],...`` per
  :mod:`labcli.core.sim.faults`, e.g. ``faults=checksum:0.01,drop:0.01,stall:0.001@2.5``;
  drawn from ``seed``.  ``port.faults`` is then the
  :class:`~labcli.core.sim.faults.FaultInjector` holding the exact ground truth;
* ``firmware`` (none): run this compiled firmware on simavr instead of the
  firmware model (:mod:`labcli.core.sim.hil_port`, chosen by :func:`serial_class_for_url`).

The grammar (parsing, defaults, the accepted form every refusal shows) is
:mod:`labcli.core.sim.url`, shared with the firmware on simavr.

Beside these, a rig takes its own options, declared by its paper
(``Paper.sim_options``) and refused with any other ``mode``: the McKibben
rig's non-idealities, supply and actuator design, for instance
(``ideal=1``, ``friction=0.5``, ``supply=0.3``, ``design=thin``; see
:mod:`labcli.papers.takuma2014.sim.options`).

``port.rig`` is the rig object (operator hooks for unattended runs and
tests; not part of the wire protocol).  ``port.unplug()`` makes every later
read and write fail as a hot-unplugged USB adapter does.
"""

from __future__ import annotations

import threading
import time

from serial.serialutil import PortNotOpenError, SerialException, to_bytes

from .faults import FaultInjector
from .firmware import Firmware
from .port import SimulatedPort
from .url import parse_sim_url

UNPLUGGED = "device reports readiness to read but returned no data"
BLOCK_S = 1.0  # device time offered by in_waiting while streaming (virtual clock)
MAX_BLOCK_FRAMES = 1500
SILENT_LINK_S = 5.0  # device time of frames all lost after which a virtual read gives up, as a real one times out
MAX_BUFFER = 1 << 22  # bytes held for the host before new frames are dropped (wall clock)


def serial_class_for_url(url: str) -> tuple[str, type]:
    """pyserial's hook: ``firmware=`` selects the firmware on simavr, otherwise the firmware model."""
    if parse_sim_url(url)["firmware"] is None:
        return url, Serial
    from .hil_port import HilSerial

    return url, HilSerial


class Serial(SimulatedPort):
    """The simulated rig behind the pyserial ``Serial`` API (see module docstring)."""

    def __init__(self, *args, **kwargs) -> None:
        self.firmware: Firmware | None = None
        self.faults: FaultInjector | None = None
        self._rx = bytearray()
        self._cond = threading.Condition(threading.RLock())
        self._unplugged = False
        self._cancel = False
        self._line_len = 46  # bytes per data line, refined as frames are made
        self._wall0 = 0.0
        self._pace_t0 = 0.0
        self._pace_sent = 0
        self.dropped_frames = 0
        super().__init__(*args, **kwargs)

    # ------------------------------------------------------------ open/close

    def open(self) -> None:
        # The rig is physical: reopening the port reboots the firmware, not the rig.
        opts = self._open_rig()
        spec = opts["faults"]
        self.faults = (
            None if spec is None else FaultInjector(spec, seed=opts["seed"], n_channels=len(self.rig.channels))
        )
        self.firmware = Firmware(
            self.rig, opts["rate"], faults=self.faults, rate_factor=opts["ratefactor"], version=opts["fw"]
        )
        self._unplugged = False
        self._wall0 = time.monotonic() - self.rig.time_s
        self.is_open = True
        self.reset_input_buffer()
        self._rx += self.firmware.banner()

    def close(self) -> None:
        with self._cond:
            self.is_open = False
            self._cond.notify_all()
        super().close()

    def from_url(self, url: str) -> dict:
        return parse_sim_url(url)

    # ------------------------------------------------------------ faults

    def unplug(self) -> None:
        """Simulate a hot unplug: every later read/write/in_waiting raises SerialException."""
        with self._cond:
            self._unplugged = True
            self._cond.notify_all()

    def _check(self) -> None:
        if not self.is_open:
            raise PortNotOpenError()
        if self._unplugged:
            raise SerialException(UNPLUGGED)

    def _open_firmware(self) -> Firmware:
        """The firmware of the open port (None only before the first open)."""
        if self.firmware is None:
            raise PortNotOpenError()
        return self.firmware

    # ------------------------------------------------------------ clocks

    @property
    def _virtual(self) -> bool:
        return self.options.get("clock", "virtual") == "virtual"

    def _pump(self, want_bytes: int = 0) -> None:
        """Append the frames that are due (wall clock) or wanted (virtual clock)."""
        fw = self.firmware
        if fw is None or not fw.streaming:
            return
        if self._virtual:
            # Only about what the host takes is sampled, so an operator action
            # after a read acts after the frames the host has seen (give or take
            # the couple of frames a real USB link also holds).
            silent = 0  # frames sampled that left no byte on the link (every one dropped)
            while len(self._rx) < want_bytes:
                n = max(1, min(-(-(want_bytes - len(self._rx)) // self._line_len), 100_000))
                chunk = fw.frames(n)
                fw.take_stall()  # virtual clock: the stall is the gap the rig's clock already made
                if chunk:
                    self._line_len = max(20, len(chunk) // max(1, chunk.count(b"\n")))
                    silent = 0
                else:
                    silent += n
                    if silent >= max(1.0, fw.stream_hz * SILENT_LINK_S):
                        break  # a link that carries nothing: the host's read times out, as on a real port
                self._rx += chunk
            return
        due = int((time.monotonic() - self._pace_t0) * fw.stream_hz) - self._pace_sent
        if due <= 0:
            return
        self._pace_sent += due
        if len(self._rx) > MAX_BUFFER:
            # The host is not reading: the device's buffer overflows and frames are lost.
            fw.skip(due)
            self.dropped_frames += due
            return
        self._rx += fw.frames(due)
        stall = fw.take_stall()
        if stall is not None:
            # The firmware hung: the frames it did not make fall due a stall later.
            seconds, not_made = stall
            self._pace_sent -= not_made
            self._pace_t0 += seconds

    def _next_due(self) -> float:
        fw = self._open_firmware()
        return self._pace_t0 + (self._pace_sent + 1) / fw.stream_hz

    # ------------------------------------------------------------ I/O

    @property
    def in_waiting(self) -> int:
        with self._cond:
            self._check()
            fw = self._open_firmware()
            if self._virtual and fw.streaming:
                # A streaming virtual device always has the next block ready; it
                # is sampled when read.
                block = min(max(1, round(fw.stream_hz * BLOCK_S)), MAX_BLOCK_FRAMES)
                return len(self._rx) + block * self._line_len
            self._pump()
            return len(self._rx)

    def read(self, size: int = 1) -> bytes:
        with self._cond:
            self._check()
            if size <= 0:
                return b""
            self._cancel = False
            self._pump(size)
            if len(self._rx) < size:
                # Like a real port: wait for more bytes until the timeout.  A
                # streaming virtual device never gets here (frames are made on
                # demand); an idle one lets its clock run while the host waits.
                start = time.monotonic()
                deadline = None if self._timeout is None else start + self._timeout
                while len(self._rx) < size and not self._cancel:
                    now = time.monotonic()
                    if deadline is not None and now >= deadline:
                        break
                    wake = deadline
                    if self._open_firmware().streaming and not self._virtual:
                        nd = self._next_due()
                        wake = nd if wake is None else min(wake, nd)
                    self._cond.wait(None if wake is None else max(0.0, wake - now))
                    self._check()
                    self._pump(size)
                if self._virtual:
                    self.rig.advance(time.monotonic() - start)
            data = bytes(self._rx[:size])
            del self._rx[:size]
            return data

    def write(self, data) -> int:
        with self._cond:
            self._check()
            data = to_bytes(data)
            fw = self._open_firmware()
            was_streaming, old_rate = fw.streaming, fw.rate_hz
            if not self._virtual:
                self._pump()
                if not fw.streaming:
                    # Idle device: its clock kept running with the wall clock.
                    self.rig.advance_to(time.monotonic() - self._wall0)
            reply = fw.receive(data)
            if not self._virtual and fw.streaming and (not was_streaming or fw.rate_hz != old_rate):
                self._pace_t0 = time.monotonic()
                self._pace_sent = 0
            self._rx += reply
            self._cond.notify_all()
            return len(data)

    def reset_input_buffer(self) -> None:
        with self._cond:
            if not self.is_open:
                raise PortNotOpenError()
            self._rx.clear()

    def flush(self) -> None:
        # Writes reach the firmware at once; only an unplugged port fails here.
        if self.is_open and self._unplugged:
            raise SerialException(UNPLUGGED)

    def cancel_read(self) -> None:
        with self._cond:
            self._cancel = True
            self._cond.notify_all()
