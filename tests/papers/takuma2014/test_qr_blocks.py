"""A tall design's R factor built from row blocks is the whole design's, up to the signs of its rows."""

from __future__ import annotations

import numpy as np
import pytest

from labcli.papers.takuma2014.models.posture import _Blocks
from labcli.papers.takuma2014.models.takuma import QR_ROWS, qr_r


def _same_up_to_row_signs(r: np.ndarray, ref: np.ndarray) -> None:
    signs = np.sign(np.diag(r)) * np.sign(np.diag(ref))
    np.testing.assert_allclose(r * signs[:, None], ref, rtol=1e-10, atol=1e-12 * np.abs(ref).max())


@pytest.mark.parametrize("rows", [2 * QR_ROWS + 1, 3 * QR_ROWS + 17, 5 * QR_ROWS])
@pytest.mark.parametrize("cols", [4, 7, 16])
def test_a_tall_design_factors_by_row_blocks_as_it_does_whole(rows, cols):
    rng = np.random.default_rng(rows + cols)
    a = rng.normal(size=(rows, cols)) * np.logspace(0, 3, cols)  # columns of unlike scales
    r = qr_r(a)
    assert r.shape == (cols, cols) and np.allclose(np.tril(r, -1), 0)
    _same_up_to_row_signs(r, np.linalg.qr(a, mode="r"))
    np.testing.assert_allclose(r.T @ r, a.T @ a, rtol=1e-9)  # the Gram matrix, signs aside


def test_short_or_narrow_designs_are_factored_whole_by_numpy():
    rng = np.random.default_rng(1)
    for shape in [(2 * QR_ROWS, 16), (5 * QR_ROWS, 3), (100, 80)]:
        a = rng.normal(size=shape)
        np.testing.assert_array_equal(qr_r(a), np.linalg.qr(a, mode="r"))


def test_the_cross_validation_blocks_are_factored_in_cache_sized_pieces_to_the_same_r():
    rng = np.random.default_rng(2)
    whole = rng.normal(size=(25 * QR_ROWS + 3, 9))
    calls: list[int] = []

    def block(lo: int, hi: int) -> np.ndarray:
        calls.append(hi - lo)
        return whole[lo:hi]

    blocks = _Blocks.build(len(whole), 7, block)
    edges = np.linspace(0, len(whole), 11).astype(int)
    assert max(calls) <= QR_ROWS  # every long fold built a piece at a time
    for f, (lo, hi) in enumerate(zip(edges[:-1], edges[1:], strict=True)):
        _same_up_to_row_signs(blocks.factors[f], np.linalg.qr(whole[lo:hi], mode="r"))
