"""``labcli sense``: live joint angles and tip forces from a rig's pressures, with a fitted model."""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Any

import click

from ..core.options import Typed
from ..errors import LabcliError
from ._declared import paper_command, sensing_groups
from ._options import FiniteRange, streaming_link_options


@paper_command(groups=sensing_groups)
@click.option(
    "--model",
    "model_path",
    required=True,
    type=click.Path(dir_okay=False, path_type=Path),
    help="Model JSON from `labcli fit`.",
)
@click.option(
    "--jsonl",
    is_flag=False,
    flag_value="-",
    default=None,
    metavar="[FILE]",
    help="One JSON object per estimate and per event, flushed per line: to FILE, or to stdout when no FILE is given.",
)
@click.option("--every", type=click.IntRange(min=1), default=1, show_default=True, help="Publish every Nth estimate.")
@click.option(
    "--publish",
    multiple=True,
    metavar="tcp://HOST:PORT",
    help="The same JSON lines to every client of this TCP port (port 0: any free port, printed), or to the "
    "subscribers of a ZeroMQ PUB socket at zmq+tcp://HOST:PORT (the zmq extra); repeatable.",
)
@click.option(
    "--lsl",
    default=None,
    metavar="NAME",
    help="The estimates as a Lab Streaming Layer stream NAME and the events as NAME-events (the lsl extra).",
)
@click.option(
    "--classify",
    type=click.Path(dir_okay=False, path_type=Path),
    default=None,
    metavar="PLAN.csv",
    help="A push plan: each settled push gives its object's stiffness and category (needs a push --protocol).",
)
@click.option(
    "--record",
    type=click.Path(dir_okay=False, path_type=Path),
    default=None,
    metavar="RUN.h5",
    help="A new run file: the raw frames, every estimate and every event, committed every second.",
)
@click.option(
    "--protocol",
    default=None,
    help="The session's protocol, name or .toml (a push protocol for --classify)  [default: the model's]",
)
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
    help="Stop after this many seconds of the rig's clock  [default: run until Ctrl-C]",
)
@streaming_link_options
def sense(
    port: str,
    model_path: Path,
    jsonl: str | None,
    every: int,
    publish: tuple[str, ...],
    lsl: str | None,
    classify: Path | None,
    record: Path | None,
    protocol: str | None,
    rate: float | None,
    seconds: float | None,
    timeout: float,
    boot_wait: float | None,
    baud: int,
    typed: Typed,
) -> None:
    """Estimate joint angles and tip forces live from a rig's pressures with a fitted model.

    Loads are found in the pressure stream (events load, settled, release), the
    baseline follows the chambers' leak while the rig is idle, and every 0.1 s
    theta1, theta2 (deg), Fx, Fy (N) come with their standard errors and flags.
    Without --jsonl to stdout a live view shows them with 95 % intervals and a
    rolling plot; --jsonl and --publish send the same JSON lines (seq,
    t_device_s, t_host_s, state, theta1_deg, theta1_deg_se, ..., flags, and
    {"event": ...} objects) to stdout, a file or TCP clients.  The options below the
    command's own are those the model's paper declares.  A sim:// port runs
    on the wall clock unless its URL says clock=virtual.  Ctrl-C stops and prints
    the summary.

    \b
    Examples:
        labcli sense --port sim:// --model run.model.json
        labcli sense --port /dev/ttyUSB0 --model run.model.json --jsonl --every 5
        labcli sense --port sim:// --model run.model.json --publish tcp://127.0.0.1:5555 --jsonl out.jsonl
        labcli sense --port /dev/ttyUSB0 --model run.model.json --record session.h5 --seconds 600
        labcli sense --port /dev/ttyUSB0 --model run.model.json --publish zmq+tcp://*:5556 --lsl arm
        labcli sense --port sim:// --model run.model.json --protocol takuma2014-stiffness --classify plan.csv
    """
    from ..sensing.sense import SenseOptions
    from ..sensing.sense import sense as run_sense  # heavy: when the command runs, not for --help

    opts = SenseOptions(
        port=port, model=model_path, protocol=protocol, rate_hz=rate, seconds=seconds, every=every,
        jsonl=jsonl, publish=publish, lsl=lsl, classify=classify, record=record, timeout=timeout, boot_wait=boot_wait, baud=baud, model_options=typed,
    )  # fmt: skip
    to_stdout = jsonl == "-"

    def notice(text: str) -> None:
        click.echo(text, err=True)

    view = None if to_stdout else _live_view(port)
    try:
        summary = run_sense(opts, notice=notice, view=view)
    except BrokenPipeError:  # the reader of stdout went away (| head): nothing more to say
        sys.stderr.close()
        return
    except LabcliError as exc:
        partial = getattr(exc, "summary", None)
        if partial is not None and partial.frames:
            click.echo(_summary_line(partial), err=True)
        raise click.ClickException(str(exc)) from None
    finally:
        if view is not None:
            view.stop()
    click.echo(_summary_line(summary), err=to_stdout)


def _summary_line(s: Any) -> str:
    stopped = {"seconds": "stopped", "interrupted": "stopped by Ctrl-C", "error": "stopped by an error"}
    events = ", ".join(f"{n} {k}" for k, n in s.events.items()) or "no events"
    lat = s.latency_ms()
    head = f"{stopped.get(s.stopped, 'stopped')} after {s.device_s:.1f} s of the rig's clock: {s.frames} frames"
    if not s.published:
        return f"{head}, {s.estimates} estimates, {events}."
    board = f", {s.paired} with the board's own beside them" if s.board else ""
    return (
        f"{head}, {s.estimates} estimates ({s.published} published{board}), {events}; from a frame's bytes at the host "
        f"to its estimate's line written: median {lat['median']:.2f} ms, p99 {lat['p99']:.2f} ms."
    )


class _live_view:  # noqa: N801 - used as the view factory
    """The rich live display, started when the estimator exists, stopped after the run."""

    def __init__(self, port: str) -> None:
        self.port = port
        self.live: Any = None

    def __call__(self, estimator: Any, dev: Any) -> Any:
        from rich.console import Console
        from rich.live import Live

        from ..sensing.view import LiveView

        console = Console()
        plain = not console.is_terminal
        info = dev.info
        from ..sensing.live import board_names

        view = LiveView(estimator, f"{info.device} on {self.port}")
        view.board_names = board_names(dev)  # a board with its own model: its estimates beside the host's
        self.live = Live(console=console, refresh_per_second=4, transient=False, auto_refresh=False)
        self.live.start()
        last = [0.0]

        def on_batch(frames: Any, items: list[Any]) -> None:
            import time

            view.take(frames, items)
            now = time.monotonic()
            if now - last[0] >= 0.25 or any(hasattr(i, "kind") for i in items):
                last[0] = now
                self.live.update(view.render(plain), refresh=True)

        self._final = lambda: self.live.update(view.render(plain), refresh=True)
        on_batch.on_board = view.take_board  # type: ignore[attr-defined]
        return on_batch

    def stop(self) -> None:
        if self.live is not None:
            self._final()
            self.live.stop()
            if not self.live.console.is_terminal:
                self.live.console.line()  # the last frame of a non-terminal Live ends mid-line
            self.live = None
