"""``labcli sense`` as a library call: open the rig, build the estimator, stream to the outputs.

:func:`sense` takes plain data (:class:`SenseOptions`) and returns the session's
:class:`~.live.LiveSummary`; every refusal is a :class:`~labcli.errors.LabcliError` of one
sentence, raised before the rig streams when it can be known then:

* a model file no installed paper reads, or naming a protocol that does not exist;
* a ``protocol`` (the session's, e.g. a push protocol for ``classify``) that describes another
  rig than the model's (another calibration or geometry);
* a rig whose channels lack one the model reads (:class:`~.inputs.Inputs`);
* a TCP port in use, a file that cannot be written, a ``record`` file that exists already;
* a ZeroMQ or LSL output asked for without its optional package (:mod:`.outlets`: the sentence
  names the extra to install);
* a stalled or unplugged rig while streaming (the device's own sentences).
"""

from __future__ import annotations

import os
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ..core.options import Typed
from ..core.report import captures_warning
from ..errors import ConfigError, ModelError, StoreError
from .config import EstimatorConfig
from .estimator import Estimator
from .live import LiveSummary, run
from .model import BAD_INPUT, load_model
from .publish import JsonLines, Output, TcpPublisher
from .results import DISPLAY, Estimate


@dataclass(frozen=True)
class SenseOptions:
    """What a live session is asked for (the command's options, as plain data)."""

    port: str
    model: Path
    protocol: str | None = None  # None: the model's own
    rate_hz: float | None = None  # None: the protocol's
    seconds: float | None = None  # device time; None: until Ctrl-C
    every: int = 1
    jsonl: str | None = None  # "-": stdout; a path; None: none
    publish: tuple[str, ...] = ()  # tcp://HOST:PORT, or zmq+tcp://HOST:PORT (the zmq extra)
    lsl: str | None = None  # an LSL outlet of this name (the lsl extra)
    classify: Path | None = None  # a push plan: pushes classified online
    record: Path | None = None  # a new run file: frames, estimates and events
    timeout: float = 2.0
    boot_wait: float | None = None
    baud: int = 115200
    model_options: Typed = field(default_factory=Typed)  # what the model's paper declares (sensing_options)


def same_rig(model_protocol: Any, protocol: Any) -> None:
    """ModelError unless ``protocol`` describes the rig ``model_protocol`` does (calibration, geometry)."""

    def rig(p: Any) -> tuple[Any, Any]:
        channels = getattr(getattr(p, "calibration", None), "channels", None) or ()
        cal = tuple((c.name, c.gain, c.zero_counts) for c in channels)
        geometry = getattr(getattr(p, "settings", None), "rig", None)
        return cal, dict(geometry) if isinstance(geometry, dict) else geometry

    if rig(model_protocol) != rig(protocol):
        raise ModelError(
            f"The model was fitted on the rig of protocol {model_protocol.name}, and {protocol.name} describes "
            "another rig (its calibration or geometry differ); fit a model on this rig, or use a protocol of the "
            "model's rig."
        )


def prepare(opts: SenseOptions) -> tuple[Any, Any, Any]:
    """The sensing model, the protocol whose calibration it reads, and the settled-load hook (or None)."""
    from ..core.protocol import load_protocol

    model = load_model(opts.model, opts.model_options)
    try:
        own = load_protocol(model.protocol)
    except ConfigError as e:
        raise ModelError(f"The model file {opts.model} names the protocol {model.protocol!r}, which {e}") from None
    protocol = own
    if opts.protocol is not None:
        protocol = load_protocol(opts.protocol)
        same_rig(own, protocol)
    hook = None
    if opts.classify is not None:
        make = getattr(model, "push_hook", None)
        if make is None:
            raise ModelError(f"The model file {opts.model} is of a paper that classifies no pushes online.")
        hook = make(protocol, opts.classify)
    return model, protocol, hook


UNSUPPLIED_S = 3.0  # rig seconds of estimates flagged bad-input from the start before the session says why


class AirWatch:
    """One sentence when a session's first estimates are all ``bad-input``: the pressures read as
    no air (vented chambers, the supply off, a sensor unplugged), which the flags alone do not say."""

    def __init__(self, notice: Callable[[str], None], after_s: float = UNSUPPLIED_S) -> None:
        self.notice, self.after_s = notice, after_s
        self.bad = 0
        self.first: float | None = None  # the first estimate's time
        self.done = False

    def take(self, frames: Any, items: list[Any]) -> None:
        for item in items:
            if self.done or not isinstance(item, Estimate):
                continue
            if BAD_INPUT not in item.flags:
                self.done = True  # air came: nothing to say
                continue
            self.bad += 1
            self.first = item.t_device_s if self.first is None else self.first
            if item.t_device_s - self.first >= self.after_s - 1e-6:  # a chamber still filling reads low a while
                self.done = True
                self.notice(
                    f"The first {self.bad} estimates ({item.t_device_s - self.first:.1f} s of the rig's clock) are all "
                    "flagged bad-input: the pressures read as no air. Supply the chambers and close their valves (at a simulated rig's "
                    "console: `supply`, then `close`), or check the pressure sensors' wiring."
                )


def _recorder(opts: SenseOptions, model: Any, protocol: Any, dev: Any) -> Any:
    from ..core.monitoring import channel_scale
    from .record import RunRecorder

    assert dev.info is not None and opts.record is not None
    scale = channel_scale(dev.info.channels, protocol.calibration)
    return RunRecorder(opts.record, model=model, protocol=protocol, device_info=dev.info, port=opts.port, scale=scale)


def open_outputs(opts: SenseOptions, notice: Callable[[str], None], model: Any = None) -> list[Output]:
    """The outputs asked for, opened (a TCP port bound) before the rig is; ``model``: the quantities
    an LSL outlet's channels carry."""
    from .outlets import LslOutlet, ZmqPublisher

    outputs: list[Output] = []
    try:
        for url in opts.publish:
            pub: TcpPublisher | ZmqPublisher
            pub = ZmqPublisher(url) if url.startswith("zmq+") else TcpPublisher(url, notice=notice)
            notice(f"Publishing JSON lines on {pub.url}.")
            outputs.append(pub)
        if opts.lsl is not None:
            keys = [f"{q}_{DISPLAY.get(u, (u, 1.0))[0]}" for q, u in zip(model.quantities, model.units, strict=True)]
            outputs.append(LslOutlet(opts.lsl, keys, 1.0 / (EstimatorConfig().block_s * opts.every)))
            notice(f"Streaming the estimates on LSL as {opts.lsl} (events as {opts.lsl}-events).")
        if opts.jsonl is not None:
            outputs.append(JsonLines.to(opts.jsonl))
    except BaseException:
        for out in outputs:
            out.close()
        raise
    return outputs


def sense(
    opts: SenseOptions,
    *,
    notice: Callable[[str], None] = lambda text: None,
    view: Callable[[Estimator, Any], Callable[[Any, list[Any]], None]] | None = None,
) -> LiveSummary:
    """Run a live session (module docstring).  ``view(estimator, device)`` gives the ``on_batch``
    callback of a live display; ``notice`` takes one-sentence messages (clients, the port bound)."""
    from ..core.device import Device

    model, protocol, hook = prepare(opts)
    # Every live estimate is of one capture: a model fitted on several a load gives intervals too narrow.
    narrow = captures_warning(
        f"the model file {opts.model}", int(getattr(model, "captures_per_load", 1)), "the live loads", 1
    )
    if narrow:
        notice(f"Warning: {narrow}")
    rate = float(opts.rate_hz if opts.rate_hz is not None else protocol.rate_hz)
    url = opts.port
    if url.startswith("sim://") and "clock=" not in url:
        # A live session wants the simulated rig paced like hardware, not as fast as it is read.
        url += ("&" if "?" in url else "?") + "clock=wall"
    if opts.record is not None and os.path.lexists(opts.record):
        raise StoreError(f"{opts.record} already exists; choose a new file name for the session's run file.")
    outputs = open_outputs(opts, notice, model)
    try:
        with Device.open(
            url, baudrate=opts.baud, timeout=opts.timeout, boot_wait=opts.boot_wait, name=opts.port
        ) as dev:
            assert dev.info is not None
            actual = dev.set_rate(rate)
            est = Estimator(
                model, calibration=protocol.calibration, channels=dev.info.channels, rate_hz=actual, on_settled=hook
            )
            recorder = _recorder(opts, model, protocol, dev) if opts.record is not None else None
            shown = view(est, dev) if view is not None else None
            try:
                air = AirWatch(notice)
                takers = [f for f in (air.take, shown, recorder.take if recorder else None) if f is not None]

                def on_batch(frames: Any, items: list[Any]) -> None:
                    for take in takers:
                        take(frames, items)

                summary = run(
                    dev,
                    est,
                    outputs,
                    seconds=opts.seconds,
                    every=opts.every,
                    on_batch=on_batch,
                    on_board=getattr(shown, "on_board", None),
                )
            finally:
                if recorder is not None:
                    recorder.close()  # what came before an error or Ctrl-C is kept too
            summary.rate_hz = actual
            return summary
    finally:
        for out in outputs:
            out.close()
