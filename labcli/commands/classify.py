"""``labcli classify``: object stiffness and material category from pushes (Section 4, Figure 9)."""

from __future__ import annotations

from pathlib import Path

import click

from ..core.options import Typed
from ..errors import LabcliError
from ._declared import paper_command, protocol_option


@paper_command("classify")
@click.argument("source", metavar="PUSHES", type=click.Path(dir_okay=False, path_type=Path))
@protocol_option("classify", "Protocol of a push CSV (name or .toml) [default: {default}]; run files carry their own.")
@click.option(
    "--json",
    "as_json",
    is_flag=True,
    help="Print every push's and every object's results as JSON (mm, deg, N, N/m), streamed.",
)
def classify(source: Path, protocol: str | None, as_json: bool, typed: Typed) -> None:
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
    from ..core.dispatch import prepare

    try:
        job = prepare("classify", typed, inputs=[source])
        result = job.analysis.run(source, job.options, protocol=protocol)
    except LabcliError as e:
        raise click.ClickException(str(e)) from None
    job.analysis.show(result, as_json=as_json)
