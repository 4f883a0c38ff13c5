"""``run.windows``: a run's raw windows, each a range of the run-wide frame arrays (:mod:`.frames`).

The engine streams a window into the file as its frames arrive (:meth:`Windows.begin`, a
:class:`~.frames.WindowWriter`); a record then refers to it by ``[start, stop)`` and the
checksum of its frames.  A window handed to ``run.records.write`` with its frames in memory
(a test's, a schema-1 file being copied, one read from another run file) is written the
same way at the commit.  Reading a record's window checks its frames against that checksum:
a damaged window is named in a warning and left out.  Every window is a
:class:`~labcli.core.window.Window`.

>>> w = run.windows.begin("trial 12")         # doctest: +SKIP
>>> w.append(t_s, seq, counts, si)            # doctest: +SKIP
>>> stored = w.finish()                       # the Window a record's ``raw`` takes
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import TYPE_CHECKING, Any, NamedTuple

import numpy as np

from ...errors import ConfigError, StoreError
from ..window import NOT_KEPT, Stored, Window
from .frames import WindowWriter, counts_out
from .opening import READ_ERRORS, read_afresh
from .unused import Unused, read_unused

if TYPE_CHECKING:
    from .runfile import RunFile
    from .view import RecordColumns

# A record's windows: key in the record -> column prefix in the file (group name in schema 1).
WINDOW_GROUPS = {"baseline": "baseline", "load": "loaded", "loaded": "loaded"}


class Frames(NamedTuple):
    """A window's frames as the writer takes them, checked (:func:`checked_frames`)."""

    time: np.ndarray  # (n,) s, the rig's clock unwrapped
    seq: np.ndarray  # (n,) uint32
    counts: np.ndarray  # (n, k) as sent
    values: np.ndarray  # (n, k) SI


class Windows:
    """``run.windows`` (see the module docstring)."""

    def __init__(self, run: RunFile) -> None:
        self._run = run

    def begin(self, doing: str = "a raw window", flush: bool = True) -> WindowWriter:
        """Start a raw window written as it arrives (the engine's Baseline and Capture).

        ``append(time, seq, counts, si)`` adds each block (whole chunks of frames go into the
        file and are flushed as they fill, not yet part of any record); ``finish()`` returns the
        stored :class:`~labcli.core.window.Window` a record's ``raw`` then takes.  A window no
        record takes (a redo, a kill) stays unused: it lies past every committed window, the
        next one starts after it, and it is marked so (:meth:`unused`).  ``flush=False``: the chunks are not flushed as they fill (a
        window already whole in memory, written just before the commit that syncs it).
        """
        run = self._run
        run.writer.check()
        run.check_v2(doing)
        w = run.writer
        return WindowWriter(
            self,
            run.tables.frames,
            lambda nbytes: w.reserve(nbytes, doing),
            (lambda: w.flush(doing)) if flush else (lambda: None),
            lambda: w.writing(doing),
        )

    def frames(self, start: int, stop: int) -> Window:
        """Raw frames ``[start, stop)`` read into memory; StoreError when any cannot be read."""
        run = self._run
        if run.v1 is not None:
            raise StoreError(f"{run.path} keeps its raw windows per record (schema 1); use records.read().")
        try:  # a read torn by a writer's checkpoint is read again afresh (:func:`.opening.read_afresh`)
            w, whole = read_afresh(run, lambda: run.tables.frames.read(start, stop), lambda got: not got[1])
        except READ_ERRORS:
            w, whole = {}, False
        if not whole:
            raise StoreError(
                f"{run.path}: raw frames {start} to {stop} cannot all be read (damaged); "
                "labcli inspect --verify names the records they belong to."
            )
        return Window.of(w["seq"], counts_out(w["counts"]), w["si"], t_s=w["t_s"])

    def unused(self) -> list[Unused]:
        """The ranges of raw frames no committed record takes, and why (:mod:`.unused`).

        A run being recorded is read up to the frames its writer streams in now: a read torn by a
        checkpoint (a chunk past the end the file had at its opening, a row of marks that fails
        its checksum) is read again afresh, and only damage that outlasts it is said."""
        run = self._run
        try:
            ranges, damage = read_afresh(run, lambda: read_unused(run), lambda got: got[1] is not None)
        except READ_ERRORS:
            raise StoreError(
                f"{run.path}: the raw frames no record takes cannot be read (damaged); "
                "check the file with labcli inspect --verify and use a backup copy."
            ) from None
        if damage:
            run.warn(damage)
        return ranges

    @property
    def extent(self) -> int:
        """Frames written so far, committed or not (the next window starts past them, at a chunk boundary)."""
        run = self._run
        return 0 if run.v1 is not None else run.tables.frames.extent

    def of_record(self, rec: RecordColumns, i: int, name: str) -> Window | None:
        """The ``name`` window ("baseline", "loaded") of record ``i`` of ``rec``, read into memory; None
        when it has none, or (with a warning) when its frames fail their checksum."""
        run = self._run
        if run.v1 is not None:
            return run.v1.window(rec.sources[i], name)
        a, b = int(rec.cols[f"{name}_start"][i]), int(rec.cols[f"{name}_stop"][i])
        if a < 0:
            return None
        checksum = int(rec.cols[f"{name}_checksum"][i])

        def read() -> tuple[dict[str, np.ndarray], bool]:
            frames = run.tables.frames  # the tables of the latest opening
            w, ok = frames.read(a, b)
            return w, ok and frames.checksum(a, b)[0] == checksum

        try:  # a read torn by a writer's checkpoint is read again afresh (:func:`.opening.read_afresh`)
            w, ok = read_afresh(run, read, lambda got: not got[1])
        except (StoreError, *READ_ERRORS):
            w, ok = None, False
        if w is None or not ok:
            what = f"{run.record_type.noun} {rec.ids[i]}"
            run.warn(
                f"{run.path}: the {name} window of {what} is damaged (its frames fail their checksum) and is left out."
            )
            return None
        window = Window.of(w["seq"], counts_out(w["counts"]), w["si"], t_s=w["t_s"])
        window.stored = Stored(self, a, b, checksum)
        return window

    def checked(self, record: Mapping[str, Any], label: str) -> list[tuple[str, Window | Frames]]:
        """The record's windows, checked before anything is written: column prefix, and the window
        already in this file or the frames to write."""
        out: list[tuple[str, Window | Frames]] = []
        k = len(self._run.channels)
        for key, w in (record.get("raw") or {}).items():
            if key not in WINDOW_GROUPS:
                raise StoreError(f"{label} record: unknown window {key!r} in 'raw' (use baseline and load).")
            name = WINDOW_GROUPS[key]
            if any(name == have for have, _ in out):
                raise StoreError(f"{label} record: 'raw' gives the {name} window twice.")
            if not isinstance(w, Window):
                raise StoreError(f"{label} record: its {name} window is a {type(w).__name__}, not a Window.")
            if w.stored is not None and w.stored.source is self:
                out.append((name, w))
            elif w.kept:
                out.append((name, checked_frames(w, k, label, name)))
            else:
                raise ConfigError(NOT_KEPT)
        return out

    def store(self, checked: list[tuple[str, Window | Frames]], label: str) -> tuple[dict[str, int], int]:
        """Write the windows given as frames; the record's window columns and the bytes of frames written."""
        row: dict[str, int] = {}
        nbytes = 0
        for name, w in checked:
            if isinstance(w, Frames):
                nbytes += len(w.seq) * 8 * (2 + 2 * len(self._run.channels))
                # Whole in memory: its chunks need no checkpoint of their own, the commit syncs them.
                writer = self.begin(doing=label, flush=False)
                writer.append(w.time, w.seq, w.counts, w.values)
                w = writer.finish()
            assert w.stored is not None
            s = w.stored
            row.update({f"{name}_start": s.start, f"{name}_stop": s.stop, f"{name}_checksum": s.checksum})
        return row, nbytes


def checked_frames(w: Window, k: int, label: str, which: str) -> Frames:
    """A window's frames as the writer takes them, refused in one sentence unless shaped n x ``k``."""
    seq = np.asarray(w.seq)
    n = seq.shape[0] if seq.ndim == 1 else -1
    counts = np.asarray(w.counts)
    si = np.asarray(w.si, dtype=np.float64)
    time = np.asarray(w.t_s, dtype=np.float64)
    if n < 0 or counts.shape != (n, k) or si.shape != (n, k) or time.shape != (n,):
        raise StoreError(
            f"{label} record: the {which} window must hold n frames of {k} channels "
            f"(seq (n,), counts (n,{k}), si (n,{k})), got seq {seq.shape}, counts {counts.shape}, si {si.shape}."
        )
    seq32 = (seq.astype(np.int64) % (1 << 32)).astype(np.uint32)
    return Frames(time, seq32, counts_out(counts), si)  # decimals as sent are kept exactly, not rounded
