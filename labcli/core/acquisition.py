"""``labcli acquire`` as one library call: check the options, resume or plan the run,
let the experiment's session run on the engine, close everything whatever happens.

The experiment that owns the protocol's kind plans the run
(:meth:`labcli.core.experiment.Experiment.acquisition`): its session of steps, its plan,
what "nothing left to resume" means.  This module knows no experiment.
"""

from __future__ import annotations

import contextlib
import shlex
import signal
import threading
from dataclasses import replace
from pathlib import Path
from typing import Any, Callable, Iterator

from ..errors import ConfigError, StoreError
from .device import Device
from .engine import SILENT_S, Outcome, RunEngine
from .experiment import AcquireOptions
from .protocol import load_protocol, loads_protocol
from .registry import record_type, run_protocol
from .store import RESUME_OR_FORCE, RunFile
from .ui import RichUI, UnattendedUI


def resume_command(path: str, port: str, *, unattended: bool = False, rate_hz: float | None = None) -> str:
    """The exact command line that continues a run."""
    cmd = f"labcli acquire {shlex.quote(str(path))} --port {shlex.quote(port)} --resume"
    if rate_hz:
        cmd += f" --rate {rate_hz:g}"
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


def _check_options(resume: bool, force: bool, plan: Any, no_plan: bool) -> None:
    if resume and force:
        raise ConfigError("--resume continues a run and --force overwrites it: give one of them, not both.")
    if plan is not None and no_plan:
        raise ConfigError("--plan and --no-plan contradict each other: give one of them.")


def _resume(path: str, protocol: str | None, options: AcquireOptions) -> tuple[Any, RunFile, Outcome | None]:
    """The run being resumed, open for writing, and its acquisition; an Outcome when it is done."""
    if options.plan is not None or options.no_plan:
        raise ConfigError(f"The plan of {path} was fixed when the run began; drop --plan/--no-plan with --resume.")
    existing = RunFile.open(path, "a")
    try:
        base = loads_protocol(existing.protocol_text, source=f"{path} (protocol)")
        if protocol is not None and _protocol_name(protocol) != base.name:
            raise ConfigError(
                f"{path} was recorded with protocol {base.name}, not {protocol}; drop --protocol to resume it."
            )
        experiment, proto = run_protocol(base, options.experiment, stored_kind=existing.kind, run_path=path)
        acq = experiment.acquisition(proto, replace(options, resume=existing))
        done = acq.already_done(existing, path)
        if done is not None:
            outcome = Outcome("finished", done, 0, len(existing.completed_ids()))
            existing.close()
            return acq, existing, outcome
    except BaseException:
        existing.close()
        raise
    return acq, existing, None


def _plan_new(path: str, protocol: str | None, options: AcquireOptions, force: bool) -> Any:
    """The acquisition of a new run (nothing is created yet)."""
    if Path(path).exists() and not force:
        raise StoreError(f"{path} already exists; {RESUME_OR_FORCE}.")
    if protocol is None:
        raise ConfigError("labcli acquire needs a protocol for a new run: give --protocol NAME or FILE.")
    experiment, proto = run_protocol(load_protocol(protocol), options.experiment)
    return experiment.acquisition(proto, options)


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
) -> Outcome:
    """Run ``labcli acquire``: open the rig and the run file, build the session, run it.

    ``protocol``: a shipped name or a .toml path (a new run needs one; a resumed run
    carries its own, and a name given must match it).  Raises
    :class:`~labcli.errors.LabcliError` (one sentence) for anything the person at the
    rig can fix; returns the :class:`Outcome` otherwise.
    """
    path = str(path)
    _check_options(resume, force, plan, no_plan)
    options = AcquireOptions(path, plan=plan, no_plan=no_plan, experiment=experiment, unattended=unattended)
    store: Any = None
    if resume:
        acq, store, finished = _resume(path, protocol, options)
        if finished is not None:
            return finished
    else:
        acq = _plan_new(path, protocol, options, force)
    try:
        device = Device.open(port, timeout=device_timeout)
    except BaseException:
        if store is not None:
            store.close()
        raise
    try:
        if unattended and device.rig is None:
            raise ConfigError(
                f"--unattended drives the simulated rig only, and {port} is a real port: "
                "run without --unattended and follow the prompts."
            )
        completed = list(store.completed_ids()) if store is not None else []
        if store is None:
            store = _creator(path, acq, device.info, port, operator, force)
        engine = _engine(device, store, acq, ui, path, port, unattended, rate_hz, silent_s)
        for cb in subscribers:
            engine.subscribe(cb)
        try:
            return engine.run(acq.session(completed), restart=acq.session,
                              reopen=lambda: Device.open(port, timeout=device_timeout))
        finally:
            # The session is over (finished, quit, interrupted or the rig lost): a Ctrl-C now
            # has nothing left to stop, and must not cut the file's close short.
            with sigint_ignored():
                if engine.store_created:
                    engine.store.close()
                if engine.device is not device:  # reopened after the rig was lost
                    with contextlib.suppress(Exception):
                        engine.device.close()
    finally:
        with contextlib.suppress(Exception):
            device.close()
        if store is not None and not callable(store):
            store.close()


def _creator(path: str, acq: Any, info: Any, port: str, operator: str, force: bool) -> Callable[[], RunFile]:
    """Creates the run file on first use, so a session that fails its setup check leaves none."""

    def create() -> RunFile:
        return RunFile.create(path, protocol=acq.protocol, kind=acq.kind, device_info=info, port=port,
                              operator=operator, plan=acq.plan, force=force)

    return create


def _engine(device: Any, store: Any, acq: Any, ui: Any, path: str, port: str, unattended: bool,
            rate_hz: float | None, silent_s: float) -> RunEngine:
    return RunEngine(
        device, store, acq.protocol, ui or (UnattendedUI() if unattended else RichUI()), run_path=path,
        resume_command=resume_command(path, port, unattended=unattended, rate_hz=rate_hz),
        rate_hz=rate_hz, silent_s=silent_s, noun=record_type(acq.kind).noun,
    )
