"""The one transaction that writes a fitted model: the model file, and its record in the run.

``labcli fit RUN.h5`` writes ``RUN.model.json`` beside the run and records the same JSON in
the run (``/models/<name>``).  Either both happen or neither: the run is opened for
writing before the model file is touched (a run locked by a viewer, or read-only, leaves
both files as they were), and a model file written for a run that then refuses the record
is put back as it was.
"""

from __future__ import annotations

from pathlib import Path

from ..errors import StoreError
from .files import atomic_write, check_output, replace_restorably
from .store import RunFile, space


def default_model_path(run: str | Path) -> Path:
    """``run.h5`` -> ``run.model.json`` beside it."""
    run = Path(run)
    return run.with_name(run.stem + ".model.json")


def check_fit_paths(run: str | Path, output: str | Path) -> None:
    """Refuse, before fitting, what would stop the model being saved or would destroy data.

    A run another labcli process is writing is refused in the lock's one sentence (rather
    than fitted on the trials it has so far, and refused at the end); the model file may not
    land on the input, on any other run file, or on anything but a regular file.
    """
    if space.writer_holds(str(run)):
        raise StoreError(f"{run} {space.BUSY}.")
    check_output(output, inputs=(run,), what="the model to ")


def save_model(text: str, path: str | Path, *, run: str | Path | None = None, name: str = "") -> bool:
    """Write the model JSON ``text`` to ``path`` and, given a run file, record it there as ``name``.

    Returns True when the model was recorded in the run.  Raises
    :class:`~labcli.errors.LabcliError` (one sentence) and leaves both files as they were
    when either cannot take it.
    """
    data = text.encode("utf-8")
    if run is None:
        atomic_write(path, data, what="the model to ")
        return False
    with RunFile.open(run, "a") as rf:
        restore = replace_restorably(path, data, what="the model to ")
        try:
            rf.models.record(name, text)
        except BaseException:
            restore()
            raise
    return True
