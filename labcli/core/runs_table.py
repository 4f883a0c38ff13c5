"""The table ``labcli runs`` prints: one row per run file, units and counts said in the header."""

from __future__ import annotations

from typing import Any

from .catalogue import RunEntry
from .report import print_table, report_console
from .words import count


def _split(s: dict[str, Any] | None) -> str:
    return "—" if not s else f"{s['fit']}/{s['validation']}"


def _records(e: RunEntry) -> str:
    if e.complete is None:
        return "—"
    return f"{e.complete}/{e.planned}" if e.planned is not None else str(e.complete)


def print_runs(folder: str, entries: list[RunEntry]) -> None:
    """The catalogue as a table, then one line per run that did not check out."""
    from rich.table import Table

    con = report_console()
    if not entries:
        con.print(f"No run files (.h5, .hdf5) under {folder}.")
        return
    table = Table(title=f"{count(len(entries), 'run file')} under {folder}", title_justify="left")
    for name in (
        "file",
        "uid",
        "kind",
        "protocol",
        "rig",
        "operator",
        "start (UTC)",
        "complete/planned",
        "split fit/val",
        "models",
        "notes",
        "status",
    ):
        table.add_column(name, no_wrap=True)
    for e in entries:
        table.add_row(
            e.file,
            e.uid[:8] or "—",
            e.kind or "—",
            e.protocol or "—",
            e.rig or ("imported" if e.imported else "—"),
            e.operator or "—",
            e.started[:16].replace("T", " ") or "—",
            _records(e) + (f" {e.records}" if e.records else ""),
            _split(e.split),
            ", ".join(e.models) or "—",
            str(e.notes),
            e.status,
        )
    print_table(con, table)
    for e in entries:
        if e.problem:
            con.print(f"{e.file}: {e.problem}")
