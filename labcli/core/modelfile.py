"""Where a fitted model goes, and which model an analysis applies.

Writing: ``labcli fit RUN.h5`` writes ``RUN.model.json`` beside the run and records the same
JSON in the run (``/models/<name>``, the model in force).  ``-o M.json`` writes M.json only
(the run file is not touched) unless ``--record`` asks for the record too.  Recording is
one transaction: the run is opened for writing before the model file is touched (a run
locked by a viewer, or read-only, leaves both files as they were), and a model file written
for a run that then refuses the record is put back as it was.

Reading (:func:`model_text`), one precedence everywhere: an explicit ``--model`` file, else
the model the run records in force (``/models/<name>``), else the file ``RUN.model.json``
beside the run (for a table, the only place there is).
"""

from __future__ import annotations

from pathlib import Path

from ..errors import ConfigError, ModelError, StoreError
from .files import atomic_write, check_model_output, check_output, replace_restorably
from .store import RunFile, space


def default_model_path(run: str | Path) -> Path:
    """``run.h5`` -> ``run.model.json`` beside it."""
    run = Path(run)
    return run.with_name(run.stem + ".model.json")


MODEL_PRECEDENCE = (
    "an explicit --model, else the model the run records in force (/models/<name>), else RUN.model.json beside the run"
)


def model_destination(
    run: str | Path, output: str | Path | None, record: bool | None, is_run: bool
) -> tuple[Path, bool]:
    """The model file a fit writes and whether the run records the model too.

    Without ``output``: ``RUN.model.json``, recorded in a run file.  With ``output``: that
    file only, unless ``record``.  ``record`` on a table is refused: it has nowhere to keep one.
    """
    if record and not is_run:
        raise ConfigError(
            f"--record keeps the model in a run file, and {run} is a table; leave --record out "
            "(the model goes to the file -o names)."
        )
    path = Path(output) if output is not None else default_model_path(run)
    keep = is_run and (record if record is not None else output is None)
    return path, keep


def model_text(run: str | Path, explicit: str | Path | None, is_run: bool, name: str) -> tuple[str | None, str]:
    """The JSON text of the model to apply to ``run`` and where it came from (a label for the report).

    See :data:`MODEL_PRECEDENCE`.  The text is None for a model file (explicit or beside the
    run) so that the caller reads it with its own one-sentence errors; the label is then the
    file's path, else ``run.h5:/models/<name>``.
    """
    if explicit is not None:
        return None, str(explicit)
    side = default_model_path(run)
    if is_run:
        with RunFile.open(run) as rf:
            recorded = rf.models.get(name)
        if recorded is not None:
            return recorded, f"{run}:/models/{name}"
        if not side.exists():
            raise ModelError(
                f"{run} records no model under /models/{name} and the model file {side} does not exist; "
                f"write one with `labcli fit {run}`."
            )
    return None, str(side)


def check_fit_paths(run: str | Path, output: str | Path, protocol: str | None = None) -> None:
    """Refuse, before fitting, what would stop the model being saved or would destroy data.

    A run another labcli process is writing is refused in the lock's one sentence (rather
    than fitted on the trials it has so far, and refused at the end); the model file may not
    land on an input (the run or table, a protocol given as a file), on any other run file, or on anything but a regular file.
    """
    if space.writer_holds(str(run)):
        raise StoreError(f"{run} {space.BUSY}.")
    check_output(output, inputs=(run, protocol), what="the model to ")
    check_model_output(output)


def save_model(
    text: str, path: str | Path, *, run: str | Path | None = None, name: str = "", record: bool = True
) -> bool:
    """Write the model JSON ``text`` to ``path`` and, given a run file and ``record``, record it there as ``name``.

    Returns True when the model was recorded in the run.  Raises
    :class:`~labcli.errors.LabcliError` (one sentence) and leaves both files as they were
    when either cannot take it.
    """
    data = text.encode("utf-8")
    if run is None or not record:
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
