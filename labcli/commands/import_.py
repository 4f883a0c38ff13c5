"""``labcli import``: build a run file from a trial or push CSV table."""

from __future__ import annotations

import os

import click

from ..errors import LabcliError


@click.command("import")
@click.argument("table", type=click.Path(dir_okay=False))
@click.option("-o", "--output", required=True, type=click.Path(dir_okay=False), help="Run file to create (.h5).")
@click.option("--protocol", "protocol_name", required=True,
              help="Protocol name (e.g. takuma2014) or TOML file; its kind decides trial or push table.")
@click.option("--operator", default="", help="Who recorded the data.")
@click.option("--force", is_flag=True, help="Overwrite OUTPUT if it exists.")
def import_(table: str, output: str, protocol_name: str, operator: str, force: bool) -> None:
    """Build a run file from TABLE, a trial (or push) CSV, e.g. from MATLAB or a spreadsheet.

    Every cell is checked; problems are reported by row and column.  The run
    file has no raw windows and is marked imported; a trial table's ``set``
    column becomes the run's split.

    \b
    Example:
        labcli import trials.csv -o run.h5 --protocol takuma2014
    """
    from ..protocol import load_protocol
    from ..store import import_table
    from ..tables import read_push_csv, read_trial_csv

    try:
        protocol = load_protocol(protocol_name)
        push = protocol.kind == "push"
        df = (read_push_csv if push else read_trial_csv)(table)
        with import_table(df, output, protocol=protocol, force=force, source=os.path.basename(table),
                          operator=operator) as run:
            s = run.split()
    except LabcliError as e:
        raise click.ClickException(str(e)) from None
    what = (("push", "pushes") if push else ("trial", "trials"))[len(df) != 1]
    split = "" if s is None else f" (split: {len(s['fit'])} fit, {len(s['validation'])} validation)"
    click.echo(f"Imported {len(df)} {what} from {table} into {output}{split}.")
