"""``labcli validate``: a fitted model against a run's validation data (Figure 7 of a force
run; Fig. 8 of an rPAM joint-map run)."""

from __future__ import annotations

from pathlib import Path

import click

from ..core.dispatch import for_analysis
from ..errors import LabcliError
from ._options import typed_options

DEFAULT_PROTOCOL = "takuma2014"  # what a trial CSV is read with when --protocol is not given


@click.command("validate")
@click.argument("run", type=click.Path(dir_okay=False, path_type=Path))
@click.option(
    "--model",
    "model_path",
    type=click.Path(dir_okay=False, path_type=Path),
    default=None,
    help="Model JSON from `labcli fit`  [default: the model RUN records, else RUN.model.json beside it]",
)
@click.option(
    "--mode",
    type=click.Choice(["pressure-only", "measured-angles"]),
    default="pressure-only",
    show_default=True,
    help="Angles for the force equations: from the pressures (Eqs. 34-35) or the potentiometers.",
)
@click.option(
    "--plot",
    type=click.Path(dir_okay=False, path_type=Path),
    default=None,
    help="Write Figure 7 (observed vs calculated) to this .png, .pdf or .svg file.",
)
@click.option(
    "--protocol",
    default=None,
    help="Protocol of a trial CSV (name or .toml) [default: takuma2014]; run files carry their own.",
)
@click.option(
    "--allow-overlap",
    is_flag=True,
    help="Validate even when validation trials were used to fit the model (a warning says how many).",
)
@click.option(
    "--json",
    "as_json",
    is_flag=True,
    help="Print the metrics and every validation trial's observed and calculated values as JSON.",
)
@click.option(
    "--set",
    "overrides",
    multiple=True,
    metavar="KEY=VALUE",
    help="rPAM runs: override a protocol value for this analysis, e.g. --set actuator.A0_m2=2.2e-4 "
    "(repeatable; the run file keeps its own).",
)
@click.option(
    "--force",
    "force",
    type=click.Choice(["derived", "paper"]),
    default=None,
    help="rPAM runs: the reading of the actuator force (Eqs. 1-3): derived (the cage-held wall's energy and "
    "the gas's virtual work) or paper (the lumen's free body: cage term + P A0/lambda + Eq. 3) "
    "[default: the protocol's actuator.force_reading].",
)
def validate(
    run: Path,
    model_path: Path | None,
    mode: str,
    plot: Path | None,
    protocol: str | None,
    allow_overlap: bool,
    as_json: bool,
    overrides: tuple[str, ...],
    force: str | None,
) -> None:
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
    and --plot draws the rPAM paper's Figure 8.

    \b
    Example:
        labcli validate run.h5 --model run.model.json --plot fig7.png
        labcli validate trials.csv --mode measured-angles --json
        labcli validate joint.h5 --model stretch.model.json --plot fig8.png
    """
    try:
        analysis = for_analysis("validate", inputs=[run], default_protocol=DEFAULT_PROTOCOL).analysis("validate")
        result = analysis.run(
            run,
            model_path=model_path,
            mode=mode,
            plot=plot,
            protocol=protocol,
            overrides=overrides,
            force=force,
            allow_overlap=allow_overlap,
            typed=typed_options("mode"),
        )
    except LabcliError as e:
        raise click.ClickException(str(e)) from None
    analysis.show(result, as_json=as_json)
