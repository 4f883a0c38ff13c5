"""What every report shares: the console, a table cell, and the lines of ``labcli inspect``.

The papers' report modules print their analyses with :func:`report_console` and
:func:`cell`; :func:`format_run_summary` prints what ``RunFile.summary()`` found, with
the lines each record type adds (:meth:`labcli.core.paper.RecordType.inspect_lines`)
built from :func:`records_line`, :func:`split_line` and :func:`settling_line`.
"""

from __future__ import annotations

import math
from typing import Any

from .words import count


def report_console(*, markup: bool = False) -> Any:
    """A rich console for a report, as wide as the terminal (COLUMNS, else 80 when piped).

    A table wider than that prints in column groups (:func:`print_table`), never with a
    number cut short.
    """
    from rich.console import Console  # rich only once something is printed

    # soft_wrap: prose lines are never broken by rich (a path stays whole for copying); tables still fit.
    return Console(highlight=False, markup=markup, soft_wrap=True)


def _cell_width(cell: Any) -> int:
    from rich.cells import cell_len
    from rich.text import Text

    text = cell.plain if isinstance(cell, Text) else str(cell)
    return max((cell_len(line) for line in text.split("\n")), default=0)


def _column_widths(table: Any) -> list[int]:
    """Each column's natural width in cells, padding included (rich's default: one each side)."""
    return [max([_cell_width(c.header)] + [_cell_width(x) for x in c._cells]) + 2 for c in table.columns]


def print_table(con: Any, table: Any) -> None:
    """Print a rich table whole: plain when piped, and in column groups when the console is narrow.

    rich shrinks a table that does not fit by cutting cells short ("0.009…"); a number cut
    short is a wrong number.  Here the columns that do not fit go to a further table below,
    each group repeating the first column (the row's name), so every cell prints in full.
    """
    from rich.table import Table

    if not con.is_terminal:
        table.box = None  # piped or logged: no box drawing, only text and spaces
    widths = _column_widths(table)
    if sum(widths) + 2 <= con.width or len(table.columns) <= 2:
        con.print(table)
        return
    groups: list[list[int]] = []
    used = widths[0]
    for i in range(1, len(widths)):
        if not groups or used + widths[i] + 2 > con.width:
            groups.append([])
            used = widths[0]
        groups[-1].append(i)
        used += widths[i]
    n_rows = len(table.columns[0]._cells)
    for k, group in enumerate(groups):
        part = Table(
            title=table.title if k == 0 else None,
            title_justify=table.title_justify,
            box=table.box,
            show_header=table.show_header,
            header_style=table.header_style,
        )
        for i in [0, *group]:
            c = table.columns[i]
            part.add_column(c.header, justify=c.justify, style=c.style, no_wrap=True)
        for r in range(n_rows):
            part.add_row(*(table.columns[i]._cells[r] for i in [0, *group]))
        con.print(part)


def print_warnings(warnings: list[str]) -> None:
    """Each warning on its own line of stderr, before the report (a pipe of stdout keeps only the report)."""
    import sys

    for w in warnings:
        print(f"Warning: {w}", file=sys.stderr)


def _captured(n: int) -> str:
    return "single captures" if n == 1 else f"means of {n} captures a load"


def captures_warning(model: str, fitted: int, rows: str, captured: int) -> str | None:
    """The sentence for a model applied to rows averaging another number of captures than its fit
    rows did (``acquisition.captures_per_load``): its standard errors are a mean of ``fitted``
    captures' (a capture's repeatability variance over that number), so they do not fit the rows.
    None when the numbers agree.  ``model`` and ``rows`` name them (``rows`` plural)."""
    if fitted == captured:
        return None
    side = "narrow" if fitted > captured else "wide"
    return (
        f"{model[:1].upper()}{model[1:]} was fitted on {_captured(fitted)} (acquisition.captures_per_load) "
        f"but {rows} are {_captured(captured)}: its standard errors and 95 % intervals are too {side} for them."
    )


def cell(x: Any, spec: str) -> str:
    """``x`` formatted with ``spec``, or a dash where there is no number (None, NaN, inf)."""
    if x is None or (isinstance(x, float) and not math.isfinite(x)):
        return "—"
    return format(x, spec)


# --------------------------------------------------------------------------- labcli inspect


def ids_text(ids: list[int], limit: int = 10) -> str:
    """``1, 2, 3, ... (5 more)``: a list of record ids, cut short."""
    shown = ", ".join(str(i) for i in ids[:limit])
    return shown + (f", ... ({len(ids) - limit} more)" if len(ids) > limit else "")


def format_run_summary(s: dict[str, Any], record_lines: list[str]) -> str:
    """The summary of a run file as lines people read; units on every number.

    ``record_lines``: what the run's record type says of its records
    (:meth:`~labcli.core.paper.RecordType.inspect_lines`).
    """
    lines = [
        f"{s['path']}: labcli run file, schema {s['schema_version']} (written by labcli {s['labcli_version']})",
        f"  kind        {s['kind']}, protocol {s['protocol']}" + (", imported from a table" if s["imported"] else ""),
    ]
    if s["device"] or s["port"]:
        lines.append(f"  rig         {s['device']} firmware {s['firmware']} on {s['port']}")
    lines.append(f"  operator    {s['operator'] or '(not given)'}, started {s['started']}")
    lines.append(f"  channels    {', '.join(s['channels'])}")
    lines.extend(record_lines)
    if s.get("unused_frames"):
        lines.append(f"  raw         {s['unused_frames']['text']}")
    if s["models"]:
        lines.append(f"  models      {', '.join(s['models'])}")
    for n in s.get("notes", ()):
        about = "" if n["record"] is None else f"{n['about']}: "
        lines.append(f"  note        {about}{n['text']} ({n['time'][:16].replace('T', ' ')})")
    return "\n".join(lines)


def records_line(s: dict[str, Any]) -> str:
    """``  trials      12 complete, 1 incomplete (13), 108 planned``."""
    rec = s["records"]
    planned = "" if s["planned"] is None else f", {s['planned']} planned"
    n = s.get("captures_per_load", 1)
    if n > 1 and s["planned"] is not None:  # the captures' plan trials (loads), as labcli split counts them
        planned += f" ({count(s['planned'] // n, 'plan trial')}, {n} captures each)"
    incomplete = f" ({ids_text(s['incomplete_ids'])})" if s["incomplete"] else ""
    return f"  {rec:<11} {s['complete']} complete, {s['incomplete']} incomplete{incomplete}{planned}"


def split_line(s: dict[str, Any]) -> str:
    """``  split       90 fit, 18 validation, 0 unassigned (plan)``."""
    sp = s["split"]
    if sp is None:
        return "  split       none (labcli split assigns one)"
    how = sp["strategy"] + ("" if sp["seed"] is None else f", seed {sp['seed']}")
    unit = " captures" if s.get("captures_per_load", 1) > 1 else ""  # labcli split counts their loads
    return f"  split       {sp['fit']} fit, {sp['validation']} validation, {sp['unassigned']} unassigned{unit} ({how})"


def settling_line(s: dict[str, Any]) -> str:
    """How long the records took to settle, and which were accepted on a timeout."""
    rec = s["records"]
    st = s["settle"]
    if st and st["n"]:
        timeouts = f" ({ids_text(st['timeout_ids'])})" if st["timeout_accepted"] else ""
        return (
            f"  settling    median {st['median_s']:.2f} s, max {st['max_s']:.2f} s over {st['n']} {rec}; "
            f"{st['timeout_accepted']} accepted on timeout{timeouts}"
        )
    if st and st["timeout_accepted"]:
        return f"  settling    {st['timeout_accepted']} accepted on timeout ({ids_text(st['timeout_ids'])})"
    return "  settling    no settle times recorded"
