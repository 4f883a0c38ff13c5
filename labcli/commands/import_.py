"""``labcli import``: build a run file from a trial, push or rPAM point CSV table."""

from __future__ import annotations

import os

import click

from ..errors import ConfigError, LabcliError


@click.command("import")
@click.argument("table", type=click.Path(dir_okay=False))
@click.option("-o", "--output", required=True, type=click.Path(dir_okay=False), help="Run file to create (.h5).")
@click.option("--protocol", "protocol_name", required=True,
              help="Protocol name (e.g. takuma2014) or TOML file; its kind decides trial, push or point table.")
@click.option("--experiment", type=click.Choice(["stretch", "joint"]), default=None,
              help="rPAM protocols only: the experiment TABLE holds (stretch test or joint map).")
@click.option("--operator", default="", help="Who recorded the data.")
@click.option("--force", is_flag=True, help="Overwrite OUTPUT if it exists.")
def import_(table: str, output: str, protocol_name: str, experiment: str | None, operator: str,
            force: bool) -> None:
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
    from ..core.protocol import load_protocol
    from ..core.store import MAX_ID, import_table, storable_cells
    from ..core.tables import read_point_csv, read_push_csv, read_trial_csv

    try:
        protocol = load_protocol(protocol_name)
        kind = protocol.kind
        if kind == "rpam":
            if experiment is None:
                raise ConfigError(
                    f"{protocol_name} is a protocol of kind 'rpam' with two experiments; labcli import reads "
                    "its point tables with --experiment stretch (the stretch test) or --experiment joint "
                    "(the joint map), and trial tables with a force protocol such as takuma2014."
                )
            from ..experiments.rpam2015.session import acquisition_protocol

            protocol = acquisition_protocol(protocol, experiment)
            df = read_point_csv(table, experiment, id_range=(0, MAX_ID), check=storable_cells)
            noun = ("point", "points")
        elif experiment is not None:
            raise ConfigError(f"--experiment picks one experiment of an rPAM protocol; {protocol_name} is of "
                              f"kind '{kind}', so leave --experiment out.")
        elif kind in ("force", "push"):
            push = kind == "push"
            df = (read_push_csv if push else read_trial_csv)(table, id_range=(0, MAX_ID), check=storable_cells)
            noun = ("push", "pushes") if push else ("trial", "trials")
        else:
            raise ConfigError(
                f"{protocol_name} is a protocol of kind '{kind}'; labcli import reads trial tables of force "
                "protocols (such as takuma2014), push tables of push protocols (such as takuma2014-stiffness) "
                "and point tables of rPAM protocols (such as rpam2015)."
            )
        with import_table(df, output, protocol=protocol, force=force, source=os.path.basename(table),
                          operator=operator) as run:
            s = run.split()
    except LabcliError as e:
        raise click.ClickException(str(e)) from None
    what = noun[len(df) != 1]
    if experiment is not None:
        what += " of the stretch test" if experiment == "stretch" else " of the joint map"
    split = "" if s is None else f" (split: {len(s['fit'])} fit, {len(s['validation'])} validation)"
    click.echo(f"Imported {len(df)} {what} from {table} into {output}{split}.")
