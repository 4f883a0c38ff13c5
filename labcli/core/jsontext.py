"""JSON typed by hand or written by another program, read without surprises.

``json.loads`` turns a 400-digit integer into a Python int that ``float()`` cannot take
(OverflowError), refuses 5000 digits outright (ValueError: the int-conversion limit) and
recurses once per level of nesting (RecursionError at ~1000).  :func:`loads_bounded`
parses numbers too large for a float into :class:`OutOfRange` markers, which every
field check refuses by name, and refuses nesting deeper than any labcli document before
parsing starts.  :func:`json_kind` names a parsed value in a message.
"""

from __future__ import annotations

import json
import math
import re
import secrets
from collections.abc import Mapping
from itertools import accumulate
from typing import Any

from .nogc import paused_gc

MAX_DEPTH = 64  # labcli's own documents nest at most 5 deep (a covariance matrix in a model)
_FLOAT_DIGITS = 308  # any integer of this many digits or fewer is below 1.8e308
_STRING = re.compile(r'"(?:[^"\\]|\\.)*"', re.DOTALL)
_BRACKETS = re.compile(r"[^\[\]{}]+")
# Numbers that may not fit a float; without any, json's own (C) number parsing is safe and fast.
_HUGE_NUMBER = re.compile(rf"[0-9]{{{_FLOAT_DIGITS + 1}}}|[eE][+-]?[0-9]{{3}}")
LONG_TEXT = 20_000  # characters past which the scans below go whole-array
# Each byte to what it may be in a number: a digit 0, an exponent letter e, a sign +, else a space.
_NUMBER_SHAPES = bytes(
    ord("0")
    if chr(b).isdigit() and b < 128
    else ord("e")
    if chr(b) in "eE"
    else ord("+")
    if chr(b) in "+-"
    else ord(" ")
    for b in range(256)
)


class OutOfRange:
    """A JSON number no float can hold (``1e400``, a 400-digit integer); its text is kept."""

    def __init__(self, text: str) -> None:
        self.text = text

    def describe(self) -> str:
        digits = len(self.text.lstrip("-"))
        if self.text.lstrip("-").isdigit():
            return f"a {digits}-digit number (beyond the largest float, about 1.8e308)"
        return f"the number {self.text[:40]} (beyond the largest float, about 1.8e308)"

    def __repr__(self) -> str:  # for a debugger, never shown in a message
        return f"OutOfRange({self.text[:20]!r}...)"


def _int(text: str) -> int | OutOfRange:
    return int(text) if len(text.lstrip("-")) <= _FLOAT_DIGITS else OutOfRange(text)


def _float(text: str) -> float | OutOfRange:
    v = float(text)
    return v if math.isfinite(v) else OutOfRange(text)


def nesting_depth(text: str) -> int:
    """How deep the brackets of a JSON text nest, strings left out (no parsing, no recursion)."""
    if len(text) > LONG_TEXT and "\\" not in text:
        return _long_nesting_depth(text)
    bare = _STRING.sub("", text)
    brackets = _BRACKETS.sub("", bare)
    if not brackets:
        return 0
    return max(accumulate(1 if c in "[{" else -1 for c in brackets))


def _long_nesting_depth(text: str) -> int:
    """:func:`nesting_depth` of a long text without a backslash, whole-array.

    A model of a random split has 10^6 brackets among 15 MB, where the string pattern's pass took
    a tenth of a second.  With no backslash no quote is escaped, so every double quote opens or
    closes a string, as the pattern would pair them: a bracket is in a string when an odd number
    of quotes come before it.  (A bracket or quote is one byte of UTF-8, never part of another
    character's bytes.)
    """
    import numpy as np

    codes = np.frombuffer(text.encode("utf-8", "surrogatepass"), dtype=np.uint8)
    step = np.zeros(len(codes), dtype=np.int8)
    step[(codes == ord("[")) | (codes == ord("{"))] = 1
    step[(codes == ord("]")) | (codes == ord("}"))] = -1
    at = np.flatnonzero(step)
    quotes = np.flatnonzero(codes == ord('"'))
    at = at[np.searchsorted(quotes, at) % 2 == 0]  # outside every string
    return int(np.max(np.cumsum(step[at], dtype=np.int64))) if len(at) else 0


def _may_hold_huge_number(text: str) -> bool:
    """Whether ``text`` holds a match of :data:`_HUGE_NUMBER` (309 digits in a row, or an exponent
    of three digits); a long text is searched as bytes with every digit made ``0``, every exponent
    letter ``e`` and every sign ``+``, where the pattern tried at every digit of a model's 10^6
    trial ids took a third of a second."""
    if len(text) <= LONG_TEXT:
        return _HUGE_NUMBER.search(text) is not None
    plain = text.encode("utf-8", "surrogatepass").translate(_NUMBER_SHAPES)
    return b"0" * (_FLOAT_DIGITS + 1) in plain or b"e000" in plain or b"e+000" in plain


class JSONDepthError(ValueError):
    """The text nests deeper than :data:`MAX_DEPTH`; ``depth`` says how deep."""

    def __init__(self, depth: int) -> None:
        super().__init__(f"nested {depth} levels deep")
        self.depth = depth


def loads_bounded(text: str) -> Any:
    """``json.loads`` that never overflows or recurses deeply.

    Raises :class:`json.JSONDecodeError` for bad syntax and :class:`JSONDepthError` for
    nesting beyond :data:`MAX_DEPTH`; numbers beyond a float come back as :class:`OutOfRange`.
    """
    if len(text) > LONG_TEXT:
        with paused_gc():
            fast = _with_pair_lists(text)
        if fast is not None:
            return fast
    return _loads_checked(text)


def _loads_checked(text: str, max_depth: int = MAX_DEPTH) -> Any:
    depth = nesting_depth(text)
    if depth > max_depth:
        raise JSONDepthError(depth)
    with paused_gc():  # a model file's 10^5 trial ranges are as many lists: no cycles among them
        if not _may_hold_huge_number(text):
            return json.loads(text)  # no number of 309 digits or a 3-digit exponent: every one fits a float
        return json.loads(text, parse_int=_int, parse_float=_float)


class PairList(list):  # noqa: FURB189 (a plain list to every reader; ``array`` beside it)
    """A list of ``[a, b]`` pairs of ints read whole-array: the pairs as lists, and ``array`` (n, 2)
    int64 the same numbers, for a reader that wants them as an array (:mod:`labcli.core.idranges`)."""

    array: Any


PAIR_LIST_MIN = 20_000  # characters: a list of pairs this long is read whole-array
_DIGITS_AND_MINUS = str.maketrans("", "", "0123456789-")
_BRACKETS_TO_SPACE = str.maketrans("[]", "  ")


def _pair_list(segment: str) -> PairList | None:
    """``json.loads(segment)`` for ``[[a, b], [c, d], ...]`` of whole numbers written as the writer
    writes them (``", "`` between items, no other space), read whole-array; None for anything else.

    A model fitted on a random split lists its trials as 10^5 such pairs per equation, 15 MB of a
    file json read item by item.  The text is checked to be exactly that shape: its characters
    other than digits and minus signs are the pairs' brackets and separators, each number is
    parsed, and the numbers' own decimal widths (a minus sign for each negative one, no leading
    zero, no ``-0``) add up to the digits there are, so the list is the one json would read.
    """
    import warnings

    import numpy as np

    k = segment.count("[") - 1
    shape = "[" + ", ".join(["[, ]"] * k) + "]"
    if k < 1 or segment.translate(_DIGITS_AND_MINUS) != shape:
        return None
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("error")  # a token numpy reads only in part: not such a list
            a = np.fromstring(segment.translate(_BRACKETS_TO_SPACE), dtype=np.int64, sep=",")
    except (ValueError, DeprecationWarning, OverflowError):
        return None
    if len(a) != 2 * k or not np.all(np.abs(a) < 10**15):
        return None
    negative = int(np.count_nonzero(a < 0))
    widths = np.searchsorted(10 ** np.arange(1, 16, dtype=np.int64), np.abs(a), side="right") + 1
    digits = len(segment) - len(shape)  # the digits and minus signs
    if segment.count("-") != negative or int(widths.sum()) + negative != digits:
        return None
    pairs = a.reshape(-1, 2)
    out = PairList(pairs.tolist())
    out.array = pairs
    return out


def _with_pair_lists(text: str) -> Any:
    """:func:`loads_bounded` of a long text with its long lists of pairs read whole-array
    (:func:`_pair_list`), or None: the caller reads it whole.

    Each such list is put in the text's place of a string no text holds, the rest is read as
    usual (its checks, on what remains, take a fraction of the time), and the lists are put
    back.  Anything off (a backslash anywhere, a list not of the writer's shape, the rest not
    valid JSON or nested within two levels of the limit) gives None, and the whole text is read
    as before: its error, if any, names its own line and column.
    """
    if "\\" in text:
        return None
    mark = f"pair-list-{secrets.token_hex(8)}-"
    pieces: list[str] = []
    lists: list[PairList] = []
    at = search = 0
    close = -1  # the first "]]" at or after the last start looked at: the same for every start before it
    while (start := text.find("[[", search)) >= 0:
        if close < start and (close := text.find("]]", start)) < 0:
            break
        end, search = close + 2, start + 2
        # A list of pairs opens with "[[" once: a run of brackets ("[[[[") is passed in one step each.
        if end - start >= PAIR_LIST_MIN and text.find("[[", start + 1, end) < 0 and _value_place(text, start, end):
            parsed = _pair_list(text[start:end])
            if parsed is not None:
                pieces += [text[at:start], f'"{mark}{len(lists)}"']
                lists.append(parsed)
                at = search = end
    if not lists:
        return None
    try:
        rest = _loads_checked("".join([*pieces, text[at:]]), MAX_DEPTH - 2)
    except (json.JSONDecodeError, JSONDepthError):
        return None
    placed: list[int] = []
    rest = _put_back(rest, mark, lists, placed)
    # Each list back in its one place, as a value: a mark left as an object's key (a text json
    # refuses, as a key must be a string) or placed twice is no such document.
    return rest if sorted(placed) == list(range(len(lists))) else None


def _value_place(text: str, start: int, end: int) -> bool:
    """Whether ``text[start:end]`` stands where a JSON value does: after ``:``, ``[`` or ``,`` and
    before ``,``, ``]`` or ``}`` (spaces aside)."""
    before = text[max(0, start - 64) : start].rstrip()
    after = text[end : end + 64].lstrip()
    return bool(before) and before[-1] in ":[," and bool(after) and after[0] in ",]}"


def _put_back(value: Any, mark: str, lists: list[PairList], placed: list[int]) -> Any:
    """``value`` with each string ``mark + k`` replaced by ``lists[k]`` (``k`` noted in ``placed``)."""
    if isinstance(value, str):
        if not value.startswith(mark):
            return value
        k = int(value[len(mark) :])
        placed.append(k)
        return lists[k]
    if isinstance(value, dict):
        for key, v in value.items():
            if isinstance(v, (dict, list, str)):
                value[key] = _put_back(v, mark, lists, placed)
    elif isinstance(value, list) and not all(type(v) in (int, float) for v in value):
        for i, v in enumerate(value):
            if isinstance(v, (dict, list, str)):
                value[i] = _put_back(v, mark, lists, placed)
    return value


def json_kind(v: Any) -> str:
    """A parsed JSON value named for a message: ``the string 'big'``, ``a list``, ``null``."""
    if v is None:
        return "null"
    if isinstance(v, OutOfRange):
        return v.describe()
    if isinstance(v, bool):
        return f"the boolean {str(v).lower()}"
    if isinstance(v, str):
        return f"the string {v[:40]!r}"
    if isinstance(v, (int, float)):
        return f"the number {v!r}"
    if isinstance(v, Mapping):
        return "an object"
    if isinstance(v, list):
        return "a list"
    return type(v).__name__


LONG_LIST = 100  # a list of more whole numbers than this goes on one line of indented JSON


class PlainList(list):
    """A list whose items are plain JSON already (numbers, strings, lists of them): written as it is.

    :func:`dumps_indented` puts a long one on one line without looking at its items, and a
    model's ``to_dict`` keeps it without cleaning them (:class:`labcli.core.idranges.Ranges`).
    """


def dumps_indented(value: Any, *, allow_nan: bool = True) -> str:
    """``json.dumps(value, indent=2)``, with each long list of whole numbers (trial ids) or :class:`PlainList`
    (trial ranges) on one line.

    A list of many ids one per line would make a document mostly line breaks, and indented
    output goes through json's pure-Python encoder, item by item.  Model files list their fitted
    trials as ranges (:mod:`labcli.core.idranges`): one pair for a contiguous split, but 10^5
    for a random split of an archive, which the indented encoder took seven seconds to write
    one number a line.  The same JSON value either way.
    """
    long_lists: list[list[int]] = []
    index: dict[int, int] = {}  # id() of a list in ``value`` (alive throughout) -> its place in long_lists
    mark = f"long-list-{secrets.token_hex(8)}-"  # a fresh mark: no text in the document can hold it

    def swap(v: Any) -> Any:
        if isinstance(v, dict):
            return {k: swap(x) for k, x in v.items()}
        if isinstance(v, (list, tuple)):
            if len(v) > LONG_LIST and (isinstance(v, PlainList) or all(type(x) is int for x in v)):
                # Encoded once however often the one list appears: a model lists its trial ranges
                # for each of its equations (10^5 pairs each on a random split of an archive).
                if id(v) not in index:
                    index[id(v)] = len(long_lists)
                    long_lists.append(list(v))
                return f"{mark}{index[id(v)]}"
            return [swap(x) for x in v]
        return v

    text = json.dumps(swap(value), indent=2, allow_nan=allow_nan)
    for k, ids in enumerate(long_lists):
        text = text.replace(f'"{mark}{k}"', json.dumps(ids, separators=(", ", ": ")))
    return text
