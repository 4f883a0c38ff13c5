"""``run.windows``: a run's raw windows, each a range of the run-wide frame arrays (:mod:`.frames`).

The engine streams a window into the file as its frames arrive (:meth:`Windows.begin`, a
:class:`~.frames.WindowWriter`); a record then refers to it by ``[start, stop)`` and the
checksum of its frames.  A window handed to :meth:`~.records.Records.write` as arrays (a
test's, a schema-1 file being copied) is written the same way at the commit.  Reading a
record's window checks its frames against that checksum: a damaged window is named in a
warning and left out.

>>> w = run.windows.begin("trial 12")         # doctest: +SKIP
>>> w.append(t_s, seq, counts, si)            # doctest: +SKIP
>>> stored = w.finish()                       # what the record's ``raw`` takes
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import TYPE_CHECKING, Any

import numpy as np

from ...errors import StoreError
from .frames import StoredWindow, WindowWriter, counts_out
from .h5 import WINDOW_GROUPS, window_arrays

if TYPE_CHECKING:
    from .runfile import RunFile
    from .view import RecordColumns

# A record's windows as checked before anything is written: column prefix, and the window
# already in the file or the arrays to write.
Checked = list[tuple[str, Any]]


class Windows:
    """``run.windows`` (see the module docstring)."""

    def __init__(self, run: RunFile) -> None:
        self._run = run

    def begin(self, doing: str = "a raw window") -> WindowWriter:
        """Start a raw window written as it arrives (the engine's Baseline and Capture).

        ``append(time, seq, counts, si)`` adds each block (whole chunks of frames go into the
        file and are flushed as they fill, not yet part of any record); ``finish()`` returns the
        :class:`StoredWindow` a record's ``raw`` then takes.  A window no record takes (a redo,
        a kill) stays unused: it lies past every committed window and the next one starts
        after it.
        """
        run = self._run
        run.writer.check()
        run.check_v2(doing)
        w = run.writer
        return WindowWriter(
            run,
            run.tables.frames,
            lambda nbytes: w.reserve(nbytes, doing),
            lambda: w.flush(doing),
            lambda: w.writing(doing),
        )

    def frames(self, start: int, stop: int) -> dict[str, np.ndarray]:
        """Raw frames ``[start, stop)``: ``t_s``, ``seq``, ``counts``, ``si``; StoreError when any cannot be read."""
        run = self._run
        if run.v1 is not None:
            raise StoreError(f"{run.path} keeps its raw windows per record (schema 1); use records.read().")
        w, whole = run.tables.frames.read(start, stop)
        if not whole:
            raise StoreError(
                f"{run.path}: raw frames {start} to {stop} cannot all be read (damaged); "
                "labcli inspect --verify names the records they belong to."
            )
        w["counts"] = counts_out(w["counts"])
        return w

    @property
    def extent(self) -> int:
        """Frames written so far (committed or not): where the next window starts, rounded up to a chunk."""
        run = self._run
        return 0 if run.tables is None else run.tables.frames.extent

    def of_record(self, rec: RecordColumns, i: int, name: str) -> dict[str, np.ndarray] | None:
        """The ``name`` window ("baseline", "loaded") of record ``i`` of ``rec``; None when it has
        none, or (with a warning) when its frames fail their checksum."""
        run = self._run
        if run.v1 is not None:
            return run.v1.window(rec.sources[i], name)
        a, b = int(rec.cols[f"{name}_start"][i]), int(rec.cols[f"{name}_stop"][i])
        if a < 0:
            return None
        frames = run.tables.frames
        try:
            w, ok = frames.read(a, b)
            total, _ = frames.checksum(a, b)
        except StoreError:
            w, ok, total = None, False, None
        if w is None or not ok or total != int(rec.cols[f"{name}_checksum"][i]):
            what = f"{run.record_type.noun} {rec.ids[i]}"
            run.warn(
                f"{run.path}: the {name} window of {what} is damaged (its frames fail their checksum) and is left out."
            )
            return None
        w["counts"] = counts_out(w["counts"])
        return w

    def checked(self, record: Mapping[str, Any], label: str) -> Checked:
        """The record's raw windows, checked before anything is written (see :data:`Checked`)."""
        out: Checked = []
        k = len(self._run.channels)
        for key, raw in (record.get("raw") or {}).items():
            if key not in WINDOW_GROUPS:
                raise StoreError(f"{label} record: unknown window {key!r} in 'raw' (use baseline and load).")
            name = WINDOW_GROUPS[key]
            if any(name == w[0] for w in out):
                raise StoreError(f"{label} record: 'raw' gives the {name} window twice.")
            stored = raw.get("stored") if isinstance(raw, Mapping) else None
            if isinstance(stored, StoredWindow):
                if stored.run is not self._run:
                    raise StoreError(f"{label} record: its {name} window was written into another run file.")
                out.append((name, stored))
            else:
                out.append((name, window_arrays(raw, k, label, name)))
        return out

    def store(self, checked: Checked, label: str) -> tuple[dict[str, int], int]:
        """Write the windows given as arrays; the record's window columns and the bytes of frames written."""
        row: dict[str, int] = {}
        nbytes = 0
        for name, w in checked:
            if not isinstance(w, StoredWindow):
                nbytes += len(w["seq"]) * 8 * (2 + 2 * len(self._run.channels))
                writer = self.begin(doing=label)
                writer.append(w["time"], w["seq"], w["counts"], w["values"])
                w = writer.finish()
            row.update({f"{name}_start": w.start, f"{name}_stop": w.stop, f"{name}_checksum": w.checksum})
        return row, nbytes
