"""What every report shares: the console, a table cell, and the lines of ``labcli inspect``.

The experiments' report modules print their analyses with :func:`report_console` and
:func:`cell`; :func:`format_run_summary` prints what ``RunFile.summary()`` found, with
the lines each record type adds (:meth:`labcli.core.experiment.RecordType.inspect_lines`)
built from :func:`records_line`, :func:`split_line` and :func:`settling_line`.
"""

from __future__ import annotations

import math
from typing import Any


def report_console(min_width: int, *, markup: bool = False) -> Any:
    """A rich console for a report; piped or logged, it is at least ``min_width`` wide."""
    from rich.console import Console  # rich only once something is printed

    con = Console(highlight=False, markup=markup)
    if not con.is_terminal:
        con.width = max(con.width, min_width)  # a pipe or a log file: never truncate numbers
    return con


def print_warnings(warnings: list[str]) -> None:
    """Each warning on its own line of stderr, before the report (a pipe of stdout keeps only the report)."""
    import sys

    for w in warnings:
        print(f"Warning: {w}", file=sys.stderr)


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
    (:meth:`~labcli.core.experiment.RecordType.inspect_lines`).
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
    if s["models"]:
        lines.append(f"  models      {', '.join(s['models'])}")
    return "\n".join(lines)


def records_line(s: dict[str, Any]) -> str:
    """``  trials      12 complete, 1 incomplete (13), 108 planned``."""
    rec = s["records"]
    planned = "" if s["planned"] is None else f", {s['planned']} planned"
    incomplete = f" ({ids_text(s['incomplete_ids'])})" if s["incomplete"] else ""
    return f"  {rec:<11} {s['complete']} complete, {s['incomplete']} incomplete{incomplete}{planned}"


def split_line(s: dict[str, Any]) -> str:
    """``  split       90 fit, 18 validation, 0 unassigned (plan)``."""
    sp = s["split"]
    if sp is None:
        return "  split       none (labcli split assigns one)"
    how = sp["strategy"] + ("" if sp["seed"] is None else f", seed {sp['seed']}")
    return (f"  split       {sp['fit']} fit, {sp['validation']} validation, "
            f"{sp['unassigned']} unassigned ({how})")


def settling_line(s: dict[str, Any]) -> str:
    """How long the records took to settle, and which were accepted on a timeout."""
    rec = s["records"]
    st = s["settle"]
    if st and st["n"]:
        timeouts = f" ({ids_text(st['timeout_ids'])})" if st["timeout_accepted"] else ""
        return (f"  settling    median {st['median_s']:.2f} s, max {st['max_s']:.2f} s over {st['n']} {rec}; "
                f"{st['timeout_accepted']} accepted on timeout{timeouts}")
    if st and st["timeout_accepted"]:
        return f"  settling    {st['timeout_accepted']} accepted on timeout ({ids_text(st['timeout_ids'])})"
    return "  settling    no settle times recorded"
