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

The time from a batch's arrival (``read`` returning it) to each of its estimates being
published is kept per estimate (:attr:`LiveSummary.latency_s`), so that what a controller
waits for is measured where it happens.

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
    obj = item.as_json()
    if board is not None:
        obj["board"] = board
    obj["t_host_s"] = round(time.time(), 6)
    return json.dumps(obj, separators=(", ", ": "), allow_nan=False)


def board_names(dev: Any) -> tuple[str, ...]:
    """The quantities the board's own model estimates (empty: none, or a 1.0 board)."""
    caps = getattr(dev, "caps", None)
    return tuple(getattr(caps, "estimates", ()) or ())


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
    summary = LiveSummary()
    if rate_hz is not None:
        summary.rate_hz = dev.set_rate(rate_hz)
    clock = DeviceClock()
    first: float | None = None
    shown = 0  # estimates seen, for --every
    w0, c0 = time.perf_counter(), time.process_time()
    names = board_names(dev)
    model = getattr(estimator, "model", None)
    units = dict(zip(getattr(model, "quantities", ()), getattr(model, "units", ()), strict=False))
    if names:
        dev.stream_estimates(1)
    boards: dict[int, Any] = {}

    def board_of(seq: int) -> dict[str, Any] | None:
        got = boards.get(seq)
        return None if got is None else board_fields(names, got, units)

    def take(batch: Any, arrived: float) -> bool:
        """Feed one batch; True once ``seconds`` of device time have passed."""
        nonlocal first, shown
        if not len(batch):
            return False
        t = clock.seconds(batch.t_us)
        first = float(t[0]) if first is None else first
        done = seconds is not None and float(t[-1]) - first >= seconds
        if done:  # the frames past the end are left unread, whatever the size of the link's batches
            assert seconds is not None
            k = int(np.searchsorted(t - first, seconds, side="right"))
            if k == 0:
                return True
            batch, t = type(batch)(batch.seq[:k], batch.t_us[:k], batch.values[:k]), t[:k]
        summary.frames += len(batch)
        summary.device_s = float(t[-1]) - first
        if names:
            for b in dev.take_estimates():
                boards[b.seq] = b
                summary.board += 1
                if on_board is not None:
                    on_board(b)
            while len(boards) > BOARD_KEEP:
                del boards[next(iter(boards))]
        items = estimator.update(batch)
        for item in items:
            if isinstance(item, Event):
                summary.events[item.kind] = summary.events.get(item.kind, 0) + 1
                publish = True
            else:
                summary.estimates += 1
                publish = shown % every == 0
                shown += 1
            if publish and outputs:
                board = board_of(item.seq) if names and isinstance(item, Estimate) else None
                line = line_of(item, board)
                for out in outputs:
                    out.publish(line)
                if isinstance(item, Estimate):
                    summary.published += 1
                    summary.paired += board is not None
                    summary.latency_s.append(time.perf_counter() - arrived)
        if on_batch is not None:
            on_batch(batch, items)
        return done

    dev.start()
    try:
        try:
            while True:
                batch = dev.read(timeout=READ_S)
                if take(batch, time.perf_counter()):
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
                take(rest, time.perf_counter())
        summary.wall_s = time.perf_counter() - w0
        summary.cpu_s = time.process_time() - c0
        summary.counters = dict(dev.counters)
    return summary
