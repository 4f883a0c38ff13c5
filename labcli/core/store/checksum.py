"""Checksums of a run file's rows and raw windows, computed on whole arrays at once.

HDF5's Fletcher32 filter checks each chunk of each dataset; these checksums check what
belongs together across datasets: one row of a table (every column's bytes), one raw window
(every frame of every array).  Both fold 64-bit words with FNV-1a's step,
``h = (h xor w) * 0x100000001b3`` mod 2**64, from a start that depends on the row's (the
frame's) position.  The step is a bijection of ``h`` for a fixed word, so a change confined
to one 64-bit word (any single flipped bit, for instance) always changes the result; wider
changes go unnoticed with a chance of 2**-64.  Not a defence against tampering: a record of
what was written.

A row's checksum is never 0: 0 is the fill value of unwritten rows (see
:mod:`labcli.core.store.columns`).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

_BASIS = np.uint64(0xCBF29CE484222325)
_PRIME = np.uint64(0x100000001B3)
_STEP = np.uint64(0x9E3779B97F4A7C15)  # spreads consecutive positions over the 64-bit range


def words(a: np.ndarray, n: int) -> np.ndarray:
    """The bytes of each of the ``n`` entries of ``a`` (along axis 0) as little-endian 64-bit words."""
    a = np.asarray(a)
    if n == 0:
        return np.empty((0, 0), dtype="<u8")
    if a.dtype.kind in "fiub" and a.dtype.byteorder not in ("<", "|", "="):
        a = a.astype(a.dtype.newbyteorder("<"))
    b = np.ascontiguousarray(a).view(np.uint8).reshape(n, -1)
    pad = (-b.shape[1]) % 8
    if pad:
        b = np.concatenate([b, np.zeros((n, pad), dtype=np.uint8)], axis=1)
    return np.ascontiguousarray(b).view("<u8")


class Repeated:
    """One entry's value (``row``, shape ``(1, ...)``) standing for ``n`` equal entries, never spelt out.

    A column left at its fill value over a million imported rows (a 1 KiB text of flags, say)
    is folded from its one row's words, and :mod:`.columns` writes nothing for it: HDF5 reads
    unwritten rows as the fill value.
    """

    nbytes = 0  # bytes it adds to a write

    def __init__(self, row: np.ndarray, n: int) -> None:
        self.row, self.n = row, n

    def __len__(self) -> int:
        return self.n


def fold(parts: Sequence[np.ndarray | Repeated], positions: np.ndarray) -> np.ndarray:
    """One 64-bit checksum per entry: every part's words for that entry, started at its position."""
    n = len(positions)
    h = _BASIS ^ (positions.astype(np.uint64) * _STEP)
    if n == 1:  # one long entry (a blob of ids): word after word in Python ints, not 1-element arrays
        return np.array(
            [_fold_one(int(h[0]), [words(p.row if isinstance(p, Repeated) else p, 1)[0] for p in parts])],
            dtype=np.uint64,
        )
    for part in parts:
        if isinstance(part, Repeated):
            h = _fold_same(h, words(part.row, 1)[0] if n else np.empty(0, dtype="<u8"))
            continue
        w = words(part, n)
        for j in range(w.shape[1]):  # in place: no two fresh arrays of n words per word folded
            np.bitwise_xor(h, w[:, j], out=h)
            np.multiply(h, _PRIME, out=h)
    return h


def _fold_one(h: int, parts: Sequence[np.ndarray]) -> int:
    prime, mask = int(_PRIME), (1 << 64) - 1
    for w in parts:
        for word in w.tolist():
            h = ((h ^ word) * prime) & mask
    return h


def _fold_same(h: np.ndarray, w: np.ndarray) -> np.ndarray:
    """``h`` folded with the same words ``w`` for every entry; a run of k zero words is one product by P**k."""
    zeros = 0
    for word in w:
        if word == 0:
            zeros += 1
            continue
        if zeros:
            h = h * np.uint64(pow(int(_PRIME), zeros, 1 << 64))
            zeros = 0
        h = (h ^ word) * _PRIME
    if zeros:
        h = h * np.uint64(pow(int(_PRIME), zeros, 1 << 64))
    return h


def row_checksums(parts: Sequence[np.ndarray | Repeated], first_row: int) -> np.ndarray:
    """Checksums of rows ``first_row, first_row + 1, ...`` of a table, given its columns' values."""
    n = len(parts[0]) if parts else 0
    h = fold(parts, np.arange(first_row, first_row + n, dtype=np.uint64))
    h[h == 0] = 1
    return h


def words_checksum(values: np.ndarray) -> int:
    """One checksum of a long entry's bytes (a split's ids), computed whole-array.

    Each 64-bit word (the bytes as stored, the last word padded with zeros) is folded on its
    own from a start given by its place, and the folds are summed mod 2**64: a raw window's
    checksum (:func:`frames_checksum`) with each word a frame.  A change confined to one word
    always changes it, as it changes the word-by-word fold of :func:`row_checksums`, which
    split logs written before it keep (``ids_checksum_version`` 1, :mod:`.split`).
    """
    b = np.ascontiguousarray(values).view(np.uint8).reshape(1, -1)
    return int(frames_checksum([words(b, 1)[0]], 0))


def frames_checksum(parts: Sequence[np.ndarray], first_frame: int) -> np.uint64:
    """The part of a raw window's checksum given by frames ``first_frame, ...`` of it.

    A window's checksum is the sum, mod 2**64, of its frames' folds, each started at the
    frame's place in the window; blocks of a window streamed in turn add up to the same value.
    """
    n = len(parts[0]) if parts else 0
    if n == 0:
        return np.uint64(0)
    h = fold(parts, np.arange(first_frame, first_frame + n, dtype=np.uint64))
    return np.add.reduce(h, dtype=np.uint64)
