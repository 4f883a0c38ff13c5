"""``labcli runs``: a catalogue of the run files under a folder."""

from __future__ import annotations

import json

import click

from ..errors import LabcliError


@click.command("runs")
@click.argument("folder", default=".", type=click.Path(file_okay=False))
@click.option("--json", "as_json", is_flag=True, help="Print one JSON object per run file, in a list.")
@click.option(
    "--verify",
    is_flag=True,
    help="Check every raw window against its checksum too (slower; as labcli inspect --verify).",
)
def runs(folder: str, as_json: bool, verify: bool) -> None:
    """List every run file under FOLDER (default: here), at any depth, one row each.

    Columns: file, uid (its first 8 characters; --json has all), kind, protocol,
    rig, operator, start (UTC), records complete/planned, split (fit/validation),
    models, notes, and status: ok (metadata and every row check out), verified
    (--verify: every raw window too), damaged (what was found is said below the
    table), or not a run.  Files are only read.

    \b
    Example:
        labcli runs out/
        labcli runs out/ --json | jq '.[] | select(.status != "ok")'
        labcli runs sample_runs --verify
    """
    from ..core.catalogue import catalogue  # heavy: when the command runs, not for --help

    try:
        entries = catalogue(folder, verify=verify)
    except LabcliError as e:
        raise click.ClickException(str(e)) from None
    if as_json:
        click.echo(json.dumps([e.as_dict() for e in entries], indent=2))
        return
    from ..core.runs_table import print_runs

    print_runs(folder, entries)
