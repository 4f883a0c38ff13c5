"""``labcli fit``: a run's model, fitted (Eqs. 34-37 on a force run; Eq. 7's stretch correction
on an rPAM stretch-test run)."""

from __future__ import annotations

from pathlib import Path

import click

from ..core.options import Typed
from ..errors import LabcliError
from ._declared import paper_command, protocol_option


@paper_command("fit")
@click.argument("run", type=click.Path(dir_okay=False, path_type=Path))
@click.option(
    "-o",
    "--output",
    type=click.Path(dir_okay=False, path_type=Path),
    default=None,
    help="Model JSON to write [default: RUN.model.json beside the run].",
)
@protocol_option("fit", "Protocol of a trial CSV (name or .toml) [default: {default}]; run files carry their own.")
@click.option(
    "--record/--no-record",
    default=None,
    help="Also keep the model in the run file as the one in force  [default: with no -o, yes; with -o, no]",
)
@click.option("--json", "as_json", is_flag=True, help="Print the model and the paper's values as JSON.")
def fit(run: Path, output: Path | None, protocol: str | None, record: bool | None, as_json: bool, typed: Typed) -> None:
    """Fit a model to the fit trials of RUN, with the analysis of the paper that recorded it.

    RUN is a run file (.h5) or a trial CSV.  On a force run (takuma2014) the default form
    regresses the joint torques at the arm's true posture (rest posture from the
    potentiometers plus the deflection) and gives every estimate a standard error; --form
    paper fits the paper's Eqs. 34-37 as printed and prints each coefficient with its
    standard error, 95% interval and the paper's value (Section 3.3).  Saves the model JSON
    beside the run (RUN.model.json) and records it in the run file as the model in force;
    -o M.json writes M.json only, unless --record.  validate applies an explicit --model,
    else the model the run records, else RUN.model.json.  On an rPAM stretch-test run
    (rpam2015) it fits the cubic stretch correction F_stretch(lambda) of the rPAM paper's
    Eq. 7 instead, with its uncertainty.  Each paper's own options are listed under its
    name below.

    \b
    Example:
        labcli fit run.h5                  # writes run.model.json (posture form)
        labcli fit run.h5 --form paper     # Eqs. 34-37 beside the paper's coefficients
        labcli fit trials.csv --protocol takuma2014 -o model.json --json
        labcli fit run.h5 --form paper -o paper.json   # the run file is not touched
        labcli fit stretch.h5 --plot fig6-stretch.png
    """
    from ..core.dispatch import prepare

    try:
        job = prepare("fit", typed, inputs=[run])
        result = job.analysis.run(run, job.options, output=output, protocol=protocol, record=record)
    except LabcliError as e:
        raise click.ClickException(str(e)) from None
    job.analysis.show(result, as_json=as_json)
