"""``labcli export``: a run's table (trials, pushes, rPAM points, ...) as CSV (with its sidecar) or parquet."""

from __future__ import annotations

import click

from ..errors import LabcliError


@click.command("export")
@click.argument("run", type=click.Path(dir_okay=False))
@click.option(
    "-o",
    "--output",
    required=True,
    type=click.Path(dir_okay=False),
    help="File to write (replaced atomically; never RUN itself, another run file or a non-regular file).",
)
@click.option(
    "--format",
    "fmt",
    type=click.Choice(["csv", "parquet"]),
    default=None,
    help="Table format [default: parquet for a .parquet OUTPUT, else csv].",
)
def export(run: str, output: str, fmt: str | None) -> None:
    """Write RUN's table as CSV: trials, pushes for a push run, points for an rPAM run.

    Pressures in MPa, forces in N, angles in degrees, masses in grams; the
    ``set`` column comes from the run's split, a ``note`` column from the notes
    on its trials (``labcli note``), when there are any.  ``labcli import`` reads the
    file back, and exporting the imported run gives the same bytes.

    Beside a CSV goes OUTPUT.json, its description in the Frictionless Table
    Schema style: each column's type and unit, and where the rows came from
    (run uid where recorded, protocol, device, labcli version, run file).
    ``labcli.load_trials`` reads it back into the DataFrame's attrs.  With
    --format parquet (needs pyarrow: pip install 'labcli[parquet]') the same
    description goes into the parquet file's own metadata.

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
        labcli export run.h5 -o trials.parquet
    """
    from ..core import table_meta  # heavy: when the command runs, not for --help
    from ..core.files import check_output
    from ..core.store import RunFile
    from ..core.store.notes import with_notes
    from ..core.table_meta import SIDECAR_SUFFIX

    parquet = fmt == "parquet" or (fmt is None and output.lower().endswith((".parquet", ".pq")))
    try:
        check_output(output, inputs=(run,))
        if not parquet:
            check_output(output + SIDECAR_SUFFIX, inputs=(run,))
        with RunFile.open(run) as rf:
            records, df = rf.record_type, rf.records.table()
            table_meta.describe(df, records.table_spec, table_meta.provenance(rf.attrs, run))
            with_notes(df, records.id_column, rf.notes.all())
        if parquet:
            table_meta.write_parquet(df, output)
        else:
            records.write_csv(df, output)
            table_meta.write_sidecar(df, records.table_spec, output)
    except LabcliError as e:
        raise click.ClickException(str(e)) from None
    click.echo(f"Wrote {records.count(len(df))} from {run} to {output}.")
