"""The stream reader's whole-chunk path: a chunk of nothing but good integer frames, in one pass.

:class:`labcli.core.wire.StreamReader` tries :func:`whole_chunk` first on every chunk of
enough bytes; a chunk with anything else in it (a log line, a reply, noise, a decimal)
goes to the reader's line-finding path and the reference parser.
"""

from __future__ import annotations

import functools
import warnings

import numpy as np

_U32 = 1 << 32  # seq and t_us are unsigned 32-bit (labcli.core.wire.U32)


def whole_chunk(block: bytes, k: int, max_line: int) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """``seq, t_us, values`` of every line of ``block``, or None unless each is a plain integer data line.

    ``block`` holds complete lines; ``k`` values a line; ``max_line`` bytes at most before ``\\n``.
    A block shorter than _MIN_LINES data lines is left to the reader's line-by-line path.

    The common chunk is nothing but ``$D,<seq>,<t_us>,<v1>,...,<vk>*<HH>`` lines of short
    unsigned integers, so it is judged as a whole, in as few numpy calls as possible, since at
    4 KiB each call's fixed cost outweighs its work.  A ``\\r`` must sit before a ``\\n`` (and is
    then dropped, as :func:`labcli.core.wire.parse_line` drops it).  One pass finds the
    newlines; one gather reads, back from each line's end, its ``*`` and both checksum digits
    and, on from it, the ``$D,`` that opens the next line; one reduction checks every checksum.
    Then every byte but a digit or a comma becomes NUL, those the gather found become
    separators (each ``*`` a comma, each line's end a ``-1`` between lines), and a NUL left is
    a byte no data line may hold there; one ``fromstring`` reads every number, refusing an
    empty field, and each ``-1`` must close a row of ``k + 2`` numbers.  Any line that fails
    sends the chunk to :meth:`labcli.core.wire.StreamReader._parse_vectorised`, which finds it
    and hands it to :func:`labcli.core.wire.parse_line`: what is accepted here is exactly what
    :func:`labcli.core.wire.parse_line` accepts as a frame (the property tests hold both to that).
    """
    fromstring = getattr(np, "fromstring", None)  # numpy's C text parser
    if fromstring is None or len(block) < _MIN_LINES * (2 * k + 10) or not block.startswith(b"$D,"):
        return None
    rows, table = _ROWS, _CHECKSUM_LF
    if b"\r" in block:
        bare = block.replace(b"\r", b"")
        crlf = len(block) - len(bare)
        if crlf > _FEW and block.count(b"\n") == crlf:  # every line ends "\r\n", or fails the gather
            rows, table = _ROWS_CR, _CHECKSUM_CR
        elif _each_before_lf(block, crlf):
            block = bare
        else:
            return None
    # The newline before the first line is found with the others; "$D," after the last
    # line stands for the next line's, whose opening the gather reads from each line's end.
    buf = bytearray(b"\n")
    buf += block
    buf += b"$D,"
    a = np.frombuffer(buf, np.uint8)
    bounds = (a == 10).nonzero()[0]  # n + 1: line i is a[bounds[i] + 1 : bounds[i + 1]]
    n = bounds.shape[0] - 1
    ends = bounds[1:]
    if k > _BOUNDED_K or _ZEROS in block:  # else no line can be longer than max_line (see _ZEROS)
        if (ends - bounds[:-1]).max() > max_line + 1 + (rows is _ROWS_CR):
            return None
    at = ends - rows
    got = a[at]
    # Each line's bytes XOR the '\n' before it: the checksum table folds in all but the payload.
    xor = np.bitwise_xor.reduceat(a[:-4], bounds[:-1])
    hh = got[-2:]
    if got[:-2].tobytes() != _head(n, rows is _ROWS_CR) or hh.tobytes().translate(None, _HEX_DIGITS):
        return None
    if table[hh[0], hh[1]].tobytes() != xor.tobytes():
        return None
    text = buf.translate(_DIGITS_COMMAS)
    np.frombuffer(text, np.uint8).put(at[1:], _fill(n, rows is _ROWS_CR))
    if text.find(0, 4, len(text) - 1) >= 0:
        return None  # a byte other than a digit or a comma inside a line
    if not _EMPTY_FIELD_RAISES and (b",," in text or text[4] == 44):
        return None  # an empty field, which an older numpy reads up to, warns and stops at
    # "\n$D," before the first line and the "," after the last left out.
    digits = np.frombuffer(text, np.uint8, len(text) - 5, 4)
    digits.flags.writeable = False  # fromstring reads a read-only buffer: no copy to bytes
    try:
        nums = fromstring(digits, dtype=np.int64, sep=",")
    except ValueError:  # an empty field
        return None
    if nums.shape[0] != n * (k + 3):
        return None
    nums = nums.reshape(n, k + 3)
    if nums[:, -1].tobytes() != _minus_ones(n):  # k + 2 fields a line
        return None
    if _MAX(nums, axis=None) >= _U32:  # seq and t_us are unsigned 32-bit; a value may be larger
        top = nums.max(axis=0).tolist()  # fromstring saturates at 2**63 - 1 on a longer number
        if top[0] >= _U32 or top[1] >= _U32 or max(top) == _I64_MAX:
            return None
    return nums[:, 0], nums[:, 1], nums[:, 2:-1].astype(np.float64)


def _each_before_lf(block: bytes, crlf: int) -> bool:
    """Whether each of the ``crlf`` '\\r' bytes of ``block`` sits just before a '\\n'."""
    find = block.find
    i = -1
    for _ in range(crlf):  # a few a chunk: a '\r\n' now and then
        i = find(b"\r", i + 1)
        if block[i + 1] != 10:  # the block ends with '\n', so i + 1 is in it
            return False
    return True


def _fromstring_refuses_empty_fields() -> bool:
    fromstring = getattr(np, "fromstring", None)
    if fromstring is None:
        return False
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        try:
            fromstring(b"1,,2", dtype=np.int64, sep=",")
        except ValueError:
            return True
    return False


def follows_on(seq: np.ndarray, last: int | None) -> bool:
    """Whether the int64 ``seq`` climbs one step a frame on from ``last`` (a batch with none lost)."""
    return last is not None and seq.tobytes() == steps_bytes(seq.shape[0], last + 1)


def steps_bytes(n: int, first: int = 0) -> bytes:
    """``first, first + 1, ..., first + n - 1`` as int64 bytes: a batch's seq when none is lost.

    Cut from one run of numbers kept from call to call (a stream's seq climbs by the batch): a
    slice of bytes costs less than subtracting the expected first from every seq.
    """
    global _STEPS, _STEPS_FIRST
    at = first - _STEPS_FIRST
    if at < 0 or 8 * (at + n) > len(_STEPS):
        _STEPS_FIRST, at = first, 0
        _STEPS = np.arange(first, first + max(4 * n, 1 << 14), dtype=np.int64).tobytes()
    return _STEPS[8 * at : 8 * (at + n)]


_STEPS = b""
_STEPS_FIRST = 0


@functools.lru_cache(maxsize=64)
def _head(n: int, cr: bool) -> bytes:
    return b"".join(c * n for c in (b",", b"*", b"\r", b"\n", b"$", b"D") if cr or c != b"\r")


@functools.lru_cache(maxsize=64)
def _fill(n: int, cr: bool) -> np.ndarray:
    return np.repeat(_FILL_CR if cr else _FILL_LF, n, axis=1)


@functools.lru_cache(maxsize=64)
def _minus_ones(n: int) -> bytes:
    return np.full(n, -1, np.int64).tobytes()


# Rows of the per-line gather, as offsets back from each line's '\n': the next line's ',', this
# line's '*' (and '\r'), its '\n', the next line's '$' and 'D', then this line's checksum
# digits.  All but the first become _FILL_LF (_FILL_CR) in the text the numbers are read from:
# "*HH\n$D" becomes ",  -1 " (the next line's ',' stays).
_ROWS = np.array([[-3], [3], [0], [-1], [-2], [2], [1]])
_ROWS_CR = np.array([[-3], [4], [1], [0], [-1], [-2], [3], [2]])
_FILL_LF = np.array([[44], [45], [49], [32], [32], [32]], np.uint8)  # '*' '\n' '$' 'D' H H
_FILL_CR = np.array([[44], [32], [45], [49], [32], [32], [32]], np.uint8)  # '*' '\r' '\n' '$' 'D' H H
_FEW = 16  # '\r' bytes a chunk worth finding one by one
_MIN_LINES = 8  # of the shortest data line (2 k + 10 bytes): in fewer, line by line is quicker
# A field has fewer than len(_ZEROS) leading zeros unless _ZEROS is in the chunk, and at most 19
# digits after them unless fromstring saturates (which whole_chunk refuses): so at most 30
# digits, and a line of _BOUNDED_K values or fewer is at most 3 + 31 * (k + 2) + 3 <= 256 bytes.
_ZEROS = b"0" * 12
_BOUNDED_K = 6
_I64_MAX = int(np.iinfo(np.int64).max)
_MAX = np.maximum.reduce  # ndarray.max less its Python wrapper
_HEXNUM = np.full(256, -1, np.int32)
for _i, _c in enumerate(b"0123456789abcdef"):
    _HEXNUM[_c] = _i
for _i, _c in enumerate(b"ABCDEF"):
    _HEXNUM[_c] = 10 + _i
# What a line's bytes XOR the '\n' before it come to when its two checksum digits are right,
# by [first digit, second digit]: the checksum they name (the payload's XOR) ^ '\n' '$' '*'
# ^ both digits (^ '\r' for a line that ends "\r\n").  Only hex digits are looked up (whole_chunk
# checks them first), so uint8 is enough.
_DIGIT_PAIRS = np.arange(256)[:, None] ^ np.arange(256)
_CHECKSUM_LF = (((_HEXNUM[:, None] * 16 + _HEXNUM) ^ 10 ^ 36 ^ 42 ^ _DIGIT_PAIRS) & 255).astype(np.uint8)
_CHECKSUM_CR = _CHECKSUM_LF ^ np.uint8(13)
_HEX_DIGITS = b"0123456789abcdefABCDEF"
_DIGITS_COMMAS = bytes(c if 48 <= c <= 57 or c == 44 else 0 for c in range(256))
_EMPTY_FIELD_RAISES = _fromstring_refuses_empty_fields()
