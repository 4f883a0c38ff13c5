"""Sets of trial numbers kept as inclusive ranges: a million fitted trials are one pair, not a million numbers.

A model file lists the trials it was fitted on, so that ``validate`` can refuse to test a model on
its own data.  Written one number each, a fit on 10^6 trials put 4 x 10^6 integers into the file
(31 MB of JSON, read back as as many Python integers); as ``[first, last]`` pairs a contiguous
fit set is one pair (the file: 21 KB).  Files written before list the numbers one by one; :func:`parse`
reads both.
"""

from __future__ import annotations

from collections.abc import Callable
from itertools import chain
from typing import Any, NoReturn

import numpy as np

from .jsontext import PairList, PlainList
from .nogc import paused_gc


class Ranges(PlainList):
    """Sorted, disjoint, non-adjacent ``[first, last]`` pairs of Python ints: plain JSON as they are.

    A list like any other; its type tells a writer (:func:`labcli.core.jsontext.dumps_indented`, a
    model's ``to_dict``) that a random split's 10^5 pairs need no walking item by item: as nested
    lists they took json's indented encoder seven seconds a model file.
    """


Pairs = list[list[int]]  # [first, last] pairs in any order, possibly touching


def to_ranges(ids: Any) -> Ranges:
    """The distinct trial numbers ``ids`` as sorted inclusive ``[first, last]`` pairs."""
    a = np.asarray(ids, dtype=np.int64).ravel()
    if not a.size:
        return Ranges()
    # Not np.unique: numpy 2 hashes, 427 ms on 8 x 10^5 sorted ids where checking the order takes 1 ms.
    # A table lists its trials in order, so the sort is nearly always skipped.
    if not np.all(a[1:] > a[:-1]):
        a = np.sort(a)
        a = a[np.r_[True, a[1:] != a[:-1]]]
    cut = np.flatnonzero(np.diff(a) != 1)
    with paused_gc():  # a random split's 10^5 pairs: as many lists, no cycles
        return Ranges(np.column_stack([np.r_[a[0], a[cut + 1]], np.r_[a[cut], a[-1]]]).tolist())


def _bounds(ranges: Pairs) -> tuple[np.ndarray, np.ndarray]:
    r = np.asarray(ranges, dtype=np.int64).reshape(-1, 2)
    return r[:, 0], r[:, 1]


def count(ranges: Pairs) -> int:
    """How many trial numbers the ranges hold."""
    lo, hi = _bounds(ranges)
    return int(np.sum(hi - lo + 1))


def contains(ranges: Pairs, ids: Any) -> np.ndarray:
    """Per number of ``ids``, whether the ranges hold it (bool array)."""
    ids = np.asarray(ids, dtype=np.int64)
    lo, hi = _bounds(ranges)
    if not lo.size:
        return np.zeros(ids.shape, bool)
    k = np.searchsorted(lo, ids, side="right") - 1
    return (k >= 0) & (ids <= hi[np.clip(k, 0, None)])


def parse(value: Any, key: str, bad: Callable[[str, str], NoReturn]) -> Ranges:
    """A model file's trial list: ``[first, last]`` pairs, or (older files) the numbers one by one.

    ``bad(key, what)`` raises the caller's error for a value that is neither.
    """

    def whole(t: Any) -> bool:  # and within int64: a 400-digit number is no trial
        return isinstance(t, int) and not isinstance(t, bool) and -(2**63) <= t < 2**63

    if not isinstance(value, list):
        bad(key, "must list whole trial numbers, or [first, last] ranges of them")
    written = _as_written(value)
    if written is not None:
        return written
    if all(whole(t) for t in value):
        return to_ranges(value)
    if not all(isinstance(r, list) and len(r) == 2 and all(whole(t) for t in r) and r[0] <= r[1] for r in value):
        bad(key, "must list whole trial numbers, or [first, last] ranges of them")
    return merge(value)  # merged without listing them: [0, 10^15] is one pair, not a petabyte


def _as_written(value: list[Any]) -> Ranges | None:
    """``value`` itself when it is ranges as :func:`to_ranges` writes them (checked whole-array), else None.

    A model fitted on a random split lists 10^5 pairs; read one number at a time they took a
    second of every ``validate``.
    """
    a = getattr(value, "array", None)
    if isinstance(value, PairList) and isinstance(a, np.ndarray) and a.shape == (len(value), 2):
        pass  # read whole-array from the file's text: ints in pairs, the array beside them (core.jsontext)
    else:
        # Element types checked in C loops (map, chain), not one generator step per pair: 10^5 pairs.
        if not value or set(map(type, value)) != {list} or set(map(len, value)) != {2}:
            return None
        if set(map(type, chain.from_iterable(value))) != {int}:
            return None
        try:  # every item is an int (checked above): read flat, as an (n, 2) array
            a = np.fromiter(chain.from_iterable(value), dtype=np.int64, count=2 * len(value)).reshape(-1, 2)
        except OverflowError:
            return None  # beyond int64: refused, one by one, below
    if not (np.all(a[:, 0] <= a[:, 1]) and np.all(a[1:, 0] > a[:-1, 1] + 1)):
        return None
    return Ranges(value)


def merge(ranges: Pairs) -> Ranges:
    """Ranges as :func:`to_ranges` would write them (sorted, merged), from any [first, last] pairs."""
    lo, hi = _bounds(ranges)
    if not lo.size:
        return Ranges()
    order = np.argsort(lo, kind="stable")
    lo, hi = lo[order], hi[order]
    if np.all(lo <= hi) and np.all(np.abs(lo) < 2**62) and np.all(np.abs(hi) < 2**62):
        # Whole-array: a pair starts a new range where it begins past every earlier end + 1
        # (the loop below, for the ranges a model file holds: 10^5 pairs per equation).
        reach = np.maximum.accumulate(hi)
        first = np.flatnonzero(np.r_[True, lo[1:] > reach[:-1] + 1])
        with paused_gc():
            return Ranges(np.column_stack([lo[first], np.maximum.reduceat(hi, first)]).tolist())
    out = Ranges()
    with paused_gc():
        for a, b in zip(lo.tolist(), hi.tolist(), strict=False):
            if out and a <= out[-1][1] + 1:
                out[-1][1] = max(out[-1][1], b)
            else:
                out.append([a, b])
    return out
