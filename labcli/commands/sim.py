"""``labcli sim``: serve the simulated rig on a pseudo-terminal."""

from __future__ import annotations

import signal
from typing import Any

import click


@click.command()
@click.option("--pty", "use_pty", is_flag=True, help="Serve on a new pseudo-terminal (required).")
@click.option("--seed", type=click.IntRange(min=0), default=0, show_default=True,
              help="Seed of the rig's actuators, sensor offsets and noise.")
@click.option("--rate", type=click.FloatRange(1, 5000), default=200.0, show_default=True,
              help="Sample rate at power-up, Hz (the host's RATE command changes it).")
@click.option("--noise", type=click.FloatRange(min=0), default=1.0, show_default=True,
              help="Scale of the sensor noise (1 = 0.5 count pressure, 0.7 count angle rms).")
@click.option("--drift", type=click.FloatRange(min=0), default=0.0, show_default=True,
              help="Scale of sensor zero drift and chamber leak.")
@click.option("--faults", default="", metavar="KIND:RATE[@X],...",
              help="Make the link noisy: rates per frame of checksum, garbage, truncate, overlong, drop, "
                   "stall@SECONDS, burst@FRAMES, e.g. checksum:0.01,drop:0.01,stall:0.001@2.5 (drawn from --seed).")
@click.option("--firmware", type=click.Path(dir_okay=False), default=None, metavar="ELF",
              help="Run this compiled rig firmware on simavr (e.g. firmware/build/labcli_rig.elf) instead of "
                   "the built-in firmware model; the rig's sensors drive its analog inputs.")
def sim(use_pty: bool, seed: int, rate: float, noise: float, drift: float, faults: str, firmware: str | None) -> None:
    """Serve the simulated rig on a pseudo-terminal until Ctrl-C.

    The rig answers the wire protocol (ID?, RATE, START, STOP) on the printed
    device path, paced by the wall clock, so any serial program can talk to
    it.  Inside labcli the port sim:// needs no pseudo-terminal.  With
    --faults the link corrupts, drops and stalls frames (seeded); on exit the
    faults injected and the counts a host must report are printed.  With
    --firmware the bytes come from the reference firmware running on a
    simulated ATmega328P (simavr), its power-up rate its own.

    \b
    Examples:
        labcli sim --pty --seed 3 --rate 500
        labcli monitor --port /dev/pts/5     (in another terminal)
        labcli sim --pty --rate 1000 --faults checksum:0.01,garbage:0.005,stall:0.001@0.5
        labcli sim --pty --firmware firmware/build/labcli_rig.elf
    """
    from ..core.sim.faults import FaultSpec, FaultSpecError  # heavy: when the command runs, not for --help

    try:
        spec = FaultSpec.parse(faults)
    except FaultSpecError as e:
        raise click.BadParameter(str(e), param_hint="'--faults'") from None

    if not use_pty:
        raise click.ClickException(
            "nothing to serve: add --pty to serve the simulated rig on a pseudo-terminal"
            " (labcli commands can use the port sim:// directly)."
        )
    if firmware is not None:
        server = _serve_firmware(firmware, spec.active, seed=seed, noise=noise, drift=drift)
    else:
        from ..core.sim.pty import serve_pty

        try:
            server = serve_pty(seed=seed, rate=rate, noise=noise, drift=drift, faults=spec)
        except OSError as e:
            raise click.ClickException(f"cannot open a pseudo-terminal: {e.strerror or e}.") from None

    def _stop(signum, frame):
        server.request_stop()

    old = {s: signal.signal(s, _stop) for s in (signal.SIGINT, signal.SIGTERM)}
    try:
        on = f", firmware {firmware} on simavr" if firmware is not None else ""
        click.echo(f"Simulated rig on {server.path}{on} (Ctrl-C to stop)")
        while not server.wait(0.5):
            pass
    finally:
        for s, h in old.items():
            signal.signal(s, h)
        server.stop()
        click.echo("Simulated rig stopped.")
        if getattr(server, "error", None):
            click.echo(server.error, err=True)
        if server.faults is not None:
            click.echo(f"Faults: {server.faults.summary()}")


def _serve_firmware(elf: str, faults: bool, **rig: float) -> Any:
    """The firmware on simavr behind a pty; the options of the firmware model do not apply."""
    from click.core import ParameterSource

    from ..core.sim.hil import FirmwareSimError
    from ..core.sim.hil_pty import serve_firmware_pty

    if click.get_current_context().get_parameter_source("rate") == ParameterSource.COMMANDLINE:
        raise click.BadParameter("the firmware powers up at its own rate and takes RATE from the host; "
                                 "drop --rate with --firmware", param_hint="'--rate'")
    if faults:
        raise click.BadParameter("the firmware's link is what its UART makes; drop --faults with --firmware",
                                 param_hint="'--faults'")
    try:
        return serve_firmware_pty(elf, **rig)
    except FirmwareSimError as e:
        raise click.ClickException(str(e)) from None
    except OSError as e:
        raise click.ClickException(f"cannot open a pseudo-terminal: {e.strerror or e}.") from None
