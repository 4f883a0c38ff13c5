"""``labcli fit``: a run's model, fitted (Eqs. 34-37 on a force run; Eq. 7's stretch correction
on an rPAM stretch-test run)."""

from __future__ import annotations

from pathlib import Path

import click

from ..core.dispatch import for_analysis
from ..errors import LabcliError
from ._options import typed_options

DEFAULT_PROTOCOL = "takuma2014"  # what a trial CSV is read with when --protocol is not given


@click.command("fit")
@click.argument("run", type=click.Path(dir_okay=False, path_type=Path))
@click.option(
    "-o",
    "--output",
    type=click.Path(dir_okay=False, path_type=Path),
    default=None,
    help="Model JSON to write [default: RUN.model.json beside the run].",
)
@click.option(
    "--protocol",
    default=None,
    help="Protocol of a trial CSV (name or .toml) [default: takuma2014]; run files carry their own.",
)
@click.option(
    "--max-amplification",
    type=click.FloatRange(min=1, min_open=True),
    default=100.0,
    show_default=True,
    help="Leave a posture out of the Fx (Fy) fit when that force's error amplification near theta2 = 0 exceeds this.",
)
@click.option(
    "--form",
    type=click.Choice(["posture", "paper"]),
    default="posture",
    show_default=True,
    help="posture: torques at the arm's rest posture plus deflection, forces by (J^T)^-1, with "
    "standard errors; paper: Eqs. 34-37 exactly as printed, beside the paper's coefficients.",
)
@click.option(
    "--record/--no-record",
    default=None,
    help="Also keep the model in the run file as the one in force  [default: with no -o, yes; with -o, no]",
)
@click.option("--json", "as_json", is_flag=True, help="Print the model and the paper's values as JSON.")
@click.option(
    "--plot",
    type=click.Path(dir_okay=False, path_type=Path),
    default=None,
    help="rPAM stretch-test runs: write the stretch test's figure (Fig. 6) to this .png, .pdf or .svg.",
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
def fit(
    run: Path,
    output: Path | None,
    protocol: str | None,
    max_amplification: float,
    form: str,
    as_json: bool,
    plot: Path | None,
    overrides: tuple[str, ...],
    record: bool | None,
    force: str | None,
) -> None:
    """Fit a force model to the fit trials of RUN.

    RUN is a run file (.h5) or a trial CSV.  The default form regresses the joint torques at
    the arm's true posture (rest posture from the potentiometers plus the deflection) and gives
    every estimate a standard error; --form paper fits the paper's Eqs. 34-37 as printed and
    prints each coefficient with its standard error, 95% interval and the paper's value
    (Section 3.3).  Saves the model JSON beside the run (RUN.model.json) and records it in the
    run file as the model in force; -o M.json writes M.json only, unless --record.  validate
    applies an explicit --model, else the model the run records, else RUN.model.json.  On an
    rPAM stretch-test run it fits the cubic stretch correction F_stretch(lambda) of the rPAM
    paper's Eq. 7 instead, with its uncertainty.

    \b
    Example:
        labcli fit run.h5                  # writes run.model.json (posture form)
        labcli fit run.h5 --form paper     # Eqs. 34-37 beside the paper's coefficients
        labcli fit trials.csv --protocol takuma2014 -o model.json --json
        labcli fit run.h5 --form paper -o paper.json   # the run file is not touched
        labcli fit stretch.h5 --plot fig6-stretch.png
    """
    try:
        analysis = for_analysis("fit", inputs=[run], default_protocol=DEFAULT_PROTOCOL).analysis("fit")
        result = analysis.run(
            run,
            output=output,
            protocol=protocol,
            max_amplification=max_amplification,
            form=form,
            plot=plot,
            overrides=overrides,
            force=force,
            typed=typed_options("max_amplification", "form"),
            record=record,
        )
    except LabcliError as e:
        raise click.ClickException(str(e)) from None
    analysis.show(result, as_json=as_json)
