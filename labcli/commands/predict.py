"""``labcli predict``: a fitted model's estimates for new data (a table of pressures, or a run file)."""

from __future__ import annotations

from pathlib import Path

import click

from ..core.options import Typed
from ..errors import LabcliError
from ._declared import paper_command


@paper_command("predict")
@click.argument("table", type=click.Path(dir_okay=False, path_type=Path))
@click.option(
    "--model",
    "model_path",
    required=True,
    type=click.Path(dir_okay=False, path_type=Path),
    help="Model JSON from `labcli fit`.",
)
@click.option(
    "--output",
    "-o",
    type=click.Path(dir_okay=False, path_type=Path),
    default=None,
    help="Write the rows with their estimates to this CSV [default: print a summary only].",
)
@click.option("--json", "as_json", is_flag=True, help="Print the summary as JSON.")
def predict(table: Path, model_path: Path, output: Path | None, as_json: bool, typed: Typed) -> None:
    """Estimate theta1, theta2, Fx and Fy for every row of TABLE with a fitted model.

    TABLE is a CSV of pressures (P_L10..P_R20 before, P_L1..P_R2 with the load, in MPa; the
    rest posture theta1_0_deg, theta2_0_deg when known) or a run file (.h5).  No truth is
    needed; truth columns (theta1_deg, theta2_deg, Fx_N, Fy_N) are carried through, renamed
    with _true.  Each estimate comes with its standard error (_se) and flags, the model applied
    exactly as `labcli validate` applies it.

    \b
    Example:
        labcli predict new-trials.csv --model run.model.json -o estimates.csv
    """
    from ..core.dispatch import prepare

    try:
        job = prepare("predict", typed, inputs=[table])
        result = job.analysis.run(table, job.options, model_path=model_path, output=output)
    except LabcliError as e:
        raise click.ClickException(str(e)) from None
    job.analysis.show(result, as_json=as_json)
