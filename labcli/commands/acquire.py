"""``labcli acquire``: guide a run at the rig and record it into an HDF5 file."""

from __future__ import annotations

import signal

import click

from ..errors import LabcliError
from ._declared import experiment_option, protocol_option
from ._options import FiniteRange, port_options


@click.command()
@click.argument("run", metavar="RUN.h5", type=click.Path(dir_okay=False))
@port_options
@protocol_option("acquire", "Shipped protocol name or .toml path  [default: {default}]")
@click.option(
    "--plan",
    "plan",
    type=click.Path(dir_okay=False),
    default=None,
    help="Plan CSV (trial,set,mass_g,direction_deg)  [default: the protocol's plan]",
)
@click.option("--no-plan", is_flag=True, help="Type each weight and direction at the rig instead.")
@click.option("--operator", default="", help="Who runs the rig, stored in the file  [default: a resumed run's own]")
@click.option("--resume", is_flag=True, help="Continue RUN.h5 at its first trial not yet complete.")
@click.option("--force", is_flag=True, help="Overwrite RUN.h5 if it exists.")
@click.option("--unattended", is_flag=True, help="Simulated rig only: act out every prompt and accept every trial.")
@click.option(
    "--rate",
    "rate",
    type=FiniteRange(min=0, min_open=True),
    default=None,
    help="Frames per second  [default: the protocol's rate_hz]",
)
@click.option(
    "--allow-other-rig",
    is_flag=True,
    help="With --resume: continue on a rig other than the one the run was recorded on.",
)
@click.option(
    "--captures",
    type=click.IntRange(min=1),  # the protocol's key says how many at most (labcli.core.air)
    default=None,
    help="Take each plan load N times in a row, each capture after the friction relief; fit, validate and "
    "predict average them  [default: the protocol's acquisition.captures_per_load, 1]",
)
@experiment_option("Which experiment of {holders} to record: {choices}.")
def acquire(
    run: str,
    port: str,
    baud: int,
    timeout: float,
    protocol: str | None,
    plan: str | None,
    no_plan: bool,
    operator: str,
    resume: bool,
    force: bool,
    unattended: bool,
    rate: float | None,
    allow_other_rig: bool,
    captures: int | None,
    experiment: str | None,
) -> None:
    """Guide a run at the rig, trial by trial, and record it into RUN.h5.

    Setup check, baseline with the valves closed, then per trial: baseline,
    load (from the plan, or typed), equilibrium judged from the data, capture,
    summary row to accept, redo, skip or quit.  Each accepted trial is written
    whole; Ctrl-C, q or an unplugged rig lose only the trial in progress.
    The readings are checked as the run goes: air supplied, a load that moved
    them, a weight removed; a trial that looks wrong is stored only when you
    type a.  --resume continues only on the rig the run was recorded on.

    \b
    Example:
        labcli acquire run.h5 --port /dev/ttyUSB0 --operator kim
        labcli acquire run.h5 --port /dev/ttyUSB0 --resume
        labcli acquire sim.h5 --port 'sim://?seed=1&clock=virtual' --unattended
        labcli acquire three.h5 --port 'sim://?seed=1&clock=virtual' --unattended --captures 3
        labcli acquire stretch.h5 --protocol rpam2015 --experiment stretch \\
            --port 'sim://?mode=rpam&clock=virtual' --unattended
    """
    from ..core.acquisition import acquire as run_acquisition  # heavy: when the command runs, not for --help

    try:
        outcome = run_acquisition(
            run,
            port,
            protocol=protocol,
            plan=plan,
            no_plan=no_plan,
            operator=operator,
            resume=resume,
            force=force,
            unattended=unattended,
            rate_hz=rate,
            experiment=experiment,
            baud=baud,
            device_timeout=timeout,
            allow_other_rig=allow_other_rig,
            captures=captures,
        )
    except LabcliError as e:
        raise click.ClickException(str(e)) from None
    except KeyboardInterrupt:
        # The engine answers every Ctrl-C once the session runs; one that escapes came before
        # it began (reading the protocol, opening the port), when nothing had been written.
        click.echo(f"Interrupted before the session began; {run} is as it was.", err=True)
        raise SystemExit(130) from None
    # The session is over; its outcome is printed whole.
    previous = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        # A session nobody could answer ended in error; a Ctrl-C (130) is said plainly.
        prefix = "Error: " if outcome.exit_code == 1 else ""
        click.echo(prefix + outcome.message, err=outcome.exit_code != 0)
    finally:
        # In labcli's own process Ctrl-C stays ignored to the end: from here a KeyboardInterrupt
        # could only land in Python's clean-up and print "Exception ignored ..." after the outcome.
        if not (click.get_current_context().find_root().obj or {}).get("own_process"):
            signal.signal(signal.SIGINT, previous)
    if outcome.exit_code:
        raise SystemExit(outcome.exit_code)
