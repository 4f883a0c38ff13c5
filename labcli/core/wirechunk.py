"""The stream reader's whole-chunk path: a chunk of nothing but good integer frames, in one pass.

:class:`labcli.core.wire.StreamReader` tries :func:`whole_chunk` first on every chunk of
enough lines; a chunk with anything else in it (a log line, a reply, noise, a decimal)
goes to the reader's line-finding path and the reference parser.
"""

from __future__ import annotations

import functools

import numpy as np

_U32 = 1 << 32  # seq and t_us are unsigned 32-bit (labcli.core.wire.U32)


def whole_chunk(block: bytes, n: int, k: int, max_line: int) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """``seq, t_us, values`` of every line of ``block``, or None unless each is a plain integer data line.

    ``block`` holds ``n`` complete lines; ``k`` values a line; ``max_line`` bytes at most before ``\\n``.

    The common chunk is nothing but ``$D,<seq>,<t_us>,<v1>,...,<vk>*<HH>`` lines of short
    unsigned integers, so it is judged as a whole, in as few numpy calls as possible, since at
    4 KiB each call's fixed cost outweighs its work: every ``\\r\\n`` becomes ``\\n`` (a ``\\r``
    anywhere else then fails the next check); the bytes left once digits and hex letters are
    deleted must be the line pattern itself; one pass finds the newlines, one gather reads the
    ``$D,`` that opens each line, its ``*`` and both checksum digits, one reduction checks every
    checksum, one ``fromstring`` reads every number.  Any line that fails sends the chunk to
    :meth:`labcli.core.wire.StreamReader._parse_vectorised`, which finds it and hands it to
    :func:`labcli.core.wire.parse_line`: what is accepted here is exactly what
    :func:`labcli.core.wire.parse_line` accepts as a frame (the property tests hold both to that).
    """
    fromstring = getattr(np, "fromstring", None)  # numpy's C text parser
    # Neither digits nor hex letters: "$" k + 2 commas "*" "\n" a line (a '\r' before it), nothing else.
    shape = block.translate(None, _DIGITS_HEX)
    crlf = len(shape) - n * (k + 5)
    if crlf:
        shape = shape.translate(None, b"\r")  # where each '\r' sits is checked below
    if fromstring is None or shape != _pattern(k, n):
        return None
    buf = bytearray(b"\n")  # the newline before each line's first byte is then found with the others
    buf += block
    a = np.frombuffer(buf, np.uint8)
    bounds = (a == 10).nonzero()[0]  # n + 1: line i is a[bounds[i] + 1 : bounds[i + 1]]
    if (bounds[1:] - bounds[:-1]).max() > max_line + 1:
        return None
    # (6, n): where each line's '$' ',' 'D' (from the '\n' before it) '*' and checksum should be.
    step = bounds.itemsize  # bounds[i + j] for row block i, line j, as a view: no gather
    at = (np.ndarray((2, 3, n), bounds.dtype, bounds, 0, (step, 0, step)) + _OFFSETS).reshape(6, n)
    if crlf:  # each '\r' must sit just before a '\n', where parse_line strips one
        cr = (a[at[5]] == 13).view(np.uint8)
        if np.count_nonzero(cr) != crlf:
            return None
        at[3:] -= cr
    got = a[at]
    # Each line's bytes XOR the '\n' before it: the checksum table folds in all but the payload.
    xor = np.bitwise_xor.reduceat(a[:-1], bounds[:-1])
    want = _CHECKSUM_OF[cr, got[4], got[5]] if crlf else _CHECKSUM_LF[got[4], got[5]]
    if got[:4].tobytes() != _head(n) or want.tobytes() != xor.tobytes():
        return None
    a[at[2:]] = 32  # 'D' and the checksums are not numbers to read
    text = buf.translate(_NUMBERS_ONLY)
    if 0 in text:
        return None  # a hex letter inside a number
    digits = np.frombuffer(text, np.uint8)
    digits.flags.writeable = False  # fromstring reads a read-only buffer: no copy to bytes
    nums = fromstring(digits, dtype=np.int64, sep=" ")  # an empty field shows as a missing number
    if nums.shape[0] != n * (k + 2):
        return None
    nums = nums.reshape(n, k + 2)
    if nums.max() >= _U32:  # seq and t_us are unsigned 32-bit; a value may be larger
        top = nums.max(axis=0).tolist()  # fromstring saturates at 2**63 - 1 on a longer number
        if top[0] >= _U32 or top[1] >= _U32 or max(top) == _I64_MAX:
            return None
    seq, t_us = nums[:, :2].T.copy()
    return seq, t_us, nums[:, 2:].astype(np.float64)


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
def _head(n: int) -> bytes:
    return b"$" * n + b"," * n + b"D" * n + b"*" * n


# Rows of the per-line gather: from the '\n' before the line, its '$', the ',' after 'D' and
# 'D'; from its own '\n', '*' and both checksum digits.  Rows 2-5 are blanked before the numbers
# are read; rows 3-5 move back one byte on a line that ends "\r\n".
_OFFSETS = np.array([[[1], [3], [2]], [[-3], [-2], [-1]]])
_I64_MAX = int(np.iinfo(np.int64).max)
_HEXNUM = np.full(256, -1, np.int32)
for _i, _c in enumerate(b"0123456789abcdef"):
    _HEXNUM[_c] = _i
for _i, _c in enumerate(b"ABCDEF"):
    _HEXNUM[_c] = 10 + _i
# What a line's bytes XOR the '\n' before it come to when its two checksum digits are right,
# by [ends "\r\n", first digit, second digit]: the checksum they name (the payload's XOR) ^ '\n'
# '$' '*' ^ both digits (^ '\r').  Only hex digits reach it (the line pattern and the '*' before
# them see to that), so uint8 is enough.
_DIGIT_PAIRS = np.arange(256)[:, None] ^ np.arange(256)
_CHECKSUM_LF = (((_HEXNUM[:, None] * 16 + _HEXNUM) ^ 10 ^ 36 ^ 42 ^ _DIGIT_PAIRS) & 255).astype(np.uint8)
_CHECKSUM_OF = np.stack([_CHECKSUM_LF, _CHECKSUM_LF ^ np.uint8(13)])
_HEX_LETTERS = b"abcdefABCDEF"
_DIGITS_HEX = b"0123456789" + _HEX_LETTERS
# Digits stay, separators are blank; a hex letter left once 'D' and the checksums are blanked is 0.
_NUMBERS_ONLY = bytes(c if 48 <= c <= 57 else 0 if c in _HEX_LETTERS else 32 for c in range(256))
