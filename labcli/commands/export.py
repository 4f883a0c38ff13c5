"""``labcli export``: a run's trial (or push) table as CSV."""

from __future__ import annotations

import click

from ..errors import LabcliError


@click.command("export")
@click.argument("run", type=click.Path(dir_okay=False))
@click.option("-o", "--output", required=True, type=click.Path(dir_okay=False),
              help="CSV file to write (replaced atomically).")
def export(run: str, output: str) -> None:
    """Write RUN's trial table (push table for a push run) as CSV.

    Pressures in MPa, forces in N, angles in degrees, masses in grams; the
    ``set`` column comes from the run's split.  ``labcli import`` reads the
    file back, and exporting the imported run gives the same bytes.

    \b
    Example:
        labcli export run.h5 -o trials.csv
    """
    from ..store import RunFile
    from ..tables import write_push_csv, write_trial_csv

    try:
        with RunFile.open(run) as rf:
            push = rf.kind == "push"
            df = rf.push_table() if push else rf.trial_table()
        (write_push_csv if push else write_trial_csv)(df, output)
    except LabcliError as e:
        raise click.ClickException(str(e)) from None
    noun = ("push", "pushes") if push else ("trial", "trials")
    click.echo(f"Wrote {len(df)} {noun[len(df) != 1]} from {run} to {output}.")
