"""Freed memory kept for reuse while a bulk command builds and drops arrays of hundreds of MB.

glibc's malloc serves a block over its mmap threshold (128 KiB at start, rising to at most
32 MiB as such blocks are freed) with fresh pages of its own and gives them back to the
system when the block is freed, so the next array that size is faulted in again, a page at a
time.  ``labcli import`` of 10^6 trials makes and drops many arrays of 8-40 MB (the table's
columns read, converted, checked, written): about 210,000 page faults, a third of its CPU time
spent in the kernel, where a user's ``read_csv`` and h5py write took 73,000.  With large
blocks taken from the heap and freed memory kept there for the next one, the faults halve
and the peak memory stays where it was (docs/performance.md, "Tables").  Outside glibc
(macOS, Windows, musl) nothing changes.
"""

from __future__ import annotations

import ctypes
import sys
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

# mallopt(3) parameters and glibc's starting values (restored after the block)
M_TRIM_THRESHOLD, M_MMAP_THRESHOLD = -1, -3
START_THRESHOLD = 128 * 1024
KEPT = 2**31 - 1  # bytes: every block from the heap, and nothing freed returned until the block ends

# The thresholds are the process's, so blocks nest by a count: only the outermost sets and restores
# them (an inner block's exit would otherwise end the outer block's reuse half-way).
_depth = 0
_lock = threading.Lock()


def _libc() -> Any:
    if not sys.platform.startswith("linux"):
        return None
    try:
        libc = ctypes.CDLL(None)
        return libc if hasattr(libc, "mallopt") and hasattr(libc, "malloc_trim") else None
    except OSError:
        return None


@contextmanager
def kept_heap() -> Iterator[None]:
    """Large blocks from the heap, freed memory kept there for reuse, for the block; then given back.

    Blocks nest (and may be entered from several threads): the outermost one sets the thresholds
    and restores them.  Afterwards they are glibc's starting ones, fixed (mallopt ends their rise)."""
    global _depth
    libc = _libc()
    with _lock:
        outermost = _depth == 0
        _depth += 1
        kept = (
            outermost
            and libc is not None
            and bool(libc.mallopt(M_MMAP_THRESHOLD, KEPT))
            and bool(libc.mallopt(M_TRIM_THRESHOLD, KEPT))
        )
    try:
        yield
    finally:
        with _lock:
            _depth -= 1
            if _depth == 0 and libc is not None:
                libc.mallopt(M_MMAP_THRESHOLD, START_THRESHOLD)
                libc.mallopt(M_TRIM_THRESHOLD, START_THRESHOLD)
                if kept:
                    libc.malloc_trim(0)
