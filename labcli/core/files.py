"""Files replaced whole: an interrupted write leaves the old file, never half of a new one.

And outputs that never destroy data: an output is never written over a command's own input,
nor over a run file unless the command replaces runs on purpose (``--force``), and only
regular files are ever replaced, never a device node, a directory or a FIFO
(:func:`check_output`).
"""

from __future__ import annotations

import os
import stat
import tempfile
from collections.abc import Callable
from pathlib import Path

from ..errors import ConfigError, LabcliError

RUN_FILE_SUFFIXES = (".h5", ".hdf5")  # a path ending so names a run file; anything else, a table
HDF5_SIGNATURE = b"\x89HDF\r\n\x1a\n"  # the first bytes of every HDF5 file labcli writes (no user block)
TMP_STEM = 200  # bytes of the name kept in a temporary file's name, so that any legal name has one


def name_too_long(path: str | os.PathLike) -> str | None:
    """The words for a file name longer than its file system allows (None when it fits)."""
    path = os.fspath(path)
    name = os.path.basename(path)
    folder = os.path.dirname(os.path.abspath(path))
    try:
        limit = os.pathconf(folder if os.path.isdir(folder) else "/", "PC_NAME_MAX")
    except (OSError, ValueError):
        limit = 255
    size = len(name.encode("utf-8", "surrogateescape"))
    if size <= limit:
        return None
    return (
        f"the file name is too long ({size} bytes; this file system allows at most {limit}), so choose a shorter name"
    )


def kind_of(path: str | os.PathLike) -> str | None:
    """What a path that exists but is not a regular file is ("a directory", "a device", ...); None otherwise."""
    try:
        mode = os.stat(path).st_mode
    except OSError:
        return None
    if stat.S_ISREG(mode):
        return None
    if stat.S_ISDIR(mode):
        return "a directory"
    if stat.S_ISCHR(mode) or stat.S_ISBLK(mode):
        return "a device"
    if stat.S_ISFIFO(mode):
        return "a FIFO (named pipe)"
    if stat.S_ISSOCK(mode):
        return "a socket"
    return "not a regular file"


def is_run_file(path: str | os.PathLike) -> bool:
    """Whether ``path`` is a regular file that starts as an HDF5 file does (a run file, or other HDF5 data)."""
    if kind_of(path) is not None:
        return False
    try:
        with open(path, "rb") as fh:
            return fh.read(len(HDF5_SIGNATURE)) == HDF5_SIGNATURE
    except OSError:
        return False


def same_file(a: str | os.PathLike, b: str | os.PathLike) -> bool:
    try:
        return os.path.samefile(a, b)
    except OSError:
        return False


def check_output(
    path: str | os.PathLike,
    *,
    inputs: tuple[str | os.PathLike | None, ...] = (),
    what: str = "",
    replaces_runs: bool = False,
) -> None:
    """Refuse, in one sentence, an output path whose writing would destroy data.

    Refused: a name too long for its file system; any of ``inputs`` (the same file, by any
    name); anything but a regular file; a run file (any HDF5 file), unless ``replaces_runs``
    (a command that builds runs, given ``--force``).  ``what`` names the content ("the model ").
    """
    check_not_input(path, inputs, what)
    check_writable_name(path, what)
    if not replaces_runs and is_run_file(path):
        raise ConfigError(
            f"Cannot write {what}{path}: it is a run file (HDF5), and writing there would destroy its "
            "records; choose another output name."
        )


def check_not_input(
    path: str | os.PathLike, inputs: tuple[str | os.PathLike | None, ...], what: str = "", verb: str = "write"
) -> None:
    """Refuse, in one sentence, an output that is one of ``inputs`` (the same file by any name: a
    symbolic or a hard link included), whatever ``--force`` says; None and names that are not
    files (a shipped protocol's name) are skipped."""
    for source in inputs:
        if source is not None and same_file(path, source):
            raise ConfigError(
                f"Cannot {verb} {what}{path}: it is this command's input, and writing there would "
                "destroy it; choose another output name."
            )


def check_writable_name(
    path: str | os.PathLike, what: str = "", *, verb: str = "write", error: type[LabcliError] = ConfigError
) -> None:
    """Refuse a name too long for its file system, or a path that is there and not a regular file."""
    too_long = name_too_long(path)
    if too_long:
        raise error(f"Cannot {verb} {what}{path}: {too_long}.")
    kind = kind_of(path)
    if kind:
        raise error(
            f"{path} is {kind}, not a regular file; labcli writes only regular files, so give the path of a file."
        )


def atomic_write(path: str | os.PathLike, data: bytes, *, what: str = "") -> None:
    """Replace ``path`` with ``data`` (written beside it, flushed, fsynced, renamed into place).

    Errors are one sentence, ``Cannot write {what}{path}: ...``; ``what`` names the content
    ("the model to ") where the path alone would not say it.
    """
    path = Path(path)
    folder = path.parent if str(path.parent) else Path(".")
    check_writable_name(path, what)
    stem = path.name.encode("utf-8", "surrogateescape")[:TMP_STEM].decode("utf-8", "ignore")
    try:
        fd, tmp = tempfile.mkstemp(prefix=f".{stem}.", suffix=".tmp", dir=folder)
    except OSError as exc:
        raise ConfigError(
            f"Cannot write {what}{path}: {exc.strerror or exc} (check the folder exists and is writable)."
        ) from None
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
