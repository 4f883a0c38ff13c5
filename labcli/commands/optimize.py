"""``labcli optimize``: link lengths of an rPAM joint that maximise its travel."""

from __future__ import annotations

import json

import click

from ..errors import LabcliError


def _kpa(value: float | None, name: str) -> float | None:
    if value is not None and not value == value:  # NaN typed on the command line
        raise click.BadParameter("must be a number of kPa", param_hint=name)
    if value is not None and not 0 <= value < float("inf"):
        # Gauge pressure: a muscle cannot be driven below atmosphere.
        raise click.BadParameter(f"{value:g} is not a gauge pressure; give 0 kPa or more.", param_hint=name)
    return value


@click.command()
@click.option("--protocol", "protocol", default="rpam2015", show_default=True,
              help="rPAM protocol: a .toml path or a shipped name.")
@click.option("--seed", type=int, default=None, help="Seed of the search (default: the protocol's).")
@click.option("--pa", "pa_kpa", type=float, default=None, metavar="KPA", help="Pressure of actuator a, kPa (default: the protocol's, 96).")
@click.option("--pb", "pb_kpa", type=float, default=None, metavar="KPA", help="Pressure of actuator b, kPa (default: the protocol's, 41).")
@click.option("--set", "overrides", multiple=True, metavar="KEY=VALUE",
              help="Override any protocol value, e.g. --set actuator.L0_m=0.08 (repeatable).")
@click.option("--json", "as_json", is_flag=True, help="Print the result as JSON on stdout.")
def optimize(protocol: str, seed: int | None, pa_kpa: float | None, pb_kpa: float | None,
             overrides: tuple[str, ...], as_json: bool) -> None:
    """Maximise the joint angle of an rPAM joint over L1, L2, L3 (Section IV, g1-g7).

    Differential evolution, seeded and reproducible, stands in for the paper's genetic
    algorithm.  Reports the optimum, the constraints at their bounds and the distance to
    the toggle angle atan(L2/L3).

    \b
    Example:
        labcli optimize --protocol protocols/rpam2015.toml --seed 1
        labcli optimize --pa 110 --pb 41 --set actuator.L0_m=0.08 --json
    """
    from rich.console import Console
    from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn

    from ..experiments.rpam2015.models.rpam_optimize import optimize_protocol

    _kpa(pa_kpa, "--pa")
    _kpa(pb_kpa, "--pb")
    err = Console(stderr=True)
    progress = Progress(
        TextColumn("[bold]optimising[/bold] gen {task.completed:>3.0f}"),
        BarColumn(bar_width=16),
        TextColumn("{task.fields[best]}"),
        TimeElapsedColumn(),
        console=err,
        transient=True,
        disable=not err.is_terminal,
    )
    task = progress.add_task("de", total=None, best="")

    def report(generation: int, best: dict[str, float]) -> None:
        alpha = best["alpha_deg"]
        text = "no feasible design yet" if alpha != alpha else (
            f"best alpha {alpha:5.2f} deg at L1 {best['L1_m']:.4f}, L2 {best['L2_m']:.4f}, "
            f"L3 {best['L3_m']:.4f} m"
        )
        progress.update(task, completed=generation, total=best["maxiter"], best=text)

    try:
        with progress:
            result = optimize_protocol(protocol, overrides=overrides, seed=seed, Pa_kPa=pa_kpa,
                                       Pb_kPa=pb_kpa, progress=report)
    except LabcliError as e:
        raise click.ClickException(str(e)) from None

    d = result.to_dict()
    if as_json:
        click.echo(json.dumps(d, indent=2))
        return
    click.echo(f"Optimum at Pa = {d['Pa_kPa']:g} kPa, Pb = {d['Pb_kPa']:g} kPa (seed {d['seed']}, "
               f"{d['generations']} generations):")
    click.echo(f"  L1    = {d['L1_m']:.4f} m")
    click.echo(f"  L2    = {d['L2_m']:.4f} m")
    click.echo(f"  L3    = {d['L3_m']:.4f} m")
    click.echo(f"  alpha = {d['alpha_deg']:.2f} deg")
    click.echo(f"  L_a   = {d['L_a_m']:.4f} m, L_b = {d['L_b_m']:.4f} m")
    click.echo(f"  toggle angle atan(L2/L3) = {d['toggle_deg']:.2f} deg, "
               f"{d['toggle_margin_deg']:.3g} deg beyond the optimum")
    active = d["active_constraints"]
    click.echo("  active constraints: " + ("; ".join(active) if active else "none (interior optimum)"))
