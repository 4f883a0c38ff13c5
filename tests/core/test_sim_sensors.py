"""The simulated rigs' sensor front end: transfer, offset, drift, noise, quantisation, rails."""

from __future__ import annotations

import math

import numpy as np
import pytest

from labcli.core.protocol import load_protocol
from labcli.core.registry import run_protocol
from labcli.core.sim.sensors import DRIFT_PERIOD_S, Linear, SensorChannel, SensorFrontEnd
from labcli.papers.rpam2015.sim.rig import RpamRig
from labcli.papers.takuma2014.sim.rig import SimRig

# The reference rig's pressure sensor: 1-5 V for 0-1 MPa on a 12-bit ADC at 5 V.
P = Linear(5 / (4 * 4095), 4095 / 5)


def front(*channels: SensorChannel, noise: float = 1.0, drift: float = 0.0, seed: int = 0) -> SensorFrontEnd:
    return SensorFrontEnd(
        channels,
        noise=noise,
        drift=drift,
        noise_rng=np.random.default_rng([seed, 1]),
        drift_rng=np.random.default_rng([seed, 3]),
    )


def test_a_linear_sensor_is_the_inverse_of_its_calibration():
    v = np.linspace(0.0, 1.0, 101)
    np.testing.assert_allclose(P.to_si(P(v)), v, rtol=0, atol=1e-15)
    assert P(np.array([0.0]))[0] == 819.0 and P(np.array([1.0]))[0] == pytest.approx(4095.0, abs=1e-9)


def test_without_noise_a_count_is_the_rounded_transfer_of_the_value_and_its_offset():
    f = front(SensorChannel("P", P, noise_counts=0.5, offset=0.0015), noise=0.0)
    v = np.linspace(0.0, 0.9, 50)[:, None]
    counts = f.read(v, np.zeros(50))
    assert counts.dtype == np.int64
    np.testing.assert_array_equal(counts[:, 0], np.rint(P(v[:, 0] + 0.0015)))
    # The offset of 1.5 kPa is 4.9 counts: what a zero error looks like through the calibration.
    assert f.ideal_counts(v, np.zeros(50))[0, 0] - P(np.array([0.0]))[0] == pytest.approx(0.0015 / P.gain)


@pytest.mark.parametrize("noise", [1.0, 4.0])
def test_noise_is_gaussian_at_its_rms_times_the_noise_setting(noise):
    sd = 2.5
    f = front(SensorChannel("P", P, noise_counts=sd), noise=noise)
    n = 40_000
    v = np.full((n, 1), 0.3)
    err = f.read(v, np.zeros(n))[:, 0] - f.ideal_counts(v, np.zeros(n))[:, 0]
    # Rounding adds a uniform error of 1/12 count^2 (independent of a noise this wide).
    want = math.sqrt((noise * sd) ** 2 + 1 / 12)
    assert err.std() == pytest.approx(want, rel=0.02)  # 40,000 draws: the sd is known to 0.4 %
    assert abs(err.mean()) < 4 * want / math.sqrt(n)
    # Gaussian, not uniform or two-valued: 4.6 % beyond two standard deviations.
    assert np.mean(np.abs(err) > 2 * want) == pytest.approx(0.0455, abs=0.006)


def test_drift_starts_at_zero_and_moves_no_faster_than_its_slowest_period_allows():
    amp = 3.0
    f = front(*(SensorChannel(f"C{i}", P, drift_counts=amp) for i in range(4)), noise=0.0, drift=2.0)
    assert np.all((DRIFT_PERIOD_S[0] <= f.drift_period_s) & (f.drift_period_s <= DRIFT_PERIOD_S[1]))
    t = np.linspace(0.0, 3 * 3600.0, 20_001)
    d = f.drift_at(t)
    np.testing.assert_array_equal(d[0], 0.0)
    # A sinusoid of amplitude drift x amp counts: it spans at most twice that ...
    assert np.all(d.max(axis=0) - d.min(axis=0) <= 2 * 2.0 * amp + 1e-9)
    # ... and over three hours (several periods) nearly all of it.
    assert np.all(d.max(axis=0) - d.min(axis=0) >= 0.99 * 2 * 2.0 * amp)
    # Its rate is drift x amp x 2 pi / T counts per second at most: under 0.07 count/s here.
    rate = np.abs(np.diff(d, axis=0)).max(axis=0) / (t[1] - t[0])
    np.testing.assert_array_less(rate, 2.0 * amp * 2 * np.pi / f.drift_period_s * 1.0001)
    assert rate.max() == pytest.approx((2.0 * amp * 2 * np.pi / f.drift_period_s).max(), rel=1e-3)
    # Initial slope: d/dt of amp (sin(2 pi t / T + phi) - sin phi) at 0.
    slope = (f.drift_at(np.array([1e-3])) - f.drift_at(np.array([0.0])))[0] / 1e-3
    np.testing.assert_allclose(slope, 2.0 * amp * 2 * np.pi / f.drift_period_s * np.cos(f.drift_phase), rtol=1e-4)
    # drift = 0: the same periods are drawn, and nothing moves.
    still = front(*(SensorChannel(f"C{i}", P, drift_counts=amp) for i in range(4)), noise=0.0, drift=0.0)
    np.testing.assert_array_equal(still.drift_period_s, f.drift_period_s)
    v = np.full((3, 4), 0.2)
    np.testing.assert_array_equal(still.ideal_counts(v, np.array([0.0, 600.0, 1200.0])), P(v))


def test_counts_are_held_on_the_rails_and_noise_is_drawn_for_every_sample():
    f = front(SensorChannel("P", P, noise_counts=0.5), noise=1.0, seed=5)
    g = front(SensorChannel("P", P, noise_counts=0.5), noise=1.0, seed=5)
    over = f.read(np.array([[-0.5], [2.0], [0.5]]), np.zeros(3))[:, 0]
    assert over[0] == 0 and over[1] == 4095
    # The third sample drew the third number whether or not the first two were clipped.
    inside = g.read(np.array([[0.4], [0.4], [0.5]]), np.zeros(3))[:, 0]
    assert over[2] == inside[2]
    # Same seed, same counts.
    a = front(SensorChannel("P", P, noise_counts=0.5), seed=9).read(np.full((100, 1), 0.3), np.zeros(100))
    b = front(SensorChannel("P", P, noise_counts=0.5), seed=9).read(np.full((100, 1), 0.3), np.zeros(100))
    np.testing.assert_array_equal(a, b)


@pytest.mark.parametrize("rig, protocol", [(SimRig, "takuma2014"), (RpamRig, "rpam2015")])
def test_each_rigs_counts_read_back_through_its_protocols_calibration(rig, protocol):
    r = rig(seed=2, noise=0.0, variation=False)
    calibration = run_protocol(load_protocol(protocol), "joint" if protocol == "rpam2015" else None)[1].calibration
    assert tuple(c.name for c in calibration.channels) == r.sensors.names == tuple(r.channels)
    k = len(r.channels)
    rng = np.random.default_rng(0)
    lo = np.array([c.range[0] for c in calibration.channels])
    hi = np.array([c.range[1] for c in calibration.channels])
    values = lo + (hi - lo) * rng.uniform(0.05, 0.95, (200, k))
    counts = r.sensors.read(values, np.zeros(200))
    back = calibration.to_si(counts)
    half_count = np.abs(np.array([c.gain for c in calibration.channels])) / 2
    assert np.all(np.abs(back - values) <= half_count * (1 + 1e-9))


def test_both_rigs_read_their_sensors_through_the_front_end():
    for r in (SimRig(seed=1, noise=2.0, drift=0.5), RpamRig(seed=1, noise=2.0, drift=0.5)):
        assert isinstance(r.sensors, SensorFrontEnd)
        assert (r.noise, r.drift) == (2.0, 0.5)
        assert r.sensors.rails == (0, 4095)
