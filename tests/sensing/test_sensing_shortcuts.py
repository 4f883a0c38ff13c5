"""The estimator's per-block shortcuts held to the plain numpy they stand for.

The run-time estimator does its bookkeeping once a block, where a numpy call costs more than its
arithmetic, so several pieces skip numpy's general paths: the device clock's wrap scan, the
block means, the noise's running median, the baseline's extrapolation asked twice a block, the
response fit's sums of one new block and its grid's spread.  Each must give what the general
form gives: the same numbers, bit for bit where the arithmetic is the same, and the general
form's answer on the inputs the shortcut does not take (a clock that wraps, a NaN).
"""

from __future__ import annotations

import numpy as np
import pytest

from labcli.sensing.baseline import TrendTracker
from labcli.sensing.blocks import BlockAverager, Recent
from labcli.sensing.config import EstimatorConfig
from labcli.sensing.inputs import U32, DeviceClock
from labcli.sensing.transient import ResponseFit, _grid_var


def clock_reference(batches: list[np.ndarray]) -> np.ndarray:
    """Device seconds by the plain rule: every jump back by more than half the range is a wrap."""
    t = np.concatenate(batches).astype(np.int64)
    back = np.diff(t, prepend=t[0]) < -(U32 >> 1)
    return (t + np.cumsum(back) * U32) * 1e-6


@pytest.mark.parametrize("case", ["steady", "wrap inside", "wrap between", "small jump back", "one frame"])
def test_the_clock_reads_a_wrap_wherever_it_falls_and_only_a_wrap(case):
    start = {"steady": 5_000, "wrap inside": U32 - 120_000, "wrap between": U32 - 250_000}.get(case, 9_000_000)
    t = (start + 5_000 * np.arange(100)) % U32
    if case == "small jump back":
        t[37:] -= 12_000  # the firmware's clock restarted a little back, not around
    sizes = [1] * 100 if case == "one frame" else [10] * 10
    if case == "wrap between":
        assert (t[49] > t[50]) and (t[50] < 100_000)  # the 50th frame is the first after the wrap
        sizes = [10] * 5 + [10] * 5
    batches = np.split(t, np.cumsum(sizes)[:-1])
    clock = DeviceClock()
    got = np.concatenate([clock.seconds(b) for b in batches])
    assert np.array_equal(got, clock_reference(batches))


def test_block_means_and_spreads_are_numpys_mean_and_variance_of_the_mean():
    rng = np.random.default_rng(3)
    avg = BlockAverager(6, 7)
    x = rng.normal(0.3, 1e-3, (7 * 12 + 3, 6))
    t = np.arange(len(x)) * 1e-3
    out = avg.push(t, np.arange(len(x)), x)
    xs = x[: 7 * 12].reshape(12, 7, 6)
    assert np.array_equal(out.mean, xs.mean(axis=1))
    assert np.array_equal(out.var, ((xs - xs.mean(axis=1)[:, None]) ** 2).sum(axis=1) / (6 * 7))
    assert np.array_equal(out.tc, t[: 7 * 12].reshape(12, 7).mean(axis=1))
    assert np.array_equal(out.t, t[6 : 7 * 12 : 7]) and avg.pending == 3


@pytest.mark.parametrize("n", [1, 2, 7, 8, 100, 230])
def test_the_running_median_is_numpys_median_of_the_last_rows(n):
    rng = np.random.default_rng(n)
    recent = Recent(100, 5)
    rows = rng.lognormal(-18, 1, (n, 5))
    if n > 2:
        rows[n // 2, 3] = np.nan  # a block that held a NaN: its channel's median is NaN while it is kept
    for r in rows:
        recent.append(r)
    expected = np.median(rows[-100:], axis=0)
    assert np.array_equal(recent.median(), expected, equal_nan=True)
    assert len(recent) == min(n, 100)


def test_the_baselines_extrapolation_asked_twice_is_the_same_and_follows_every_update():
    tr = TrendTracker(np.full(3, 1e-12), np.full(3, 1e-15), np.full(3, 5e-5))
    tr.start(0.0, np.array([0.3, 0.31, 0.0]), np.full(3, 1e-8))
    first = tr.at(1.0)
    again = tr.at(1.0)  # the same block asks again: the same answer, not worked out anew
    assert again[0] is first[0] and again[1] is first[1]
    tr.update(0.5, np.array([0.3001, 0.3099, 0.001]), np.full(3, 1e-8))
    fresh = TrendTracker(tr.q_level, tr.q_slope, tr.slope_sd)
    fresh.restore(tr.snapshot())
    after = tr.at(1.0)
    assert not np.array_equal(after[0], first[0])
    assert all(np.array_equal(a, b) for a, b in zip(after, fresh.at(1.0), strict=True))
    snap = tr.snapshot()
    tr.update(0.8, np.array([0.2, 0.2, 0.1]), np.full(3, 1e-8))
    tr.restore(snap)
    assert all(np.array_equal(a, b) for a, b in zip(tr.at(1.0), after, strict=True))


def grid_var_reference(values: np.ndarray, best: tuple[int, ...]) -> np.ndarray:
    out = np.zeros(values.shape[-1])
    for axis, i in enumerate(best):
        n = values.shape[axis]
        if n < 2:
            continue
        lo, hi = max(i - 1, 0), min(i + 1, n - 1)
        a, b = list(best), list(best)
        a[axis], b[axis] = lo, hi
        out += ((values[tuple(b)] - values[tuple(a)]) / (hi - lo)) ** 2 / 12.0
    return out


@pytest.mark.parametrize("shape", [(9, 9, 5, 6), (1, 4, 1, 3), (3, 1, 2, 2)])
def test_the_grids_spread_is_the_loop_over_its_axes(shape):
    rng = np.random.default_rng(len(shape) + shape[0])
    values = rng.normal(size=shape)
    for best in [(0, 0, 0), tuple(s - 1 for s in shape[:3]), tuple(s // 2 for s in shape[:3])]:
        assert np.array_equal(_grid_var(values, best), grid_var_reference(values, best))


def test_a_fit_summed_block_by_block_is_the_fit_of_its_blocks_summed_at_once():
    c, k, p = EstimatorConfig(), 6, 4
    rng = np.random.default_rng(8)

    def fit() -> ResponseFit:
        return ResponseFit(
            0.0,
            k,
            taus=c.tau_s * np.asarray(c.tau_factors),
            shifts=c.block_s * np.asarray(c.onset_shifts_blocks),
            thermal_tau=c.thermal_tau_s,
            kappas=np.asarray(c.thermal_kappas),
            capacity=200,
            heated=(np.arange(k) < p).astype(float),
            shared=np.arange(k) < p,
        )

    one, many = fit(), fit()
    for i in range(60):
        t = c.block_s * (i + 0.5)
        e = 0.01 * np.arange(1, k + 1) * (1 - np.exp(-t / 0.8)) + rng.normal(0, 1e-4, k)
        one.add(t, e, np.full(k, 1e-8))
        one.solve()  # a block at a time: the one-block sums
        many.add(t, e, np.full(k, 1e-8))
    a, b = one.solve(), many.solve()  # all 60 at once: the general sums
    for name in ("A", "B", "var_A", "var_B"):
        np.testing.assert_allclose(getattr(a, name), getattr(b, name), rtol=1e-12, atol=0)
    assert a.tau == pytest.approx(b.tau, rel=1e-12)
