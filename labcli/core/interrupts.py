"""Ctrl-C that lands where Python cannot raise it is kept for the next safe point.

Python delivers SIGINT as a KeyboardInterrupt in whatever Python code runs
next.  When that code is a finaliser (h5py closes its objects from weakref
callbacks and ``__del__``), the exception cannot propagate: the interpreter
hands it to :data:`sys.unraisablehook`, which by default prints "Exception
ignored ... KeyboardInterrupt", and the Ctrl-C is gone.  For an acquisition
that means the experimenter pressed Ctrl-C and the session ran on to the end.

:func:`kept` installs a hook that records such a KeyboardInterrupt instead of
printing it; :func:`check` raises it at a point where raising is safe (the
engine calls it between steps and between frame batches).  Re-sending the
signal from inside the hook does not work: the new KeyboardInterrupt lands in
the same finaliser and is swallowed again.  :func:`deferred` holds a Ctrl-C back while a trial is
written, and raises it once the write is whole.
"""

from __future__ import annotations

import contextlib
import signal
import sys
import threading
from collections.abc import Iterator
from typing import Any

_pending = threading.Event()


def _hook(previous: Any) -> Any:
    def hook(unraisable: Any) -> None:
        if unraisable.exc_type is not None and issubclass(unraisable.exc_type, KeyboardInterrupt):
            _pending.set()
            return
        previous(unraisable)

    return hook


@contextlib.contextmanager
def kept() -> Iterator[None]:
    """While inside, a KeyboardInterrupt raised in a finaliser is kept for :func:`check`."""
    previous = sys.unraisablehook
    _pending.clear()  # one left from an earlier session is not this one's
    sys.unraisablehook = _hook(previous)
    try:
        yield
    finally:
        sys.unraisablehook = previous


def pending() -> bool:
    """A Ctrl-C was kept and not yet raised."""
    return _pending.is_set()


def check() -> None:
    """Raise a kept Ctrl-C as KeyboardInterrupt (once); do nothing otherwise."""
    if _pending.is_set():
        _pending.clear()
        raise KeyboardInterrupt


@contextlib.contextmanager
def deferred() -> Iterator[None]:
    """Hold Ctrl-C until a trial is written whole (the store's write is not interruptible).

    A process started with Ctrl-C ignored (``nohup``, a script's background job) was asked to run
    through it: catching it here would honour a Ctrl-C that lands during a write and no other.
    """
    if threading.current_thread() is not threading.main_thread() or signal.getsignal(signal.SIGINT) is signal.SIG_IGN:
        yield
        return
    caught: list[Any] = []
    previous = signal.signal(signal.SIGINT, lambda *a: caught.append(a))
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)
        if caught:
            raise KeyboardInterrupt
        check()
