"""``labcli monitor --record FILE.h5``: a plain recording of a stream, readable with h5py alone.

Not a run file (no trials, no protocol steps): one HDF5 file holding what the rig sent, frame
by frame, with what it means::

    /                      @NX_class NXroot  @default entry  @creator labcli ...
      entry/               NXentry  @program_name labcli  @start_time  @kind stream
                           @device @firmware @port @rate_hz @channels
        stream/            NXdata  @signal <first channel>  @axes time
          time   (n,)      s since the first frame, from the rig's clock (unwrapped)
          seq    (n,)      the rig's frame counter
          counts (n, k)    the raw readings  @channels
          <channel> (n,)   each channel in SI (MPa, rad; counts where uncalibrated)  @units

Frames are appended as they arrive and flushed about once a second, so a recording stopped
by Ctrl-C or the rig is whole up to its last frame; an existing file is never overwritten.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from typing import Any

import numpy as np

from ..errors import ConfigError, StoreError
from .files import check_writable_name
from .settle import TimeUnwrapper
from .timestamps import utc_now
from .version import __version__

FLUSH_S = 1.0  # seconds of the rig's clock between flushes


class StreamRecorder:
    """Appends frames to a new stream file (see the module docstring); use as a context manager."""

    def __init__(
        self,
        path: str | os.PathLike,
        channels: Sequence[str],
        units: Sequence[str],
        *,
        attrs: dict[str, Any] | None = None,
    ) -> None:
        import h5py

        self.path = os.fspath(path)
        if os.path.lexists(self.path):
            raise ConfigError(f"{self.path} already exists; record into a new file (labcli never overwrites data).")
        check_writable_name(self.path, "the recording ")
        self.channels = list(channels)
        self._unwrap = TimeUnwrapper()
        self._t0: float | None = None
        self._flushed_at = 0.0
        self.frames = 0
        try:
            self.h5 = h5py.File(self.path, "x")
        except OSError as e:
            raise StoreError(f"{self.path} cannot be created ({e.strerror or e}).") from None
        f = self.h5
        f.attrs.update({"NX_class": "NXroot", "default": "entry", "creator": f"labcli {__version__}"})
        entry = f.create_group("entry")
        entry.attrs.update({"NX_class": "NXentry", "default": "stream", "program_name": "labcli"})
        entry.attrs.update({"program_version": __version__, "start_time": utc_now(), "kind": "stream"})
        entry.attrs["channels"] = self.channels
        for key, value in (attrs or {}).items():
            entry.attrs[key] = value
        g = entry.create_group("stream")
        g.attrs.update({"NX_class": "NXdata", "signal": self.channels[0] if self.channels else "counts"})
        g.attrs["axes"] = "time"
        k = len(self.channels)
        opts = {"compression": "gzip", "shuffle": True, "chunks": True}
        self._time = g.create_dataset("time", (0,), "f8", maxshape=(None,), **opts)
        self._time.attrs["units"] = "s"
        self._seq = g.create_dataset("seq", (0,), "i8", maxshape=(None,), **opts)
        self._seq.attrs["units"] = "1"
        self._counts = g.create_dataset("counts", (0, k), "f8", maxshape=(None, k), **opts)
        self._counts.attrs.update({"units": "counts", "channels": self.channels})
        self._si = []
        for name, unit in zip(self.channels, units, strict=True):
            ds = g.create_dataset(name, (0,), "f8", maxshape=(None,), **opts)
            ds.attrs["units"] = unit
            self._si.append(ds)
        f.flush()

    def add(self, seq: np.ndarray, t_us: np.ndarray, counts: np.ndarray, si: np.ndarray) -> None:
        """Append frames (the rig's counter and clock, raw counts, SI values ``(n, k)``)."""
        n = int(np.asarray(seq).shape[0])
        if not n:
            return
        t = self._unwrap(t_us)  # s
        if self._t0 is None:
            self._t0 = float(t[0])
        t = t - self._t0
        a = self.frames
        for ds, values in ((self._time, t), (self._seq, seq)):
            ds.resize((a + n,))
            ds[a:] = values
        self._counts.resize((a + n, len(self.channels)))
        self._counts[a:] = counts
        si = np.asarray(si, dtype=float)
        for j, ds in enumerate(self._si):
            ds.resize((a + n,))
            ds[a:] = si[:, j]
        self.frames = a + n
        if t[-1] - self._flushed_at >= FLUSH_S:
            self.h5.flush()
            self._flushed_at = float(t[-1])

    def close(self) -> None:
        if self.h5.id.valid:
            self.h5.attrs["file_time"] = utc_now()
            self.h5.close()

    def __enter__(self) -> StreamRecorder:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
