"""The stream reader's whole-chunk path: a chunk of nothing but good integer frames, in one pass.

:class:`labcli.core.wire.StreamReader` tries :func:`whole_chunk` first on every chunk of
enough lines; a chunk with anything else in it (a log line, a reply, noise, a decimal)
goes to the reader's line-finding path and the reference parser.
"""

from __future__ import annotations

import numpy as np

_U32 = 1 << 32  # seq and t_us are unsigned 32-bit (labcli.core.wire.U32)


def whole_chunk(block: bytes, n: int, k: int, max_line: int) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """``seq, t_us, values`` of every line of ``block``, or None unless each is a plain integer data line.

    ``block`` holds ``n`` complete lines; ``k`` values a line; ``max_line`` bytes at most before ``\\n``.

    The common chunk is nothing but ``$D,<seq>,<t_us>,<v1>,...,<vk>*<HH>`` lines of short
    unsigned integers, so it is judged as a whole, with as few passes as numpy's fixed cost
    per call allows at 4 KiB: the bytes left once digits and hex letters are deleted must be
    the line pattern itself; one pass locates the separators (field widths, the checksum's
    place), one reduction checks every checksum, one ``fromstring`` reads every number.  Any
    line that fails sends the chunk to :meth:`labcli.core.wire.StreamReader._parse_vectorised`, which finds it
    and hands it to :func:`labcli.core.wire.parse_line`: what is accepted here is exactly what
    :func:`labcli.core.wire.parse_line` accepts as a frame (the property tests hold both to that).
    """
    fromstring = getattr(np, "fromstring", None)  # numpy's C text parser
    crlf = block.count(b"\r")
    if fromstring is None or (crlf and block.count(b"\r\n") != crlf):
        return None
    if not block.startswith(b"$D,") or block.count(b"\n$D,") != n - 1:
        return None  # each line opens "$D,"
    # Neither digits, hex letters nor "\r": "$" k + 2 commas "*" "\n" a line, nothing else.
    if block.translate(None, _DIGITS_HEX_CR) != (b"$" + b"," * (k + 2) + b"*\n") * n:
        return None
    a = np.frombuffer(block, np.uint8)
    low = a < 48  # '$' ',' '*' '\r' '\n': nothing else is left below '0', as shown above
    sep = np.flatnonzero(low & (a != 13) if crlf else low).reshape(n, k + 5)  # '$' commas '*' '\n'
    nl = sep[:, k + 4]
    if sep[-1, k + 3] + 3 > nl[-1]:
        return None  # fewer than two checksum digits at the end
    # At most max_line bytes before '\n' (a '\r' there is counted against it here).
    if nl[0] > max_line or (nl[1:] - nl[:-1]).max(initial=0) > max_line + 1:
        return None
    at = sep[:, _AT_COLUMNS[k]] + _AT_OFFSETS  # the 'D', both checksum digits, the byte after them
    got = a[at]
    xor = np.bitwise_xor.reduceat(a, sep[:, :: k + 3].ravel())[::2]  # '$' ^ the payload
    ok = xor == _CHECKSUM_OF[got[:, 1], got[:, 2]]
    ok &= got[:, 3] <= 13  # no third checksum digit
    if not ok.all():
        return None
    blanked = bytearray(block)
    np.frombuffer(blanked, np.uint8)[at[:, :3]] = 32  # 'D' and the checksums are not numbers to read
    text = bytes(blanked).translate(_NUMBERS_ONLY)
    if 0 in text:
        return None  # a hex letter inside a number
    nums = fromstring(text, dtype=np.int64, sep=" ")  # an empty field shows as a missing number
    if nums.shape[0] != n * (k + 2):
        return None
    nums = nums.reshape(n, k + 2)
    if nums.max() >= _U32:  # seq and t_us are unsigned 32-bit; a value may be larger
        top = nums.max(axis=0).tolist()  # fromstring saturates at 2**63 - 1 on a longer number
        if top[0] >= _U32 or top[1] >= _U32 or max(top) == _I64_MAX:
            return None
    seq, t_us = nums[:, :2].T.copy()
    return seq, t_us, nums[:, 2:].astype(np.float64)


class _Columns(dict):  # k -> the sep columns of the 'D' ('$' + 1) and of '*' (+1, +2, +3)
    def __missing__(self, k: int) -> np.ndarray:
        self[k] = np.array([0, k + 3, k + 3, k + 3])
        return self[k]


_AT_COLUMNS = _Columns()
_AT_OFFSETS = np.array([1, 1, 2, 3])
_I64_MAX = int(np.iinfo(np.int64).max)
_HEXNUM = np.full(256, -1, np.int32)
for _i, _c in enumerate(b"0123456789abcdef"):
    _HEXNUM[_c] = _i
for _i, _c in enumerate(b"ABCDEF"):
    _HEXNUM[_c] = 10 + _i
# The checksum two hex digits name, XOR '$' (the reduction starts at it); not hex: -1, no XOR's.
_CHECKSUM_OF = np.where((_HEXNUM[:, None] >= 0) & (_HEXNUM[None, :] >= 0), (_HEXNUM[:, None] * 16 + _HEXNUM) ^ 36, -1)
_HEX_LETTERS = b"abcdefABCDEF"
_DIGITS_HEX_CR = b"0123456789\r" + _HEX_LETTERS
# Digits stay, separators are blank; a hex letter left once 'D' and the checksums are blanked is 0.
_NUMBERS_ONLY = bytes(c if 48 <= c <= 57 else 0 if c in _HEX_LETTERS else 32 for c in range(256))
