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
the same finaliser and is swallowed again.
"""

from __future__ import annotations

import contextlib
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
