"""Watching a streaming rig: per-channel statistics (the whole run, and the last seconds) and link health.

:func:`watch` starts the stream, reads until the time is up (or Ctrl-C),
stops it and returns a :class:`MonitorSummary`; a callback sees a
:class:`Snapshot` a few times per second for a live display, with the
rolling statistics and traces of the last ``window_s`` seconds of the rig's
clock (:class:`~labcli.core.rolling.Rolling`); another (``on_frames``) sees
every batch, for a recording.  Values are calibrated to SI (MPa, rad) with the
protocol's calibration; channels the protocol does not know stay in raw counts.

A board that carries its own model (wire protocol 1.1, ``CAPS?`` naming ``est=...``) is asked
for an estimate line per frame, and its estimates are watched as the channels are: the latest,
and their mean and standard deviation since the stream began (SI: rad, N), beside the readings.
"""

from __future__ import annotations

import math
import time
from collections import deque
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from ..errors import ConfigError
from .rolling import Rolling
from .settle import TimeUnwrapper

if TYPE_CHECKING:
    from .device import Device
    from .wire import FrameBatch


class RunningStats:
    """Mean and sample standard deviation per column, merged batch by batch (Chan et al.)."""

    def __init__(self, k: int) -> None:
        self.n = 0
        self.mean = np.zeros(k)
        self._m2 = np.zeros(k)

    def update(self, x: np.ndarray) -> None:
        m = x.shape[0]
        if not m:
            return
        bmean = x.mean(axis=0)
        bm2 = ((x - bmean) ** 2).sum(axis=0)
        n = self.n + m
        delta = bmean - self.mean
        self.mean = self.mean + delta * (m / n)
        self._m2 = self._m2 + bm2 + delta**2 * (self.n * m / n)
        self.n = n

    @property
    def std(self) -> np.ndarray:
        if self.n < 2:
            return np.zeros_like(self.mean)
        return np.sqrt(self._m2 / (self.n - 1))


@dataclass(frozen=True)
class ChannelScale:
    """Counts -> SI per device channel, and how each is shown to people."""

    names: tuple[str, ...]
    units: tuple[str, ...]  # SI unit per channel (MPa, rad; "counts" when uncalibrated)
    display_units: tuple[str, ...]  # MPa, deg, counts
    to_si: Callable[[np.ndarray], np.ndarray]
    to_display: Callable[[np.ndarray], np.ndarray]
    adc: tuple[float, float] | None = None  # the ADC's range in counts, when the calibration names it


def calibrated(protocol: Any) -> Any:
    """``protocol``, or for one holding several experiments (rPAM's joint map and stretch test)
    the first experiment's, whose calibration reads the rig's channels."""
    if protocol.calibration is not None:
        return protocol
    from .registry import protocol_kinds, run_protocol

    for choice in protocol_kinds()[protocol.kind].experiments:
        chosen = run_protocol(protocol, choice)[1]
        if chosen.calibration is not None:
            return chosen
    raise ConfigError(f"Protocol {protocol.name} calibrates no channels, so the monitor cannot show readings.")


def channel_scale(channels: Sequence[str], calibration: Any) -> ChannelScale:
    """Match the device's channel order to a protocol calibration by name."""
    known = {name: i for i, name in enumerate(calibration.names)}
    cols = [known.get(name) for name in channels]
    k_cal = len(calibration.names)
    si_units = calibration.units
    disp_units = calibration.display_units
    units = tuple(si_units[c] if c is not None else "counts" for c in cols)
    shown = tuple(disp_units[c] if c is not None else "counts" for c in cols)
    mapped = [(j, c) for j, c in enumerate(cols) if c is not None]

    def _apply(fn: Callable[[np.ndarray], np.ndarray], x: np.ndarray) -> np.ndarray:
        x = np.asarray(x, dtype=float)
        out = x.copy()
        if mapped:
            full = np.zeros(x.shape[:-1] + (k_cal,))
            for j, c in mapped:
                full[..., c] = x[..., j]
            conv = fn(full)
            for j, c in mapped:
                out[..., j] = conv[..., c]
        return out

    return ChannelScale(
        tuple(channels),
        units,
        shown,
        lambda counts: _apply(calibration.to_si, counts),
        lambda si: _apply(calibration.to_display, si),
        _adc_range(calibration),
    )


def _adc_range(calibration: Any) -> tuple[float, float] | None:
    rng = getattr(calibration, "adc_range", None)
    return (float(rng[0]), float(rng[1])) if rng is not None else None


@dataclass
class Snapshot:
    elapsed_s: float
    rate_hz: float  # as the firmware set it
    frames_per_s: float  # over the last second
    latest_si: np.ndarray  # mean of the last batch, per channel
    stats: RunningStats  # since the stream began
    counters: dict[str, int]
    rolling: Rolling | None = None  # the last window_s seconds of the rig's clock
    board: BoardWatch | None = None  # the board's own estimates, when it has a model


class BoardWatch:
    """The board's own estimates (``$S`` lines) of a stream: the latest and running statistics (SI)."""

    def __init__(self, names: Sequence[str]) -> None:
        self.names = tuple(names)
        self.units = tuple("rad" if n.startswith("theta") else "N" for n in self.names)
        self.stats = RunningStats(len(self.names))
        self.latest = np.full(len(self.names), np.nan)

    def add(self, estimates: Sequence[Any]) -> None:
        rows = [e.values for e in estimates if len(e.values) == len(self.names)]
        if rows:
            x = np.asarray(rows, dtype=float)
            self.stats.update(x)
            self.latest = x[-1]

    def to_json(self) -> dict[str, Any]:
        """Per quantity: mean and std since the stream began (SI) and the unit; ``n`` estimates."""
        mean = self.stats.mean if self.stats.n else np.full(len(self.names), np.nan)
        std = self.stats.std if self.stats.n else np.full(len(self.names), np.nan)
        out: dict[str, Any] = {"n": self.stats.n}
        for name, m, sd, u in zip(self.names, mean, std, self.units, strict=True):
            out[name] = {
                "mean": float(m) if math.isfinite(m) else None,
                "std": float(sd) if math.isfinite(sd) else None,
                "unit": u,
            }
        return out


@dataclass
class MonitorSummary:
    port: str
    device: str
    firmware: str
    rate_hz: float
    seconds: float
    counters: dict[str, int]
    channels: tuple[str, ...]
    units: tuple[str, ...]
    mean: np.ndarray
    std: np.ndarray
    interrupted: bool = False
    board: BoardWatch | None = None
    warnings: tuple[str, ...] = ()  # what the link did against physics (:func:`physics_warnings`)

    @property
    def frames_per_s(self) -> float:
        return self.counters["frames"] / self.seconds if self.seconds > 0 else 0.0

    def to_json(self) -> dict[str, Any]:
        def num(x: float) -> float | None:
            return float(x) if math.isfinite(x) else None

        c = self.counters
        return {
            "port": self.port,
            "device": self.device,
            "firmware": self.firmware,
            "rate_hz": num(self.rate_hz),
            "seconds": round(self.seconds, 3),
            "frames": c["frames"],
            "frames_per_s": round(self.frames_per_s, 1),
            "lost": c["lost"],
            "stalls": c.get("stalls", 0),
            "bad_checksum": c["bad_checksum"],
            "malformed": c["malformed"],
            "overlong": c["overlong"],
            "log_lines": c["log_lines"],
            "events": c.get("events", 0),
            "estimates": c.get("estimates", 0),
            "interrupted": self.interrupted,
            "warnings": list(self.warnings),
            "channels": {
                name: {"mean": num(m), "std": num(s), "unit": u}
                for name, m, s, u in zip(self.channels, self.mean, self.std, self.units, strict=False)
            },
            **({"board_estimates": self.board.to_json()} if self.board is not None else {}),
        }


def watch(
    dev: Device,
    scale: ChannelScale,
    *,
    rate_hz: float | None = None,
    seconds: float | None = None,
    on_update: Callable[[Snapshot], None] | None = None,
    refresh_s: float = 0.25,
    window_s: float = 5.0,
    on_frames: Callable[[FrameBatch, np.ndarray], None] | None = None,
) -> MonitorSummary:
    """Stream from ``dev`` for ``seconds`` (None: until Ctrl-C) and summarise.

    ``window_s``: the rolling statistics' span; ``on_frames(batch, si)`` sees every batch
    (a recording).  The stream is always stopped on the way out, Ctrl-C included; frames in
    flight before ``OK STOP`` count too.
    """
    actual = dev.set_rate(rate_hz) if rate_hz is not None else float("nan")
    k = len(scale.names)
    stats = RunningStats(k)
    rolling = Rolling(k, window_s)
    unwrap = TimeUnwrapper()
    latest = np.full(k, np.nan)
    recent: deque[tuple[float, int]] = deque()
    interrupted = False
    adc = AdcTally(scale.adc)
    names = tuple(getattr(getattr(dev, "caps", None), "estimates", ()) or ())
    board = BoardWatch(names) if names else None
    if board is not None:
        dev.stream_estimates(1)

    def take(batch: FrameBatch) -> None:
        nonlocal latest
        if board is not None:
            board.add(dev.take_estimates())
        if len(batch):
            adc.add(batch.values)
            si = scale.to_si(batch.values)
            stats.update(si)
            t = unwrap(batch.t_us)
            adc.clock(t)
            rolling.add(t, si)
            latest = si.mean(axis=0)
            if on_frames is not None:
                on_frames(batch, si)

    dev.start()
    t0 = time.monotonic()
    next_update = t0
    try:
        try:
            while True:
                now = time.monotonic()
                if seconds is not None and now - t0 >= seconds:
                    break
                wait = refresh_s if seconds is None else max(0.0, min(refresh_s, t0 + seconds - now))
                batch = dev.read(timeout=wait)
                take(batch)
                now = time.monotonic()
                recent.append((now, stats.n))
                while recent and now - recent[0][0] > 1.0:
                    recent.popleft()
                if on_update is not None and now >= next_update:
                    span = now - recent[0][0] if len(recent) > 1 else 0.0
                    fps = (recent[-1][1] - recent[0][1]) / span if span > 0 else 0.0
                    on_update(Snapshot(now - t0, actual, fps, latest, stats, dev.counters, rolling, board))
                    next_update = now + refresh_s
        except KeyboardInterrupt:
            interrupted = True
    finally:
        elapsed = time.monotonic() - t0
        if dev.streaming:
            take(dev.stop())
    summary = _summary(dev, scale, actual, elapsed, stats, interrupted, board)
    summary.warnings = tuple(physics_warnings(summary, adc))
    return summary


class AdcTally:
    """Frames whose counts sat at an end of the ADC's range, or beyond it, per channel."""

    def __init__(self, adc: tuple[float, float] | None) -> None:
        self.adc = adc
        self.frames = 0
        self.railed: np.ndarray | None = None
        self.outside: np.ndarray | None = None
        self.t_first: float | None = None
        self.t_last: float | None = None
        self.timed = 0

    def add(self, values: Any) -> None:
        if self.adc is None:
            return
        v = np.asarray(values, dtype=float)
        v = v.reshape(len(v), -1)
        lo, hi = self.adc
        if self.railed is None or self.outside is None:
            self.railed = np.zeros(v.shape[1], dtype=np.int64)
            self.outside = np.zeros(v.shape[1], dtype=np.int64)
        with np.errstate(invalid="ignore"):
            self.outside += np.sum(~((v >= lo) & (v <= hi)), axis=0)
            self.railed += np.sum((v == lo) | (v == hi), axis=0)
        self.frames += v.shape[0]

    def clock(self, t_s: Any) -> None:
        """The device's own times of a batch (s): the rate is judged on the rig's clock, not the host's."""
        t = np.asarray(t_s, dtype=float)
        if len(t):
            self.t_first = float(t[0]) if self.t_first is None else self.t_first
            self.t_last = float(t[-1])
            self.timed += len(t)

    @property
    def device_rate(self) -> float:
        """Frames per second of the device's clock (NaN until two frames span some time)."""
        if self.t_first is None or self.t_last is None or not self.t_last > self.t_first:
            return math.nan
        return (self.timed - 1) / (self.t_last - self.t_first)


RATE_FACTOR = 2.0  # a measured frame rate this far from the confirmed one is not the rig's rate
MIN_FRAMES = 20  # fewer frames say too little of a rate


def physics_warnings(summary: MonitorSummary, adc: AdcTally) -> list[str]:
    """What the stream did against physics, one sentence each: no frame at all, a confirmed rate
    the frames do not follow, counts outside the ADC's range or pinned at its ends, a ``seq`` jump
    larger than the frames the rig could have sent in the time."""
    out: list[str] = []
    c = summary.counters
    frames, seconds, rate = c["frames"], summary.seconds, summary.rate_hz
    if frames == 0:
        out.append(f"no frame arrived in {seconds:.1f} s, so there is no reading to show (mean and std are empty)")
        return out
    fps = adc.device_rate if math.isfinite(adc.device_rate) else summary.frames_per_s
    if math.isfinite(rate) and not rate > 0:
        out.append(f"the rig confirmed a rate of {rate:g} Hz, which no rig runs at; it sent {fps:.1f} frames/s")
    elif math.isfinite(rate) and frames >= MIN_FRAMES and not rate / RATE_FACTOR <= fps <= rate * RATE_FACTOR:
        out.append(
            f"the rig confirmed {rate:g} Hz but sent {fps:.1f} frames/s by its own clock; its confirmation is not its rate"
        )
    span = max(seconds, (adc.t_last - adc.t_first) if adc.t_first is not None and adc.t_last is not None else 0.0)
    possible = span * max(fps, rate if math.isfinite(rate) and rate > 0 else 0.0) * RATE_FACTOR + 10
    if c["lost"] > possible:
        out.append(
            f"the frame numbers (seq) jumped by {c['lost']} in {seconds:.1f} s, more than the rig could send; "
            "that is a corrupted seq, not lost frames"
        )
    if adc.adc is not None and adc.outside is not None and adc.railed is not None:
        lo, hi = adc.adc
        for j, name in enumerate(summary.channels):
            if j >= len(adc.outside):
                break
            if adc.outside[j]:
                out.append(
                    f"{name} sent {adc.outside[j]} of {adc.frames} frames with counts outside the ADC's range "
                    f"{lo:g} to {hi:g}: not readings"
                )
            elif adc.railed[j] > adc.frames / 2:
                out.append(f"{name} sat at an end of the ADC's range ({lo:g} or {hi:g} counts): a sensor at its rail")
    return out


def _summary(
    dev: Device,
    scale: ChannelScale,
    rate_hz: float,
    elapsed: float,
    stats: RunningStats,
    interrupted: bool,
    board: BoardWatch | None,
) -> MonitorSummary:
    """What :func:`watch` saw, once the stream has stopped."""
    info = dev.info
    nan = np.full(len(scale.names), np.nan)
    return MonitorSummary(
        port=dev.port,
        device=info.device if info else "",
        firmware=info.firmware if info else "",
        rate_hz=rate_hz,
        seconds=elapsed,
        counters=dev.counters,
        channels=scale.names,
        units=scale.units,
        mean=stats.mean if stats.n else nan,
        std=stats.std if stats.n else nan,
        interrupted=interrupted,
        board=board,
    )
