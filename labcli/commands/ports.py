"""``labcli ports``: the serial ports this machine has, which board each looks like, which is a rig."""

from __future__ import annotations

import click

from ._options import FiniteRange


@click.command()
@click.option(
    "--probe",
    is_flag=True,
    help="Open each port and ask ID?, to say which is a labcli rig (resets an Uno-class board, as any program "
    "opening its port does).",
)
@click.option(
    "--boot-wait",
    type=FiniteRange(min=0),
    default=2.0,
    show_default=True,
    help="Seconds a probed board may take to boot after the port opens.",
)
def ports(probe: bool, boot_wait: float) -> None:
    """List the serial ports on this machine (device, board, description, hardware id).

    The board is named from the port's USB vendor and product ids: an Arduino Uno, Nano, Mega,
    or the USB-serial bridge of a clone or an adapter (CH340, FTDI, CP210x).  With --probe each
    port is asked ID? and the ones answering in the labcli wire protocol are marked as rigs,
    with their firmware.  The pseudo-terminals of a running `labcli sim --pty` are listed too,
    marked as the simulated rig (hardware id `sim`, with the serving process).

    \b
    Example:
        labcli ports
        labcli ports --probe
        labcli monitor --port /dev/ttyACM0 --seconds 5
    """
    from serial.tools import list_ports

    from ..core.sim.served import served
    from ..core.usbboards import PortRow, probe_all, rows_of

    rows = rows_of(list_ports.comports())
    rows += [PortRow(s.device, s.description, f"sim pid {s.pid}", "labcli simulated rig") for s in served()]
    if not rows:
        click.echo(
            "No serial ports found on this machine: plug in the rig's USB cable (and check its driver), "
            "or use --port sim:// for the simulated rig."
        )
        return
    if probe:
        rows = probe_all(rows, boot_wait=boot_wait)
    head = PortRow("DEVICE", "DESCRIPTION", "HWID", "BOARD", "ID?")
    table = [[r.device, r.board or "-", *([r.rig] if probe else []), r.description, r.hwid] for r in [head, *rows]]
    widths = [max(len(line[i]) for line in table) for i in range(len(table[0]) - 1)]
    for line in table:
        click.echo("  ".join([*(f"{c:<{w}}" for c, w in zip(line, widths, strict=False)), line[-1]]))
