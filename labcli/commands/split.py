"""``labcli split``: assign a run's completed trials to the fit and validation sets."""

from __future__ import annotations

import click

from ..errors import LabcliError


@click.command("split")
@click.argument("run", type=click.Path(dir_okay=False))
@click.option(
    "--fit",
    "n_fit",
    type=int,
    default=None,
    help="Trials in the fit set [default: the run's protocol's].",
)
@click.option(
    "--validation",
    "n_validation",
    type=int,
    default=None,
    help="Trials in the validation set [default: the run's protocol's].",
)
@click.option(
    "--strategy",
    type=click.Choice(["sequential", "random"]),
    default="sequential",
    show_default=True,
    help="sequential: first trials recorded fit, the next validate (the paper's); random: seeded draw.",
)
@click.option("--seed", type=int, default=None, help="Seed of the random draw [default: 0].")
def split(run: str, n_fit: int | None, n_validation: int | None, strategy: str, seed: int | None) -> None:
    """Assign RUN's completed trials to the fit and validation sets.

    The split is stored in the run file (``/split``, with its strategy and
    seed) and becomes the ``set`` column of the trial table.

    \b
    Example (the paper's 90 fit + 18 validation trials):
        labcli split run.h5 --fit 90 --validation 18
        labcli split run.h5 --fit 90 --validation 18 --strategy random --seed 7
    """
    from ..core.store import RunFile  # heavy: when the command runs, not for --help

    if seed is not None and strategy != "random":
        raise click.UsageError("--seed applies only to --strategy random.")
    try:
        with RunFile.open(run, "a") as rf:
            s = rf.split.assign(n_fit, n_validation, strategy, seed)
            total = len(rf.records.ids())
    except LabcliError as e:
        raise click.ClickException(str(e)) from None
    how = strategy if strategy == "sequential" else f"random, seed {s['seed']}"
    unassigned = total - len(s["fit"]) - len(s["validation"])
    click.echo(
        f"{run}: {len(s['fit'])} fit, {len(s['validation'])} validation, "
        f"{unassigned} unassigned of {total} completed trials ({how})."
    )
