"""``labcli sim``: serve the simulated rig on a pseudo-terminal."""

from __future__ import annotations

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
def sim(use_pty: bool, seed: int, rate: float, noise: float, drift: float) -> None:
    """Serve the simulated rig on a pseudo-terminal until Ctrl-C.

    The rig answers the wire protocol (ID?, RATE, START, STOP) on the printed
    device path, paced by the wall clock, so any serial program can talk to
    it.  Inside labcli the port sim:// needs no pseudo-terminal.

    \b
    Example:
        labcli sim --pty --seed 3 --rate 500
        labcli monitor --port /dev/pts/5     (in another terminal)
    """
    import signal

    if not use_pty:
        raise click.ClickException(
            "nothing to serve: add --pty to serve the simulated rig on a pseudo-terminal"
            " (labcli commands can use the port sim:// directly)."
        )
    from ..sim.pty import serve_pty

    try:
        server = serve_pty(seed=seed, rate=rate, noise=noise, drift=drift)
    except OSError as e:
        raise click.ClickException(f"cannot open a pseudo-terminal: {e.strerror or e}.") from None

    def _stop(signum, frame):
        server.request_stop()

    old = {s: signal.signal(s, _stop) for s in (signal.SIGINT, signal.SIGTERM)}
    try:
        click.echo(f"Simulated rig on {server.path} (Ctrl-C to stop)")
        while not server.wait(0.5):
            pass
    finally:
        for s, h in old.items():
            signal.signal(s, h)
        server.stop()
        click.echo("Simulated rig stopped.")
