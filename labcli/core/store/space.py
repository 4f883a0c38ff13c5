"""Where a run file meets the file system: locks, putting a new file in place, leftovers, free space.

* **One lock for every writer.**  A run file open for writing holds HDF5's own lock on it (an
  exclusive ``flock``) for as long as it is open; every labcli write to a run (acquisition,
  resume, import, the model ``fit`` records, ``split``) opens it so.  Replacing a run
  (``--force``) first takes the same lock on the file it replaces, so it is refused while
  any writer (or a viewer) has that file open.  Readers open without locks and read only what
  is committed (:mod:`.columns`), so they never stop a writer.
* **New files appear whole.**  A run is built under a temporary name in its own folder
  (``.labcli-<what>-<random>.partial``), held open (and so locked) by its builder, and put
  in place by a hard link, which fails if the name was taken meanwhile: of two runs started
  on one path at the same moment, one gets it and the other is told so.  With ``force`` it
  is renamed over the old file, under that file's lock.
* **Leftovers are cleaned at the next start.**  A builder killed before it finished leaves
  its ``.partial`` file; the next labcli that creates a file in that folder removes every
  ``.partial`` whose builder is gone (nobody holds its lock).
* **A full disk is seen before HDF5 sees it.**  Before each write the run file reserves the
  space it may need past its end (``posix_fallocate``), and checks the file size limit
  (``ulimit -f``); if either refuses, nothing is written and the error says so.  HDF5 itself
  never meets a failed write, which is what left files it could not open again.
"""

from __future__ import annotations

import contextlib
import errno
import fcntl
import os
import resource
import secrets
import signal
import threading
from collections.abc import Callable, Iterator

from ...errors import DiskFull, StoreError
from ..files import check_writable_name, kind_of

PARTIAL_PREFIX = ".labcli-"
PARTIAL_SUFFIX = ".partial"
SLACK = 256 * 1024  # room kept past each write for HDF5's own bookkeeping (B-tree nodes, headers)
BUSY = "is open in another program (a viewer, or a run still recording); close it there and try again"


def mb(n: float) -> str:
    return f"{n / 1e6:.1f} MB" if n >= 1e5 else f"{n / 1e3:.0f} kB"


def ignore_file_size_signal() -> None:
    """Let writes past ``ulimit -f`` fail with EFBIG instead of killing the process (SIGXFSZ)."""
    if hasattr(signal, "SIGXFSZ") and threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)


def file_size_limit() -> int | None:
    limit = resource.getrlimit(resource.RLIMIT_FSIZE)[0]
    return None if limit == resource.RLIM_INFINITY else int(limit)


def free_bytes(path: str) -> int:
    st = os.statvfs(os.path.dirname(os.path.abspath(path)) or ".")
    return st.f_bavail * st.f_frsize


def reserve(fd: int, end: int, need: int, path: str, doing: str, kept: str | Callable[[], str]) -> None:
    """Make sure ``need`` bytes past ``end`` can be written to the file ``fd``, or raise DiskFull.

    ``doing`` says what was about to be written ("trial 12"), ``kept`` what is safe ("the 11
    trials stored before are intact", or what says it, asked only when it is said); both go
    into the one sentence.
    """
    need += SLACK
    limit = file_size_limit()
    if limit is not None and end + need > limit:
        raise DiskFull(
            f"{path} cannot grow past the file size limit of {mb(limit)} (ulimit -f), so {doing} was "
            f"not written; {_said(kept)}. Raise the limit, then try again."
        )
    try:
        os.posix_fallocate(fd, end, need)
        return
    except OSError as e:
        code = e.errno
    if code in (errno.ENOSPC, errno.EDQUOT, errno.EFBIG):
        raise no_room(code, path, doing, _said(kept))
    # A file system without fallocate: judge by the free space it reports.
    if free_bytes(path) < need:
        raise DiskFull(
            f"The disk holding {path} is full ({mb(free_bytes(path))} free), so {doing} was not written; "
            f"{_said(kept)}. Free some space, then try again."
        )


def _said(kept: str | Callable[[], str]) -> str:
    return kept() if callable(kept) else kept


def no_room(code: int | None, path: str, doing: str, kept: str) -> DiskFull:
    """The one sentence for a write refused for want of room (``code``: ENOSPC, EDQUOT or EFBIG)."""
    if code == errno.EFBIG:
        return DiskFull(
            f"{path} cannot grow past the file size limit (ulimit -f), so {doing} was not written; "
            f"{kept}. Raise the limit, then try again."
        )
    return DiskFull(
        f"The disk holding {path} is full ({mb(free_bytes(path))} free), so {doing} was not written; "
        f"{kept}. Free some space, then try again."
    )


def check_new_file(path: str) -> None:
    """Refuse, in one sentence, a path labcli cannot create a run at."""
    check_writable_name(path, verb="create", error=StoreError)
    folder = os.path.dirname(os.path.abspath(path))
    if not os.path.isdir(folder):
        raise StoreError(f"cannot create {path}: the directory {folder} does not exist.")
    if not os.access(folder, os.W_OK | os.X_OK):
        raise StoreError(f"Cannot create {path}: the folder {folder} is not writable (permission denied).")


def partial_path(path: str, what: str) -> str:
    folder = os.path.dirname(os.path.abspath(path))
    return os.path.join(folder, f"{PARTIAL_PREFIX}{what}-{secrets.token_hex(6)}{PARTIAL_SUFFIX}")


def clean_partials(folder: str) -> list[str]:
    """Remove the ``.partial`` files of builders that are gone; returns what was removed."""
    removed: list[str] = []
    try:
        names = os.listdir(folder)
    except OSError:
        return removed
    for name in names:
        if not (name.startswith(PARTIAL_PREFIX) and name.endswith(PARTIAL_SUFFIX)):
            continue
        p = os.path.join(folder, name)
        try:
            fd = os.open(p, os.O_RDONLY)
        except OSError:
            continue
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            continue  # its builder is still at work
        finally:
            os.close(fd)
        with contextlib.suppress(OSError):
            os.unlink(p)
            removed.append(p)
    return removed


def writer_holds(path: str) -> bool:
    """True while another process writes ``path`` (it holds the exclusive lock)."""
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK)  # a FIFO given as a run never blocks here
    except OSError:
        return False
    try:
        fcntl.flock(fd, fcntl.LOCK_SH | fcntl.LOCK_NB)
    except OSError:
        return True
    finally:
        os.close(fd)
    return False


@contextlib.contextmanager
def replacing(path: str) -> Iterator[None]:
    """Hold the exclusive lock of the existing file at ``path`` while it is replaced."""
    try:
        fd = os.open(path, os.O_RDONLY)
    except FileNotFoundError:
        yield
        return
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            raise StoreError(f"{path} {BUSY}; --force never replaces a run another program has open.") from None
        yield
    finally:
        os.close(fd)


def publish(tmp: str, path: str, *, force: bool, exists_hint: str) -> None:
    """Put the whole file ``tmp`` in place at ``path`` (see the module docstring)."""
    if force and os.path.lexists(path):
        what = kind_of(path)
        if what:
            raise StoreError(f"{path} is {what}, not a regular file; labcli replaces only regular files.")
        with replacing(path):
            os.replace(tmp, path)
    else:
        try:
            os.link(tmp, path)
        except FileExistsError:
            raise StoreError(f"{path} already exists; {exists_hint}.") from None
        except OSError:
            # A file system without hard links (FAT on a USB stick): check, then rename.
            if os.path.lexists(path):
                raise StoreError(f"{path} already exists; {exists_hint}.") from None
            os.replace(tmp, path)
        else:
            os.unlink(tmp)
    sync_folder(path)


def sync_folder(path: str) -> None:
    """fsync the folder holding ``path``, so that a new name survives a power cut."""
    with contextlib.suppress(OSError):
        fd = os.open(os.path.dirname(os.path.abspath(path)) or ".", os.O_RDONLY)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)
