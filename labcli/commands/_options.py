"""What the commands share beyond click: which options the person typed, option types they all use."""

from __future__ import annotations

import math
from typing import Any

import click
from click.core import ParameterSource


def typed_options(*names: str) -> frozenset[str]:
    """The options among ``names`` (parameter names) given on the command line, not left at their default.

    A paper refuses an option that means nothing to its runs only when it was typed.
    """
    ctx = click.get_current_context(silent=True)
    if ctx is None:
        return frozenset()
    return frozenset(n for n in names if ctx.get_parameter_source(n) == ParameterSource.COMMANDLINE)


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


def streaming_link_options(f: Any) -> Any:
    """--timeout, --boot-wait and --baud, as every command that streams from a rig spells them."""
    f = click.option("--baud", type=BAUD, default=115200, help=BAUD_HELP)(f)
    f = click.option(
        "--boot-wait",
        type=FiniteRange(min=0),
        default=None,
        help="Extra seconds for a board that resets when the port opens  [default: 2 for serial ports, 0 for URLs]",
    )(f)
    return click.option(
        "--timeout",
        type=FiniteRange(min=0, min_open=True),
        default=2.0,
        show_default=True,
        help="Seconds to wait for the rig's answers, and of silence tolerated while streaming.",
    )(f)
