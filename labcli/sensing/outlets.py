"""Optional outputs for a lab's own stack: a ZeroMQ PUB socket and a Lab Streaming Layer outlet.

Each is an :class:`~.publish.Output` like the TCP publisher, and each imports its library only
when it is asked for (``labcli sense --publish zmq+tcp://...``, ``--lsl NAME``), so neither is
a dependency of labcli: a missing one is one sentence naming the extra that installs it
(``pip install 'labcli[zmq]'``, ``'labcli[lsl]'``).

* :class:`ZmqPublisher` binds a PUB socket and sends each JSON line as one message (no topic:
  a SUB socket subscribes to ``b""``).  ZeroMQ drops messages for a subscriber that falls
  behind its high-water mark, so a slow controller never holds the rig up.
* :class:`LslOutlet` opens two LSL streams: ``NAME`` of type ``Estimates``, one double channel
  per quantity and per standard error (``theta1_deg``, ``theta1_deg_se``, ..., labelled with
  their units in the stream's description) at the estimates' nominal rate, and ``NAME-events``
  of type ``Markers``, one string sample per event (its JSON line).  LSL stamps each sample with
  its own clock, which LabRecorder and every LSL client synchronise across machines.
"""

from __future__ import annotations

import errno
import json
import math
from collections.abc import Sequence
from typing import Any

from ..errors import ConfigError

ZMQ_FORM = "expected zmq+tcp://HOST:PORT, e.g. zmq+tcp://127.0.0.1:5556 (zmq+tcp://*:5556 for every interface)"


def _missing(what: str, extra: str, module: str) -> ConfigError:
    return ConfigError(
        f"{what} needs the optional package {module}, which is not installed; install it with "
        f"pip install 'labcli[{extra}]'."
    )


class ZmqPublisher:
    """The JSON lines to every subscriber of a ZeroMQ PUB socket bound at ``zmq+tcp://HOST:PORT``."""

    def __init__(self, url: str, *, hwm: int = 10000) -> None:
        rest = url[len("zmq+tcp://") :] if url.startswith("zmq+tcp://") else ""
        host, sep, port = rest.rpartition(":")
        if not sep or not host or not port.isdigit() or not 0 < int(port) <= 65535:
            raise ConfigError(f"Cannot publish on {url!r}: {ZMQ_FORM}.")
        try:
            import zmq
        except ImportError:
            raise _missing("Publishing on ZeroMQ (--publish zmq+tcp://...)", "zmq", "pyzmq") from None
        self._zmq: Any = zmq  # typed or not, as installed: held as Any so mypy reads the same either way
        self._sock: Any = zmq.Context.instance().socket(zmq.PUB)
        self._sock.setsockopt(zmq.SNDHWM, hwm)
        self._sock.setsockopt(zmq.LINGER, 500)  # ms: what is queued at the end still goes out
        try:
            self._sock.bind(f"tcp://{host}:{port}")
        except zmq.ZMQError as e:
            self._sock.close(0)
            if e.errno == errno.EADDRINUSE:
                raise ConfigError(
                    f"Cannot publish on {url}: the port is in use; choose another port or stop the program holding it."
                ) from None
            raise ConfigError(f"Cannot publish on {url}: {e.strerror}.") from None
        self.url = url

    def publish(self, line: str) -> None:
        try:
            self._sock.send(line.encode("utf-8"), self._zmq.NOBLOCK)
        except self._zmq.Again:  # every subscriber is at its high-water mark: this line is dropped for them
            pass

    def close(self) -> None:
        self._sock.close()


class LslOutlet:
    """The estimates as an LSL stream ``name`` and the events as ``name-events`` (module docstring).

    ``keys``: the JSON lines' value keys in channel order (``theta1_deg``, ...), each followed by
    its ``_se`` twin; ``rate_hz``: the estimates' nominal rate (after ``--every``).
    """

    def __init__(self, name: str, keys: Sequence[str], rate_hz: float, *, source_id: str = "") -> None:
        if not name.strip():
            raise ConfigError("--lsl needs a stream name, e.g. --lsl arm.")
        try:
            import pylsl
        except (ImportError, RuntimeError):  # RuntimeError: pylsl without its liblsl library
            raise _missing("An LSL outlet (--lsl)", "lsl", "pylsl") from None
        self.keys = [k for key in keys for k in (key, f"{key}_se")]
        info = pylsl.StreamInfo(
            name, "Estimates", len(self.keys), rate_hz, pylsl.cf_double64, source_id or f"labcli-{name}"
        )
        channels = info.desc().append_child("channels")
        for key in self.keys:
            ch = channels.append_child("channel")
            ch.append_child_value("label", key)
            ch.append_child_value("unit", key.removesuffix("_se").rsplit("_", 1)[1])
        events = pylsl.StreamInfo(
            f"{name}-events",
            "Markers",
            1,
            pylsl.IRREGULAR_RATE,
            pylsl.cf_string,
            f"{source_id or 'labcli-' + name}-events",
        )
        self._values: Any = pylsl.StreamOutlet(info)
        self._events: Any = pylsl.StreamOutlet(events)
        self.name = name

    def publish(self, line: str) -> None:
        obj = json.loads(line)
        if "event" in obj:
            self._events.push_sample([line])
            return
        self._values.push_sample([_number(obj.get(k)) for k in self.keys])

    def close(self) -> None:
        self._values = self._events = None  # the outlets close when dropped


def _number(v: Any) -> float:
    return float(v) if isinstance(v, (int, float)) else math.nan
