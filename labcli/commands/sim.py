"""``labcli sim``: serve the simulated rig on a pseudo-terminal."""

from __future__ import annotations

import signal
from typing import Any

import click

from ..core.options import Typed
from ..errors import LabcliError
from ._declared import RegistryChoice, RegistryHelpOption, paper_command, rig_groups
from ._options import FiniteRange, seed_option


def sim_modes() -> list[str]:
    from ..core import registry

    return registry.sim_modes()


def _modes() -> dict[str, str]:
    from ..core import registry

    return {"modes": ", ".join(registry.sim_modes()), "default": registry.default_sim_mode()}


@paper_command("sim", rig_groups)
@click.option("--pty", "use_pty", is_flag=True, help="Serve on a new pseudo-terminal (required).")
@click.option(
    "--mode",
    cls=RegistryHelpOption,
    type=RegistryChoice(sim_modes),
    default=None,
    template="Which simulated rig: {modes}  [default: {default}]",
    fill=_modes,
)
@seed_option("Seed of the rig's actuators, sensor offsets and noise (labcli demo's by default).")
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
    mode: str | None,
    seed: int,
    rate: float,
    noise: float,
    drift: float | None,
    faults: str,
    firmware: str | None,
    typed: Typed,
) -> None:
    """Serve a simulated rig on a pseudo-terminal until Ctrl-C (or `quit`).

    The rig answers the wire protocol (ID?, RATE, START, STOP) on the printed
    device path, paced by the wall clock, so any serial program can talk to
    it.  Inside labcli the port sim:// needs no pseudo-terminal.  --mode picks
    the rig (each paper's rigs and their own options are listed below; the
    same options go in a sim:// URL, e.g. sim://?mode=rpam&experiment=stretch).
    With --faults the link corrupts, drops and stalls frames (seeded); on exit
    the faults injected and the counts a host must report are printed.  With
    --firmware the bytes come from the reference firmware running on a
    simulated ATmega328P (simavr), its power-up rate its own.

    The operator acts on the rig by typing on this command's standard input,
    one action a line: the rig's own (help lists them: supply, hang, push ...
    on the McKibben rig; pressures, mount, hang ... on the rPAM stand), and on
    every rig wait SECONDS, help, quit.

    \b
    Examples:
        labcli sim --pty --seed 3 --rate 500
        labcli monitor --port /dev/pts/5     (in another terminal)
        labcli sim --pty --rate 1000 --faults checksum:0.01,garbage:0.005,stall:0.001@0.5
        labcli sim --pty --supply 0.3,0.3,0.4,0.2 --ideal
        labcli sim --pty --mode rpam --experiment stretch
        labcli sim --pty --firmware firmware/build/labcli_rig.elf
    """
    from ..core.sim import rig_values  # heavy: when the command runs, not for --help
    from ..core.sim.faults import FaultSpec, FaultSpecError

    try:
        spec = FaultSpec.parse(faults)
    except FaultSpecError as e:
        raise click.BadParameter(str(e), param_hint="'--faults'") from None
    if not use_pty:
        raise click.ClickException(
            "nothing to serve: add --pty to serve the simulated rig on a pseudo-terminal"
            " (labcli commands can use the port sim:// directly)."
        )
    try:
        mode, rig_options = rig_values(mode, typed)
    except LabcliError as e:
        raise click.ClickException(str(e)) from None
    if firmware is not None:
        server = _serve_firmware(firmware, spec.active, seed=seed, noise=noise, drift=drift, mode=mode, **rig_options)
    else:
        from ..core.sim.pty import serve_pty

        try:
            server = serve_pty(seed=seed, rate=rate, noise=noise, drift=drift, mode=mode, faults=spec, **rig_options)
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
