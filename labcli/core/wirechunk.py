"""The stream reader's whole-chunk path: a chunk of nothing but good integer frames, in one pass.

:class:`labcli.core.wire.StreamReader` tries :func:`clean_rows` first on every chunk of enough
bytes (with the partial line carried from the chunk before; a read of fewer than 8 lines is
judged line by line in Python first); a chunk with anything else in it
(a log line, a reply, noise, a decimal) goes to the reader's line-finding path (whose digit
decoding, :func:`digits_to_rows`, is here too) and the reference parser.

The common chunk is nothing but ``$D,<seq>,<t_us>,<v1>,...,<vk>*<HH>`` lines of short unsigned
integers, so it is judged as a whole, in as few numpy calls as possible, since at 4 KiB each
call's fixed cost outweighs its work.  A ``\\r`` must sit before a ``\\n`` (and is then dropped,
as :func:`labcli.core.wire.parse_line` drops it).  One pass finds the newlines; one gather reads
the 8 bytes from each line's ``*`` (``*HH\\n$D,`` and the next line's first digit, or
``*HH\\r\\n$D,``) as one 64-bit number, and their shape is checked as bytes; one reduction XORs
every line, checked against what both checksum digits make it (two ``bytes.translate`` tables,
the n lines compared as one number).  A blank or a sign anywhere refuses the chunk (fromstring
would read past it or take it for a number's); two 32-bit writes a line turn each line's end
into ``,  -1 ,`` (a ``-1`` between lines); one ``fromstring`` reads every number, refusing an
empty field and any byte but a digit or a comma (a numpy that only warns at those has every
such byte made a NUL, and looked for, first).  The high 32 bits of every number, as bytes, then say at once that each ``-1``
closes a row of ``k + 2`` numbers and that every number is below 2**32 (else the rows and ranges
are checked one by one).  Any line that fails sends the chunk to
:meth:`labcli.core.wire.StreamReader._parse_vectorised`, which finds it and hands it to
:func:`labcli.core.wire.parse_line`: what is accepted here is exactly what
:func:`labcli.core.wire.parse_line` accepts as a frame (the property tests hold both to that).
"""

from __future__ import annotations

import functools
import sys
import warnings

import numpy as np

_U32 = 1 << 32  # seq and t_us are unsigned 32-bit (labcli.core.wire.U32)


def whole_chunk(block: bytes, k: int, max_line: int) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """``seq, t_us, values`` of every line of ``block``, or None unless each is a plain integer data line.

    ``block`` holds complete lines; ``k`` values a line; ``max_line`` bytes at most before ``\\n``.
    The stream reader calls :func:`clean_rows` on its carried bytes and the new chunk directly.
    """
    rows = clean_rows(b"", block, len(block), k, max_line)
    return None if rows is None else (rows[:, 0], rows[:, 1], rows[:, 2:-1].astype(np.float64))


def clean_rows(head: bytes, data: bytes, end: int, k: int, max_line: int) -> np.ndarray | None:
    """The rows ``seq, t_us, v1..vk, -1`` (int64) of the lines ``head + data[:end]``, or None.

    None unless every line is a plain integer data line (see the module's docstring for how
    that is judged); ``data[:end]`` ends with ``\\n`` (``head`` is the partial line carried from
    the previous chunk).  A block shorter than _MIN_LINES data lines is left to the reader's
    line-by-line path.
    """
    fromstring = getattr(np, "fromstring", None)  # numpy's C text parser
    if fromstring is None or len(head) + end < _MIN_LINES * (2 * k + 10):
        return None
    # Four bytes before the '\n' that opens the first line let each window below start at a line's
    # '\n' position itself (no index arithmetic); "$D,0" after the last line stands for the next
    # line's opening, which is read after each line's end.
    buf = bytearray(b"####\n")
    buf += head
    buf += data[:end] if end < len(data) else data
    if buf[4:8] != b"\n$D,":
        return None
    crlf = 0
    if 13 in buf:  # (a byte as a number: a bytes operand would first fail as one, at a cost)
        bare = buf.replace(b"\r", b"")
        crlf = len(buf) - len(bare)
        if crlf <= _FEW:  # a '\r\n' now and then: each found one by one
            if not _each_before_lf(buf, crlf):
                return None
            buf, crlf = bare, 0
    buf += b"$D,0"
    a = np.frombuffer(buf, np.uint8, -1, 4)
    bounds = (a == 10).nonzero()[0]  # n + 1: line i is a[bounds[i] + 1 : bounds[i + 1]]
    n = bounds.shape[0] - 1
    wide = crlf == n  # every line ends "\r\n" (checked by the window below)
    if crlf and not wide:  # many '\r', not one a line: found one by one
        if not _each_before_lf(buf, crlf):
            return None
        return clean_rows(b"", bytes(bare[5:]), len(bare) - 5, k, max_line)
    ends = bounds[1:]
    # 8 bytes from each line's '*': "*HH\n$D,<first digit of the next seq>" or "*HH\r\n$D,", read
    # as one unaligned 64-bit number each (a gather of n items, not 8 n).
    got = np.ndarray((a.shape[0] - 4,), _U8LE, buf, 0 if wide else 1, (1,))[ends]
    g = got.tobytes()
    if g.translate(_AS_H) != _shape(n, wide) or g[5 + wide :: 8] != _D(n):
        return None
    # Each line's bytes XOR the '\n' before it, against what both checksum digits make it (the
    # tables fold in all but the payload), as three numbers of n bytes.
    xor = np.bitwise_xor.reduceat(a[:-5], bounds[:-1]).tobytes()
    first = g[1::8].translate(_CHECKSUM_FIRST_CR if wide else _CHECKSUM_FIRST)
    if int.from_bytes(first, "little") ^ int.from_bytes(g[2::8].translate(_CHECKSUM_SECOND), "little") != (
        int.from_bytes(xor, "little")
    ):
        return None
    if not _EMPTY_FIELD_RAISES:  # an older numpy reads up to a stray byte, warns and stops
        text = buf.translate(_DIGITS_COMMAS)  # every byte but a digit or a comma a NUL, found below
    elif 32 in buf or 45 in buf or 43 in buf or 9 in buf or 11 in buf or 12 in buf:  # " -+\t\v\f"
        return None  # a blank or a sign, which fromstring reads past or as part of a number ('\n'
        # and '\r' are only at the lines' ends, which are written over)
    else:
        text = buf  # fromstring itself refuses any other byte but a digit or a comma
    # Each line's end becomes ",  -1 ," (",   -1 ,"): a -1 between lines, in two 32-bit writes.
    np.ndarray((a.shape[0] - 3,), _U4LE, text, 0 if wide else 1, (1,))[ends] = _FILL_CR if wide else _FILL_LF
    np.ndarray((a.shape[0] - 3,), _U4LE, text, 4, (1,))[ends] = _FILL_NEXT
    if not _EMPTY_FIELD_RAISES and (text.find(0, 8) >= 0 or text.find(b",,") >= 0 or text[8] == 44):
        return None  # a stray byte (a NUL now) or an empty field, found before fromstring meets it
    try:  # "####\n$D," before the first line and the "0" after the last left out
        nums = fromstring(bytes(memoryview(text)[8:-1]), dtype=np.int64, sep=",")
    except ValueError:  # a byte but a digit or a comma, or an empty field
        return None
    if nums.view(np.uint32)[_HIGH::2].tobytes() == _high_words(n, k):
        # The common chunk, judged by the high 32 bits of every number: 0 (a number below 2**32)
        # but for a -1 closing each row of k + 2 (the only negative numbers are those -1).
        if k > _BOUNDED_K or buf.find(_MANY_ZEROS) >= 0:  # else no line is longer than max_line (_ZEROS)
            if _MAX(ends - bounds[:-1]) > max_line + 1 + wide:
                return None
        return nums.reshape(n, k + 3)
    overlong = (k > _BOUNDED_K or buf.find(_ZEROS) >= 0) and _MAX(ends - bounds[:-1]) > max_line + 1 + wide
    return _checked_rows(nums, n, k, overlong)


def _checked_rows(nums: np.ndarray, n: int, k: int, overlong: bool) -> np.ndarray | None:
    """``nums`` as ``n`` rows if each has ``k + 2`` numbers and a -1, seq and t_us below 2**32."""
    if nums.shape[0] != n * (k + 3):
        return None
    nums = nums.reshape(n, k + 3)
    if nums[:, -1].tobytes() != _minus_ones(n):  # k + 2 fields a line
        return None
    top = nums.max(axis=0).tolist()  # fromstring saturates at 2**63 - 1 on a longer number
    if top[0] >= _U32 or top[1] >= _U32 or max(top) == _I64_MAX:  # seq and t_us are unsigned 32-bit
        return None
    return None if overlong else nums


def digits_to_rows(
    a: np.ndarray, lo: np.ndarray, hi: np.ndarray, k: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Decode ``a[lo:hi]`` ranges of ``digits(,digits)*\\*`` into numbers, all lines at once.

    The reader's line-finding path calls it on the lines it found to be plain integer data
    lines.  Returns ``seq, t_us, values`` and a per-line mask of lines whose numbers fit the fast
    path (seq/t_us below 2**32, values of at most 15 digits); the others are for
    :func:`labcli.core.wire.parse_line` to judge.
    """
    lens = hi - lo
    n = lens.shape[0]
    total = int(lens.sum())
    first = np.cumsum(lens) - lens
    b = a[np.repeat(lo - first, lens) + np.arange(total, dtype=np.int64)]
    seppos = np.flatnonzero((b == 44) | (b == 42))  # n * (k + 2) separators, one ending each field
    flen: np.ndarray = np.empty_like(seppos)
    flen[0] = seppos[0]
    flen[1:] = seppos[1:] - seppos[:-1] - 1
    flen = flen.reshape(n, k + 2)
    b[first + lens - 1] = 44  # '*' -> ',' : one separator throughout
    nums = _parse_csv_ints(b, seppos).reshape(n, k + 2)
    valid = (
        (flen[:, 0] <= _MAX_U32_DIGITS)
        & (flen[:, 1] <= _MAX_U32_DIGITS)
        & (flen[:, 2:] <= _MAX_VALUE_DIGITS).all(axis=1)
    )
    valid &= (nums[:, 0] < _U32) & (nums[:, 1] < _U32)
    return nums[:, 0].copy(), nums[:, 1].copy(), nums[:, 2:].astype(np.float64), valid


def _parse_csv_ints(b: np.ndarray, seppos: np.ndarray) -> np.ndarray:
    """``b``: ASCII digits, each field ended by ','.  Too-long fields come out wrong, never raise."""
    try:
        # numpy's C text parser: one call for the whole chunk (saturates on overflow).
        nums = np.fromstring(b.tobytes(), dtype=np.int64, sep=",")
        if nums.shape[0] == seppos.shape[0]:
            return nums
    except (AttributeError, ValueError):  # a numpy without text-mode fromstring
        pass
    # Place value by place value: digit * 10**(distance to its field's end), summed per field.
    total = b.shape[0]
    sep = b == 44
    power = seppos[np.cumsum(sep) - sep] - np.arange(total) - 1
    np.clip(power, 0, 18, out=power)
    digit = b.astype(np.int64) - 48
    digit[sep] = 0
    fstart = np.empty_like(seppos)
    fstart[0] = 0
    fstart[1:] = seppos[:-1] + 1
    return np.add.reduceat(digit * _POW10[power], fstart)


def _each_before_lf(block: bytes | bytearray, crlf: int) -> bool:
    """Whether each of the ``crlf`` '\\r' bytes of ``block`` sits just before a '\\n'."""
    find = block.find
    i = -1
    for _ in range(crlf):  # a few a chunk: a '\r\n' now and then
        i = find(b"\r", i + 1)
        if block[i + 1] != 10:  # the block ends with '\n', so i + 1 is in it
            return False
    return True


def _fromstring_refuses_empty_fields() -> bool:
    """Whether numpy's fromstring raises at an empty field and at any byte it cannot read.

    A blank or a sign it reads as part of a number (as strtol does), so the whole-chunk path
    refuses those itself; an older numpy warns and stops instead of raising.
    """
    fromstring = getattr(np, "fromstring", None)
    if fromstring is None:
        return False
    refused = 0
    strays = (b"1,,2", b"1,\x002", b"1,2\x00,3", b"1,2,3\x00", b"1,2x,3", b"1,*2", b"1,$2", b"1,2.5", b"1,\xff2")
    for text in strays:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            try:
                fromstring(text, dtype=np.int64, sep=",")
            except ValueError:
                refused += 1
    return refused == len(strays)


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
def _shape(n: int, wide: bool) -> bytes:
    """What the 8 bytes from each of ``n`` good lines' ``*`` read as once each hex digit is an ``H``."""
    return (b"*HH\r\n$H," if wide else b"*HH\n$H,H") * n


@functools.lru_cache(maxsize=64)
def _D(n: int) -> bytes:
    return b"D" * n


@functools.lru_cache(maxsize=64)
def _high_words(n: int, k: int) -> bytes:
    """The high 32 bits of ``n`` rows of ``k + 2`` numbers below 2**32 and a -1 each, as bytes."""
    return (b"\0" * 4 * (k + 2) + b"\xff" * 4) * n


@functools.lru_cache(maxsize=64)
def _minus_ones(n: int) -> bytes:
    return np.full(n, -1, np.int64).tobytes()


# What "*HH\n$D," ("*HH\r\n$D,") becomes in the text the numbers are read from: the '*' a comma,
# the line's end a -1 between two lines (the next line's ',' stays); written 4 bytes at a time,
# from the '*' and from the '\n'.
_FILL_LF = int.from_bytes(b",  -", "little")
_FILL_CR = int.from_bytes(b",   ", "little")
_FILL_NEXT = int.from_bytes(b"-1 ,", "little")
_FEW = 16  # '\r' bytes a chunk worth finding one by one
_MIN_LINES = 8  # of the shortest data line (2 k + 10 bytes): in fewer, line by line is quicker
# A field has fewer than len(_ZEROS) leading zeros unless _ZEROS is in the chunk, and at most 19
# digits after them unless fromstring saturates (which clean_rows refuses): so at most 30
# digits, and a line of _BOUNDED_K values or fewer is at most 3 + 31 * (k + 2) + 3 <= 256 bytes.
# With every number below 2**32 (10 digits), fewer than len(_MANY_ZEROS) leading zeros keep a
# field within 30 digits too; the longer run is the quicker to search for.
_ZEROS = b"0" * 12
_POW10 = 10 ** np.arange(19, dtype=np.int64)
_MAX_VALUE_DIGITS = 15  # below 2**53: counts stay exact in float64
_MAX_U32_DIGITS = 10
_MANY_ZEROS = b"0" * 21
_BOUNDED_K = 6
_I64_MAX = int(np.iinfo(np.int64).max)
_MAX = np.maximum.reduce  # ndarray.max less its Python wrapper
_U8LE, _U4LE = np.dtype("<u8"), np.dtype("<u4")  # (a dtype object, not its name to parse each call)
_HIGH = 1 if sys.byteorder == "little" else 0  # which 32-bit half of an int64 holds its high bits
_HEXNUM = np.full(256, -1, np.int32)
for _i, _c in enumerate(b"0123456789abcdef"):
    _HEXNUM[_c] = _i
for _i, _c in enumerate(b"ABCDEF"):
    _HEXNUM[_c] = 10 + _i
# What a line's bytes XOR the '\n' before it come to when its two checksum digits are right,
# by [first digit, second digit]: the checksum they name (the payload's XOR) ^ '\n' '$' '*'
# ^ both digits (^ '\r' for a line that ends "\r\n").  Only hex digits are looked up (clean_rows
# checks them first), so uint8 is enough.
_DIGIT_PAIRS = np.arange(256)[:, None] ^ np.arange(256)
_CHECKSUM_LF = (((_HEXNUM[:, None] * 16 + _HEXNUM) ^ 10 ^ 36 ^ 42 ^ _DIGIT_PAIRS) & 255).astype(np.uint8)
_CHECKSUM_CR = _CHECKSUM_LF ^ np.uint8(13)
# The same as the XOR of one byte for each digit (the checksum's two nibbles share no bit):
# _CHECKSUM_FIRST[H1] ^ _CHECKSUM_SECOND[H2] == _CHECKSUM_LF[H1, H2], each a bytes.translate table.
_CHECKSUM_FIRST = bytes((((_HEXNUM << 4) ^ np.arange(256) ^ 10 ^ 36 ^ 42) & 255).astype(np.uint8))
_CHECKSUM_FIRST_CR = bytes((((_HEXNUM << 4) ^ np.arange(256) ^ 10 ^ 36 ^ 42 ^ 13) & 255).astype(np.uint8))
_CHECKSUM_SECOND = bytes(((_HEXNUM ^ np.arange(256)) & 255).astype(np.uint8))
# A hex digit becomes 'H' (and an 'H', no hex digit, a NUL): the window's shape is then one run of bytes.
_AS_H = bytes(72 if c in b"0123456789abcdefABCDEF" else 0 if c == 72 else c for c in range(256))
_DIGITS_COMMAS = bytes(c if 48 <= c <= 57 or c == 44 else 0 for c in range(256))
_EMPTY_FIELD_RAISES = _fromstring_refuses_empty_fields()
