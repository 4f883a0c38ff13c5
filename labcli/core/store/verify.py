"""``labcli inspect --verify``: every record, raw window, log entry and the metadata, checked.

Schema 2 carries checksums for all of it (row checksums, window checksums, HDF5's
Fletcher32 on every chunk, a checksum over the attributes); schema 1 carries none, so for
such a file verifying means that everything can be read and holds values of the right
shape and range.
"""

from __future__ import annotations

import warnings
from typing import TYPE_CHECKING, Any

from ...errors import LabcliError, LabcliWarning
from .columns import Table

if TYPE_CHECKING:
    from .runfile import RunFile


def verify(run: RunFile) -> dict[str, Any]:
    """``{"ok", "records", "windows", "problems": [sentence, ...]}`` for an open run file."""
    try:
        return _verify(run)
    except Exception as e:  # noqa: BLE001 - a damaged object header can fail in any way
        why = str(e).strip("'\"").split(" (")[0] or type(e).__name__
        return {
            "ok": False,
            "records": 0,
            "windows": 0,
            "problems": [f"the file's structure: HDF5 cannot read it ({why})"],
        }


def _verify(run: RunFile) -> dict[str, Any]:
    problems: list[str] = []
    if not run._metadata_ok():  # warned of when the file was opened, before these checks began
        problems.append(
            "metadata: the attributes of the run's groups and datasets do not match their checksum, or cannot be read"
        )
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", LabcliWarning)
        try:
            rec = run.records.columns()
        except LabcliError as e:
            return {"ok": False, "records": 0, "windows": 0, "problems": [str(e)]}
        problems += [f"{what}: {why}" for what, why in rec.damaged]
        windows = 0
        for i in range(len(rec.ids)):
            for name in ("baseline", "loaded"):
                if run.version >= 2 and int(rec.cols[f"{name}_start"][i]) < 0:
                    continue
                before = len(caught)
                try:
                    w = run.windows.of_record(rec, i, name)
                except Exception:  # noqa: BLE001 - a damaged schema-1 group can fail in any way
                    problems.append(f"{run.record_type.noun} {rec.ids[i]}: its {name} window cannot be read")
                    continue
                if w is not None:
                    windows += 1
                elif len(caught) > before:
                    problems.append(f"{run.record_type.noun} {rec.ids[i]}: its {name} window fails its checksum")
        for what, read in (
            ("split", run.split.get),
            ("models", run.models.all),
            ("sessions", run.sessions.all),
            ("unused raw frames", run.windows.unused),
            ("plan", run.plan_table),
            ("protocol", lambda: run.protocol_text),
            ("calibration", run.calibration),
            ("metadata", lambda: run.attrs),
        ):
            try:
                read()
            except LabcliError as e:
                problems.append(f"{what}: {e}")
        if run.version >= 2 and "plan" in run.h5["entry"]:
            problems += [f"plan row {r}: {why}" for r, why in Table(run.h5["entry/plan"]).read().damaged]
    for warning in caught:
        message = str(warning.message)
        if any(k in message for k in ("metadata", "split", "model", "session", "raw/unused")):
            problems.append(message.split(": ", 1)[-1])
    return {"ok": not problems, "records": len(rec.ids), "windows": windows, "problems": list(dict.fromkeys(problems))}
