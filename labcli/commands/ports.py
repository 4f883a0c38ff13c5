"""``labcli ports``: the serial ports this machine has, to find the rig's."""

from __future__ import annotations

import click


@click.command()
def ports() -> None:
    """List the serial ports on this machine (device, description, hardware id).

    The pseudo-terminals of a running `labcli sim --pty` are listed too, marked as
    the simulated rig (hardware id `sim`, with the serving process).

    \b
    Example:
        labcli ports
        labcli monitor --port /dev/ttyUSB0 --seconds 5
    """
    from serial.tools import list_ports

    from ..core.sim.served import served

    rows = [
        (p.device, p.description or "n/a", p.hwid or "n/a")
        for p in sorted(list_ports.comports(), key=lambda p: p.device)
    ]
    rows += [(s.device, s.description, f"sim pid {s.pid}") for s in served()]
    if not rows:
        click.echo(
            "No serial ports found on this machine: plug in the rig's USB cable (and check its driver), "
            "or use --port sim:// for the simulated rig."
        )
        return
    head = ("DEVICE", "DESCRIPTION", "HWID")
    widths = [max(len(r[i]) for r in rows + [head]) for i in range(2)]
    for dev, desc, hwid in [head, *rows]:
        click.echo(f"{dev:<{widths[0]}}  {desc:<{widths[1]}}  {hwid}")
