"""``labcli acquire`` as one library call: check the options, resume or plan the run,
let the paper's session run on the engine, close everything whatever happens.

The paper that owns the protocol's kind plans the run
(:meth:`labcli.core.paper.Paper.acquisition`): its session of steps, its plan,
what "nothing left to resume" means.  This module knows no paper.

A resumed run continues only on the rig it was recorded on: the rig's identity (the
``ID?`` reply's device and firmware, its channels, and the calibration of a ``--protocol``
given with ``--resume``) must match the run's (:mod:`labcli.core.sessionlog`), unless
``--allow-other-rig`` says that another rig is meant.
"""

from __future__ import annotations

import contextlib
import shlex
import signal
import threading
from collections.abc import Callable, Iterator
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

from ..errors import ConfigError, DeviceError, StoreError
from .device import Device, RigLink
from .engine import SILENT_S, NewRun, Outcome, RunEngine
from .files import check_not_input
from .paper import AcquireOptions
from .protocol import load_protocol, loads_protocol
from .registry import default_protocol, record_type, run_protocol
from .sessionlog import RigIdentity, SessionInfo, describe, recorded_identity
from .simoperator import Connection, connect
from .store import RESUME_OR_FORCE, RunFile
from .store.space import check_new_file
from .timestamps import utc_now
from .ui import RichUI, UnattendedUI

DEFAULT_BAUD = 115200  # the wire protocol's default


def resume_command(
    path: str,
    port: str,
    *,
    unattended: bool = False,
    rate_hz: float | None = None,
    baud: int = DEFAULT_BAUD,
    other_rig: bool = False,
) -> str:
    """The exact command line that continues a run."""
    cmd = f"labcli acquire {shlex.quote(str(path))} --port {shlex.quote(port)} --resume"
    if baud != DEFAULT_BAUD:
        cmd += f" --baud {baud}"
    if rate_hz:
        cmd += f" --rate {rate_hz:g}"
    if other_rig:
        cmd += " --allow-other-rig"
    if unattended:
        cmd += " --unattended"
    return cmd


@contextlib.contextmanager
def sigint_ignored() -> Iterator[None]:
    """Ignore Ctrl-C while a finished session closes its files."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)


def _protocol_name(arg: str) -> str:
    return Path(arg).stem if arg.endswith(".toml") else arg


def _check_options(path: str, resume: bool, force: bool, plan: Any, no_plan: bool, protocol: str | None) -> None:
    if resume and force:
        raise ConfigError("--resume continues a run and --force overwrites it: give one of them, not both.")
    if plan is not None and no_plan:
        raise ConfigError("--plan and --no-plan contradict each other: give one of them.")
    check_not_input(path, (plan, protocol), "the run to ")  # --force replaces an earlier run, never an input


def same_plan(a: Any, b: Any) -> bool:
    """Whether two plan tables (DataFrames, or None) hold the same rows, numbers to 12 digits."""
    import numpy as np

    if a is None or b is None:
        return a is None and b is None
    if len(a) != len(b) or set(a.columns) != set(b.columns):
        return False
    for c in a.columns:
        x, y = a[c].to_numpy(), b[c].to_numpy()
        if x.dtype.kind in "fiu" and y.dtype.kind in "fiu":
            if not np.allclose(x.astype(float), y.astype(float), rtol=1e-12, atol=0.0, equal_nan=True):
                return False
        elif [str(v) for v in x] != [str(v) for v in y]:
            return False
    return True


def _resume(path: str, protocol: str | None, options: AcquireOptions) -> tuple[Any, RunFile, Outcome | None, Any]:
    """The run being resumed, open for writing, its acquisition, an Outcome when it is done,
    and the protocol ``--protocol`` gave (None: the run's own), whose calibration is this rig's."""
    if options.no_plan:
        raise ConfigError(f"The plan of {path} was fixed when the run began; drop --no-plan with --resume.")
    given_plan, options = options.plan, replace(options, plan=None)
    existing = RunFile.open(path, "a")
    try:
        base = loads_protocol(existing.protocol_text, source=f"{path} (protocol)")
        if protocol is not None and _protocol_name(protocol) != base.name:
            raise ConfigError(
                f"{path} was recorded with protocol {base.name}, not {protocol}; drop --protocol to resume it."
            )
        paper, proto = run_protocol(base, options.experiment, stored_kind=existing.kind, run_path=path)
        given = None
        if protocol is not None:
            given = run_protocol(load_protocol(protocol), options.experiment, stored_kind=existing.kind, run_path=path)[
                1
            ]
        resumed = replace(options, resume=existing)
        check_captures(paper, proto, resumed)
        acq = paper.acquisition(proto, resumed)
        if given_plan is not None:  # the same plan again is harmless; another one would change the run
            planned = paper.acquisition(proto, replace(options, plan=given_plan)).plan
            if not same_plan(acq.plan, planned):
                raise ConfigError(
                    f"{given_plan} is not the plan {path} began with; drop --plan to resume "
                    "with the run's own plan, or start a new run for the new one."
                )
        done = acq.already_done(existing, path)
        if done is not None:
            outcome = Outcome("finished", done, 0, len(existing.records.ids()))
            existing.close()
            return acq, existing, outcome, given
    except BaseException:
        existing.close()
        raise
    return acq, existing, None, given


def check_rig(run: Any, path: str, info: Any, calibration: Any, *, allow_other: bool = False) -> list[str]:
    """What differs between the rig a run was recorded on and the rig at hand (``info``, read with
    ``calibration``); refused in one sentence unless ``allow_other``.  Imported runs had no rig."""
    recorded = recorded_identity(run)
    if not recorded.device:
        return []
    differences = recorded.differences(RigIdentity.of(info, calibration))
    if differences and not allow_other:
        raise DeviceError(
            f"{path} was recorded on {recorded.device} (firmware {recorded.firmware}), but the rig on {info.port} "
            f"has {describe(differences)}: resume on the rig that began the run, or pass --allow-other-rig "
            "to continue it on this one."
        )
    return differences


def _plan_new(path: str, protocol: str | None, options: AcquireOptions, force: bool) -> Any:
    """The acquisition of a new run (nothing is created yet)."""
    check_new_file(path)  # before the rig is woken: a name the file system refuses, a device, a folder
    if Path(path).exists() and not force:
        raise StoreError(f"{path} already exists; {RESUME_OR_FORCE}.")
    paper, proto = run_protocol(load_protocol(protocol or default_protocol("acquire")), options.experiment)
    check_captures(paper, proto, options)
    return paper.acquisition(proto, options)


def check_captures(paper: Any, protocol: Any, options: AcquireOptions) -> None:
    """Refuse (ConfigError) more than one capture of each load, by ``--captures`` or the protocol's
    ``acquisition.captures_per_load``, for a run kind the paper does not list in ``capture_kinds``:
    its session would take each load once regardless.  The one place the sentence is written; its words
    are the paper's ``single_captures[kind]`` (the unit such a run takes once, and why), else loads.
    The key is judged when a run begins: one already stored goes on as it began."""
    kind = protocol.kind
    if kind in getattr(paper, "capture_kinds", ()):
        return
    unit, why = getattr(paper, "single_captures", {}).get(kind, ("load", ""))
    what = why or f"paper {paper.name} takes each {unit} of a {kind} run once"
    if options.captures is not None and options.captures > 1:
        n = options.captures
        raise ConfigError(f"--captures {n} asks for each {unit} {n} times, but {what}; leave it out.")
    n = protocol.air.captures_per_load
    if n > 1 and options.resume is None:  # a run begun before the key was checked goes on as it began
        raise ConfigError(
            f"Protocol {protocol.name} gives acquisition.captures_per_load = {n}, but {what}: "
            "set the key to 1 or leave it out."
        )


@dataclass(frozen=True)
class Link:
    """How the rig is reached: the port as typed, its baud rate, the wait for answers."""

    port: str
    baud: int = DEFAULT_BAUD
    timeout: float = 2.0

    def open(self) -> Device:
        return Device.open(self.port, baudrate=self.baud, timeout=self.timeout)

    def connect(self) -> Connection:
        """The rig opened, with who acts at it when it is simulated (:mod:`.simoperator`)."""
        return connect(self.open())


@dataclass(frozen=True)
class SessionOptions:
    """What the session log records beside the link and the rig, and how the session runs."""

    operator: str = ""
    resumed: bool = False
    other_rig: bool = False
    unattended: bool = False
    rate_hz: float | None = None
    silent_s: float = SILENT_S


def acquire(
    path: str | Path,
    port: str,
    *,
    protocol: str | None = None,
    plan: str | Path | None = None,
    no_plan: bool = False,
    operator: str = "",
    resume: bool = False,
    force: bool = False,
    unattended: bool = False,
    rate_hz: float | None = None,
    experiment: str | None = None,
    ui: Any = None,
    subscribers: tuple[Callable[[Any, Any], None], ...] = (),
    device_timeout: float = 2.0,
    silent_s: float = SILENT_S,
    baud: int = DEFAULT_BAUD,
    allow_other_rig: bool = False,
    valves: str | None = None,
    captures: int | None = None,
) -> Outcome:
    """Run ``labcli acquire``: open the rig and the run file, build the session, run it.

    ``protocol``: a shipped name or a .toml path (a new run without one: the registry's default for ``acquire``;
    a resumed run carries its own, a name given must match it, and its calibration, this rig's, is checked against
    the run's).  ``allow_other_rig``: resume on another rig.  ``valves``: ``"hand"`` keeps the prompts on a board
    that drives its valves.  ``captures``: each load taken that many times (the paper judges it).  Raises
    :class:`~labcli.errors.LabcliError` (one sentence) for anything the person at the rig can fix; else the Outcome.
    """
    path = str(path)
    _check_options(path, resume, force, plan, no_plan, protocol)
    options = AcquireOptions(path, plan, no_plan, experiment, unattended, captures=captures)
    link = Link(port, baud, device_timeout)
    existing: RunFile | None = None
    given = None
    if resume:
        acq, existing, finished, given = _resume(path, protocol, options)
        if finished is not None:
            return finished
    else:
        acq = _plan_new(path, protocol, options, force)
    try:
        rig = link.connect()
    except BaseException:
        if existing is not None:
            existing.close()
        raise
    try:
        if unattended and rig.operator is None:
            raise ConfigError(
                f"--unattended drives the simulated rig only, and {port} is a real port: "
                "run without --unattended and follow the prompts."
            )
        other = []
        if existing is not None:
            other = check_rig(
                existing, path, rig.device.info, (given or acq.protocol).calibration, allow_other=allow_other_rig
            )
        operator, kept = kept_operator(existing, operator)
        # A resumed run is open already; a new one is created when its first trial begins.
        run = (
            existing
            if existing is not None
            else NewRun(path, acq.protocol, acq.kind, rig.device.info, port, operator, acq.plan, force)
        )
        opts = SessionOptions(operator, resume, bool(other), unattended, rate_hz, silent_s)
        engine = _engine(rig, run, acq, ui, link, path, opts, valves)
        _say_kept(engine, kept)
        if other:
            engine.ui.warn(f"continuing {path} on another rig ({describe(other)}), as --allow-other-rig allows")
        for cb in subscribers:
            engine.subscribe(cb)
        completed = existing.records.ids() if existing is not None else []
        return _run(engine, acq, completed, link, rig.device)
    finally:
        with contextlib.suppress(Exception):
            rig.device.close()
        if existing is not None:
            existing.close()


def _run(engine: RunEngine, acq: Any, completed: list[int], link: Link, device: RigLink) -> Outcome:
    """The session on the engine to its end; then the run file closed, whatever happened."""
    try:
        return engine.run(acq.session(completed), restart=acq.session, reopen=link.connect)
    finally:
        # The session is over (finished, quit, interrupted or the rig lost): a Ctrl-C now
        # has nothing left to stop, and must not cut the file's close short.
        with sigint_ignored():
            if engine.run_file is not None:
                engine.run_file.close()
            if engine.device is not device:  # reopened after the rig was lost
                with contextlib.suppress(Exception):
                    engine.device.close()


def _say_kept(engine: RunEngine, kept: str) -> None:
    if kept:
        engine.ui.info(f"Operator {kept}, as the run recorded (--operator names another).")


def kept_operator(run: Any, operator: str) -> tuple[str, str]:
    """The session's operator and, when a resumed run kept its own (none was given), that one too."""
    if run is None or operator:
        return operator, ""
    kept = recorded_operator(run)
    return kept, kept


def recorded_operator(run: Any) -> str:
    """Who ran the run's latest session that named one (else the operator the run began with, or "")."""
    for session in reversed(run.sessions.all()):
        if session["operator"]:
            return str(session["operator"])
    return str(run.attrs.get("operator", "") or "")


def _record_noun(acq: Any) -> str:
    """What the session's sentences call one record: a capture where each load is taken several times
    (``acquisition.captures_per_load``; a trial is then a load), else the record type's noun."""
    captures = getattr(getattr(acq.protocol, "air", None), "captures_per_load", 1)
    return "capture" if captures > 1 else record_type(acq.kind).noun


def _engine(
    rig: Connection,
    run: RunFile | NewRun,
    acq: Any,
    ui: Any,
    link: Link,
    path: str,
    opts: SessionOptions,
    valves: str | None = None,
) -> RunEngine:
    command = resume_command(
        path, link.port, unattended=opts.unattended, rate_hz=opts.rate_hz, baud=link.baud, other_rig=opts.other_rig
    )
    info = SessionInfo(
        utc_now(),
        link.port,
        link.baud,
        RigIdentity.of(rig.device.info, acq.protocol.calibration),
        opts.operator,
        command,
        opts.resumed,
        opts.other_rig,
    )
    return RunEngine(
        rig.device,
        run,
        acq.protocol,
        ui or (UnattendedUI() if opts.unattended else RichUI()),
        run_path=path,
        resume_command=command,
        simulated_operator=rig.operator,
        rate_hz=opts.rate_hz,
        silent_s=opts.silent_s,
        noun=_record_noun(acq),
        session=info,
        valves=valves,
    )
