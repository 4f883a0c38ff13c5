"""What the commands share beyond click: option types they all use, the options of every command
that opens a port, and the default seed of the simulated rig."""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any, TypeVar

import click

F = TypeVar("F", bound=Callable[..., Any])


class FiniteRange(click.FloatRange):
    """A click FloatRange that also refuses nan and inf (which compare as inside any range)."""

    def convert(self, value: Any, param: Any, ctx: Any) -> Any:
        rv = click.FLOAT.convert(value, param, ctx)
        if not math.isfinite(rv):
            self.fail(f"{value!r} is not a finite number.", param, ctx)
        return super().convert(rv, param, ctx)


FINITE = FiniteRange()  # any finite number

# The serial link's speed: the wire protocol's default, and what USB-serial bridges offer.
BAUD = click.IntRange(50, 12_000_000)
BAUD_HELP = "Serial speed of the rig's link, bits per second  [default: 115200, the wire protocol's]"
TIMEOUT_S = 2.0  # the wait for the rig's answers, and the silence tolerated while streaming

# labcli sim and labcli demo serve the same simulated rig unless told otherwise.
SEED = 1


def port_options(f: F) -> F:
    """``-p/--port``, ``--baud`` and ``--timeout``: spelled and meaning the same on every command that opens a port."""
    f = click.option(
        "--timeout",
        type=FiniteRange(min=0, min_open=True),
        default=TIMEOUT_S,
        show_default=True,
        help="Seconds to wait for the rig's answers, and of silence tolerated while streaming.",
    )(f)
    f = click.option("--baud", type=BAUD, default=115200, help=BAUD_HELP)(f)
    return click.option(
        "-p",
        "--port",
        required=True,
        help="Serial port (/dev/ttyUSB0, COM3) or pyserial URL (sim://?seed=1&clock=virtual).",
    )(f)


def seed_option(help: str) -> Callable[[F], F]:
    """``--seed`` of the simulated rig, defaulting to :data:`SEED` (``labcli sim`` and ``labcli demo``)."""
    return click.option("--seed", type=click.IntRange(min=0), default=SEED, show_default=True, help=help)


def streaming_link_options(f: F) -> F:
    """:func:`port_options` and ``--boot-wait``, as every command that streams from a rig spells them."""
    f = click.option(
        "--boot-wait",
        type=FiniteRange(min=0),
        default=None,
        help="Extra seconds for a board that resets when the port opens  [default: 2 for serial ports, 0 for URLs]",
    )(f)
    return port_options(f)
