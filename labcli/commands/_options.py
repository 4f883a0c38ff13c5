"""What the commands share beyond click: which options the person typed."""

from __future__ import annotations

import click
from click.core import ParameterSource


def typed_options(*names: str) -> frozenset[str]:
    """The options among ``names`` (parameter names) given on the command line, not left at their default.

    An experiment refuses an option that means nothing to its runs only when it was typed.
    """
    ctx = click.get_current_context(silent=True)
    if ctx is None:
        return frozenset()
    return frozenset(n for n in names if ctx.get_parameter_source(n) == ParameterSource.COMMANDLINE)
