"""Files replaced whole: an interrupted write leaves the old file, never half of a new one.

And outputs that never destroy data: an output is never written over a command's own input,
nor over a run file unless the command replaces runs on purpose (``--force``), and only
regular files are ever replaced, never a device node, a directory or a FIFO
(:func:`check_output`).
"""

from __future__ import annotations

import os
import re
import stat
import tempfile
from collections.abc import Callable
from pathlib import Path

from ..errors import ConfigError, LabcliError

RUN_FILE_SUFFIXES = (".h5", ".hdf5")  # a path ending so names a run file; anything else, a table
HDF5_SIGNATURE = b"\x89HDF\r\n\x1a\n"  # the first bytes of every HDF5 file labcli writes (no user block)
TMP_STEM = 200  # bytes of the name kept in a temporary file's name, so that any legal name has one


def stored_text(s: str) -> str:
    """``s`` as text a run file (UTF-8) can hold: the bytes of a file name that are not UTF-8,
    which Python keeps as lone surrogates, written as ``\\xff`` escapes; the rest as it reads."""
    return s.encode("utf-8", "surrogateescape").decode("utf-8", "backslashreplace")


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


MB = 1_000_000
INPUT_LIMITS = {  # the largest input of each kind labcli reads (bytes); far above any real one
    "a protocol file": 1 * MB,
    "a plan": 64 * MB,
    "a table": 1000 * MB,  # 10^6 trials are ~150 MB
    "a model file": 64 * MB,
    "a firmware image": 16 * MB,
    "a sim script": 1 * MB,
}


def _size_words(n: int) -> str:
    return f"{n / MB:.3g} MB" if n >= MB else f"{n} bytes"


def _open_input(path: str | os.PathLike, what: str, label: str, error: type[Exception]) -> tuple[int, int]:
    """An open descriptor on the regular file ``path`` and its size; ``error`` for anything else.

    Opened without blocking, so that a FIFO with no writer is refused at once instead of
    waiting; a folder raises IsADirectoryError and a missing file FileNotFoundError, as
    ``open`` does, so that callers keep their own sentences for those.
    """
    fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK | getattr(os, "O_CLOEXEC", 0))
    try:
        st = os.fstat(fd)
        if stat.S_ISDIR(st.st_mode):
            raise IsADirectoryError(21, "Is a directory", os.fspath(path))
        if not stat.S_ISREG(st.st_mode):
            kind = kind_of(path) or "not a regular file"
            raise error(
                f"{label} is {kind}, not a regular file; labcli reads {what} only from a regular file, "
                "so give the path of one."
            )
        limit = INPUT_LIMITS[what]
        if st.st_size > limit:
            raise error(_too_big(label, st.st_size, what, limit))
        return fd, st.st_size
    except BaseException:
        os.close(fd)
        raise


def _too_big(label: str, size: int | None, what: str, limit: int) -> str:
    """``size`` None: the file grew past the bound while it was read."""
    limit_words = f"the {_size_words(limit)} {what} may be"
    if size is None:
        return f"{label} grew past {limit_words} while it was read; check that it is the right file."
    return f"{label} is {_size_words(size)}, larger than {limit_words}; check that it is the right file."


def check_input(
    path: str | os.PathLike, what: str, *, label: str | None = None, error: type[Exception] = ConfigError
) -> None:
    """Refuse, in one sentence, an input that is not a regular file (a FIFO, a device such as
    /dev/zero, a socket) or is larger than :data:`INPUT_LIMITS` allows ``what`` to be.

    A missing path or a folder raise FileNotFoundError or IsADirectoryError, as ``open`` does.
    """
    fd, _ = _open_input(path, what, os.fspath(path) if label is None else label, error)
    os.close(fd)


def read_input(
    path: str | os.PathLike, what: str, *, label: str | None = None, error: type[Exception] = ConfigError
) -> bytes:
    """The bytes of the input ``path``, checked as :func:`check_input` does and read with its bound
    (a file that grows past it while read is refused too)."""
    label = os.fspath(path) if label is None else label
    fd, _ = _open_input(path, what, label, error)
    limit = INPUT_LIMITS[what]
    chunks: list[bytes] = []
    got = 0
    try:
        while True:
            block = os.read(fd, min(1 << 20, limit + 1 - got))
            if not block:
                return b"".join(chunks)
            chunks.append(block)
            got += len(block)
            if got > limit:
                raise error(_too_big(label, None, what, limit))
    finally:
        os.close(fd)


def is_run_file(path: str | os.PathLike) -> bool:
    """Whether ``path`` is a regular file that starts as an HDF5 file does (a run file, or other HDF5 data)."""
    if kind_of(path) is not None:
        return False
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK)  # a FIFO swapped in after the check never blocks
    except OSError:
        return False
    try:
        return os.read(fd, len(HDF5_SIGNATURE)) == HDF5_SIGNATURE
    except OSError:
        return False
    finally:
        os.close(fd)


# How every model file labcli writes begins: an object whose first key names its schema (or kind).
_MODEL_HEAD = re.compile(rb'\A\s*\{\s*"(?:schema|kind)"\s*:\s*"')


def is_model_file(path: str | os.PathLike) -> bool:
    """Whether ``path`` holds a model a paper wrote: a JSON object naming its ``schema`` or ``kind``.

    A file that opens as labcli's model files do is one without being parsed: a model fitted on a
    random split of 10^6 trials is 15 MB, and reading it whole took a second of every refit.
    """
    from .jsontext import loads_bounded

    try:
        with open(path, "rb") as f:
            if _MODEL_HEAD.match(f.read(256)):
                return True
    except OSError:
        return False
    try:
        d = loads_bounded(read_input(path, "a model file").decode("utf-8"))
    except (OSError, LabcliError, ValueError, RecursionError):
        return False
    return isinstance(d, dict) and (isinstance(d.get("schema"), str) or isinstance(d.get("kind"), str))


def check_model_output(path: str | os.PathLike) -> None:
    """Refuse to replace a file that is there and is not a model (a table, notes, a plan): a fit
    replaces only an earlier model; an empty file holds nothing to lose."""
    if os.path.isfile(path) and os.path.getsize(path) > 0 and not is_model_file(path):
        raise ConfigError(
            f"Cannot write the model to {path}: it is not a model file, and fit replaces only a model "
            "it wrote earlier; choose another output name."
        )


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
