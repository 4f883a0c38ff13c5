"""Raw windows: every frame of a run in run-wide arrays, each window a range of them.

``/entry/raw`` holds the device time (``time``, s, unwrapped) and frame counter (``seq``) of
every frame stored, the calibrated values (``values``, SI, frames x channels, float64) and
the counts as sent (``counts``, frames x channels, int32), and per channel an NXlog group
(``raw/P_L1``) whose ``value`` and ``raw_value`` are that channel's column of ``values`` and
``counts`` (HDF5 virtual datasets, unlimited, mapped once when the file is made: they cost no
byte and no write, and grow with the frames), its ``time`` a link to the shared one; the
channel's calibration (``gain``, ``offset``) is in ``raw/calibration/<channel>`` (in
``raw/<channel>`` up to schema 2).  Up to schema 3 each channel's ``value`` and ``raw_value``
are datasets of their own (``values`` and ``counts`` do not exist); such a file is read, and
added to, in its own layout.  A window whose counts are
not all whole int32 numbers (a device sending decimals) keeps them exactly in the channel's
``raw_decimal`` (float64), written for that window's frames only, whose ``raw_value`` holds
:data:`DECIMAL` (never a whole count, see :func:`_whole`); ``raw_decimal`` is never written
for any other frame and costs nothing.  Files written before counts were stored as
integers hold float64 ``raw_value`` and no ``raw_decimal``; they read the same.  A record refers to its windows by ``[start, stop)``
and a checksum over the window's frames (:func:`~labcli.core.store.checksum.frames_checksum`).

A window starts at a chunk boundary: the frames of a committed window share no chunk with
frames written later (see :mod:`.columns` for why).  The frames between the end of one
window and the next boundary are never written; they cost nothing compressed.

Why two arrays of frames x channels rather than a dataset per channel: a window is then four
writes (time, seq, values, counts), as a hand-written log would make, not 2 + 2k; each HDF5
dataset written costs a resize, an object header rewritten and the work of a write call,
whatever its size, and at a few hundred frames a window those, not the bytes, were most of a
commit.  Long windows keep each channel's frames in chunks of their own (chunks of
``chunk_frames`` x 1): a channel's values compress as well as they did alone (channels side by
side in a chunk, pressures beside angles, compress worse: a file about 14 % larger at 4000 frames
a window).  Short windows (chunks of at most :data:`SIDE_BY_SIDE` frames) keep the channels side
by side in one chunk: there a chunk's fixed cost (its filters set up, its index entry, its
Fletcher32) outweighs its bytes, and twelve chunks fewer a trial took a sixth off a 400-frame
commit for a file about 3 % larger.  The chunking is HDF5's, recorded with each dataset:
every reader is indifferent to it.

A window is written as it arrives (:class:`WindowWriter`): frames go into the file as soon
as they fill a chunk, and only that chunk and the window's running statistics stay in
memory, so a capture window of any length takes the same memory.  What the writer finishes
is a :class:`~labcli.core.window.Window` stored in the file: what the engine hands the
session in place of the samples (its mean and spread; the samples read back on demand).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from contextlib import AbstractContextManager as ContextManager
from typing import Any

import h5py
import numpy as np

from ...errors import StoreError
from ..paper import Column
from ..window import FrameSource, Stats, Stored, Window
from .checksum import frames_checksum
from .columns import append_all, create_dataset, per_channel, read_rows
from .columns import uncached as _uncached
from .h5 import put, text

TIME = Column("time", "s", what="device time, unwrapped")
MOD = 1 << 64
DECIMAL = np.int32(-(2**31))  # raw_value of a frame whose counts are in raw_decimal
SIDE_BY_SIDE = 512  # frames per chunk up to which a chunk holds every channel (see the module docstring)


def chunk_frames(frames_per_window: float) -> int:
    """Frames per chunk for windows of about this many frames: a power of two from 64 to 4096."""
    want = max(1.0, float(frames_per_window)) if math.isfinite(frames_per_window) else 256.0
    return int(min(4096, max(64, 2 ** math.ceil(math.log2(want)))))


def create(
    entry: h5py.Group, channels: Sequence[str], units: Sequence[str], gain: np.ndarray, offset: np.ndarray, chunk: int
) -> h5py.Group:
    """The empty ``raw`` group of a new run (see the module docstring)."""
    g = entry.create_group("raw")
    put(g, "NX_class", "NXcollection")
    put(g, "channels", list(channels))
    g.attrs["chunk_frames"] = np.int64(chunk)
    time = create_dataset(g, TIME, chunk)
    create_dataset(g, Column("seq", "1", kind="uint", what="frame counter as sent"), chunk)
    k = len(channels)
    grid: tuple[h5py.Dataset, ...] = ()
    if k:
        names = tuple(channels)
        values = Column("values", per_channel(units), shape=(k,), components=names, what="calibrated, per channel")
        counts = Column("counts", "counts", kind="int", shape=(k,), components=names, what="as sent, per channel")
        apart = chunk > SIDE_BY_SIDE
        grid = (
            create_dataset(g, values, chunk, by_component=apart),
            create_dataset(g, counts, chunk, dtype=np.dtype("<i4"), by_component=apart),
        )
    calibration = g.create_group("calibration")  # NXlog defines no gain or offset: kept beside the logs
    put(calibration, "NX_class", "NXcollection")
    for j, (name, unit) in enumerate(zip(channels, units, strict=False)):
        c = g.create_group(name)
        put(c, "NX_class", "NXlog")
        c["time"] = time  # a second name for the shared dataset (NXlog's own time axis)
        _column_of(c, "value", grid[0], j, unit or "1", f"{name}, calibrated")
        _column_of(c, "raw_value", grid[1], j, "counts", f"{name} as sent")
        create_dataset(c, Column("raw_decimal", "counts", what=f"{name} as sent, where not whole"), chunk)
        cal = calibration.create_group(name)
        put(cal, "NX_class", "NXcollection")
        for key, v, u in (("gain", gain[j], f"{unit or '1'}/count"), ("offset", offset[j], unit or "1")):
            ds = create_dataset(cal, Column(key, u), 1, length=1)
            ds[0] = v
    return g


def _column_of(g: h5py.Group, name: str, source: h5py.Dataset, j: int, units: str, what: str) -> h5py.Dataset:
    """Dataset ``name`` of ``g``: column ``j`` of the frames x channels ``source``, every frame, as many as
    it holds now or later (a virtual dataset of unlimited extent, in this same file)."""
    unlimited = h5py.h5s.UNLIMITED
    k = source.shape[1]
    dcpl = h5py.h5p.create(h5py.h5p.DATASET_CREATE)
    dcpl.set_fill_value(np.array(source.fillvalue, dtype=source.dtype))
    view = h5py.h5s.create_simple((0,), (unlimited,))
    view.select_hyperslab((0,), (1,), block=(unlimited,))
    column = h5py.h5s.create_simple((0, k), (unlimited, k))
    column.select_hyperslab((0, j), (1, 1), block=(unlimited, 1))
    dcpl.set_virtual(view, b".", source.name.encode(), column)
    space = h5py.h5s.create_simple((0,), (unlimited,))
    ds = h5py.Dataset(h5py.h5d.create(g.id, name.encode(), h5py.h5t.py_create(source.dtype), space, dcpl=dcpl))
    put(ds, "units", units)
    put(ds, "long_name", what)
    return ds


def channel_units(raw: h5py.Group, channels: Sequence[str]) -> tuple[str, ...]:
    """Each channel's unit: from ``raw/values`` (schema 4: the channels' NXlog values are views no
    reader opens, :func:`.opening._views`), else from each channel's own ``value``."""
    if "values" not in raw:
        return tuple(text(raw[c]["value"].attrs["units"]) for c in channels)
    each = text(raw["values"].attrs["units"]).split(",")
    units = tuple(each * len(channels) if len(each) == 1 else each)
    if len(units) != len(channels):
        raise ValueError(f"raw/values has {len(each)} units for {len(channels)} channels")
    return units


def window_parts(time: np.ndarray, seq: np.ndarray, counts: np.ndarray, si: np.ndarray) -> list[np.ndarray]:
    """The arrays a window's checksum folds, frame by frame."""
    return [
        np.asarray(time, dtype="<f8"),
        np.asarray(seq, dtype="<u8"),
        np.asarray(si, dtype="<f8"),
        np.asarray(counts, dtype="<f8"),
    ]


class Frames:
    """The raw frames of an open run file (either layout, see the module docstring)."""

    def __init__(self, g: h5py.Group) -> None:
        self.g = g
        self.channels = [c.decode() if isinstance(c, bytes) else str(c) for c in g.attrs["channels"]]
        self.chunk = int(g.attrs["chunk_frames"])
        self.time, self.seq = _uncached(g, "time"), _uncached(g, "seq")
        # Schema 4: the channels side by side in two arrays; up to 3, a dataset per channel and kind.
        self.grid = "values" in g
        if self.grid:
            self.values, self.counts = _uncached(g, "values"), _uncached(g, "counts")
            raw_dtype = self.counts.dtype
        else:
            self.value = [_uncached(g, f"{c}/value") for c in self.channels]
            self.raw_value = [_uncached(g, f"{c}/raw_value") for c in self.channels]
            raw_dtype = self.raw_value[0].dtype if self.channels else np.dtype("<i4")
        # Integer counts (and the decimals apart) since raw counts are stored as integers; float64 before.
        self.integer = bool(self.channels) and raw_dtype.kind == "i"
        self.raw_decimal = [_uncached(g, f"{c}/raw_decimal") for c in self.channels] if self.integer else []
        self.raw_dtype = raw_dtype
        self._extent: int | None = None  # set by this object's writes (a reader reads the file's)

    @property
    def extent(self) -> int:
        """Frames the arrays hold (``time`` first: no array holds more)."""
        if self._extent is not None:  # a writer's own count: only its writes grow the arrays
            return self._extent
        return int(self.time.shape[0])

    def next_start(self) -> int:
        return -(-self.extent // self.chunk) * self.chunk

    def write(self, start: int, time: np.ndarray, seq: np.ndarray, counts: np.ndarray, si: np.ndarray) -> None:
        """Frames at ``start`` (every array grows to end after them)."""
        items = [(self.time, np.asarray(time, dtype="<f8")), (self.seq, np.asarray(seq, dtype="<u8"))]
        whole = not self.integer or _whole(counts)
        k = len(self.channels)
        raw = np.asarray(counts, dtype=self.raw_dtype) if whole else np.full((len(counts), k), DECIMAL, dtype="<i4")
        if self.grid and k:
            items += [(self.values, np.asarray(si, dtype="<f8")), (self.counts, raw)]
        for j in range(k if not self.grid else 0):
            items.append((self.value[j], np.ascontiguousarray(si[:, j], dtype="<f8")))
            items.append((self.raw_value[j], np.ascontiguousarray(raw[:, j])))
        # The decimals as sent, exactly, where the counts say so.
        decimal = [] if whole else [(self.raw_decimal[j], np.asarray(counts[:, j], dtype="<f8")) for j in range(k)]
        # ``time`` is written first, so no frame array holds more frames than it does.
        end = self.extent
        append_all(items, start, extent=end)
        append_all(decimal, start)
        self._extent = max(end, start + len(items[0][1]))

    def read(self, a: int, b: int) -> tuple[dict[str, np.ndarray], bool]:
        """Frames ``[a, b)`` as ``t_s``, ``seq``, ``counts`` (n, k), ``si`` (n, k); and whether all read."""
        if not 0 <= a <= b <= self.extent:
            raise StoreError(f"frames {a} to {b} lie outside the {self.extent} frames stored")
        ok = True

        def get(ds: h5py.Dataset, stop: int = b) -> np.ndarray:
            nonlocal ok
            values, bad = read_rows(ds, a, stop)
            ok = ok and not bad.any()
            return values

        t, seq = get(self.time), get(self.seq)
        if not self.channels:
            si, counts = np.zeros((b - a, 0)), np.zeros((b - a, 0))
        elif self.grid:
            si, counts = get(self.values), get(self.counts)
        else:
            si = np.stack([get(d) for d in self.value], axis=1)
            counts = np.stack([get(d) for d in self.raw_value], axis=1)
        upto = min(b, self.raw_decimal[0].shape[0]) if self.integer else a
        if upto > a:  # a window here sent decimals: they end where raw_decimal ends
            decimal = np.full(counts.shape, np.nan)
            decimal[: upto - a] = np.stack([get(d, upto) for d in self.raw_decimal], axis=1)
            counts = np.where(counts == DECIMAL, decimal, counts)
        return {"t_s": t, "seq": seq.astype(np.uint32), "counts": counts, "si": si}, ok

    def checksum(self, a: int, b: int, block: int = 1 << 16) -> tuple[int, bool]:
        """The checksum of frames ``[a, b)`` as stored, read in blocks."""
        total, ok = 0, True
        for lo in range(a, b, block):
            hi = min(lo + block, b)
            w, good = self.read(lo, hi)
            ok = ok and good
            total = (total + int(frames_checksum(window_parts(w["t_s"], w["seq"], w["counts"], w["si"]), lo - a))) % MOD
        return total, ok


def _whole(counts: np.ndarray) -> bool:
    """Whether every count is a whole number int32 holds (what devices send)."""
    c = np.asarray(counts, dtype=np.float64)
    return c.size == 0 or bool(np.all(c == np.rint(c)) and np.abs(c).max() < 2**31)


def counts_out(counts: np.ndarray) -> np.ndarray:
    """Counts as read back: int32 when every value is a whole number (what devices send), else as stored."""
    c = np.asarray(counts, dtype=np.float64)
    if np.all(np.isfinite(c)) and np.all(c == np.rint(c)) and (c.size == 0 or np.abs(c).max() < 2**31):
        return c.astype(np.int32)
    return c


class WindowWriter:
    """One raw window being written block by block (``run.windows.begin``); ``source``: where
    the finished window's frames are read back from (the run file's ``run.windows``).

    Frames are held until they fill whole chunks, which are then written and flushed (not
    synced: nothing of the window counts until a record that references it is committed),
    so every chunk is written once and a window of any length holds at most a chunk of
    frames in memory.  :meth:`finish` writes the rest.
    """

    def __init__(
        self,
        source: FrameSource,
        frames: Frames,
        reserve: Callable[[int], None],
        flush: Callable[[], None],
        writing: Callable[[], ContextManager[None]],
    ) -> None:
        self.source = source
        self._frames = frames
        self._reserve = reserve
        self._flush = flush
        self._writing = writing
        self.start = frames.next_start()
        self.stop = self.start  # frames written so far end here
        self._held: list[tuple[np.ndarray, ...]] = []
        self._n_held = 0
        self._sum = 0
        self._stats = Stats()
        self._open = True

    def __len__(self) -> int:
        """Frames taken so far (written or held)."""
        return self.stop - self.start + self._n_held

    def append(self, time: Any, seq: Any, counts: Any, si: Any) -> None:
        """Add frames: device time (s, unwrapped), counter, counts as sent (n, k), SI values (n, k)."""
        if not self._open:
            raise StoreError("this window is finished; begin another one to add frames")
        k = len(self._frames.channels)
        time = np.asarray(time, dtype=np.float64).reshape(-1)
        n = time.shape[0]
        seq = (np.asarray(seq, dtype=np.int64).reshape(-1) % (1 << 32)).astype(np.uint64)
        counts = np.asarray(counts, dtype=np.float64).reshape(n, k)
        si = np.asarray(si, dtype=np.float64).reshape(n, k)
        if seq.shape[0] != n:
            raise StoreError(f"a block of {n} frames came with {seq.shape[0]} frame counters")
        if n == 0:
            return
        self._held.append((time, seq, counts, si))
        self._n_held += n
        whole = self._n_held // self._frames.chunk * self._frames.chunk
        if whole:
            self._write(whole)
            self._flush()

    def _write(self, n: int) -> None:
        """Write the first ``n`` frames held."""
        held = [np.concatenate(a) if len(self._held) > 1 else a[0] for a in zip(*self._held, strict=False)]
        block = [a[:n] for a in held]
        rest = [a[n:] for a in held]
        self._held = [tuple(rest)] if len(rest[0]) else []
        self._n_held -= n
        time, seq, counts, si = block
        self._reserve(n * (8 * (2 + 2 * len(self._frames.channels))))
        with self._writing():
            self._frames.write(self.stop, time, seq, counts, si)
        self._sum = (
            self._sum + int(frames_checksum(window_parts(time, seq, counts, si), self.stop - self.start))
        ) % MOD
        self._stats.add(si)
        self.stop += n

    def finish(self) -> Window:
        """Write what is held and close the window; the stored :class:`~labcli.core.window.Window` a record's ``raw`` takes."""
        if self._open and self._n_held:
            self._write(self._n_held)
        self._open = False
        stored = Stored(self.source, self.start, self.stop, self._sum)
        return Window(len(self._frames.channels), stats=self._stats, stored=stored)
