"""``labcli split``: assign a run's (or a trial table's) completed trials to the fit and validation sets."""

from __future__ import annotations

import click

from ..errors import LabcliError
from ._declared import protocol_option


@click.command("split")
@click.argument("run", type=click.Path(dir_okay=False))
@click.option(
    "--fit",
    "n_fit",
    type=int,
    default=None,
    help="Trials (loads, for a run of several captures a load) in the fit set  [default: the run's protocol's; a shorter run keeps its proportion]",
)
@click.option(
    "--validation",
    "n_validation",
    type=int,
    default=None,
    help="Trials (loads) in the validation set  [default: the run's protocol's; or the proportion]",
)
@click.option(
    "--strategy",
    type=click.Choice(["sequential", "random"]),
    default="sequential",
    show_default=True,
    help="sequential: first trials recorded fit, the next validate (the paper's); random: seeded draw.",
)
@click.option("--seed", type=click.IntRange(0, 2**32 - 1), default=None, help="Seed of the random draw  [default: 0]")
@protocol_option(
    "split",
    "A trial CSV's protocol (name or .toml), for its default sizes  [default: {default}]; run files carry their own.",
)
@click.option(
    "-o",
    "--output",
    type=click.Path(dir_okay=False),
    default=None,
    help="A trial CSV's table with its set column filled  [default: the CSV itself]",
)
def split(
    run: str,
    n_fit: int | None,
    n_validation: int | None,
    strategy: str,
    seed: int | None,
    protocol: str | None,
    output: str | None,
) -> None:
    """Assign the completed trials of RUN (a run file or a trial CSV) to the fit and validation sets.

    A run file stores the split (``/split``, with its strategy and seed; earlier
    splits stay as its history) and shows it as the ``set`` column of its trial
    table.  A trial CSV gets its ``set`` column filled (in place, or in -o OUT.csv).
    Without --fit and --validation the protocol's sizes are used (the paper's 90 +
    18); a shorter run is split in the same proportion, and the output says so.
    A run of several captures a load (acquisition.captures_per_load) is split by
    load: the sizes count loads and each set takes every capture of its loads.

    \b
    Example (the paper's 90 fit + 18 validation trials):
        labcli split run.h5
        labcli split run.h5 --fit 90 --validation 18 --strategy random --seed 7
        labcli split trials.csv -o trials-split.csv
    """
    from ..core.splitting import split as split_run  # heavy: when the command runs, not for --help

    if seed is not None and strategy != "random":
        raise click.UsageError("--seed applies only to --strategy random.")
    try:
        done = split_run(run, n_fit, n_validation, strategy, seed, protocol=protocol, output=output)
    except LabcliError as e:
        raise click.ClickException(str(e)) from None
    click.echo(done.sentence())
