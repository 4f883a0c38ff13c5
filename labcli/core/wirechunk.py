"""The stream reader's whole-chunk path: a chunk of nothing but good integer frames, in one pass.

:class:`labcli.core.wire.StreamReader` tries :func:`whole_chunk` first on every chunk of
enough lines; a chunk with anything else in it (a log line, a reply, noise, a decimal)
goes to the reader's line-finding path and the reference parser.
"""

from __future__ import annotations

import functools
import warnings

import numpy as np

_U32 = 1 << 32  # seq and t_us are unsigned 32-bit (labcli.core.wire.U32)


def whole_chunk(block: bytes, n: int, k: int, max_line: int) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """``seq, t_us, values`` of every line of ``block``, or None unless each is a plain integer data line.

    ``block`` holds ``n`` complete lines; ``k`` values a line; ``max_line`` bytes at most before ``\\n``.

    The common chunk is nothing but ``$D,<seq>,<t_us>,<v1>,...,<vk>*<HH>`` lines of short
    unsigned integers, so it is judged as a whole, in as few numpy calls as possible, since at
    4 KiB each call's fixed cost outweighs its work: the bytes left once digits and hex letters
    are deleted must be the line pattern itself; a ``\\r`` must sit before a ``\\n`` (and is
    then dropped, as :func:`labcli.core.wire.parse_line` drops it); one pass finds the newlines;
    one gather reads, back from each line's end, its ``*`` and both checksum digits and, on
    from it, the ``$D,`` that opens the next line; one reduction checks every checksum; one
    ``fromstring`` reads every number, comma-separated as on the wire, and refuses an empty
    field.  Any line that fails sends the chunk to
    :meth:`labcli.core.wire.StreamReader._parse_vectorised`, which finds it and hands it to
    :func:`labcli.core.wire.parse_line`: what is accepted here is exactly what
    :func:`labcli.core.wire.parse_line` accepts as a frame (the property tests hold both to that).
    """
    fromstring = getattr(np, "fromstring", None)  # numpy's C text parser
    # Neither digits nor hex letters: "$" k + 2 commas "*" "\n" a line (a '\r' before it), nothing else.
    shape = block.translate(None, _DIGITS_HEX)
    crlf = len(shape) - n * (k + 5)
    tail, table = _TAIL, _CHECKSUM_LF
    if crlf:
        shape = shape.replace(b"\r", b"")
        if crlf == n:  # every line ends "\r\n" (the gather checks where each '\r' is)
            tail, table = _TAIL_CR, _CHECKSUM_CR
        else:
            block = _without_cr(block, crlf)
    if fromstring is None or shape != _pattern(k, n) or not block.startswith(b"$D,"):
        return None
    if not _EMPTY_FIELD_RAISES and b",," in block:
        return None  # an older numpy reads up to an empty field, warns and stops
    # The newline before the first line is found with the others; "$D," after the last
    # line stands for the next line's, whose opening the gather reads from each line's end.
    buf = bytearray(b"\n")
    buf += block
    buf += b"$D,"
    a = np.frombuffer(buf, np.uint8)
    bounds = (a == 10).nonzero()[0]  # n + 1: line i is a[bounds[i] + 1 : bounds[i + 1]]
    ends = bounds[1:]
    if k > _BOUNDED_K or _ZEROS in block:  # else no line can be longer than max_line (see _ZEROS)
        if (ends - bounds[:-1]).max() > max_line + 1 + (tail is _TAIL_CR):
            return None
    at = ends - tail  # the rows of _TAIL (and the '\r' before each '\n')
    got = a[at]
    # Each line's bytes XOR the '\n' before it: the checksum table folds in all but the payload.
    xor = np.bitwise_xor.reduceat(a[:-4], bounds[:-1])
    if got[:-2].tobytes() != _head(n, tail is _TAIL_CR) or table[got[-2], got[-1]].tobytes() != xor.tobytes():
        return None
    a[at[-3:]] = 32  # the next line's 'D' and the checksums are not numbers to read
    buf[2] = 32  # nor the first line's 'D'
    text = buf.translate(_NUMBERS_ONLY)
    if 0 in text:
        return None  # a hex letter inside a number
    # "\n$D," before the first line and "$D," after the last left out; each '*' now a comma,
    # each '\n' a 0 between lines ("...,v_k,  0  ,seq,..."), so an empty first or last field
    # is ",," and fromstring refuses it.
    digits = np.frombuffer(text, np.uint8, len(text) - 7, 4)
    digits.flags.writeable = False  # fromstring reads a read-only buffer: no copy to bytes
    try:
        nums = fromstring(digits, dtype=np.int64, sep=",")
    except ValueError:  # an empty field
        return None
    if nums.shape[0] != n * (k + 3):
        return None
    nums = nums.reshape(n, k + 3)
    if nums.max() >= _U32:  # seq and t_us are unsigned 32-bit; a value may be larger
        top = nums.max(axis=0).tolist()  # fromstring saturates at 2**63 - 1 on a longer number
        if top[0] >= _U32 or top[1] >= _U32 or max(top) == _I64_MAX:
            return None
    return nums[:, 0], nums[:, 1], nums[:, 2:-1].astype(np.float64)


def _without_cr(block: bytes, crlf: int) -> bytes:
    """``block`` less its ``crlf`` '\\r' bytes if each sits just before a '\\n', else ``b""``."""
    find = block.find
    i = -1
    for _ in range(crlf):  # a few a chunk: a '\r\n' now and then
        i = find(b"\r", i + 1)
        if block[i + 1] != 10:  # the block ends with '\n', so i + 1 is in it
            return b""
    return block.replace(b"\r", b"")


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


def steps_bytes(n: int) -> bytes:
    """``0, 1, ..., n - 1`` as int64 bytes: a batch's seq less its expected first, when none is lost."""
    global _STEPS
    if 8 * n > len(_STEPS):
        _STEPS = np.arange(2 * n, dtype=np.int64).tobytes()
    return _STEPS[: 8 * n]


_STEPS = b""


@functools.lru_cache(maxsize=64)
def _pattern(k: int, n: int) -> bytes:
    return (b"$" + b"," * (k + 2) + b"*\n") * n


@functools.lru_cache(maxsize=64)
def _head(n: int, cr: bool) -> bytes:
    return b"".join(c * n for c in (b"$", b",", b"*", b"\r", b"D") if cr or c != b"\r")


# Rows of the per-line gather, as offsets back from each line's '\n': the next line's '$' and
# ',', this line's '*' (and '\r'), then the rows blanked before the numbers are read: the next
# line's 'D' and this line's two checksum digits.
_TAIL = np.array([[-1], [-3], [3], [-2], [2], [1]])
_TAIL_CR = np.array([[-1], [-3], [4], [1], [-2], [3], [2]])
# A field has fewer than len(_ZEROS) leading zeros unless _ZEROS is in the chunk, and at most 19
# digits after them unless fromstring saturates (which whole_chunk refuses): so at most 30
# digits, and a line of _BOUNDED_K values or fewer is at most 3 + 31 * (k + 2) + 3 <= 256 bytes.
_ZEROS = b"0" * 12
_BOUNDED_K = 6
_I64_MAX = int(np.iinfo(np.int64).max)
_HEXNUM = np.full(256, -1, np.int32)
for _i, _c in enumerate(b"0123456789abcdef"):
    _HEXNUM[_c] = _i
for _i, _c in enumerate(b"ABCDEF"):
    _HEXNUM[_c] = 10 + _i
# What a line's bytes XOR the '\n' before it come to when its two checksum digits are right,
# by [first digit, second digit]: the checksum they name (the payload's XOR) ^ '\n' '$' '*'
# ^ both digits.  Only hex digits reach it (the line pattern and the '*' before
# them see to that), so uint8 is enough.
_DIGIT_PAIRS = np.arange(256)[:, None] ^ np.arange(256)
_CHECKSUM_LF = (((_HEXNUM[:, None] * 16 + _HEXNUM) ^ 10 ^ 36 ^ 42 ^ _DIGIT_PAIRS) & 255).astype(np.uint8)
_CHECKSUM_CR = _CHECKSUM_LF ^ np.uint8(13)  # the same for a line that ends "\r\n"
_HEX_LETTERS = b"abcdefABCDEF"
_DIGITS_HEX = b"0123456789" + _HEX_LETTERS
# Digits and commas stay, '*' is a comma and '\n' a 0 (see whole_chunk), other bytes are blank; a
# hex letter left once 'D' and the checksums are blanked is NUL, for whole_chunk to refuse.
_NUMBERS_ONLY = bytes(
    c if 48 <= c <= 57 or c == 44 else 44 if c == 42 else 48 if c == 10 else 0 if c in _HEX_LETTERS else 32
    for c in range(256)
)
_EMPTY_FIELD_RAISES = _fromstring_refuses_empty_fields()
