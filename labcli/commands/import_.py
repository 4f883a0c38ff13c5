"""``labcli import``: build a run file from a trial, push or rPAM point CSV table."""

from __future__ import annotations

import click

from ..errors import LabcliError
from ._declared import RegistryHelpOption, experiment_option, shipped_protocols


@click.command("import")
@click.argument("table", type=click.Path(dir_okay=False))
@click.option("-o", "--output", required=True, type=click.Path(dir_okay=False), help="Run file to create (.h5).")
@click.option(
    "--protocol",
    "protocol_name",
    required=True,
    cls=RegistryHelpOption,
    template="Protocol name ({shipped}) or TOML file; its kind decides trial, push or point table.",
    fill=shipped_protocols,
)
@experiment_option("For {holders}: the experiment TABLE holds, {choices}.")
@click.option("--operator", default="", help="Who recorded the data.")
@click.option("--force", is_flag=True, help="Overwrite OUTPUT if it exists.")
def import_(table: str, output: str, protocol_name: str, experiment: str | None, operator: str, force: bool) -> None:
    """Build a run file from TABLE, a trial, push or rPAM point CSV, e.g. from MATLAB or a spreadsheet.

    Every cell is checked; problems are reported by row and column.  The run
    file has no raw windows and is marked imported; a trial table's ``set``
    column becomes the run's split.  An rPAM protocol (rpam2015) takes the
    point table `labcli export` writes for its runs, with --experiment saying
    which: stretch (point, mass_g, P_A, P_B, L_m, lambda, ...) or joint
    (point, P_A, P_B, alpha_deg, P_A0, P_B0, L_m, ...).

    \b
    Example:
        labcli import trials.csv -o run.h5 --protocol takuma2014
        labcli import stretch.csv -o stretch.h5 --protocol rpam2015 --experiment stretch
    """
    from ..core.store import import_csv  # heavy: when the command runs, not for --help

    try:
        imported = import_csv(
            table, output, protocol=protocol_name, experiment=experiment, operator=operator, force=force
        )
    except LabcliError as e:
        raise click.ClickException(str(e)) from None
    click.echo(imported.sentence(table, output))
