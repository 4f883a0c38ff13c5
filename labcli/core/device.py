"""The rig on the other end of a serial link, spoken to in the wire protocol.

``Device.open`` takes a port name (``/dev/ttyUSB0``, ``COM3``) or any pyserial
URL, ``sim://`` included, and does the handshake: flush, ``ID?`` until the
firmware answers (a board reset by opening the port needs a moment), channel
names learnt from the reply.  Every failure a person can act on becomes one
typed :class:`~labcli.errors.DeviceError` naming the port and what to check.

    with Device.open("sim://?seed=1", timeout=2.0) as dev:
        dev.set_rate(200)
        dev.start()
        batch = dev.read(timeout=1.0)     # FrameBatch of raw counts
        dev.stop()

The handshake also asks ``CAPS?``: a wire-protocol 1.1 board names its valves, pressure
limit, events and model (:class:`~labcli.core.board.BoardCaps`), a 1.0 board answers ``ERR``
and is driven as before.  The valve, pressure-limit and baseline commands
(:meth:`Device.set_valves`, :meth:`Device.set_pressure_limit`, :meth:`Device.take_baseline`)
refuse a board without them in one sentence.
"""

from __future__ import annotations

import errno
import os
import select
import time
from dataclasses import dataclass
from typing import Any, Protocol, runtime_checkable

import serial

from ..errors import DeviceDisconnected, DeviceError, DeviceNotFound, DeviceTimeout, DeviceUnsupported
from .board import V1, VALVE_LETTERS, BoardCaps, parse_states
from .boardlines import Estimate, Event
from .sim import register as register_url_handlers
from .wire import FrameBatch, StreamReader, format_command

# The serial port of a POSIX system, read by select and os.read (see _Stamped); None elsewhere.
_POSIX_SERIAL: type | None = getattr(getattr(serial, "serialposix", None), "Serial", None)

try:  # absent on Windows
    from termios import error as _TermiosError
except ImportError:  # pragma: no cover

    class _TermiosError(Exception):  # type: ignore[no-redef]
        pass


POLL_S = 0.05  # port read timeout: how often a waiting read looks at its deadline
ID_RETRY_S = 0.5  # a board still booting ignores commands; ask again this often
DEFAULT_BOOT_WAIT_S = 2.0  # DTR reset of an Arduino-class board on open: 1-3 s
# What a stream can send instead of frames (StreamReader counters), for "sends no valid frames".
NOISE_COUNTERS = ("bad_checksum", "malformed", "overlong")


@dataclass(frozen=True)
class DeviceInfo:
    device: str
    firmware: str
    channels: tuple[str, ...]
    port: str


def _open_error(port: str, exc: BaseException) -> DeviceNotFound:
    text = str(exc)
    code = getattr(exc, "errno", None)
    if "://" in port and ("not known" in text or "invalid URL" in text):
        scheme = port.split("://", 1)[0]
        return DeviceNotFound(
            f"Cannot open serial port {port}: unknown URL scheme '{scheme}://'. "
            "Use a port name such as /dev/ttyUSB0 or COM3, or sim:// for the simulated rig."
        )
    if "://" in port:
        detail = text.rstrip(".")
        return DeviceNotFound(f"Cannot open serial port {port}: {detail}. Check the URL's options.")
    if code == errno.ENOENT or "No such file" in text or "FileNotFoundError" in text or "cannot find" in text:
        return DeviceNotFound(
            f"Cannot open serial port {port}: no such device. Check the cable and run `labcli ports` to list ports."
        )
    if code in (errno.EACCES, errno.EPERM) or "Permission denied" in text or "Access is denied" in text:
        return DeviceNotFound(
            f"Cannot open serial port {port}: permission denied. Add your user to the group that owns "
            "the port (dialout on most Linux systems) and log in again."
        )
    if code == errno.EBUSY or "exclusively lock" in text or "busy" in text.lower():
        return DeviceNotFound(
            f"Cannot open serial port {port}: it is in use by another program. "
            "Close that program (a serial monitor, another labcli) and try again."
        )
    return DeviceNotFound(
        f"Cannot open serial port {port}: {text.rstrip('.')}. Check the cable and run `labcli ports` to list ports."
    )


@runtime_checkable
class RigLink(Protocol):
    """What the engine, the monitor and the operator need of an open rig: the seam another
    transport (a socket, a DAQ card's driver) plugs into.  :class:`Device` is the serial one."""

    name: str  # how messages speak of the port
    info: DeviceInfo | None  # what the rig said it is (None before the handshake)

    @property
    def rig(self) -> Any:
        """The simulated rig behind the link (None at a real rig)."""

    @property
    def streaming(self) -> bool:
        """Whether the rig is sending frames."""

    @property
    def counters(self) -> dict[str, int]:
        """Noise seen on the link so far: frames dropped, corrupt lines, ... by name."""

    def set_rate(self, hz: float) -> float:
        """Ask for a sample rate; the rate the rig runs at (Hz)."""

    def start(self) -> None:
        """Start streaming frames."""

    def stop(self) -> FrameBatch:
        """Stop streaming; the frames that were still on their way."""

    def read(self, timeout: float = 1.0) -> FrameBatch:
        """The frames that came within ``timeout`` seconds (DeviceTimeout on a silent rig)."""

    def close(self) -> None:
        """Release the link (idempotent)."""


class _Stamped:
    """The port as the reader reads it, stamping ``arrived`` (``time.perf_counter()``) whenever a read
    brings bytes: when the newest frame of a batch reached the host, before it is parsed."""

    def __init__(self, port: Any) -> None:
        self.port = port
        self.arrived: float | None = None
        if type(port) is _POSIX_SERIAL:  # a port of the operating system's, not a URL's (sim://)
            self.read_burst = self._read_fd

    def _read_fd(self, timeout: float, size: int) -> bytes:
        """What the port holds (up to ``size`` bytes), once its first byte came within ``timeout`` s.

        One wait and one read: pyserial's ``read(1)``, ``in_waiting`` and ``read(n)`` cost three
        system calls more a wake, and at an idle host's frame or two a wake that is most of the cost.
        The same wake (the first byte) and the same errors as pyserial's read.
        """
        fd = self.port.fd
        if fd is None:
            raise serial.PortNotOpenError()
        if not select.select((fd,), (), (), timeout)[0]:
            return b""
        try:
            data = os.read(fd, size)
        except BlockingIOError:  # woken, but another reader took the bytes: nothing yet
            return b""
        if not data:  # a port that went away reads as always ready and empty
            raise serial.SerialException("device reports readiness to read but returned no data (device disconnected?)")
        self.arrived = time.perf_counter()
        return data

    @property
    def in_waiting(self) -> int:
        return int(self.port.in_waiting)

    def read(self, size: int = 1) -> bytes:
        data = self.port.read(size)
        if data:
            self.arrived = time.perf_counter()
        return data


class Device:
    """An open rig.  Use :meth:`open`; the constructor takes an already open serial object."""

    def __init__(
        self, ser: Any, port: str, *, timeout: float = 2.0, baudrate: int = 115200, name: str | None = None
    ) -> None:
        self._serial = ser
        self.port = port
        self.name = port if name is None else name  # how messages speak of the port
        self.timeout = float(timeout)
        self.baudrate = baudrate
        self._reader = StreamReader(_Stamped(ser))
        self._backlog: list[FrameBatch] = []
        self._streaming = False
        self._last_frame = time.monotonic()
        self._noise_at_frame: dict[str, int] = {}  # noise counters when the last frame came
        self.info: DeviceInfo | None = None
        self.caps: BoardCaps = V1  # what the board offers beyond wire protocol 1.0 (CAPS?)
        self._other_reply: str | None = None  # last non-ID answer during the handshake

    # -- opening ---------------------------------------------------------------

    @classmethod
    def open(
        cls,
        port: str,
        *,
        baudrate: int = 115200,
        timeout: float = 2.0,
        boot_wait: float | None = None,
        name: str | None = None,
    ) -> Device:
        """Open ``port`` and do the handshake.

        ``timeout`` bounds every wait for an answer and the silence tolerated
        while streaming; ``boot_wait`` is added to the first ``ID?`` wait for a
        board that resets when the port opens (default 2 s for serial ports,
        0 for URLs such as ``sim://``); ``name`` is how error messages speak of
        the port (default ``port``), for a caller that opens a variant of what
        the user typed.
        """
        register_url_handlers()
        is_url = "://" in port
        if boot_wait is None:
            boot_wait = 0.0 if is_url else DEFAULT_BOOT_WAIT_S
        kwargs: dict[str, Any] = {"baudrate": baudrate, "timeout": POLL_S, "write_timeout": timeout}
        if not is_url:
            kwargs["exclusive"] = True  # a second program on the port would steal half the lines
        try:
            ser = serial.serial_for_url(port, **kwargs)
        except (serial.SerialException, ValueError, OSError, _TermiosError) as exc:
            raise _open_error(port if name is None else name, exc) from None
        dev = cls(ser, port, timeout=timeout, baudrate=baudrate, name=name)
        try:
            dev._handshake(timeout + boot_wait)
        except BaseException:
            dev._close_port()
            raise
        return dev

    def _handshake(self, wait: float) -> None:
        self._io(self._serial.reset_input_buffer)
        self._reader.clear()
        deadline = time.monotonic() + wait
        reply = None
        self._other_reply = None
        while reply is None:
            self._reader.replies.clear()
            self._write(format_command("ID?"))
            retry_at = min(deadline, time.monotonic() + ID_RETRY_S)
            while reply is None and time.monotonic() < retry_at:
                self._pump(retry_at - time.monotonic())
                while self._reader.replies:
                    text = self._reader.replies.popleft()
                    if text.startswith("ID,"):
                        reply = text
                        break
                    self._other_reply = text
            if reply is None and time.monotonic() >= deadline:
                self._handshake_failed(wait)
        fields = reply.split(",")
        if len(fields) < 4 or not all(f.strip() for f in fields[3:]):
            raise DeviceError(
                f"The device on {self.name} sent an ID line without channel names ({reply!r}). "
                "Check that its firmware answers ID? with ID,<device>,<firmware>,<ch1>,...,<chN>."
            )
        channels = tuple(f.strip() for f in fields[3:])
        repeated = sorted({c for c in channels if channels.count(c) > 1})
        if repeated:
            raise DeviceError(
                f"The device on {self.name} names channel{'s' if len(repeated) > 1 else ''} "
                f"{', '.join(repeated)} more than once in its ID line ({reply!r}), so its values cannot be told "
                "apart. Check that its firmware gives each channel its own name."
            )
        self.info = DeviceInfo(fields[1].strip(), fields[2].strip(), channels, self.port)
        logs = self._reader.logs
        self._reader = StreamReader(_Stamped(self._serial), n_channels=len(channels))
        self._reader.logs.extend(logs)
        # A board left streaming by an earlier session must be quiet before commands get clean
        # replies; STOP on an idle board is answered too, so always send it.
        # (A firmware that answers ERR when idle is in a known state as well.)
        self._command("STOP", expect="OK STOP", accept_err=True)
        self.caps = self._ask_caps()
        self._backlog.clear()
        self._reader.reset_counters()

    def _ask_caps(self) -> BoardCaps:
        """A 1.1 board's capabilities; a 1.0 board (``ERR``, or no answer at all) offers none."""
        try:
            reply = self._command("CAPS?", expect="CAPS", accept_err=True)
        except DeviceTimeout:
            return V1
        if reply.startswith("ERR"):
            return V1
        try:
            return BoardCaps.parse(reply)
        except ValueError:
            raise DeviceError(
                f"The device on {self.name} answered CAPS? with {reply!r}, not CAPS,<version>,<capability>,... "
                "Check that its firmware speaks wire protocol 1.1."
            ) from None

    def _handshake_failed(self, wait: float) -> None:
        reader = self._reader
        if reader.noise or self._other_reply is not None:
            if self._other_reply is not None:
                shown = self._other_reply
            else:
                shown = reader.noise[-1][1].decode("ascii", "replace")
            raise DeviceError(
                f"The device on {self.name} answered {shown!r}, which is not the labcli wire protocol. "
                f"Check the baud rate ({self.baudrate}) and that the firmware speaks wire protocol version 1."
            )
        raise DeviceTimeout(
            f"No answer to ID? from {self.name} within {wait:g} s. Check that the rig is powered and "
            f"that its firmware speaks the labcli wire protocol at {self.baudrate} baud."
        )

    # -- properties ------------------------------------------------------------

    @property
    def rig(self) -> Any:
        """The simulated rig behind a ``sim://`` port (operator hooks, truth), else None."""
        return getattr(self._serial, "rig", None)

    @property
    def counters(self) -> dict[str, int]:
        """Link statistics since the last :meth:`start` (see ``StreamReader``), ``stalls`` included."""
        return {**self._reader.counters, "stalls": self._reader.stalls}

    @property
    def stalls(self) -> int:
        """Stalls since the last :meth:`start`: frame gaps longer in device time than the
        rate's period by more than ``StreamReader.stall_us`` (counted once :meth:`set_rate` was called)."""
        return self._reader.stalls

    @property
    def stalled_s(self) -> float:
        """Device time lost to those stalls, s."""
        return self._reader.stalled_s

    @property
    def logs(self) -> list[str]:
        return list(self._reader.logs)

    @property
    def streaming(self) -> bool:
        return self._streaming

    @property
    def arrived(self) -> float | None:
        """``time.perf_counter()`` when the bytes of the newest frame :meth:`read` returned reached the host."""
        return self._reader.port.arrived

    @property
    def serial(self) -> Any:
        return self._serial

    # -- commands --------------------------------------------------------------

    def set_rate(self, hz: float) -> float:
        """Ask for ``hz`` frames per second; returns the rate the firmware actually set."""
        arg = int(hz) if float(hz).is_integer() else hz
        reply = self._command(f"RATE {arg}", expect="OK RATE")
        try:
            actual = float(reply.split()[2])
        except (IndexError, ValueError):
            raise DeviceError(
                f"The device on {self.name} answered {reply!r} to RATE {arg}, expected 'OK RATE <hz>'. "
                "Check that the firmware speaks wire protocol version 1."
            ) from None
        self._reader.set_rate(actual if actual > 0 else None)
        return actual

    def start(self) -> None:
        """Start streaming; counters and the sequence check start afresh."""
        self._reader.reset_sequence()
        self._reader.reset_counters()
        self._backlog.clear()
        self._command("START", expect="OK START")
        self._streaming = True
        self._last_frame = time.monotonic()
        self._noise_at_frame = {}

    def stop(self) -> FrameBatch:
        """Stop streaming; returns the frames not yet read, those in flight before ``OK STOP`` included."""
        try:
            self._command("STOP", expect="OK STOP")
        finally:
            self._streaming = False
        batch = FrameBatch.concat(self._backlog, len(self.info.channels) if self.info else 0)
        self._backlog.clear()
        return batch

    def read(self, timeout: float = 1.0) -> FrameBatch:
        """Frames received so far, waiting up to ``timeout`` s for the first.

        Raises DeviceTimeout when streaming and no frame came for the open
        ``timeout``; DeviceDisconnected when the port went away.
        """
        k = len(self.info.channels) if self.info else 0
        if self._backlog:
            batch = FrameBatch.concat(self._backlog, k)
            self._backlog.clear()
            return batch
        deadline = time.monotonic() + timeout
        while True:
            batch = self._pump(max(0.0, deadline - time.monotonic()))
            now = time.monotonic()
            if len(batch):
                self._last_frame = now
                self._noise_at_frame = {k: self._reader.counters[k] for k in NOISE_COUNTERS}
                return batch
            if self._streaming and now - self._last_frame > self.timeout:
                raise self._silence()
            if now >= deadline:
                return batch

    def _silence(self) -> DeviceTimeout:
        """No frame for ``timeout`` s while streaming: silence, or bytes that were never a valid frame."""
        c = self._reader.counters
        noise = {k: c[k] - self._noise_at_frame.get(k, 0) for k in NOISE_COUNTERS}
        if not any(noise.values()):
            return DeviceTimeout(
                f"No data from {self.name} for {self.timeout:g} s while streaming. "
                "Check the cable and that the rig is powered."
            )
        counts = ", ".join(f"{n} {k.replace('_', ' ')}" for k, n in noise.items() if n)
        what = f"sends no valid frames ({counts} in {self.timeout:g} s)"
        return DeviceTimeout(
            f"The rig on {self.name} {what}. Check the baud rate ({self.baudrate}) and that its firmware "
            "speaks wire protocol version 1.",
            what=what,
        )

    def _command(self, command: str, *, expect: str, accept_err: bool = False) -> str:
        self._reader.replies.clear()
        self._write(format_command(command))
        deadline = time.monotonic() + self.timeout
        while True:
            while self._reader.replies:
                text = self._reader.replies.popleft()
                if text == expect or text.startswith((expect + " ", expect + ",")):
                    return text
                if text.startswith("ERR"):
                    if accept_err:
                        return text
                    raise DeviceError(
                        f"The device on {self.name} refused {command}: {text!r}. "
                        "Check the values its firmware accepts for that command."
                    )
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                raise DeviceTimeout(
                    f"No answer to {command} from {self.name} within {self.timeout:g} s. "
                    "Check that the rig is still powered and connected."
                )
            batch = self._pump(min(remaining, 0.2))
            if len(batch):
                self._backlog.append(batch)  # frames around a command are kept, never dropped

    # -- wire protocol 1.1: valves, pressure limit, events, the board's model ------

    def _need(self, what: str, have: bool) -> None:
        if have:
            return
        fw = self.info.firmware if self.info else "?"
        if self.caps.protocol == "1.0":
            raise DeviceUnsupported(
                f"The board on {self.name} (firmware {fw}) speaks wire protocol 1.0, which has no {what}; "
                "flash firmware 1.1 (`labcli flash`) or do it by hand at the rig."
            )
        raise DeviceUnsupported(
            f"The board on {self.name} (firmware {fw}, wire protocol {self.caps.protocol}) offers no {what} "
            f"(its CAPS? reply: {self.caps.format()!r}); do it by hand at the rig."
        )

    def _states(self, reply: str, command: str) -> dict[str, str]:
        try:
            return parse_states(reply.split()[2], self.caps.valves)
        except (IndexError, ValueError):
            raise DeviceError(
                f"The device on {self.name} answered {reply!r} to {command}, expected 'OK VALVE <states>'. "
                "Check that its firmware speaks wire protocol 1.1."
            ) from None

    def set_valves(self, state: str, channel: str | None = None) -> dict[str, str]:
        """Put one chamber's valve (``channel``, a pressure channel's name) or all of them in
        ``state`` (``supply``, ``hold`` or ``vent``); returns every valve's state as the board set it."""
        self._need("valve control", bool(self.caps.valves))
        if state not in VALVE_LETTERS:
            raise ValueError(f"a valve state is supply, hold or vent, not {state!r}")
        if channel is not None and channel not in self.caps.valves:
            raise DeviceError(
                f"The board on {self.name} has no valve on {channel}; its valves serve {', '.join(self.caps.valves)}."
            )
        command = f"VALVE {channel or 'ALL'} {state.upper()}"
        return self._states(self._command(command, expect="OK VALVE"), command)

    def valve_states(self) -> dict[str, str]:
        """Every valve's state, asked of the board (``VALVE?``)."""
        self._need("valve control", bool(self.caps.valves))
        return self._states(self._command("VALVE?", expect="OK VALVE"), "VALVE?")

    def set_pressure_limit(self, counts: int | list[int]) -> tuple[int, ...]:
        """The board's over-pressure limit in raw counts, one for every valve's channel or one each
        (``board.limit_counts`` converts MPa); the board keeps it through resets.  Returns the limits set."""
        self._need("pressure limit", self.caps.pmax)
        values = [counts] if isinstance(counts, int) else list(counts)
        reply = self._command("PMAX " + " ".join(str(int(c)) for c in values), expect="OK PMAX")
        return self._limits(reply)

    def pressure_limit(self) -> tuple[int, ...]:
        """The board's over-pressure limit per valve channel, raw counts (``PMAX?``)."""
        self._need("pressure limit", self.caps.pmax)
        return self._limits(self._command("PMAX?", expect="OK PMAX"))

    def _limits(self, reply: str) -> tuple[int, ...]:
        try:
            return tuple(int(v) for v in reply.split()[2:])
        except ValueError:
            raise DeviceError(
                f"The device on {self.name} answered {reply!r}, expected 'OK PMAX <counts>...'."
            ) from None

    def take_baseline(self) -> None:
        """Have the board's model retake its baseline (its ``BASELINE`` event follows when taken)."""
        self._need("model baseline", self.caps.baseline)
        self._command("BASELINE", expect="OK BASELINE")

    def stream_estimates(self, every: int = 1) -> int:
        """Have the board send an estimate line after every ``every``-th data line (0: none)."""
        self._need("model estimates", bool(self.caps.estimates))
        reply = self._command(f"EST {int(every)}", expect="OK EST")
        try:
            return int(reply.split()[2])
        except (IndexError, ValueError):
            raise DeviceError(f"The device on {self.name} answered {reply!r}, expected 'OK EST <n>'.") from None

    def take_events(self) -> list[Event]:
        """The board's event lines received since the last call, oldest first."""
        out = list(self._reader.events)
        self._reader.events.clear()
        return out

    def take_estimates(self) -> list[Estimate]:
        """The board's estimate lines received since the last call, oldest first."""
        out = list(self._reader.estimates)
        self._reader.estimates.clear()
        return out

    # -- port I/O --------------------------------------------------------------

    def _pump(self, timeout: float) -> FrameBatch:
        return self._io(self._reader.read, timeout)

    def _write(self, data: bytes) -> None:
        self._io(self._serial.write, data)
        self._io(self._serial.flush)

    def _io(self, fn, *args):
        try:
            return fn(*args)
        except serial.SerialTimeoutException:
            raise DeviceTimeout(
                f"Writing to {self.name} did not finish within {self.timeout:g} s. "
                "Check that the rig is powered and not blocked (hardware flow control)."
            ) from None
        except (serial.SerialException, OSError, _TermiosError) as exc:
            self._streaming = False
            raise DeviceDisconnected(
                f"Lost the connection to {self.name}: the device was disconnected. "
                "Check the cable and USB power, then run the command again."
            ) from exc

    # -- closing ---------------------------------------------------------------

    def close(self) -> None:
        """Stop the stream if running (best effort) and release the port."""
        if self._streaming:
            try:
                self.stop()
            except DeviceError:
                pass
        self._close_port()

    def _close_port(self) -> None:
        try:
            self._serial.close()
        except (serial.SerialException, OSError, _TermiosError):
            pass

    def __enter__(self) -> Device:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def __repr__(self) -> str:
        return f"Device({self.port!r}, info={self.info!r})"
