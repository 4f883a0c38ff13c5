"""``labcli note``: a note about a run, or one of its trials, kept in the run file."""

from __future__ import annotations

import click

from ..errors import LabcliError


@click.command("note")
@click.argument("run", type=click.Path(dir_okay=False))
@click.argument("text", required=False)
@click.option(
    "--trial",
    "record",
    type=int,
    default=None,
    help="The trial (push, point) the note is about  [default: the run]",
)
def note(run: str, text: str | None, record: int | None) -> None:
    """Keep TEXT as a note in RUN (about the run, or one trial with --trial); without TEXT, list RUN's notes.

    Notes are added, never changed or removed; each keeps when it was written.
    ``labcli inspect`` shows them, ``labcli export`` writes a trial's notes in a
    ``note`` column and the run's in the table's description, and ``labcli runs``
    lists how many a run has.  At the rig, ``n`` at a trial's review notes that trial.

    \b
    Example:
        labcli note run.h5 "valve 2 replaced before trial 40"
        labcli note run.h5 --trial 12 "the weight swung; redone by hand"
        labcli note run.h5
    """
    from ..core.store import RunFile  # heavy: when the command runs, not for --help
    from ..core.store.summary import record_noun

    try:
        with RunFile.open(run, "r" if text is None else "a") as rf:
            if text is None:
                noun, notes = record_noun(rf), rf.notes.all()
            else:
                noun, added = record_noun(rf), rf.notes.add(text, record)
    except LabcliError as e:
        raise click.ClickException(str(e)) from None
    if text is not None:
        about = "the run" if added["record"] is None else f"{noun} {added['record']}"
        click.echo(f"{run}: note on {about} kept ({added['time']}).")
        return
    if not notes:
        click.echo(f'{run} has no notes; add one with: labcli note {run} "..."')
    for n in notes:
        about = "run" if n["record"] is None else f"{noun} {n['record']}"
        click.echo(f"{n['time']}  {about}: {n['text']}")
