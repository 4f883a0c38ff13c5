"""The change detector and the baseline tracker (labcli/sensing/detector.py, baseline.py)."""

from __future__ import annotations

import numpy as np
import pytest

from labcli.sensing.baseline import TrendTracker
from labcli.sensing.detector import ChangeDetector, whiten

WINDOWS = (1, 2, 4, 8, 16, 32, 64)


def test_white_noise_raises_almost_no_change():
    # chi-square(3) above 30 is 1.4e-6; 7 windows over 12,000 blocks (10 min at 20 blocks/s)
    # make about 0.1 false alarms expected: more than 2 would mean the statistic is not chi-square.
    rng = np.random.default_rng(1)
    det, alarms = ChangeDetector(WINDOWS, 30.0, 3), 0
    for z in rng.standard_normal((12_000, 4)):
        if det.push(z - z.mean()):
            alarms += 1
            det.reset()
    assert alarms <= 2


def test_a_small_step_is_found_within_the_windows_that_average_it():
    # 0.8 sd on two channels in opposite directions: no block sees it alone; 16-32 blocks of it do.
    rng = np.random.default_rng(2)
    det = ChangeDetector(WINDOWS, 30.0, 3)
    for z in rng.standard_normal((200, 4)):
        assert not det.push(z - z.mean())
    step = np.array([0.8, -0.8, 0.0, 0.0])
    found = None
    for i, z in enumerate(rng.standard_normal((100, 4)) + step):
        if det.push(z - z.mean()):
            found = i
            break
    assert found is not None and 5 <= found <= 60


def test_the_common_mode_is_no_change_and_wander_spares_long_windows():
    e = np.full(4, 3e-4)  # all four chambers 0.3 kPa lower: a leak, not a load
    assert np.allclose(whiten(e, np.full(4, 1e-8)), 0.0)
    # A bias of 0.2 sd that does not average away: 64 blocks of it are chi-square 2.6 alone, but
    # with the reference allowed to wander by 0.2 sd the window's statistic stays near its noise.
    det, calm = ChangeDetector(WINDOWS, 30.0, 3), ChangeDetector(WINDOWS, 30.0, 3)
    bias = np.array([0.2, -0.2, 0.2, -0.2]) * 2.0
    for _ in range(64):
        det.push(bias)
        calm.push(bias, wander=0.5)
    assert det.last > 30.0
    assert calm.last < 30.0


def test_the_tracker_follows_a_leak_and_keeps_its_slope_through_a_reset():
    rng = np.random.default_rng(3)
    tr = TrendTracker(np.full(2, 1e-12), np.full(2, 1e-15), np.full(2, 5e-5))
    slope = np.array([-1.7e-5, -0.9e-5])  # MPa/s: about 1.0 and 0.5 kPa/min
    t = 0.025 + 0.05 * np.arange(2400)  # 2 minutes of blocks
    y = 0.3 + np.outer(t, slope) + 5e-5 * rng.standard_normal((len(t), 2))
    tr.start(t[0], y[0], np.full(2, 1e-8))
    for ti, yi in zip(t[1:], y[1:], strict=True):
        tr.update(ti, yi, np.full(2, 2.5e-9))
    np.testing.assert_allclose(tr.slope, slope, rtol=0.1)
    level, var = tr.at(t[-1])
    assert np.all(np.abs(level - (0.3 + slope * t[-1])) < 3 * np.sqrt(var))
    later, later_var = tr.at(t[-1] + 30.0)
    np.testing.assert_allclose(later - level, slope * 30.0, rtol=0.1)
    assert np.all(later_var > var)
    tr.reset(t[-1], level + 0.002, np.full(2, 1e-9))
    np.testing.assert_allclose(tr.slope, slope, rtol=0.1)
    assert tr.at(t[-1])[0] == pytest.approx(level + 0.002)
