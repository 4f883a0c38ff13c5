"""``labcli sim``: serve the simulated rig on a pseudo-terminal."""

from __future__ import annotations

import signal
from typing import Any

import click

from ._options import FiniteRange


@click.command()
@click.option("--pty", "use_pty", is_flag=True, help="Serve on a new pseudo-terminal (required).")
@click.option(
    "--seed",
    type=click.IntRange(min=0),
    default=0,
    show_default=True,
    help="Seed of the rig's actuators, sensor offsets and noise.",
)
# 1..50000 are labcli.core.sim.firmware's RATE_MIN and RATE_MAX (not imported here: --help stays light).
@click.option(
    "--rate",
    type=FiniteRange(1, 50000),
    default=200.0,
    show_default=True,
    help="Sample rate at power-up, Hz (the host's RATE command changes it).",
)
@click.option(
    "--noise",
    type=FiniteRange(min=0),
    default=1.0,
    show_default=True,
    help="Scale of the sensor noise (1 = 0.5 count pressure, 0.7 count angle rms).",
)
@click.option(
    "--drift",
    type=FiniteRange(min=0),
    default=None,
    help="Scale of sensor zero drift (1 = a few counts over 10-40 min).  [default: the rig's own]",
)
@click.option(
    "--ideal",
    is_flag=True,
    help="Turn every non-ideality off (friction, leak, heat, play, link weight, sensor errors).",
)
@click.option(
    "--friction",
    type=FiniteRange(min=0),
    default=None,
    help="Scale of sleeve friction and hysteresis (1 = typical, 0 = off).",
)
@click.option(
    "--leak", type=FiniteRange(min=0), default=None, help="Scale of the closed chambers' leak (1 = about 1 kPa/min)."
)
@click.option(
    "--thermal",
    type=FiniteRange(min=0),
    default=None,
    help="Scale of the air's heating by a fast load (1 = adiabatic, relaxing over 3 s).",
)
@click.option(
    "--backlash", type=FiniteRange(min=0), default=None, help="Scale of the potentiometers' backlash (1 = 0.2 deg)."
)
@click.option(
    "--links", type=FiniteRange(min=0), default=None, help="Scale of the links' own weight (1 = 80 g and 30 g)."
)
@click.option(
    "--contact",
    type=FiniteRange(min=0),
    default=None,
    help="Scale of the friction where the tip presses a pushed object (1 = a coefficient of 0.3).",
)
@click.option(
    "--pulley",
    type=FiniteRange(min=0),
    default=None,
    help="Scale of the weight pulley's friction (1 = 2 % of the pull).",
)
@click.option(
    "--potscale",
    type=FiniteRange(min=0),
    default=None,
    help="Scale of the potentiometers' gain error (1 = 1 % rms).",
)
@click.option(
    "--potlin",
    type=FiniteRange(min=0),
    default=None,
    help="Scale of the potentiometers' non-linearity (1 = 0.5 % of the span at most).",
)
@click.option(
    "--repeat",
    type=FiniteRange(min=0),
    default=None,
    help="Scale of the pressure sensors' non-repeatability (1 = 0.2 % of full scale as three sd).",
)
@click.option(
    "--realism",
    type=click.Choice(["literature", "kind"]),
    default=None,
    help="Levels of the non-idealities: the literature's, or the kinder rig of earlier runs.",
)
@click.option(
    "--supply",
    default=None,
    metavar="MPA[,MPA,MPA,MPA]",
    help="Regulator pressure, MPa gauge: one value or four (L1,R1,L2,R2).  [default: 0.3]",
)
@click.option(
    "--design",
    type=click.Choice(["paper", "thin"]),
    default="paper",
    show_default=True,
    help="Actuators: paper-scale, or the earlier thin-muscle tuning.",
)
@click.option(
    "--faults",
    default="",
    metavar="KIND:RATE[@X],...",
    help="Make the link noisy: rates per frame of checksum, garbage, truncate, overlong, drop, "
    "stall@SECONDS, burst@FRAMES, e.g. checksum:0.01,drop:0.01,stall:0.001@2.5 (drawn from --seed).",
)
@click.option(
    "--firmware",
    type=click.Path(dir_okay=False),
    default=None,
    metavar="ELF",
    help="Run this compiled rig firmware on simavr (e.g. firmware/build/labcli_rig.elf) instead of "
    "the built-in firmware model; the rig's sensors drive its analog inputs.",
)
def sim(
    use_pty: bool,
    seed: int,
    rate: float,
    noise: float,
    drift: float,
    faults: str,
    firmware: str | None,
    ideal: bool,
    friction: float | None,
    leak: float | None,
    thermal: float | None,
    backlash: float | None,
    links: float | None,
    contact: float | None,
    pulley: float | None,
    potscale: float | None,
    potlin: float | None,
    repeat: float | None,
    realism: str | None,
    supply: str | None,
    design: str,
) -> None:
    """Serve the simulated rig on a pseudo-terminal until Ctrl-C (or `quit`).

    The rig answers the wire protocol (ID?, RATE, START, STOP) on the printed
    device path, paced by the wall clock, so any serial program can talk to
    it.  Inside labcli the port sim:// needs no pseudo-terminal.  With
    --faults the link corrupts, drops and stalls frames (seeded); on exit the
    faults injected and the counts a host must report are printed.  With
    --firmware the bytes come from the reference firmware running on a
    simulated ATmega328P (simavr), its power-up rate its own.

    The operator acts on the rig by typing on this command's standard input,
    one action a line: supply [MPA], close, vent, hang GRAMS DEG, remove,
    push OBJECT MM DEG, release, wait SECONDS, state, help, quit.

    \b
    Examples:
        labcli sim --pty --seed 3 --rate 500
        labcli monitor --port /dev/pts/5     (in another terminal)
        labcli sim --pty --rate 1000 --faults checksum:0.01,garbage:0.005,stall:0.001@0.5
        labcli sim --pty --supply 0.3,0.3,0.4,0.2 --ideal
        labcli sim --pty --firmware firmware/build/labcli_rig.elf
    """
    from ..core import registry  # heavy: when the command runs, not for --help
    from ..core.sim.faults import FaultSpec, FaultSpecError

    try:
        spec = FaultSpec.parse(faults)
    except FaultSpecError as e:
        raise click.BadParameter(str(e), param_hint="'--faults'") from None
    supply_option = registry.sim_options()["supply"]
    try:
        supply_MPa = None if supply is None else supply_option.parse(supply)
    except ValueError:
        raise click.BadParameter(f"needs {supply_option.what}, got '{supply}'", param_hint="'--supply'") from None
    rig_options = {
        "ideal": ideal,
        "friction": friction,
        "leak": leak,
        "thermal": thermal,
        "backlash": backlash,
        "links": links,
        "contact": contact,
        "pulley": pulley,
        "potscale": potscale,
        "potlin": potlin,
        "repeat": repeat,
        "realism": realism,
        "supply": supply_MPa,
        "design": design,
    }
    rig_options = {k: v for k, v in rig_options.items() if v is not None}

    if not use_pty:
        raise click.ClickException(
            "nothing to serve: add --pty to serve the simulated rig on a pseudo-terminal"
            " (labcli commands can use the port sim:// directly)."
        )
    if firmware is not None:
        server = _serve_firmware(firmware, spec.active, seed=seed, noise=noise, drift=drift, **rig_options)
    else:
        from ..core.sim.pty import serve_pty

        try:
            server = serve_pty(seed=seed, rate=rate, noise=noise, drift=drift, faults=spec, **rig_options)
        except OSError as e:
            raise click.ClickException(f"cannot open a pseudo-terminal: {e.strerror or e}.") from None
    what = f"firmware {firmware} on simavr" if firmware is not None else "firmware model"
    _serve(server, firmware, f"simulated rig {server.rig.device} (labcli sim --pty, seed {seed}, {what})")


def _serve(server: Any, firmware: str | None, description: str) -> None:
    """Serve until stopped, acting on the operator's lines typed on standard input; listed by
    ``labcli ports`` meanwhile."""
    import sys

    from ..core.sim.console import StdinConsole
    from ..core.sim.served import announce

    def _stop(signum, frame):
        server.request_stop()

    old = {s: signal.signal(s, _stop) for s in (signal.SIGINT, signal.SIGTERM)}
    try:
        on = f", firmware {firmware} on simavr" if firmware is not None else ""
        click.echo(f"Simulated rig on {server.path}{on} (Ctrl-C to stop)")
        console = StdinConsole(sys.stdin, server.operate, click.echo)
        if console.open and sys.stdin.isatty():
            click.echo("Type operator actions here, one a line (help lists them).")
        with announce(server.path, description):
            while not server.wait(0.0 if console.open else 0.5):
                console.poll(0.5)
    finally:
        for s, h in old.items():
            signal.signal(s, h)
        server.stop()
        click.echo("Simulated rig stopped.")
        if getattr(server, "error", None):
            click.echo(server.error, err=True)
        if server.faults is not None:
            click.echo(f"Faults: {server.faults.summary()}")


def _serve_firmware(elf: str, faults: bool, **rig: Any) -> Any:
    """The firmware on simavr behind a pty; the options of the firmware model do not apply."""
    from click.core import ParameterSource

    from ..core.sim.hil import FirmwareSimError
    from ..core.sim.hil_pty import serve_firmware_pty

    if click.get_current_context().get_parameter_source("rate") == ParameterSource.COMMANDLINE:
        raise click.BadParameter(
            "the firmware powers up at its own rate and takes RATE from the host; drop --rate with --firmware",
            param_hint="'--rate'",
        )
    if faults:
        raise click.BadParameter(
            "the firmware's link is what its UART makes; drop --faults with --firmware", param_hint="'--faults'"
        )
    try:
        return serve_firmware_pty(elf, **rig)
    except FirmwareSimError as e:
        raise click.ClickException(str(e)) from None
    except OSError as e:
        raise click.ClickException(f"cannot open a pseudo-terminal: {e.strerror or e}.") from None
