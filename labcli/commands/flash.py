"""``labcli flash``: write the rig firmware onto a board with avrdude."""

from __future__ import annotations

from pathlib import Path

import click

from ..errors import LabcliError


@click.command()
@click.argument("image", type=click.Path(dir_okay=False, path_type=Path))
@click.option("--port", "-p", required=True, help="The board's serial port, e.g. /dev/ttyACM0 or COM3.")
@click.option(
    "--programmer",
    default="arduino",
    show_default=True,
    help="avrdude's programmer: arduino (an Uno's bootloader over USB), or an ISP programmer such as usbasp.",
)
@click.option("--part", default="m328p", show_default=True, help="avrdude's part name of the chip (ATmega328P).")
@click.option(
    "--upload-baud",
    type=click.IntRange(300, 2_000_000),
    default=115200,
    show_default=True,
    help="The bootloader's serial speed (an Uno's: 115200).",
)
@click.option("--no-check", is_flag=True, help="Do not ask the board ID? after writing.")
def flash(image: Path, port: str, programmer: str, part: str, upload_baud: int, no_check: bool) -> None:
    """Write firmware IMAGE (.elf or .hex) onto the board on --port with avrdude, then ask it ID?.

    Opening the port resets an Uno into its bootloader, so no button is needed.  The
    firmware is what `make -C firmware` builds (firmware/build/labcli_rig.elf); built with a
    model (make -C firmware MODEL=model.h) it estimates angles and forces on the chip.

    \b
    Example:
        make -C firmware
        labcli flash firmware/build/labcli_rig.elf --port /dev/ttyACM0
        labcli monitor --port /dev/ttyACM0 --seconds 5
    """
    from ..core.flashing import flash as write

    try:
        result = write(image, port, programmer=programmer, part=part, baud=upload_baud, check=not no_check)
    except LabcliError as e:
        raise click.ClickException(str(e)) from None
    click.echo(f"Wrote {result.image} to the board on {result.port} ({' '.join(result.command)}).")
    if result.info is not None:
        caps = result.caps
        extra = f", wire protocol {caps.protocol}" if caps is not None else ""
        if caps is not None and caps.valves:
            extra += f", valves on {', '.join(caps.valves)}"
        if caps is not None and caps.model:
            extra += f", model {caps.model}"
        click.echo(
            f"The board answers: {result.info.device} firmware {result.info.firmware}{extra}; "
            f"channels {', '.join(result.info.channels)}."
        )
