"""``labcli classify``: object stiffness and material category from pushes (Section 4, Figure 9)."""

from __future__ import annotations

from pathlib import Path

import click

from ..core.dispatch import for_analysis
from ..errors import LabcliError

DEFAULT_PROTOCOL = "takuma2014-stiffness"  # what a push CSV is read with when --protocol is not given


@click.command("classify")
@click.argument("pushes", type=click.Path(dir_okay=False, path_type=Path))
@click.option(
    "--model",
    "model_path",
    type=click.Path(dir_okay=False, path_type=Path),
    required=True,
    help="Model JSON from `labcli fit` on a force run of the same rig.",
)
@click.option(
    "--reference",
    type=click.Path(dir_okay=False, path_type=Path),
    default=None,
    help="Push run or CSV whose labelled pushes (category column) are reference objects.",
)
@click.option(
    "--method",
    type=click.Choice(["auto", "reference", "bands"]),
    default="auto",
    show_default=True,
    help="Categories from labelled reference objects, from the protocol's stiffness bands, "
    "or reference objects when any push is labelled, else bands.",
)
@click.option(
    "--angles",
    type=click.Choice(["pressure-only", "measured-angles"]),
    default="pressure-only",
    show_default=True,
    help="Joint angles from the pressures (Eqs. 34-35, the paper) or from the potentiometers.",
)
@click.option(
    "--plot",
    type=click.Path(dir_okay=False, path_type=Path),
    default=None,
    help="Write Figure 9 (stiffness per object) to this .png, .pdf or .svg file.",
)
@click.option(
    "--protocol",
    default=None,
    help="Protocol of a push CSV (name or .toml) [default: takuma2014-stiffness]; run files carry their own.",
)
@click.option(
    "--pushes",
    "list_pushes",
    is_flag=True,
    help="List every push in the report [default: only when there are 60 or fewer].",
)
@click.option(
    "--json",
    "as_json",
    is_flag=True,
    help="Print every push's and every object's results as JSON (mm, deg, N, N/m), streamed.",
)
def classify(
    pushes: Path,
    model_path: Path,
    reference: Path | None,
    method: str,
    angles: str,
    plot: Path | None,
    protocol: str | None,
    list_pushes: bool,
    as_json: bool,
) -> None:
    """Stiffness of each pushed object and its material category (Section 4, Figure 9).

    PUSHES is a push run file (.h5) or a push CSV.  Per push: joint angles and force from the
    pressures, contact point C, push direction phi (given, or solved), object centre O2,
    deformation delta_x and stiffness k_o = |F| / delta_x.  Per object: mean and standard
    deviation over the unflagged pushes, category and confidence, and the evidence: the
    distance to every category, "uncertain" and "in-sample" where the category is not to be
    trusted.  Pushes are listed when there are 60 or fewer, or with --pushes.

    \b
    Example:
        labcli classify pushes.h5 --model force.model.json --plot fig9.png
        labcli classify unknown.csv --model force.model.json --reference refs.h5 --json
        labcli classify archive.h5 --model force.model.json --pushes
    """
    try:
        analysis = for_analysis("classify", inputs=[pushes], default_protocol=DEFAULT_PROTOCOL).analysis("classify")
        result = analysis.run(
            pushes,
            model_path=model_path,
            reference=reference,
            method=method,
            angles=angles,
            plot=plot,
            protocol=protocol,
        )
    except LabcliError as e:
        raise click.ClickException(str(e)) from None
    analysis.show(result, as_json=as_json, pushes=list_pushes)
