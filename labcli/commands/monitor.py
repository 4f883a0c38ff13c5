"""``labcli monitor``: live calibrated readings and link statistics from a rig."""

from __future__ import annotations

import json
from typing import Any

import click

from ..errors import LabcliError
from ._declared import protocol_option
from ._options import FiniteRange, port_options


def _reading(value: float, unit: str, extra_digits: int = 0) -> str:
    # Four decimals of MPa and two of deg are finer than one ADC count (as calibration.format_value).
    digits = (4 if unit == "MPa" else 2) + extra_digits
    return f"{value:.{digits}f} {unit}"


def _render(snap: Any, scale: Any, info: Any, plain: bool = False) -> Any:
    """The live table; ``plain`` (stdout not a terminal): no box drawing."""
    from rich import box
    from rich.console import Group
    from rich.table import Table
    from rich.text import Text

    table = Table(
        title=f"{info.device} {info.firmware} on {info.port} at {snap.rate_hz:g} Hz",
        title_justify="left",
        box=None if plain else box.HEAVY_HEAD,
    )
    table.add_column("channel")
    table.add_column("now", justify="right")
    table.add_column("mean", justify="right")
    table.add_column("std", justify="right")
    shown_now = scale.to_display(snap.latest_si)
    shown_mean = scale.to_display(snap.stats.mean)
    shown_std = scale.to_display(snap.stats.std)
    for j, name in enumerate(scale.names):
        unit = scale.display_units[j]
        table.add_row(
            name,
            _reading(shown_now[j], unit),
            _reading(shown_mean[j], unit),
            _reading(abs(shown_std[j]), unit, 1),
        )
    c = snap.counters
    link = Text(
        f"{snap.frames_per_s:.1f} frames/s · {c['frames']} frames · {c['lost']} lost · "
        f"{c['bad_checksum']} bad checksum · {c['malformed']} malformed · {c['overlong']} overlong · "
        f"{c.get('stalls', 0)} stalls · {c['log_lines']} log lines · {c.get('events', 0)} events · "
        f"{snap.elapsed_s:.1f} s"
    )
    return Group(table, link)


@click.command()
@port_options
@click.option(
    "--rate",
    type=FiniteRange(min=0, min_open=True),
    default=None,
    help="Frames per second to ask for  [default: the protocol's rate]",
)
@click.option(
    "--seconds",
    type=FiniteRange(min=0, min_open=True),
    default=None,
    help="Stop after this many seconds  [default: run until Ctrl-C]",
)
@click.option("--json", "as_json", is_flag=True, help="Print one JSON summary instead of the live table.")
@protocol_option(
    "monitor", "Protocol name or .toml file whose calibration converts counts to MPa and rad  [default: {default}]"
)
@click.option(
    "--boot-wait",
    type=FiniteRange(min=0),
    default=None,
    help="Extra seconds for a board that resets when the port opens  [default: 2 for serial ports, 0 for URLs]",
)
def monitor(
    port: str,
    baud: int,
    timeout: float,
    rate: float | None,
    seconds: float | None,
    as_json: bool,
    protocol: str | None,
    boot_wait: float | None,
) -> None:
    """Show live calibrated readings (MPa, deg) and link statistics from a rig.

    Ctrl-C stops the stream and prints the summary.  A sim:// port runs on
    the wall clock unless its URL says otherwise.  A stall is a gap in the
    rig's own clock of more than 0.25 s beyond the sample period (the
    firmware hung or dropped out); a silence longer than --timeout ends the
    run with an error.  With --json the summary (frames, lost, stalls,
    bad_checksum, malformed, log_lines, per-channel mean and std in SI
    units) is printed as one JSON object.

    \b
    Examples:
        labcli monitor --port sim:// --seconds 5
        labcli monitor --port /dev/ttyUSB0 --rate 200 --seconds 10 --json
        labcli monitor --port /dev/ttyACM0 --baud 1000000 --seconds 5
    """
    from ..core.device import Device  # heavy: when the command runs, not for --help
    from ..core.monitoring import channel_scale, watch
    from ..core.protocol import load_protocol
    from ..core.registry import default_protocol

    url = port
    if port.startswith("sim://") and "clock=" not in port:
        # A live display wants the simulated rig paced like hardware, not as fast as it is read.
        url += ("&" if "?" in port else "?") + "clock=wall"
    try:
        proto = load_protocol(protocol or default_protocol("monitor"))
        rate_hz = rate if rate is not None else proto.rate_hz
        if rate_hz is None:
            raise click.ClickException(f"Protocol {proto.name} names no sample rate; give one with --rate HZ.")
        # Errors speak of the port as the user typed it, not of the paced URL.
        with Device.open(url, baudrate=baud, timeout=timeout, boot_wait=boot_wait, name=port) as dev:
            assert dev.info is not None
            scale = channel_scale(dev.info.channels, proto.calibration)
            if as_json:
                summary = watch(dev, scale, rate_hz=rate_hz, seconds=seconds)
            else:
                from rich.console import Console
                from rich.live import Live

                console = Console()
                with Live(console=console, refresh_per_second=4, transient=False) as live:
                    summary = watch(
                        dev,
                        scale,
                        rate_hz=rate_hz,
                        seconds=seconds,
                        on_update=lambda snap: live.update(_render(snap, scale, dev.info, not console.is_terminal)),
                    )
                if not console.is_terminal:
                    console.line()  # the last frame of a non-terminal Live ends mid-line
    except LabcliError as exc:
        raise click.ClickException(str(exc)) from None

    if as_json:
        click.echo(json.dumps(summary.to_json(), indent=2))
        return
    _print_summary(summary, scale)


def _print_summary(summary: Any, scale: Any) -> None:
    c = summary.counters
    stopped = "stopped by Ctrl-C" if summary.interrupted else "stopped"
    click.echo(
        f"{summary.port}: {stopped} after {summary.seconds:.1f} s; {c['frames']} frames "
        f"({summary.frames_per_s:.1f} frames/s at {summary.rate_hz:g} Hz set), "
        f"{c.get('stalls', 0)} stalls, {c['lost']} lost, "
        f"{c['bad_checksum']} bad checksum, {c['malformed']} malformed, {c['overlong']} overlong, "
        f"{c['log_lines']} log lines, {c.get('events', 0)} events."
    )
    shown_mean = scale.to_display(summary.mean)
    shown_std = scale.to_display(summary.std)
    width = max(len(n) for n in scale.names)
    for j, name in enumerate(scale.names):
        unit = scale.display_units[j]
        click.echo(
            f"  {name:<{width}}  mean {_reading(shown_mean[j], unit)}  std {_reading(abs(shown_std[j]), unit, 1)}"
        )
