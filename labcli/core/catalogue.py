"""``labcli runs``: every run file under a folder, one row each, read and never written.

A row says what a lab asks of a run before opening it: its uid, kind, protocol, rig,
operator, start, how many records are complete of those planned, its split, its models,
its notes and whether it checks out.  Without ``verify`` the check is the one every open
does (the metadata's and every row's checksum); with it, every raw window too
(``labcli inspect --verify``).  A file that does not open as a run is listed with the
sentence that says why; nothing under the folder is changed.
"""

from __future__ import annotations

import os
import warnings
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

from ..errors import ConfigError, LabcliError, LabcliWarning
from .files import RUN_FILE_SUFFIXES


@dataclass(frozen=True)
class RunEntry:
    """One run file in the catalogue (``status``: ok, verified, damaged, or not a run)."""

    file: str  # relative to the folder listed
    status: str  # "ok", "verified", "damaged", "not a run"
    problem: str = ""  # the first thing found wrong, one sentence
    uid: str = ""
    kind: str = ""
    protocol: str = ""
    rig: str = ""  # device and firmware
    operator: str = ""
    started: str = ""
    records: str = ""  # "trials", "pushes", "points"
    complete: int | None = None
    planned: int | None = None
    split: dict[str, Any] | None = None
    models: list[str] = field(default_factory=list)
    notes: int = 0
    imported: bool = False

    def as_dict(self) -> dict[str, Any]:
        return asdict(self)


def run_files(folder: str | os.PathLike) -> list[Path]:
    """The run files (``.h5``, ``.hdf5``) under ``folder``, at any depth, in path order."""
    root = Path(folder)
    if not root.is_dir():
        what = "does not exist" if not root.exists() else "is not a folder"
        raise ConfigError(f"{root} {what}; give the folder whose run files to list.")
    found = [p for p in root.rglob("*") if p.suffix.lower() in RUN_FILE_SUFFIXES and p.is_file()]
    return sorted(found, key=lambda p: p.relative_to(root).parts)


def catalogue(folder: str | os.PathLike, *, verify: bool = False) -> list[RunEntry]:
    """One :class:`RunEntry` per run file under ``folder`` (see the module docstring)."""
    root = Path(folder)
    return [entry(p, str(p.relative_to(root)), verify=verify) for p in run_files(root)]


def entry(path: Path, name: str, *, verify: bool = False) -> RunEntry:
    """The catalogue's row of one file, opened read-only."""
    from .store import RunFile

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", LabcliWarning)
        try:
            with RunFile.open(path) as run:
                s = run.summary()
                report = run.verify() if verify else None
                notes = len(run.notes.all())
        except LabcliError as e:
            return RunEntry(name, "not a run", str(e).removeprefix(f"{path} "))
    said = [str(w.message) for w in caught if issubclass(w.category, LabcliWarning)]
    problems = list(report["problems"]) if report is not None else [*s.get("damaged", []), *said]
    problems = [p.removeprefix(f"{path}: ") for p in problems]  # the row names the file already
    status = "damaged" if problems else ("verified" if verify else "ok")
    device = str(s.get("device") or "")
    return RunEntry(
        name,
        status,
        problems[0] if problems else "",
        uid=str(s.get("run_uid", "")),
        kind=str(s.get("kind", "")),
        protocol=str(s.get("protocol", "")),
        rig=f"{device} {s.get('firmware') or ''}".strip() if device else "",
        operator=str(s.get("operator") or ""),
        started=str(s.get("started") or ""),
        records=str(s.get("records", "")),
        complete=int(s["complete"]),
        planned=s.get("planned"),
        split=s.get("split"),
        models=list(s.get("models", [])),
        notes=notes,
        imported=bool(s.get("imported", False)),
    )
