"""One force trial with capture windows of any length, on the simulated rig in virtual time.

A shipped protocol keeps its capture windows to 60 s at most (its file check); a session
written against the library may capture for as long as it likes.  :func:`long_protocol`
gives the takuma2014 protocol a longer ``capture_s`` (and 1 kHz) past that check, so the
real force session captures the air supply's window, the trial's baseline and its loaded
window at that length.  :func:`record_trial` runs one trial of it through the engine:

* ``in_memory=False``: the engine as it is (the trial's windows streamed into the file);
* ``in_memory=True``: :class:`InMemoryEngine`, the engine as it captured before windows were
  streamed: every window gathered whole in memory, the trial's arrays handed to the store
  at the commit.  It is the baseline of the memory test and of
  ``tests/benchmarks/bench_capture_memory.py``.
"""

from __future__ import annotations

import dataclasses
import io
import math
import re
from pathlib import Path
from typing import Any

import numpy as np
from rich.console import Console

from labcli.core.device import Device
from labcli.core.engine import Outcome, RunEngine
from labcli.core.protocol import Protocol, load_protocol
from labcli.core.simoperator import operator_for
from labcli.core.store import RunFile
from labcli.core.ui import UnattendedUI
from labcli.papers.takuma2014.protocol import load_plan
from labcli.papers.takuma2014.session import force_session

RATE_HZ = 1000.0
CHANNELS = 6  # the reference rig's


def port(seed: int = 1, realism: str | None = None) -> str:
    """The simulated rig's URL (``realism`` None: the simulator's default levels)."""
    return f"sim://?seed={seed}&clock=virtual" + (f"&realism={realism}" if realism else "")


def write_long_protocol(folder: Path, capture_s: float, rate_hz: float = RATE_HZ) -> Path:
    """The takuma2014 protocol file with ``capture_s`` (60 s at most, as its check allows) at ``rate_hz``,
    and its plan beside it, in ``folder``; the protocol file's path (for ``--protocol``)."""
    root = Path(__file__).resolve().parents[2] / "protocols"
    text = (root / "takuma2014.toml").read_text()
    text = re.sub(r"(?m)^rate_hz = .*$", f"rate_hz = {float(rate_hz)!r}", text)
    text = re.sub(r"(?m)^capture_s = .*$", f"capture_s = {float(capture_s)!r}", text)
    (folder / "takuma2014-plan.csv").write_text((root / "takuma2014-plan.csv").read_text())
    path = folder / "long.toml"
    path.write_text(text)
    return path


def long_protocol(capture_s: float, rate_hz: float = RATE_HZ) -> Protocol:
    """The takuma2014 protocol capturing ``capture_s`` seconds per window at ``rate_hz``."""
    p = load_protocol("takuma2014")
    return dataclasses.replace(
        p, rate_hz=float(rate_hz), settling=dataclasses.replace(p.settling, capture_s=float(capture_s))
    )


class InMemoryEngine(RunEngine):
    """The engine capturing as it did before windows were streamed: each window whole in memory."""

    def _capture(self, duration_s: float) -> Any:
        window = self.stream.collect(duration_s)
        gap = float(np.median(np.diff(window.t_s))) if len(window) > 1 else math.nan
        self._check_rate(len(window), gap)
        return window


def record_trial(
    path: Path,
    capture_s: float,
    *,
    in_memory: bool = False,
    seed: int = 1,
    rate_hz: float = RATE_HZ,
    realism: str | None = None,
) -> Outcome:
    """Record plan trial 1 of takuma2014 into a new run file at ``path`` with windows of ``capture_s``."""
    protocol = long_protocol(capture_s, rate_hz)
    plan = load_plan(load_protocol("takuma2014")).iloc[:1]
    dev = Device.open(port(seed, realism))
    try:
        with RunFile.create(path, protocol=protocol, device_info=dev.info, port=port(seed, realism), plan=plan) as run:
            engine = (InMemoryEngine if in_memory else RunEngine)(
                dev,
                run,
                protocol,
                UnattendedUI(console=Console(file=io.StringIO(), width=200)),
                run_path=str(path),
                resume_command=f"labcli acquire {path} --resume",
                simulated_operator=operator_for(dev),
            )
            return engine.run(force_session(protocol, plan))
    finally:
        dev.close()
