"""A rig's stream through the estimator to its outputs, as it runs (what ``labcli sense`` does).

::

    with Device.open(port) as dev:
        est = Estimator(model, calibration=protocol.calibration, channels=dev.info.channels, rate_hz=200)
        summary = run(dev, est, [JsonLines.to("-"), TcpPublisher("tcp://127.0.0.1:5555")], seconds=60)

:func:`run` reads the device (:class:`labcli.core.device.Device`: ``set_rate``, ``start``,
``read``, ``stop``), hands each batch of frames to the estimator and sends every event and
every ``every``-th estimate to each :class:`~.publish.Output` as one JSON line: the
estimate's own fields (:meth:`~.results.Estimate.as_json`) and ``t_host_s``, the host's
Unix time when the line was made.  It stops after ``seconds`` of the rig's own clock (a
simulated rig on its virtual clock runs as fast as it is read), on Ctrl-C, or on the
device's error (a stalled or unplugged rig: :class:`~labcli.errors.DeviceError`), stopping
the stream on the way out in every case.

The time from a batch's arrival to each of its estimates being published is kept per
estimate (:attr:`LiveSummary.latency_s`), so that what a controller waits for is measured where
it happens: from the moment the bytes of the batch's newest frame (the one that completes the
block an estimate averages) were taken off the port, the device's ``arrived``, parsing included,
to its JSON line written to every output (when ``read`` returned, for a device that does not say).

A board that carries a model of its own (wire protocol 1.1, ``CAPS?`` naming ``est=...``) is asked
for an estimate line per data frame; each of the host's estimates then carries the board's of the
same frame (``seq``) beside it, as ``"board"`` in its JSON line (:func:`board_fields`), and
``on_board`` sees every board estimate as it arrives (a live view's second column).
"""

from __future__ import annotations

import json
import math
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .inputs import DeviceClock
from .publish import Output
from .results import DISPLAY, Estimate, Event

READ_S = 0.05  # the longest a read waits for frames: Ctrl-C and the view stay responsive


@dataclass
class LiveSummary:
    """What a live session did: frames read, estimates made and published, events, times."""

    frames: int = 0
    estimates: int = 0
    published: int = 0
    events: dict[str, int] = field(default_factory=dict)
    device_s: float = 0.0  # the rig's clock from the first frame to the last
    wall_s: float = 0.0
    cpu_s: float = 0.0  # the process's CPU while running
    latency_s: list[float] = field(default_factory=list)  # batch arrival -> each published estimate
    stopped: str = ""  # "seconds", "interrupted" or "error"
    rate_hz: float = math.nan
    counters: dict[str, int] = field(default_factory=dict)
    board: int = 0  # the board's own estimates received (a board with a model)
    paired: int = 0  # host estimates published with the board's of the same frame beside them

    def latency_ms(self) -> dict[str, float]:
        lat = np.asarray(self.latency_s) * 1e3
        if not lat.size:
            return {"median": math.nan, "p99": math.nan}
        return {"median": float(np.median(lat)), "p99": float(np.percentile(lat, 99))}

    def to_json(self) -> dict[str, Any]:
        return {
            "frames": self.frames,
            "estimates": self.estimates,
            "published": self.published,
            "events": dict(self.events),
            "device_s": round(self.device_s, 3),
            "wall_s": round(self.wall_s, 3),
            "rate_hz": self.rate_hz,
            "latency_ms": {k: round(v, 3) for k, v in self.latency_ms().items()},
            "stopped": self.stopped,
            "counters": dict(self.counters),
            "board_estimates": self.board,
            "paired": self.paired,
        }


BOARD_KEEP = 4096  # board estimates kept for pairing, newest (the host's lag a block behind at most)


def board_fields(names: Sequence[str], board: Any, units: Mapping[str, str]) -> dict[str, Any]:
    """The board's estimate (a ``$S`` line, SI) as people read it, keyed as the host's are
    (``theta1_deg``, ``Fx_N``, ...; ``units``: each quantity's SI unit, an angle's ``rad`` when the
    host's model does not name it), and its ``flags`` by name."""
    out: dict[str, Any] = {}
    for name, v in zip(names, board.values, strict=False):
        si = units.get(name, "rad" if name.startswith("theta") else "N")
        unit, k = DISPLAY.get(si, (si, 1.0))
        out[f"{name}_{unit}"] = round(float(v) * k, 6)
    out["flags"] = board.flag_names
    return out


def line_of(item: Estimate | Event, board: dict[str, Any] | None = None) -> str:
    """One JSON line: the item's fields, ``board`` (the board's estimate of the same frame, when
    there is one) and ``t_host_s`` (Unix time, s)."""
    if board is None and isinstance(item, Estimate):
        return item.json_line(round(time.time(), 6))
    obj = item.as_json()
    if board is not None:
        obj["board"] = board
    obj["t_host_s"] = round(time.time(), 6)
    return json.dumps(obj, separators=(", ", ": "), allow_nan=False)


def board_names(dev: Any) -> tuple[str, ...]:
    """The quantities the board's own model estimates (empty: none, or a 1.0 board)."""
    caps = getattr(dev, "caps", None)
    return tuple(getattr(caps, "estimates", ()) or ())


class _Stream:
    """One session's state between batches: the device clock, the board's estimates kept for
    pairing, the --every count, and the summary being filled."""

    def __init__(
        self,
        dev: Any,
        estimator: Any,
        outputs: Sequence[Output],
        *,
        seconds: float | None,
        every: int,
        on_batch: Callable[[Any, list[Estimate | Event]], None] | None,
        on_board: Callable[[Any], None] | None,
    ) -> None:
        self.dev, self.estimator, self.outputs = dev, estimator, outputs
        self.seconds, self.every, self.on_batch, self.on_board = seconds, every, on_batch, on_board
        self.summary = LiveSummary()
        self.clock = DeviceClock()
        self.first: float | None = None
        self.shown = 0  # estimates seen, for --every
        self.names = board_names(dev)
        model = getattr(estimator, "model", None)
        self.units = dict(zip(getattr(model, "quantities", ()), getattr(model, "units", ()), strict=False))
        self.boards: dict[int, Any] = {}

    def _board_of(self, seq: int) -> dict[str, Any] | None:
        got = self.boards.get(seq)
        return None if got is None else board_fields(self.names, got, self.units)

    def _take_board(self) -> None:
        for b in self.dev.take_estimates():
            self.boards[b.seq] = b
            self.summary.board += 1
            if self.on_board is not None:
                self.on_board(b)
        while len(self.boards) > BOARD_KEEP:
            del self.boards[next(iter(self.boards))]

    def _publish(self, items: list[Estimate | Event], arrived: float) -> None:
        summary = self.summary
        for item in items:
            if isinstance(item, Event):
                summary.events[item.kind] = summary.events.get(item.kind, 0) + 1
                publish = True
            else:
                summary.estimates += 1
                publish = self.shown % self.every == 0
                self.shown += 1
            if publish and self.outputs:
                board = self._board_of(item.seq) if self.names and isinstance(item, Estimate) else None
                line = line_of(item, board)
                for out in self.outputs:
                    out.publish(line)
                if isinstance(item, Estimate):
                    summary.published += 1
                    summary.paired += board is not None
                    summary.latency_s.append(time.perf_counter() - arrived)

    def take(self, batch: Any, arrived: float) -> bool:
        """Feed one batch; True once ``seconds`` of device time have passed."""
        if not len(batch):
            return False
        t = self.clock.seconds(batch.t_us)
        first = self.first = float(t[0]) if self.first is None else self.first
        seconds = self.seconds
        done = seconds is not None and float(t[-1]) - first >= seconds
        if done:  # the frames past the end are left unread, whatever the size of the link's batches
            assert seconds is not None
            k = int(np.searchsorted(t - first, seconds, side="right"))
            if k == 0:
                return True
            batch, t = type(batch)(batch.seq[:k], batch.t_us[:k], batch.values[:k]), t[:k]
        self.summary.frames += len(batch)
        self.summary.device_s = float(t[-1]) - first
        if self.names:
            self._take_board()
        items = self.estimator.update(batch)
        self._publish(items, arrived)
        if self.on_batch is not None:
            self.on_batch(batch, items)
        return done


def arrival(dev: Any) -> float:
    """When the newest frame of ``dev``'s last read reached the host (``time.perf_counter()``)."""
    got = getattr(dev, "arrived", None)
    return float(got) if isinstance(got, float) else time.perf_counter()


def run(
    dev: Any,
    estimator: Any,
    outputs: Sequence[Output],
    *,
    rate_hz: float | None = None,
    seconds: float | None = None,
    every: int = 1,
    on_batch: Callable[[Any, list[Estimate | Event]], None] | None = None,
    on_board: Callable[[Any], None] | None = None,
) -> LiveSummary:
    """Stream from ``dev`` through ``estimator`` to ``outputs`` (module docstring).

    ``on_batch(frames, items)`` is called after each batch's lines went out (a live view);
    ``on_board(estimate)`` with each of the board's own estimates (``$S`` lines), when it has a model.
    Errors of the device propagate after the stream is stopped; the summary so far is on the
    error as ``exc.summary``.
    """
    stream = _Stream(dev, estimator, outputs, seconds=seconds, every=every, on_batch=on_batch, on_board=on_board)
    summary = stream.summary
    if rate_hz is not None:
        summary.rate_hz = dev.set_rate(rate_hz)
    w0, c0 = time.perf_counter(), time.process_time()
    if stream.names:
        dev.stream_estimates(1)
    dev.start()
    try:
        try:
            while True:
                batch = dev.read(timeout=READ_S)
                if stream.take(batch, arrival(dev)):
                    summary.stopped = "seconds"
                    break
        except KeyboardInterrupt:
            summary.stopped = "interrupted"
    except BaseException as exc:
        summary.stopped = "error"
        exc.summary = summary  # type: ignore[attr-defined]
        raise
    finally:
        if dev.streaming:
            try:
                rest = dev.stop()
            except Exception:  # noqa: BLE001 - the rig is gone: what it sent is already taken
                rest = None
            if rest is not None and summary.stopped == "interrupted":
                stream.take(rest, time.perf_counter())
        summary.wall_s = time.perf_counter() - w0
        summary.cpu_s = time.process_time() - c0
        summary.counters = dict(dev.counters)
    return summary
