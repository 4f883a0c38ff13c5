"""``labcli inspect``: what a run file holds, how complete it is, how the rig drifted."""

from __future__ import annotations

import json

import click

from ..core.report import format_run_summary
from ..core.words import count
from ..errors import LabcliError


@click.command("inspect")
@click.argument("run", type=click.Path(dir_okay=False))
@click.option("--json", "as_json", is_flag=True, help="Print the summary as JSON (SI units named in the keys).")
@click.option(
    "--verify",
    is_flag=True,
    help="Check every record, raw window, split, model and session entry against its checksum.",
)
def inspect(run: str, as_json: bool, verify: bool) -> None:
    """Summarise RUN: metadata, complete/incomplete trials, split, baseline drift, settling.

    An rPAM run shows its experiment instead of split and drift: points complete
    against the protocol's grid, the pressures (kPa) and payloads (g) or
    deflections (deg) the points cover, and the settling times.

    With --verify, every record and raw window is checked against its checksum
    (and every value against its physical range); each damaged one is listed
    and the exit code is 1.

    \b
    Example:
        labcli inspect run.h5
        labcli inspect run.h5 --json | jq .baseline_drift
        labcli inspect run.h5 --verify
    """
    from ..core.store import RunFile  # heavy: when the command runs, not for --help

    try:
        with RunFile.open(run) as rf:
            if verify:
                report, records = rf.verify(), rf.record_type
            else:
                summary, records = rf.summary(), rf.record_type
    except LabcliError as e:
        raise click.ClickException(str(e)) from None
    if verify:
        _print_verify(run, report, records, as_json)
        return
    if as_json:
        click.echo(json.dumps(summary, indent=2))
    else:
        click.echo(format_run_summary(summary, records.inspect_lines(summary)))


def _print_verify(run: str, report: dict, records, as_json: bool) -> None:
    """The checks' outcome; exit code 1 (one sentence on stderr) when anything is damaged."""
    n, w, problems = report["records"], report["windows"], report["problems"]
    if as_json:
        click.echo(json.dumps(report, indent=2))
    else:
        for p in problems:
            click.echo(f"damaged: {p}")
    if problems:
        raise click.ClickException(
            f"{run}: {len(problems)} damaged item{'' if len(problems) == 1 else 's'} found; "
            f"{records.count(n)} and {count(w, 'raw window')} check out."
        )
    if not as_json:
        click.echo(f"{run}: {records.count(n)} and {count(w, 'raw window')} check out.")
