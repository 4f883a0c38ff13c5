"""What the analysis commands share when they print a report: the console and a table cell."""

from __future__ import annotations

import math
from typing import Any


def report_console(min_width: int) -> Any:
    """A rich console for a report; piped or logged, it is at least ``min_width`` wide."""
    from rich.console import Console

    con = Console(highlight=False, markup=False)
    if not con.is_terminal:
        con.width = max(con.width, min_width)  # a pipe or a log file: never truncate numbers
    return con


def cell(x: Any, spec: str) -> str:
    """``x`` formatted with ``spec``, or a dash where there is no number (None, NaN, inf)."""
    if x is None or (isinstance(x, float) and not math.isfinite(x)):
        return "—"
    return format(x, spec)
