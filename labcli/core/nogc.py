"""Cyclic garbage collection held off while a bulk of acyclic containers is built.

Building 10^5-10^6 lists (a model file's trial ranges, per-trial flag lists, a parsed model
file) makes Python run several full collections, each walking every object alive, numpy's and
pandas' modules included: at 10^6 trials they were a second of ``labcli validate``.  Lists of
numbers and strings hold no reference cycles, so nothing is left uncollected by waiting until
they are built; the collector resumes (if it was on) when the block ends, with what was built
in its oldest generation.
"""

from __future__ import annotations

import gc
from collections.abc import Iterator
from contextlib import contextmanager


@contextmanager
def paused_gc() -> Iterator[None]:
    """Hold off cyclic collection for the block (reference counting still frees as usual)."""
    was_on = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        if was_on:
            if not gc.get_freeze_count():
                # What the block built goes to the oldest generation unexamined: left young, the
                # first collection after it walked every list again (0.07 s for a model's 5 x 10^5
                # trial ranges).  It stays collectable, at the next full collection.  (Skipped
                # when a program froze objects itself: unfreezing would hand those back.)
                gc.freeze()
                gc.unfreeze()
            gc.enable()
