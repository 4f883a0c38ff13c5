"""``labcli optimize``: link lengths of an rPAM joint that maximise its travel."""

from __future__ import annotations

import click

from ..core.dispatch import for_analysis
from ..errors import LabcliError

DEFAULT_PROTOCOL = "rpam2015"


def _kpa(value: float | None, name: str) -> float | None:
    if value is not None and not value == value:  # NaN typed on the command line
        raise click.BadParameter("must be a number of kPa", param_hint=name)
    if value is not None and not 0 <= value < float("inf"):
        # Gauge pressure: a muscle cannot be driven below atmosphere.
        raise click.BadParameter(f"{value:g} is not a gauge pressure; give 0 kPa or more.", param_hint=name)
    return value


SEED_MAX = 2**32 - 1  # the search's random generator takes seeds 0 to 2**32 - 1


def _seed(ctx: click.Context, param: click.Parameter, value: int | None) -> int | None:
    if value is not None and not 0 <= value <= SEED_MAX:
        raise click.BadParameter(f"{value} is outside the seed's range; give a whole number from 0 to {SEED_MAX}.")
    return value


@click.command()
@click.option(
    "--protocol",
    "protocol",
    default=DEFAULT_PROTOCOL,
    show_default=True,
    help="rPAM protocol: a .toml path or a shipped name.",
)
@click.option("--seed", type=int, default=None, callback=_seed, help="Seed of the search (default: the protocol's).")
@click.option(
    "--pa",
    "pa_kpa",
    type=float,
    default=None,
    metavar="KPA",
    help="Pressure of actuator a, kPa (default: the protocol's, 96).",
)
@click.option(
    "--pb",
    "pb_kpa",
    type=float,
    default=None,
    metavar="KPA",
    help="Pressure of actuator b, kPa (default: the protocol's, 41).",
)
@click.option(
    "--set",
    "overrides",
    multiple=True,
    metavar="KEY=VALUE",
    help="Override any protocol value, e.g. --set actuator.L0_m=0.08 (repeatable).",
)
@click.option(
    "--force",
    "force",
    type=click.Choice(["derived", "paper"]),
    default=None,
    help="Reading of the actuator force (Eqs. 1-3): derived (the cage-held wall's energy and the gas's "
    "virtual work) or paper (the lumen's free body: cage term + P A0/lambda + Eq. 3) "
    "[default: the protocol's actuator.force_reading].",
)
@click.option(
    "--min-stiffness",
    "min_stiffness",
    type=float,
    default=None,
    metavar="NM_PER_RAD",
    help="Least joint stiffness at the balance, N m/rad (default: the protocol's "
    "optimize.min_stiffness_Nm_per_rad, 0.07).",
)
@click.option("--json", "as_json", is_flag=True, help="Print the result as JSON on stdout.")
def optimize(
    protocol: str,
    seed: int | None,
    pa_kpa: float | None,
    pb_kpa: float | None,
    overrides: tuple[str, ...],
    force: str | None,
    min_stiffness: float | None,
    as_json: bool,
) -> None:
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
    _kpa(pa_kpa, "--pa")
    _kpa(pb_kpa, "--pb")
    if min_stiffness is not None and not (0 < min_stiffness < float("inf")):
        # A joint with no stiffness holds nothing; nan compares as neither.
        raise click.BadParameter(
            f"{min_stiffness:g} is not a stiffness a joint can hold with; give a number of N m/rad above 0.",
            param_hint="--min-stiffness",
        )
    try:
        analysis = for_analysis("optimize", default_protocol=DEFAULT_PROTOCOL).analysis("optimize")
        result = analysis.run(
            protocol,
            seed=seed,
            pa_kpa=pa_kpa,
            pb_kpa=pb_kpa,
            overrides=overrides,
            force=force,
            min_stiffness=min_stiffness,
        )
    except LabcliError as e:
        raise click.ClickException(str(e)) from None
    analysis.show(result, as_json=as_json)
