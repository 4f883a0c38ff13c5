"""Blobs: what a log row refers to (a split's ids, a model's JSON), kept beside its table.

A blob is a one-dimensional dataset that only grows; each piece is written at its next
chunk boundary (so no chunk holding a committed piece is written again, :mod:`.columns`),
before the row that refers to it, and the row keeps the piece's ``[start, stop)`` and
checksum.  A piece that no longer matches its checksum reads as None.
"""

from __future__ import annotations

from typing import Any

import h5py
import numpy as np

from .checksum import row_checksums, words_checksum
from .columns import append
from .h5 import text

VERSIONS = (1, 2)  # of a piece's checksum (:func:`blob_checksum`)


def blob_write(ds: h5py.Dataset, values: np.ndarray, version: int = 1) -> tuple[int, int, int]:
    """Append ``values`` to a blob at its next chunk boundary: (start, stop, checksum of ``version``)."""
    chunk = ds.chunks[0]
    start = -(-int(ds.shape[0]) // chunk) * chunk
    values = np.asarray(values, dtype=ds.dtype)
    append(ds, start, values)
    return start, start + len(values), blob_checksum(values, version)


def blob_checksum(values: np.ndarray, version: int = 1) -> int:
    """The checksum of a piece's bytes: version 1, every 64-bit word folded in turn (a model's JSON, and
    a split's ids before version 2); version 2, the words folded each on its own and summed, whole-array
    (:func:`~.checksum.words_checksum`)."""
    v = np.ascontiguousarray(values)
    if version == 1:
        return int(row_checksums([v.view(np.uint8).reshape(1, -1)], 0)[0])
    if version == 2:
        return words_checksum(v)
    raise ValueError(f"no blob checksum has version {version}")


def blob_read(g: h5py.Group, name: str, start: int, stop: int, checksum: int, version: int = 1) -> np.ndarray | None:
    """Values ``[start, stop)`` of the blob ``g[name]``, or None when they do not match their checksum
    (of ``version``) or HDF5 cannot read them (a damaged dataset header fails as KeyError or TypeError too)."""
    if version not in VERSIONS:  # a damaged row, or a labcli newer than this one: not believed
        return None
    try:
        ds = g[name]
        if not 0 <= start <= stop <= ds.shape[0]:
            return None
        values = ds[start:stop]
    except (OSError, ValueError, RuntimeError, KeyError, TypeError):
        return None
    return values if blob_checksum(values, version) == int(checksum) else None


def cell_text(v: Any) -> str:
    """A text cell of a log table as str (fixed-length bytes lose their padding)."""
    return text(v).rstrip("\x00") if isinstance(v, (bytes, np.bytes_)) else str(v)
