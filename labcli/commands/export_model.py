"""``labcli export-model``: a fitted model as C, for the rig firmware to estimate on the chip."""

from __future__ import annotations

from pathlib import Path

import click

from ..core.dispatch import for_model_file
from ..errors import LabcliError


@click.command("export-model")
@click.argument("model", type=click.Path(dir_okay=False, path_type=Path))
@click.option(
    "--c",
    "c_header",
    type=click.Path(dir_okay=False, path_type=Path),
    required=True,
    help="The C header to write, e.g. model.h.",
)
@click.option(
    "--protocol",
    default=None,
    help="Protocol (name or .toml) whose calibration turns the board's counts into MPa and rad "
    "[default: the one the model was fitted under].",
)
def export_model(model: Path, c_header: Path, protocol: str | None) -> None:
    """Write the fitted MODEL (labcli fit's JSON) as a C header for the rig firmware.

    The firmware built with it computes the joint angles and the tip force from the pressures
    at the data rate, against a baseline it takes itself, and sends them as estimate lines
    (docs/wire-protocol.md).  Every form `labcli fit` writes is exported: the posture form (with
    the sleeves' friction terms, fit's default, the chip reading the motion into each baseline it
    takes), the paper's Eqs. 34-37, and their blends; a relieved run's friction terms are refused
    (`labcli fit RUN --no-friction-terms` fits it without them).  A model fitted on runs of
    several captures a load is exported with a warning: its intervals are too narrow for the
    board's single captures.

    \b
    Example:
        labcli fit run.h5
        labcli export-model run.model.json --c model.h
        make -C firmware MODEL=$PWD/model.h
    """
    try:
        analysis = for_model_file(model, "export-model").analysis("export-model")
        assert analysis is not None
        result = analysis.run(model, c=c_header, protocol=protocol)
    except LabcliError as e:
        raise click.ClickException(str(e)) from None
    analysis.show(result)
