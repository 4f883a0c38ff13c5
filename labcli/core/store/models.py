"""``run.models``: the fitted models a run keeps, as JSON text under a name.

The model log is an append-only table (:mod:`.columns`), one row per model recorded; each
model's JSON lives in a blob beside it (:mod:`.blobs`), written before its row and checked
against the row's checksum when read.  The last good row of a name is the model in force;
earlier ones stay, as the run's history.

>>> run.models.record("posture", model.to_json())   # doctest: +SKIP
>>> run.models.names()                               # doctest: +SKIP
['posture']
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import h5py
import numpy as np

from ...errors import StoreError
from ..timestamps import utc_now
from ..version import __version__
from .blobs import blob_read, blob_write, cell_text
from .columns import Table
from .layout import MODEL_COLUMNS

if TYPE_CHECKING:
    from .runfile import RunFile

NAME_BYTES = 64


class Models:
    """``run.models`` (see the module docstring)."""

    def __init__(self, run: RunFile) -> None:
        self._run = run

    def all(self) -> dict[str, str]:
        """Model name -> JSON text, as recorded (the last of each name)."""
        run = self._run
        if run.v1 is not None:
            return run.v1.models()
        out, problems = run.read_checked(
            lambda: read_models(run.tables.models), "its recorded models", lambda got: bool(got[1])
        )
        if problems:
            run.warn(f"{run.path}: {problems[0]}; it is left out.")
        return out

    def get(self, name: str) -> str | None:
        """The JSON text of model ``name``, or None when the run has no model of that name."""
        return self.all().get(name)

    def names(self) -> list[str]:
        """The names of the recorded models, sorted."""
        return sorted(self.all())

    def record(self, name: str, json_text: str) -> None:
        """Store a fitted model's parameters (JSON text) as ``name`` (the one in force from now on)."""
        run = self._run
        run.writer.check()
        if not name or "/" in name or name.startswith(".") or len(name.encode()) > NAME_BYTES:
            raise StoreError(f"model name {name!r} must be non-empty, at most 64 bytes and contain no '/'.")
        run.check_v2("a model")
        t = run.tables.models
        run.writer.commit_row(
            t,
            {c.name: c for c in MODEL_COLUMNS},
            lambda: model_row(t.g, name, str(json_text), __version__),
            len(json_text.encode()),
            f"the model {name}",
        )


def model_row(g: h5py.Group, name: str, json_text: str, version: str) -> dict[str, object]:
    """Write the model's JSON to the blob; the row that refers to it (not yet committed)."""
    data = np.frombuffer(json_text.encode("utf-8"), dtype=np.uint8)
    start, stop, checksum = blob_write(g["json"], data)
    return {
        "name": name,
        "created": utc_now(),
        "labcli_version": version,
        "json_start": start,
        "json_stop": stop,
        "json_checksum": checksum,
    }


def read_models(t: Table) -> tuple[dict[str, str], list[str]]:
    """Model name -> JSON text of the last good row of each name, and what was found damaged."""
    rows = t.read()
    problems = [f"model row {r}: {why}" for r, why in rows.damaged]
    out: dict[str, str] = {}
    c = rows.cols
    for i in range(len(rows.rows)):
        name = cell_text(c["name"][i])
        a, b = int(c["json_start"][i]), int(c["json_stop"][i])
        data = blob_read(t.g, "json", a, b, int(c["json_checksum"][i]))
        if data is None:
            problems.append(
                f"the JSON of model {name} recorded {cell_text(c['created'][i])} does not match its checksum"
            )
            continue
        out[name] = data.tobytes().decode("utf-8")
    return out, problems
