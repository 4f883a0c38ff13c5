"""``labcli demo``: the whole paper on the simulated rig, with no hardware and no questions."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import click

from ..core.registry import default_protocol, demo_protocols, for_shipped_protocol
from ..errors import LabcliError
from ._options import seed_option


@click.command("demo")
@click.argument("outdir", default="labcli-demo", type=click.Path(file_okay=False, path_type=Path))
@seed_option("Seed of the simulated rig (labcli sim serves the same rig by default).")
@click.option("--force", is_flag=True, help="Overwrite earlier demo output in OUTDIR.")
@click.option("--json", "as_json", is_flag=True, help="Print the summary as JSON.")
@click.option(
    "--protocol",
    type=click.Choice(demo_protocols()),
    default=default_protocol("demo"),
    show_default=True,
    help="Which paper's demo: the demo protocol it ships.",
)
def demo(outdir: Path, seed: int, force: bool, as_json: bool, protocol: str) -> None:
    """Run the whole paper on the simulated rig: no hardware, no questions.

    Acquires the 108 force trials of the shipped plan unattended, splits them
    90/18, fits Eqs. 34-37, validates them (Figure 7), pushes six simulated
    objects ten times each, classifies them (Figure 9) and prints one summary.
    Everything lands in OUTDIR (default ./labcli-demo).  With --protocol rpam2015:
    the rPAM paper's stretch test, the fitted stretch correction (Fig. 6), the joint
    map against the model without and with it (Fig. 8) and the link optimisation.

    \b
    Example:
        labcli demo out/
        labcli demo out/ --seed 7 --force --json
        labcli demo out/ --protocol rpam2015
    """
    try:
        owner = for_shipped_protocol(protocol)
    except LabcliError as e:
        raise click.ClickException(str(e)) from None
    paper = owner.demo()
    if paper is None:
        raise click.ClickException(
            f"{owner.name} has no demo; labcli demo --protocol takes {', '.join(demo_protocols())}."
        )
    show = sys.stderr.isatty() and not as_json

    def progress(stage: str, done: int, total: int) -> None:
        if not show:
            return
        n = paper.stages.index(stage) + 1
        count = f" {done}/{total}" if total else ""
        click.echo(f"\r[{n}/{len(paper.stages)}] {stage}{count}".ljust(60), nl=False, err=True)

    try:
        result = paper.run(outdir, seed=seed, force=force, progress=progress)
    except LabcliError as e:
        raise click.ClickException(str(e)) from None
    if show:
        click.echo("\r" + " " * 60 + "\r", nl=False, err=True)
    if as_json:
        click.echo(json.dumps(result.to_dict(), indent=2))
        return
    paper.show(result)
