"""``labcli monitor``: live calibrated readings and link statistics from a rig."""

from __future__ import annotations

import contextlib
import json
import math
from typing import Any

import click

from ..errors import LabcliError
from ._declared import protocol_option
from ._options import FiniteRange, streaming_link_options


def _reading(value: float, unit: str, extra_digits: int = 0) -> str:
    # Four decimals of MPa and two of deg are finer than one ADC count (as calibration.format_value).
    digits = (4 if unit == "MPa" else 2) + extra_digits
    return f"{value:.{digits}f} {unit}"


def _render(snap: Any, scale: Any, info: Any, plain: bool = False, plot: bool = False) -> Any:
    """The live table (now, and mean and std over the last seconds); ``plain`` (stdout not a
    terminal): no box drawing; ``plot``: the channels' traces over the same seconds below it."""
    from rich import box
    from rich.console import Group
    from rich.table import Table
    from rich.text import Text

    rolling = snap.rolling
    window = f"last {rolling.window_s:g} s" if rolling is not None else "since start"
    table = Table(
        title=f"{info.device} {info.firmware} on {info.port} at {snap.rate_hz:g} Hz",
        title_justify="left",
        box=None if plain else box.HEAVY_HEAD,
    )
    table.add_column("channel")
    table.add_column("now", justify="right")
    table.add_column(f"mean ({window})", justify="right")
    table.add_column(f"std ({window})", justify="right")
    mean = rolling.mean if rolling is not None else snap.stats.mean
    std = rolling.std if rolling is not None else snap.stats.std
    shown_now = scale.to_display(snap.latest_si)
    shown_mean = scale.to_display(mean)
    shown_std = _std_display(scale, mean, std)
    for j, name in enumerate(scale.names):
        unit = scale.display_units[j]
        table.add_row(
            name,
            _reading(shown_now[j], unit),
            _reading(shown_mean[j], unit),
            _reading(abs(shown_std[j]), unit, 1),
        )
    if snap.board is not None:
        _board_rows(table, snap.board)
    c = snap.counters
    link = Text(
        f"{snap.frames_per_s:.1f} frames/s · {c['frames']} frames · {c['lost']} lost · "
        f"{c['bad_checksum']} bad checksum · {c['malformed']} malformed · {c['overlong']} overlong · "
        f"{c.get('stalls', 0)} stalls · {c['log_lines']} log lines · {c.get('events', 0)} events · "
        f"{snap.elapsed_s:.1f} s",
        no_wrap=True,
    )
    parts: list[Any] = [table, link]
    if plot and rolling is not None:
        from ..core.rolling import trace_table

        parts.append(trace_table(rolling, scale.names, scale.display_units, 40, scale.to_display))
    return Group(*parts)


def _board_shown(value: float, unit: str) -> str:
    if not math.isfinite(value):
        return "—"
    return f"{math.degrees(value):.2f} deg" if unit == "rad" else f"{value:.2f} {unit}"


def _board_rows(table: Any, board: Any) -> None:
    """The board's own estimates as rows of the live table: now, and mean and std since the start."""
    mean, std = board.stats.mean, board.stats.std
    for j, (name, unit) in enumerate(zip(board.names, board.units, strict=True)):
        seen = board.stats.n > 0
        table.add_row(
            f"{name} (board)",
            _board_shown(board.latest[j], unit),
            _board_shown(mean[j], unit) + " (since start)" if seen else "—",
            _board_shown(std[j], unit) if seen else "—",
        )


def _std_display(scale: Any, mean: Any, std: Any) -> Any:
    """A spread in the units shown: the difference of two displayed values (an offset cancels)."""
    return scale.to_display(mean + std) - scale.to_display(mean)


@click.command()
@streaming_link_options
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
    "--window",
    "window_s",
    type=FiniteRange(min=0.1),
    default=5.0,
    show_default=True,
    help="Seconds of the rig's clock the live mean, std and plot cover.",
)
@click.option("--plot", is_flag=True, help="Draw each channel's trace over the last --window seconds.")
@click.option(
    "--record",
    type=click.Path(dir_okay=False),
    default=None,
    help="Also record every frame into this new HDF5 file (time, seq, counts, each channel in SI).",
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
    window_s: float,
    plot: bool,
    record: str | None,
) -> None:
    """Show live calibrated readings (MPa, deg) and link statistics from a rig.

    The live table shows each channel now and its mean and std over the last
    --window seconds of the rig's clock; --plot draws each channel's trace over
    them; --record FILE.h5 keeps every frame in a new HDF5 file readable with
    h5py alone (/entry/stream: time in s, seq, counts, each channel in SI).
    Piped, the table prints once at the end, each line whole.  Ctrl-C stops the
    stream and prints the summary (mean and std over the whole run).  A sim:// port runs on
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
        labcli monitor --port sim:// --plot --window 10 --record stream.h5
    """
    from ..core.device import Device  # heavy: when the command runs, not for --help
    from ..core.monitoring import calibrated, channel_scale, watch
    from ..core.protocol import load_protocol
    from ..core.registry import default_protocol

    url = port
    if port.startswith("sim://") and "clock=" not in port:
        # A live display wants the simulated rig paced like hardware, not as fast as it is read.
        url += ("&" if "?" in port else "?") + "clock=wall"
    try:
        proto = calibrated(load_protocol(protocol or default_protocol("monitor")))
        rate_hz = rate if rate is not None else proto.rate_hz
        if rate_hz is None:
            raise click.ClickException(f"Protocol {proto.name} names no sample rate; give one with --rate HZ.")
        # Errors speak of the port as the user typed it, not of the paced URL.
        with Device.open(url, baudrate=baud, timeout=timeout, boot_wait=boot_wait, name=port) as dev:
            assert dev.info is not None
            scale = channel_scale(dev.info.channels, proto.calibration)
            with contextlib.ExitStack() as stack:
                on_frames = None
                if record is not None:
                    recorder = stack.enter_context(_recorder(record, scale, dev.info, rate_hz))
                    on_frames = lambda batch, si: recorder.add(batch.seq, batch.t_us, batch.values, si)  # noqa: E731
                if as_json:
                    summary = watch(
                        dev, scale, rate_hz=rate_hz, seconds=seconds, window_s=window_s, on_frames=on_frames
                    )
                else:
                    summary = _live(dev, scale, rate_hz, seconds, window_s, plot, on_frames)
    except LabcliError as exc:
        raise click.ClickException(str(exc)) from None

    if as_json:
        click.echo(json.dumps(summary.to_json(), indent=2))
        return
    _print_summary(summary, scale)


def _recorder(path: str, scale: Any, info: Any, rate_hz: float) -> Any:
    from ..core.streamfile import StreamRecorder

    attrs = {"device": info.device, "firmware": info.firmware, "port": info.port, "rate_hz": float(rate_hz)}
    return StreamRecorder(path, scale.names, scale.units, attrs=attrs)


def _live(
    dev: Any, scale: Any, rate_hz: float, seconds: float | None, window_s: float, plot: bool, on_frames: Any
) -> Any:
    """The live table while the stream runs; piped, printed once at the end, as wide as its lines."""
    from rich.console import Console
    from rich.live import Live

    from ..core.monitoring import watch

    terminal = Console().is_terminal
    # Piped or logged, nothing wraps: a header or a status line broken over two lines reads as two.
    console = Console() if terminal else Console(width=10_000, soft_wrap=True)
    with Live(console=console, refresh_per_second=4, transient=False) as live:
        summary = watch(
            dev,
            scale,
            rate_hz=rate_hz,
            seconds=seconds,
            window_s=window_s,
            on_frames=on_frames,
            on_update=lambda snap: live.update(_render(snap, scale, dev.info, not terminal, plot)),
        )
    if not terminal:
        console.line()  # the last frame of a non-terminal Live ends mid-line
    return summary


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
    shown_std = _std_display(scale, summary.mean, summary.std)
    width = max(len(n) for n in scale.names)
    for j, name in enumerate(scale.names):
        unit = scale.display_units[j]
        click.echo(
            f"  {name:<{width}}  mean {_reading(shown_mean[j], unit)}  std {_reading(abs(shown_std[j]), unit, 1)} "
            "over the run"
        )
    for text in summary.warnings:
        click.echo(f"Warning: {text}.", err=True)
    board = summary.board
    if board is not None and board.stats.n:
        for j, (name, unit) in enumerate(zip(board.names, board.units, strict=True)):
            click.echo(
                f"  {name} (board's model)  mean {_board_shown(board.stats.mean[j], unit)}  "
                f"std {_board_shown(board.stats.std[j], unit)} over {board.stats.n} estimates"
            )
