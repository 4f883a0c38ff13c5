"""The exchange tables read whole columns at a time: pandas' C parser, then checks on arrays.

:func:`read_fast` gives the table exactly as the cell-by-cell reader of
:mod:`labcli.core.tables` would (same values, same types, same columns), or None whenever
the file holds anything that reader might judge differently: then that reader runs and
finds every problem by file, row and column.  So the exact sentences of a bad table come
from one place, and a good table of a million rows is read at pandas' speed.

None is returned, before or after parsing, for:

* anything pandas might read more leniently than the table rules: a double quote, a NUL,
  the words pandas takes for booleans (``True``, ``FALSE``, ...), a carriage return that
  does not end a line, a row whose number of cells differs from the header's, a blank
  line before the header, a header with an unnamed, repeated or missing column;
* anything that fails a rule: a cell pandas cannot parse as its column's type, a value out
  of its range, an empty required number, a repeated id, a pair of columns half given, a
  row the caller's check refuses.

Row numbers are never computed here: a table that reads this way has no problem to name.
"""

from __future__ import annotations

import codecs
import os
import re
import warnings
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

import numpy as np

from .bounds import QUANTITIES, number_problem_mask, wrap_degrees_array
from .cells import TableSpec, infer_extra_column

if TYPE_CHECKING:  # pragma: no cover
    import pandas as pd

BLOCK = 1 << 22  # bytes scanned at a time: memory stays flat whatever the file's size
_TEXT_KINDS = ("set", "set-required", "name", "text")


def read_fast(
    path: str | os.PathLike, spec: TableSpec, span: tuple[float, float], screen: Callable[[pd.DataFrame], bool] | None
) -> pd.DataFrame | None:
    """The table at ``path`` read whole-column, or None: the cell-by-cell reader decides.

    ``screen(frame) -> bool`` says whether any row may fail the caller's own checks.
    """
    header = _scan(path)
    if header is None or not _header_fits(header, spec):
        return None
    frame = _parse(path, header, spec)
    if frame is None or not _values_fit(frame, spec, span) or (screen is not None and screen(frame)):
        return None
    return _assemble(frame, header, spec)


# --------------------------------------------------------------------------- the bytes


def _scan(path: str | os.PathLike) -> list[str] | None:
    """The header's names when the file is plain and every line has the header's number of cells.

    Lines are counted whole-array per block: the separators of the file must be the
    header's count times the lines that are not blank, and the first data line must have
    the header's count itself (pandas would take a longer first line as an index column;
    a longer line after it, it refuses), so no line is short and none long.  The blocks are
    read into one buffer, the unfinished line moved to its start: a fresh 4 MiB object per
    block (and the copies that joined and cut them) cost three times the counting.
    """
    seen = _Lines()
    try:
        with open(path, "rb", buffering=0) as fh:
            buf, held = bytearray(BLOCK), 0
            while True:
                if len(buf) < held + BLOCK:  # a line longer than a block: room for the next one after it
                    buf.extend(bytes(held + BLOCK - len(buf)))
                with memoryview(buf) as view:
                    got = fh.readinto(view[held : held + BLOCK])
                if not got:
                    seen.decoder.decode(b"", True)  # raises on a cut character: the slow reader names it
                    tail = bytes(buf[:held])
                    data = tail.rstrip(b"\r\n") + b"\n" if tail.strip(b"\r\n") else b""
                    if data and not seen.take(data, len(data)):
                        return None
                    break
                end = held + got
                seen.decode(buf, held, end)
                cut = buf.rfind(b"\n", 0, end) + 1
                if cut and not seen.take(buf, cut):
                    return None
                buf[: end - cut] = buf[cut:end]
                held = end - cut
    except (OSError, UnicodeDecodeError):
        return None
    header = seen.header
    if header is None or seen.separators != (len(header) - 1) * seen.lines:
        return None
    return header


class _Lines:
    """What :func:`_scan` has read: the header, the separators and the lines that are not blank."""

    def __init__(self) -> None:
        self.decoder = codecs.getincrementaldecoder("utf-8")()
        self.header: list[str] | None = None
        self.first_line_checked = False
        self.separators = self.lines = 0

    def decode(self, buf: bytearray, start: int, stop: int) -> None:
        """Check ``buf[start:stop]`` is UTF-8 (raises on a bad byte: the slow reader names it)."""
        if self.decoder.getstate()[0] or np.frombuffer(buf, np.uint8, stop - start, start).max() >= 0x80:
            self.decoder.decode(bytes(buf[start:stop]), False)

    def take(self, data: bytes | bytearray, stop: int) -> bool:
        """Count the whole lines ``data[:stop]``; False when they are not plain or the first data line is off."""
        if not _plain(data, stop):
            return False
        at = 0  # the lines are whole: after the header's block, a block starts with a line
        if self.header is None:
            self.header = _line(data, 0, stop).decode("utf-8-sig").rstrip("\r").split(",")
            at = data.find(b"\n", 0, stop) + 1
        # The line after the header, in whichever block it comes (once checked on a block's
        # second line when the header ended its block).
        if not self.first_line_checked and at < stop:
            self.first_line_checked = True
            if _line(data, at, stop).count(b",") != len(self.header) - 1:
                return False
        s, n = _count(data, stop)
        self.separators += s
        self.lines += n
        return True


def _line(data: bytes | bytearray, at: int, stop: int) -> bytes:
    end = data.find(b"\n", at, stop)
    return bytes(data[at : end if end >= 0 else stop])


def _count(data: bytes | bytearray, stop: int) -> tuple[int, int]:
    """Separators and lines that are not blank in ``data[:stop]`` (whole lines, each ending in a line break).

    A blank line is a line break right after another (or after a carriage return that follows
    one, or at the block's start): without one, every line break ends a line that is not blank,
    and their count is the line breaks' (the array of line ends built otherwise took three times
    the rest of the scan).
    """
    a = np.frombuffer(data, dtype=np.uint8, count=stop)
    breaks = a == 10
    if not _blank_line(a, breaks, data.find(b"\r", 0, stop) >= 0):
        return int(np.count_nonzero(a == 44)), int(np.count_nonzero(breaks))
    ends = np.flatnonzero(a == 10)
    starts = np.empty_like(ends)
    starts[:1] = 0
    starts[1:] = ends[:-1] + 1
    length = ends - starts - (a[np.maximum(ends - 1, 0)] == 13)
    return int(np.count_nonzero(a == 44)), int(np.count_nonzero(length > 0))


def _blank_line(a: np.ndarray, breaks: np.ndarray, has_cr: bool) -> bool:
    """Whether the whole lines ``a`` (``breaks`` its line breaks) hold a blank one: a line break at
    the start or right after another, or a carriage return there before one (``has_cr``: any at all)."""
    if not len(a):
        return False
    if breaks[0] or np.any(breaks[1:] & breaks[:-1]):
        return True
    if not has_cr or len(a) < 2:
        return False
    return bool((a[0] == 13 and breaks[1]) or np.any(breaks[:-2] & (a[1:-1] == 13) & breaks[2:]))


def _plain(data: bytes | bytearray, stop: int) -> bool:
    """No quoting, NUL, boolean word or bare carriage return in ``data[:stop]``: pandas reads it as the rules do."""
    if data.find(b'"', 0, stop) >= 0 or data.find(b"\x00", 0, stop) >= 0:
        return False
    if data.find(b"\r", 0, stop) >= 0 and data.count(b"\r", 0, stop) != data.count(b"\r\n", 0, stop):
        return False
    # pandas reads true/false (any case) in a number column as 1 and 0; the letters u and s
    # are in every such word, and rarely in a table of numbers and fit/validation.  Only a
    # whole cell is such a word: a column named true_stiffness_N_per_m is not.
    if any(data.find(c, 0, stop) >= 0 for c in (b"u", b"U", b"s", b"S")):
        low = bytes(data[:stop]).lower()
        if b"true" in low or b"false" in low:
            return not _boolean_cell(low)
    return True


_BOOLEAN_CELL = re.compile(rb"(?:^|,)[ \t]*(?:true|false)[ \t]*(?=,|\r?$)", re.M)


def _boolean_cell(low: bytes, most: int = 64) -> bool:
    """Whether a whole cell of ``low`` is true or false: the pattern tried on the lines that hold
    either word only (a header's true_stiffness_N_per_m is one line, where the pattern over a
    whole block cost a tenth of a second at 10^5 pushes), or on the block past ``most`` of them."""
    lines: set[int] = set()
    for word in (b"true", b"false"):
        at = low.find(word)
        while at >= 0:
            lines.add(low.rfind(b"\n", 0, at) + 1)
            if len(lines) > most:
                return _BOOLEAN_CELL.search(low) is not None
            at = low.find(word, at + len(word))
    for start in lines:
        end = low.find(b"\n", start)
        if _BOOLEAN_CELL.search(low, start, len(low) if end < 0 else end):
            return True
    return False


def _header_fits(header: list[str], spec: TableSpec) -> bool:
    names = [h.strip() for h in header]
    if not names or "" in names or len(set(names)) != len(names):
        return False
    if any(p == "required" and c not in names for c, _, p in spec.columns):
        return False
    return all((a in names) == (b in names) for a, b in spec.pairs)


# --------------------------------------------------------------------------- the columns


def _parse(path: str | os.PathLike, header: list[str], spec: TableSpec) -> pd.DataFrame | None:
    import pandas as pd

    kinds = {c: k for c, k, _ in spec.columns}
    names = [h.strip() for h in header]
    dtype: dict[str, Any] = {}
    empty_ok: dict[str, list[str]] = {}
    for name in names:
        kind = kinds.get(name, "text")
        if kind == "id":
            dtype[name] = "int64"
        elif kind in _TEXT_KINDS:
            dtype[name] = object
        else:
            dtype[name] = "float64"
            if kind.endswith("-or-empty"):
                empty_ok[name] = [""]
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # a cast of inf or a huge id: refused below, or by the slow reader
            return pd.read_csv(
                path,
                sep=",",
                header=0,
                names=names,
                dtype=dtype,
                keep_default_na=False,
                na_values=empty_ok,
                encoding="utf-8",
                engine="c",
                skip_blank_lines=True,
                index_col=False,
                **_exact_floats(),
            )
    except (ValueError, OverflowError, TypeError, pd.errors.ParserError, UnicodeDecodeError, MemoryError):
        return None


def _exact_floats() -> dict[str, str]:
    """pandas before 3.1 parses floats exactly only when asked (3.1 does always, and deprecates asking)."""
    import pandas as pd

    major, minor = (int(x) for x in pd.__version__.split(".")[:2])
    return {} if (major, minor) >= (3, 1) else {"float_precision": "round_trip"}


def _values_fit(frame: pd.DataFrame, spec: TableSpec, span: tuple[float, float]) -> bool:
    """Every cell within its kind's rules, ids unique, pairs given together."""
    present = set(frame.columns)
    for c, kind, _ in spec.columns:
        if c not in present:
            continue
        col = frame[c]
        if kind == "id":
            if col.duplicated().any():
                return False
        elif kind in ("set", "set-required"):
            allowed = ("fit", "validation", "") if kind == "set" else ("fit", "validation")
            if not col.isin(allowed).all():
                return False
        elif kind == "name":
            if not col.str.strip().astype(bool).all():
                return False
        elif kind != "text":
            v = col.to_numpy(dtype=np.float64)
            base = kind.removesuffix("-or-empty")
            given = ~np.isnan(v) if base != kind else np.ones(len(v), dtype=bool)
            if not np.all(np.isfinite(v[given])) or np.any(number_problem_mask(base, v[given], span)):
                return False
    for a, b in spec.pairs:
        if a in present and (np.isnan(frame[a].to_numpy()) != np.isnan(frame[b].to_numpy())).any():
            return False
    return True


def _assemble(frame: pd.DataFrame, header: list[str], spec: TableSpec) -> pd.DataFrame:
    """The spec's columns in order (absent ones empty, directions wrapped), then the extras as read."""
    import pandas as pd

    n = len(frame)
    out: dict[str, Any] = {}
    for c, kind, _ in spec.columns:
        base = kind.removesuffix("-or-empty")
        if c in frame.columns:
            col = frame[c]
            if base in QUANTITIES and QUANTITIES[base].wrap:
                col = pd.Series(wrap_degrees_array(col.to_numpy()), dtype="float64")
            out[c] = col.reset_index(drop=True)
        elif kind in ("set", "text"):
            out[c] = pd.Series([""] * n, dtype=object)
        else:
            out[c] = pd.Series(np.full(n, np.nan), dtype="float64")
    known = set(spec.names)
    for name in (h.strip() for h in header):
        if name not in known:
            out[name] = infer_extra_column(frame[name].tolist())
    # copy=False: the columns as parsed, not consolidated into a second copy of the whole table.
    return pd.DataFrame(out, copy=False)
