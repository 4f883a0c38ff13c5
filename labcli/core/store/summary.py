"""What ``labcli inspect`` shows of a run: metadata, completeness, split, settling.

The record type adds what is its own (:meth:`labcli.core.paper.RecordType.summarise`:
the baseline's drift over a McKibben run, an rPAM run's grid).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

from ..protocol import run_captures
from .unused import counts as unused_counts
from .unused import describe

if TYPE_CHECKING:
    from .runfile import RunFile


def summarise(run: RunFile) -> dict[str, Any]:
    """The summary of an open :class:`~labcli.core.store.RunFile` as plain data (JSON-ready)."""
    rt = run.record_type
    a = run.attrs
    rec = run.records.columns()
    ids = list(rec.ids)
    incomplete = run.records.incomplete_ids()
    plan = run.plan_table()
    out: dict[str, Any] = {
        "path": run.path,
        "schema_version": a.get("schema_version"),
        "labcli_version": a.get("labcli_version", ""),
        "kind": a.get("kind", ""),
        "protocol": a.get("protocol", ""),
        "device": a.get("device", ""),
        "firmware": a.get("firmware", ""),
        "port": a.get("port", ""),
        "operator": a.get("operator", ""),
        "started": a.get("started", ""),
        "imported": bool(a.get("imported", False)),
        "channels": list(run.channels),
        "records": rt.collection,
        "complete": len(ids),
        "incomplete": len(incomplete),
        "incomplete_ids": incomplete,
        "planned": None if plan is None else int(len(plan)),
        "split": None,
        "baseline_drift": None,  # how the baseline moved over the records, where the record type says
        "settle": None,
        "models": run.models.names(),
    }
    # A record is one capture of a plan trial (acquisition.captures_per_load, which fit averages by, a
    # plan or not: an imported export): counted as such.
    n = run_captures(run.protocol_text, run.path)
    noun = "capture" if n > 1 else rt.noun
    if n > 1:
        out.update(records="captures", captures_per_load=n)
        if plan is not None:
            out["planned"] = int(len(plan)) * n
    if run.version >= 2:
        out["run_uid"] = a.get("run_uid", "")
        out["sessions"] = len(run.sessions.all())
        unused = run.windows.unused()
        if unused:  # raw frames of a redone, skipped or interrupted record: said, never read as one
            by = unused_counts(unused)
            out["unused_frames"] = {"total": sum(by.values()), "by_reason": by, "text": describe(unused, noun)}
        notes = run.notes.all()
        if notes:  # only an annotated run says so: the summary of any other is as it was
            out["notes"] = [
                {**note, "about": "the run" if note["record"] is None else f"{noun} {note['record']}"} for note in notes
            ]
    if rec.damaged:
        out["damaged"] = [f"{what}: {why}" for what, why in rec.damaged]
    s = run.split.get()
    if s is not None:
        out["split"] = {
            "strategy": s["strategy"],
            "seed": s["seed"],
            "fit": len(s["fit"]),
            "validation": len(s["validation"]),
            "unassigned": len(set(ids) - set(s["fit"]) - set(s["validation"])) if rt.splits else 0,
        }
    out.update(rt.summarise(run, ids, rec.cols))
    out["settle"] = _settling(ids, rec.cols)
    return out


def record_noun(run: RunFile) -> str:
    """What one record of ``run`` is called in sentences: a capture in a run of several captures of each
    plan trial (``acquisition.captures_per_load``), else its record type's noun (as :func:`summarise`)."""
    return "capture" if run_captures(run.protocol_text, run.path) > 1 else run.record_type.noun


def _settling(ids: list[int], cols: dict[str, Any]) -> dict[str, Any]:
    times = np.asarray(cols["loaded_settle_time_s"], dtype=np.float64)
    accepted = [str(x) for x in cols["accepted"]]
    finite = times[np.isfinite(times)]
    return {
        "n": int(finite.size),
        "median_s": float(np.median(finite)) if finite.size else None,
        "max_s": float(np.max(finite)) if finite.size else None,
        "timeout_accepted": int(sum(x == "timeout" for x in accepted)),
        "timeout_ids": [i for i, x in zip(ids, accepted, strict=False) if x == "timeout"],
    }
