"""A run's logs: the splits assigned, the models recorded, and the sessions that recorded it.

Each is an append-only table (:mod:`.columns`); what a row refers to (a split's ids, a
model's JSON) lives in a blob dataset beside it, written at a chunk boundary before the
row, with its checksum in the row.  The last committed row of a split (of a model name) is
the one in force; earlier ones stay, as the run's history.  Writing one is a commit like a
record's: everything new first, then ``@committed``; a failure part-way leaves the log as it
was.

The session log has one row per event of an acquisition session:

=========  ================================================================================
event      what the row holds
=========  ================================================================================
begin      time, port, baud, the rig's ID reply (device, firmware, channels), the
           calibration in force (gain, offset per channel), command line, host name
added      a record stored in this session (``record``)
redone     a record the experimenter chose to redo
skipped    a record skipped
end        time and how the session ended (``how``: finished, quit, interrupted, rig lost,
           no input, ...), and a note
=========  ================================================================================

A session without an ``end`` row ended without a word (a kill, a power cut).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import h5py
import numpy as np

from ...errors import StoreError
from .checksum import row_checksums
from .columns import Table, append
from .h5 import text
from .layout import now_iso

HOW = ("finished", "quit", "interrupted", "rig lost", "no input", "disk full", "error")


def blob_write(ds: h5py.Dataset, values: np.ndarray) -> tuple[int, int, int]:
    """Append ``values`` to a blob at its next chunk boundary: (start, stop, checksum)."""
    chunk = ds.chunks[0]
    start = -(-int(ds.shape[0]) // chunk) * chunk
    append(ds, start, np.asarray(values, dtype=ds.dtype))
    return start, start + len(values), blob_checksum(values)


def blob_checksum(values: np.ndarray) -> int:
    v = np.ascontiguousarray(values)
    return int(row_checksums([v.view(np.uint8).reshape(1, -1)], 0)[0])


def blob_read(ds: h5py.Dataset, start: int, stop: int, checksum: int) -> np.ndarray | None:
    """The blob's values ``[start, stop)``, or None when they do not match their checksum."""
    try:
        if not 0 <= start <= stop <= ds.shape[0]:
            return None
        values = ds[start:stop]
    except (OSError, ValueError, RuntimeError):
        return None
    return values if blob_checksum(values) == int(checksum) else None


def _s(v: Any) -> str:
    return text(v).rstrip("\x00") if isinstance(v, (bytes, np.bytes_)) else str(v)


# --------------------------------------------------------------------------- split


def split_row(
    g: h5py.Group, fit: Sequence[int], validation: Sequence[int], strategy: str, seed: int | None
) -> dict[str, Any]:
    """Write the split's ids to the blob; the row that refers to them (not yet committed)."""
    ids = np.asarray([*fit, *validation], dtype=np.int64)
    start, stop, checksum = blob_write(g["ids"], ids)
    mid = start + len(fit)
    return {
        "strategy": strategy,
        "seed": -1 if seed is None else int(seed),
        "created": now_iso(),
        "fit_start": start,
        "fit_stop": mid,
        "validation_start": mid,
        "validation_stop": stop,
        "ids_checksum": checksum,
    }


def read_split(t: Table) -> tuple[dict[str, Any] | None, list[str]]:
    """The split in force (the last good row) and what was found damaged."""
    rows = t.read()
    problems = [f"split row {r}: {why}" for r, why in rows.damaged]
    c = rows.cols
    for i in range(len(rows.rows) - 1, -1, -1):
        a, m, b = int(c["fit_start"][i]), int(c["fit_stop"][i]), int(c["validation_stop"][i])
        ids = blob_read(t.g["ids"], a, b, int(c["ids_checksum"][i]))
        if ids is None:
            problems.append(f"the ids of split {i + 1} do not match their checksum")
            continue
        seed = int(c["seed"][i])
        return {
            "fit": [int(x) for x in ids[: m - a]],
            "validation": [int(x) for x in ids[m - a :]],
            "strategy": _s(c["strategy"][i]),
            "seed": None if seed < 0 else seed,
            "created": _s(c["created"][i]),
        }, problems
    return None, problems


# --------------------------------------------------------------------------- models


def model_row(g: h5py.Group, name: str, json_text: str, version: str) -> dict[str, Any]:
    data = np.frombuffer(json_text.encode("utf-8"), dtype=np.uint8)
    start, stop, checksum = blob_write(g["json"], data)
    return {
        "name": name,
        "created": now_iso(),
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
        name = _s(c["name"][i])
        data = blob_read(t.g["json"], int(c["json_start"][i]), int(c["json_stop"][i]), int(c["json_checksum"][i]))
        if data is None:
            problems.append(f"the JSON of model {name} recorded {_s(c['created'][i])} does not match its checksum")
            continue
        out[name] = data.tobytes().decode("utf-8")
    return out, problems


# --------------------------------------------------------------------------- sessions


def begin_event(number: int, info: Any, host_name: str) -> dict[str, Any]:
    """The ``begin`` row of session ``number`` from a :class:`labcli.core.sessionlog.SessionInfo`."""
    rig = info.rig
    return {
        "session": number,
        "event": "begin",
        "time": cut(str(info.started or now_iso()), 40),
        "port": cut(info.port, 256),
        "baud": -1 if info.baud is None else int(info.baud),
        "device": cut(rig.device, 64),
        "firmware": cut(rig.firmware, 64),
        "channels": cut(",".join(rig.channels), 256),
        "gain": np.asarray(rig.gain or np.nan, dtype=float),
        "offset": np.asarray(rig.offset or np.nan, dtype=float),
        "command_line": cut(getattr(info, "command", ""), 1024),
        "host_name": cut(host_name, 128),
        "operator": cut(getattr(info, "operator", ""), 128),
        "resumed": int(bool(getattr(info, "resumed", False))),
        "other_rig": int(bool(getattr(info, "other_rig", False))),
    }


def record_event(number: int, event: str, rid: int) -> dict[str, Any]:
    """An ``added``, ``redone`` or ``skipped`` row of session ``number``."""
    return {"session": number, "event": event, "time": now_iso(), "record": int(rid)}


def end_event(number: int, how: str) -> dict[str, Any]:
    """The ``end`` row of session ``number``: how it ended (one of :data:`HOW`)."""
    if how not in HOW:
        raise StoreError(f"a session ends as one of {', '.join(HOW)}, not {how!r}.")
    return {"session": number, "event": "end", "time": now_iso(), "how": how}


def cut(s: Any, width: int) -> str:
    """``s`` as text of at most ``width`` UTF-8 bytes (ending in "..." when cut)."""
    data = str(s).encode("utf-8")
    if len(data) <= width:
        return str(s)
    return data[: width - 3].decode("utf-8", "ignore") + "..."


def read_sessions(t: Table) -> tuple[list[dict[str, Any]], list[str]]:
    """The sessions of the log, in order, each folded from its events; and what was found damaged."""
    rows = t.read()
    problems = [f"session log row {r}: {why}" for r, why in rows.damaged]
    c = rows.cols
    sessions: dict[int, dict[str, Any]] = {}
    for i in range(len(rows.rows)):
        n, event = int(c["session"][i]), _s(c["event"][i])
        s = sessions.setdefault(
            n,
            {
                "number": n,
                "started": "",
                "ended": "",
                "how": None,
                "note": "",
                "port": "",
                "baud": None,
                "device": "",
                "firmware": "",
                "channels": [],
                "calibration": None,
                "command_line": "",
                "host_name": "",
                "operator": "",
                "resumed": False,
                "other_rig": False,
                "added": [],
                "redone": [],
                "skipped": [],
            },
        )
        if event == "begin":
            baud = int(c["baud"][i])
            s.update(
                started=_s(c["time"][i]),
                port=_s(c["port"][i]),
                baud=None if baud < 0 else baud,
                device=_s(c["device"][i]),
                firmware=_s(c["firmware"][i]),
                channels=[x for x in _s(c["channels"][i]).split(",") if x],
                calibration={"gain": [float(x) for x in c["gain"][i]], "offset": [float(x) for x in c["offset"][i]]},
                command_line=_s(c["command_line"][i]),
                host_name=_s(c["host_name"][i]),
                operator=_s(c["operator"][i]),
                resumed=int(c["resumed"][i]) == 1,
                other_rig=int(c["other_rig"][i]) == 1,
            )
        elif event in ("added", "redone", "skipped"):
            s[event].append(int(c["record"][i]))
        elif event == "end":
            s.update(ended=_s(c["time"][i]), how=_s(c["how"][i]), note=_s(c["note"][i]))
    return [sessions[k] for k in sorted(sessions)], problems
