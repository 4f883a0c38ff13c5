"""``labcli export``: a run's table (trials, pushes, rPAM points, ...) as CSV (with its sidecar), parquet,
Excel or MATLAB, as OUTPUT's extension says (:mod:`labcli.core.exports`)."""

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
    type=click.Choice(["csv", "parquet", "xlsx", "mat"]),
    default=None,
    help="Table format [default: OUTPUT's extension: .csv, .parquet, .xlsx or .mat].",
)
@click.option(
    "--all-columns",
    is_flag=True,
    help="Add what every record carries: when it began and was stored, how it was accepted, its "
    "flags, and how each window settled (times in s).",
)
def export(run: str, output: str, fmt: str | None, all_columns: bool) -> None:
    """Write RUN's table: trials, pushes for a push run, points for an rPAM run.

    The format follows OUTPUT's extension: .csv (with OUTPUT.json beside it,
    its description in the Frictionless Table Schema style: each column's type
    and unit, and where the rows came from), .parquet (pip install
    'labcli[parquet]'), .xlsx (a workbook with a row of units under the names
    and a provenance sheet; pip install 'labcli[xlsx]') or .mat (a MATLAB
    struct named as the table, with units and provenance beside it).

    Pressures in MPa, forces in N, angles in degrees, masses in grams; the
    ``set`` column comes from the run's split, a ``note`` column from the notes
    on its trials (``labcli note``), when there are any.  ``labcli import`` reads
    a CSV back, and exporting the imported run gives the same bytes (with
    --all-columns too: the flags, times and settling go back into the run).
    ``labcli.load_trials`` reads a CSV's description back into the DataFrame's
    attrs; a parquet file carries the same description in its own metadata.

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
        labcli export run.h5 -o trials.xlsx --all-columns
        labcli export run.h5 -o trials.mat
        labcli export stretch.h5 -o stretch.parquet
    """
    from ..core import exports, table_meta  # heavy: when the command runs, not for --help
    from ..core.files import check_output
    from ..core.store import RunFile
    from ..core.store.notes import with_notes
    from ..core.store.records import ALL_COLUMNS
    from ..core.store.summary import record_noun
    from ..core.table_meta import SIDECAR_SUFFIX
    from ..core.words import count

    try:
        check_output(output, inputs=(run,))  # writing over the input is the graver mistake: said first
        fmt = exports.format_of(output, fmt)
        if fmt == "csv":
            check_output(output + SIDECAR_SUFFIX, inputs=(run,))
        with RunFile.open(run) as rf:
            records, df, noun = rf.record_type, rf.records.table(all_columns=all_columns), record_noun(rf)
            table_meta.describe(df, records.table_spec, table_meta.run_provenance(rf, run))
            with_notes(df, records.id_column, rf.notes.all())
        if all_columns:
            df.attrs["units"].update({c.name: c.units for c in ALL_COLUMNS if c.units not in ("", "1")})
        exports.check_exportable(df, records.table_spec, run)
        exports.write(df, records.table_spec, records.collection, output, fmt, records.write_csv)
    except LabcliError as e:
        raise click.ClickException(str(e)) from None
    what = records.count(len(df)) if noun == records.noun else count(len(df), noun)  # a capture's row: a capture
    click.echo(f"Wrote {what} from {run} to {output}.")
