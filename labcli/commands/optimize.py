"""``labcli optimize``: link lengths of an rPAM joint that maximise its travel."""

from __future__ import annotations

import click

from ..core.options import Typed
from ..errors import LabcliError
from ._declared import paper_command, protocol_option


@paper_command("optimize")
@protocol_option("optimize", "Protocol to optimise: a .toml path or a shipped name  [default: {default}]")
@click.option("--json", "as_json", is_flag=True, help="Print the result as JSON on stdout.")
def optimize(protocol: str | None, as_json: bool, typed: Typed) -> None:
    """Maximise the joint angle of an rPAM joint over L1, L2, L3 (Section IV, g1-g7).

    Differential evolution, seeded and reproducible, stands in for the paper's genetic
    algorithm.  Besides g1-g7 the joint must hold: a stiffness of at least
    optimize.min_stiffness_Nm_per_rad and a margin to the toggle angle atan(L2/L3).
    Reports the optimum's angle, stiffness, margin, forces, moment arms and active
    constraints, with the links rounded to 0.1 mm as printed, beside the paper's design
    evaluated with the same model.

    \b
    Example:
        labcli optimize --protocol protocols/rpam2015.toml --seed 1
        labcli optimize --pa 110 --pb 41 --set actuator.L0_m=0.08 --json
        labcli optimize --force paper --min-stiffness 0.2
    """
    from ..core.dispatch import prepare

    try:
        job = prepare("optimize", typed, protocol=protocol)
        result = job.analysis.run(job.protocol, job.options)
    except LabcliError as e:
        raise click.ClickException(str(e)) from None
    job.analysis.show(result, as_json=as_json)
