"""``labcli export``: a run's trial, push or rPAM point table as CSV."""

from __future__ import annotations

import click

from ..errors import LabcliError

_EXPERIMENTS = {"rpam-stretch": "stretch", "rpam-joint": "joint"}


@click.command("export")
@click.argument("run", type=click.Path(dir_okay=False))
@click.option("-o", "--output", required=True, type=click.Path(dir_okay=False),
              help="CSV file to write (replaced atomically).")
def export(run: str, output: str) -> None:
    """Write RUN's table as CSV: trials, pushes for a push run, points for an rPAM run.

    Pressures in MPa, forces in N, angles in degrees, masses in grams; the
    ``set`` column comes from the run's split.  ``labcli import`` reads the
    file back, and exporting the imported run gives the same bytes.

    \b
    An rPAM run (rpam2015) gives one row per point, in recording order:
      stretch test: point, mass_g (payload, g), P_A, P_B (MPa), L_m (actuator
        A's length, m), lambda (L / L0)
      joint map:    point, P_A, P_B (MPa), alpha_deg (deflection from the
        vented baseline, deg), P_A0, P_B0 (baseline pressures, MPa), L_m (m)
      then the set values set_mass_g (g), set_P_A_kPa, set_P_B_kPa (kPa).
    Import it back with --protocol rpam2015 --experiment stretch|joint.

    \b
    Example:
        labcli export run.h5 -o trials.csv
        labcli export stretch.h5 -o stretch.csv
    """
    from ..core.store import RunFile
    from ..core.tables import write_point_csv, write_push_csv, write_trial_csv

    try:
        with RunFile.open(run) as rf:
            kind = rf.kind
            experiment = _EXPERIMENTS.get(kind)
            if experiment is not None:
                df = rf.point_table()
            elif kind == "push":
                df = rf.push_table()
            else:
                df = rf.trial_table()
        if experiment is not None:
            write_point_csv(df, output, experiment)
            noun = ("point", "points")
        elif kind == "push":
            write_push_csv(df, output)
            noun = ("push", "pushes")
        else:
            write_trial_csv(df, output)
            noun = ("trial", "trials")
    except LabcliError as e:
        raise click.ClickException(str(e)) from None
    what = noun[len(df) != 1]
    if experiment is not None:
        what += " of the stretch test" if experiment == "stretch" else " of the joint map"
    click.echo(f"Wrote {len(df)} {what} from {run} to {output}.")
