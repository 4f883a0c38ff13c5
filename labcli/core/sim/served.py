"""Which pseudo-terminals a ``labcli sim --pty`` is serving, for ``labcli ports``.

pyserial's port listing knows USB and on-board serial ports, not pseudo-terminals,
so a simulated rig served on ``/dev/pts/N`` would be invisible to the person looking
for it.  While it serves, ``labcli sim --pty`` leaves a small JSON note in a per-user
runtime folder (``$LABCLI_RUNTIME_DIR``, else ``$XDG_RUNTIME_DIR/labcli``, else
``<tmp>/labcli-<uid>``) naming the device path, its process and the rig; ``labcli
ports`` lists each note whose process still runs and whose device still exists,
marked as the simulated rig, and removes notes left by a server that was killed.
"""

from __future__ import annotations

import contextlib
import json
import os
import tempfile
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path


@dataclass(frozen=True)
class ServedPort:
    """A pseudo-terminal a simulated rig is serving on."""

    device: str
    pid: int
    description: str


def runtime_dir() -> Path:
    """The folder of the notes (not created here)."""
    if os.environ.get("LABCLI_RUNTIME_DIR"):
        return Path(os.environ["LABCLI_RUNTIME_DIR"])
    if os.environ.get("XDG_RUNTIME_DIR"):
        return Path(os.environ["XDG_RUNTIME_DIR"]) / "labcli"
    uid = os.getuid() if hasattr(os, "getuid") else 0
    return Path(tempfile.gettempdir()) / f"labcli-{uid}"


@contextlib.contextmanager
def announce(device: str, description: str) -> Iterator[Path | None]:
    """Leave the note for ``device`` while the block runs (None if the folder is not writable:
    the rig serves all the same, ``labcli ports`` just cannot list it)."""
    path = runtime_dir() / f"sim-{os.getpid()}.json"
    note: Path | None = path
    try:
        path.parent.mkdir(mode=0o700, parents=True, exist_ok=True)
        path.write_text(
            json.dumps({"device": device, "pid": os.getpid(), "description": description}), encoding="utf-8"
        )
    except OSError:
        note = None
    try:
        yield note
    finally:
        if note is not None:
            with contextlib.suppress(OSError):
                note.unlink()


def served() -> list[ServedPort]:
    """The simulated rigs serving now, by device path; stale notes are removed."""
    found = []
    try:
        notes = sorted(runtime_dir().glob("sim-*.json"))
    except OSError:
        return []
    for note in notes:
        try:
            data = json.loads(note.read_text(encoding="utf-8"))
            port = ServedPort(str(data["device"]), int(data["pid"]), str(data["description"]))
        except (OSError, ValueError, KeyError, TypeError):
            continue  # being written, or not ours: leave it
        if _alive(port.pid) and os.path.exists(port.device):
            found.append(port)
        else:
            with contextlib.suppress(OSError):
                note.unlink()
    return sorted(found, key=lambda p: p.device)


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # someone else's process: it exists
        return True
    return True
