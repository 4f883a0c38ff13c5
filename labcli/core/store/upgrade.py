"""Schema 1 to schema 2: a version-1 run opened for writing is copied into version 2 first.

The copy is built under a temporary name (:mod:`.space`) from what the version-1 reader
(:mod:`.v1`) gives: metadata, plan, every good record with its raw windows, the split and
the models; it replaces the old file only when whole, so a failed or killed upgrade leaves
the version-1 file as it was.  Warnings about damaged records met on the way are repeated
to the caller.
"""

from __future__ import annotations

import warnings
from types import SimpleNamespace
from typing import TYPE_CHECKING

import h5py

from ...errors import LabcliWarning
from .layout import extra_column

if TYPE_CHECKING:
    from .runfile import RunFile


def upgrade(cls: type[RunFile], path: str) -> RunFile:
    """Copy the version-1 run at ``path`` into version 2 (in a new file put in its place), open for writing."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", LabcliWarning)
        old = cls(h5py.File(path, "r", locking=False), path, "r")
        try:
            new = copy_v1(cls, old, path)
        finally:
            old.close()
    for w in caught:
        warnings.warn(w.message, stacklevel=3)
    new.publish()
    return new


def copy_v1(cls: type[RunFile], old: RunFile, path: str) -> RunFile:
    """A staged version-2 copy of the open version-1 run ``old`` (put in place by :meth:`RunFile.publish`)."""
    a = old.attrs
    rec = old.records.columns()
    cal = old.calibration()
    proto = SimpleNamespace(
        name=a.get("protocol", ""),
        text=old.protocol_text,
        kind=old.kind,
        path=None,
        channels=old.channels,
        calibration=None,
    )
    extras = [extra_column(name, list(rec.cols[name])) for name in rec.extras]
    device = SimpleNamespace(
        device=a.get("device", ""), firmware=a.get("firmware", ""), channels=old.channels, port=a.get("port", "")
    )
    new = cls.create(
        path,
        protocol=proto,
        device_info=device,
        port=a.get("port", ""),
        operator=a.get("operator", ""),
        plan=old.plan_table(),
        force=True,
        imported=bool(a.get("imported", False)),
        source=a.get("source", ""),
        started=a.get("started", ""),
        kind=old.kind,
        command_line="",
        extras=extras,
        rows_hint=len(rec.ids),
        calibration=(cal["gain"], cal["offset"], list(cal["units"])),
        staged=True,
    )
    try:
        for rid in rec.ids:
            new.records.write(old.records.read(rid))
        s = old.split.get()
        if s is not None:
            new.split.set(s["fit"], s["validation"], s["strategy"], s["seed"])
        for name, json_text in old.models.all().items():
            new.models.record(name, json_text)
    except BaseException:
        new.discard()
        raise
    return new
