"""``labcli validate``: a fitted model against a run's validation data (Figure 7 of a force
run; Fig. 8 of an rPAM joint-map run)."""

from __future__ import annotations

from pathlib import Path

import click

from ..core.options import Typed
from ..errors import LabcliError
from ._declared import paper_command, protocol_option


@paper_command("validate")
@click.argument("run", type=click.Path(dir_okay=False, path_type=Path))
@protocol_option("validate", "Protocol of a trial CSV (name or .toml) [default: {default}]; run files carry their own.")
@click.option(
    "--json",
    "as_json",
    is_flag=True,
    help="Print the metrics and every validation trial's observed and calculated values as JSON.",
)
def validate(run: Path, protocol: str | None, as_json: bool, typed: Typed) -> None:
    """Check a fitted model on the validation trials of RUN (the paper's Figure 7).

    RUN is a run file (.h5) or a trial CSV.  The model is --model, else the model the run
    file records in force (/models/<protocol>), else RUN.model.json beside the run; the
    report names it.
    Validation trials the model was fitted on are refused unless --allow-overlap; a model
    fitted on another rig or under other protocol settings gets a warning.  Reports RMSE,
    MAE, max |error|, bias, R^2 and RMSE as a share of the observed range for theta1,
    theta2 (deg) and Fx, Fy (N).
    On an rPAM joint-map run it compares the measured angles with the model without and
    with the stretch correction (--model: the stretch fit; default: the protocol's own),
    and --plot draws the rPAM paper's Figure 8.  Each paper's own options are listed under
    its name below.

    \b
    Example:
        labcli validate run.h5 --model run.model.json --plot fig7.png
        labcli validate trials.csv --mode measured-angles --json
        labcli validate joint.h5 --model stretch.model.json --plot fig8.png
    """
    from ..core.dispatch import prepare

    try:
        job = prepare("validate", typed, inputs=[run])
        result = job.analysis.run(run, job.options, protocol=protocol)
    except LabcliError as e:
        raise click.ClickException(str(e)) from None
    job.analysis.show(result, as_json=as_json)
