"""``labcli inspect``: what a run file holds, how complete it is, how the rig drifted."""

from __future__ import annotations

import json

import click

from ..core.report import format_run_summary
from ..errors import LabcliError


@click.command("inspect")
@click.argument("run", type=click.Path(dir_okay=False))
@click.option("--json", "as_json", is_flag=True, help="Print the summary as JSON (SI units named in the keys).")
def inspect(run: str, as_json: bool) -> None:
    """Summarise RUN: metadata, complete/incomplete trials, split, baseline drift, settling.

    An rPAM run shows its experiment instead of split and drift: points complete
    against the protocol's grid, the pressures (kPa) and payloads (g) or
    deflections (deg) the points cover, and the settling times.

    \b
    Example:
        labcli inspect run.h5
        labcli inspect run.h5 --json | jq .baseline_drift
    """
    from ..core.store import RunFile  # heavy: when the command runs, not for --help

    try:
        with RunFile.open(run) as rf:
            summary, records = rf.summary(), rf.record_type
    except LabcliError as e:
        raise click.ClickException(str(e)) from None
    if as_json:
        click.echo(json.dumps(summary, indent=2))
    else:
        click.echo(format_run_summary(summary, records.inspect_lines(summary)))
