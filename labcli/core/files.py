"""Files replaced whole: an interrupted write leaves the old file, never half of a new one."""

from __future__ import annotations

import os
import tempfile
from pathlib import Path
from typing import Callable

from ..errors import ConfigError

RUN_FILE_SUFFIXES = (".h5", ".hdf5")  # a path ending so names a run file; anything else, a table


def atomic_write(path: str | os.PathLike, data: bytes, *, what: str = "") -> None:
    """Replace ``path`` with ``data`` (written beside it, flushed, fsynced, renamed into place).

    Errors are one sentence, ``Cannot write {what}{path}: ...``; ``what`` names the content
    ("the model to ") where the path alone would not say it.
    """
    path = Path(path)
    folder = path.parent if str(path.parent) else Path(".")
    try:
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=folder)
    except OSError as exc:
        raise ConfigError(f"Cannot write {what}{path}: {exc.strerror or exc} "
                          "(check the folder exists and is writable).") from None
    try:
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
            fh.flush()
            os.fsync(fh.fileno())
        # mkstemp creates 0600; a file the toolkit writes is as readable as any the user writes.
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp, 0o666 & ~umask)
        os.replace(tmp, path)
    except OSError as exc:
        try:
            os.unlink(tmp)
        except OSError:
            pass
        raise ConfigError(f"Cannot write {what}{path}: {exc.strerror or exc}.") from None


def replace_restorably(path: str | os.PathLike, data: bytes, *, what: str = "") -> Callable[[], None]:
    """:func:`atomic_write`, returning a function that puts the previous file (or none) back."""
    path = Path(path)
    old = path.read_bytes() if path.is_file() else None
    atomic_write(path, data, what=what)

    def restore() -> None:
        if old is None:
            path.unlink(missing_ok=True)
        else:
            path.write_bytes(old)

    return restore
