"""Equilibrium detection on synthetic first-order-lag signals (labcli.core.settle)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from labcli.core.settle import (
    BLOCKS,
    TAIL_MAX,
    TAIL_WINDOWS,
    SettleCriteria,
    SettleDetector,
    TimeUnwrapper,
    remaining_tail,
)

RATE = 200.0
TAU = 1.0  # s, first-order lag time constant
STEP_MPA = 0.02  # 20 kPa pressure step
STEP_RAD = math.radians(4.0)
CRIT = SettleCriteria(
    window_s=1.0, hold_s=2.0, pressure_spread_MPa=0.002, angle_spread_rad=math.radians(0.5), timeout_s=30.0
)


def lag(t: np.ndarray, step: float) -> np.ndarray:
    return step * (1.0 - np.exp(-t / TAU))


def signals(duration_s: float, noise_mpa: float = 0.0, noise_rad: float = 0.0, seed: int = 0):
    """Four pressures and two angles, each a first-order lag to its own step."""
    t = np.arange(int(duration_s * RATE)) / RATE
    rng = np.random.default_rng(seed)
    cols = [lag(t, STEP_MPA * s) for s in (1.0, -0.7, 0.4, -0.2)]
    cols += [lag(t, STEP_RAD), lag(t, -0.5 * STEP_RAD)]
    si = np.column_stack(cols)
    si[:, :4] += rng.normal(0, noise_mpa, (len(t), 4)) if noise_mpa else 0
    si[:, 4:] += rng.normal(0, noise_rad, (len(t), 2)) if noise_rad else 0
    return t, si


def run(t, si, chunk=37, crit=CRIT):
    det = SettleDetector(crit, [0, 1, 2, 3], [4, 5])
    history = []
    for a in range(0, len(t), chunk):
        s = det.update(t[a : a + chunk], si[a : a + chunk])
        history.append(s)
        if s.settled or s.timed_out:
            break
    return det, history


def analytic_quiet_start(crit: SettleCriteria) -> float:
    """First block boundary where both rules hold for the largest lag (closed form).

    The mean of exp(-t/tau) over [a, a+b] is tau exp(-a/tau) (1 - exp(-b/tau)) / b.  Spread:
    the range of the block means over the last window (first block mean - last block mean).
    Tail: window means A, B, C of the last three windows; an exponential has d2 / d1 =
    exp(-w/tau) = r and the rule counts |d2| min(r / (1 - r), TAIL_MAX).
    """
    b, w = crit.window_s / BLOCKS, crit.window_s
    r = math.exp(-w / TAU)
    k = TAIL_WINDOWS * BLOCKS
    while True:
        T = k * b

        def mean(a, span):
            return TAU * math.exp(-a / TAU) * (1 - math.exp(-span / TAU)) / span

        spread = mean(T - w, b) - mean(T - b, b)
        d2 = mean(T - 2 * w, w) - mean(T - w, w)
        tail = d2 * min(r / (1 - r), TAIL_MAX)
        if (
            max(spread, tail) * STEP_MPA < crit.pressure_spread_MPa
            and max(spread, tail) * STEP_RAD < crit.angle_spread_rad
        ):
            return T
        k += 1


def test_settles_when_the_closed_form_says_and_not_before():
    t, si = signals(10.0)
    det, history = run(t, si)
    final = history[-1]
    expected_quiet = analytic_quiet_start(CRIT)
    # 20 kPa step, tau 1 s: block-mean range 0.0307 e^-T MPa < 2 kPa from T = 2.73 s; the tail
    # (1.7 kPa left after the third window) can be judged from 3 s: quiet from 3.0 s.
    assert expected_quiet == pytest.approx(3.0, abs=1e-9)
    assert final.settled
    assert final.settle_time_s == pytest.approx(expected_quiet, abs=1e-9)
    assert final.elapsed_s == pytest.approx(expected_quiet + CRIT.hold_s, abs=1e-9)
    # No earlier status claimed equilibrium.
    assert not any(s.settled for s in history[:-1])
    # At the moment of settling, what is left of the step is below the threshold.
    assert STEP_MPA * math.exp(-final.elapsed_s / TAU) < CRIT.pressure_spread_MPa


def thermal_signals(duration_s: float, excess_mpa: float, tau_th: float, noise_mpa: float = 0.0, seed: int = 0):
    """A load step (lag TAU) whose pressures overshoot by ``excess_mpa`` and relax with ``tau_th``."""
    t = np.arange(int(duration_s * RATE)) / RATE
    rng = np.random.default_rng(seed)
    lagged = 1.0 - np.exp(-t / TAU)
    # Heat of compression: rises with the lag, leaves with tau_th (the rig's closed form).
    heat = tau_th * (np.exp(-t / tau_th) - np.exp(-t / TAU)) / (tau_th - TAU)
    si = np.zeros((len(t), 6))
    for k, sgn in enumerate((1.0, -1.0, 0.8, -0.8)):
        si[:, k] = sgn * (0.006 * lagged + excess_mpa * heat / heat.max())
    si[:, 4] = math.radians(1.5) * lagged
    if noise_mpa:
        si[:, :4] += rng.normal(0, noise_mpa, (len(t), 4))
    return t, si, heat / heat.max()


def test_a_slow_thermal_tail_is_waited_out_not_accepted_by_its_small_spread():
    # The air's excess pressure after a fast load relaxes over seconds: its spread over a
    # 1 s window is a fraction of what is left, so a spread rule alone accepts it too early.
    crit = SettleCriteria(
        window_s=1.0, hold_s=2.0, pressure_spread_MPa=0.00025, angle_spread_rad=math.radians(0.1), timeout_s=60.0
    )
    excess = 0.0015  # 1.5 kPa: the rig's overshoot after 1 kg
    settle = {}
    for tau_th in (2.0, 3.0, 4.0):
        t, si, heat = thermal_signals(40.0, excess, tau_th)
        final = run(t, si, crit=crit)[1][-1]
        assert final.settled
        left = excess * np.interp(final.settle_time_s, t, heat)
        assert left < crit.pressure_spread_MPa  # what the detector accepted is within the threshold
        # Spread alone: the first window whose block-mean range is under the threshold.
        b = crit.window_s / BLOCKS
        means = [si[(t >= k * b) & (t < (k + 1) * b), 0].mean() for k in range(int(40 / b))]
        spread_ok = next(
            k for k in range(BLOCKS, len(means)) if np.ptp(means[k - BLOCKS : k]) < crit.pressure_spread_MPa
        )
        assert excess * np.interp(spread_ok * b, t, heat) > 1.5 * crit.pressure_spread_MPa  # too early
        settle[tau_th] = final.settle_time_s
    # The wait grows with the thermal time constant as the excess's own decay does:
    # ln(excess / threshold) = 1.8 s per second of tau_th.
    per_second = (settle[4.0] - settle[2.0]) / 2.0
    assert per_second == pytest.approx(math.log(excess / crit.pressure_spread_MPa), rel=0.15)


def test_the_tail_estimate_is_aitkens_limit_of_an_exponential():
    A, B, C = (np.array([1 - math.exp(-k / 2.0)]) for k in (0, 1, 2))
    r = math.exp(-1 / 2.0)
    limit_left = 1.0 - C[0]
    assert remaining_tail(A, B, C)[0] == pytest.approx(min(limit_left, TAIL_MAX * (C - B)[0]), rel=1e-12)
    # A creep (no decay) counts TAIL_MAX steps; a hump (no trend) counts its larger step.
    assert remaining_tail(np.array([0.0]), np.array([1.0]), np.array([2.0]))[0] == TAIL_MAX
    assert remaining_tail(np.array([0.0]), np.array([1.0]), np.array([0.5]))[0] == 1.0
    assert r / (1 - r) < TAIL_MAX


def test_sensor_noise_does_not_hold_a_settled_leaking_rig_back():
    # A leak of 2 kPa/min (a creep) plus sensor noise: settles at the earliest time.
    crit = SettleCriteria(
        window_s=1.0, hold_s=2.0, pressure_spread_MPa=0.0003, angle_spread_rad=math.radians(0.1), timeout_s=30.0
    )
    t = np.arange(int(20 * RATE)) / RATE
    si = np.zeros((len(t), 6))
    # The rig's pressure noise: 0.5 count rms plus rounding, 0.18 kPa.
    for seed in range(5):
        si[:, :4] = 0.3 - 2e-3 / 60 * t[:, None] + np.random.default_rng(seed).normal(0, 0.00018, (len(t), 4))
        final = run(t, si, crit=crit)[1][-1]
        assert final.settled
        assert final.elapsed_s <= TAIL_WINDOWS * crit.window_s + crit.hold_s + 1.5


def test_batch_size_does_not_change_the_answer():
    t, si = signals(10.0, noise_mpa=0.0003, noise_rad=math.radians(0.08))
    results = {chunk: run(t, si, chunk=chunk)[1][-1] for chunk in (1, 7, 200, 5000)}
    times = {round(r.elapsed_s, 9) for r in results.values()}
    assert len(times) == 1


def test_sensor_noise_of_one_count_does_not_delay_or_hasten_much():
    # One ADC count of pressure is 0.305 kPa, of angle 0.083 deg.
    clean = run(*signals(10.0))[1][-1]
    for seed in range(5):
        noisy = run(*signals(10.0, 0.000305, math.radians(0.083), seed=seed))[1][-1]
        assert noisy.settled
        assert abs(noisy.elapsed_s - clean.elapsed_s) <= 0.3


def test_the_angle_criterion_alone_holds_equilibrium_back():
    # Pressures flat from the start; the angle still creeps at 1 deg/s for 5 s.
    t = np.arange(int(12 * RATE)) / RATE
    si = np.zeros((len(t), 6))
    si[:, 4] = np.radians(np.minimum(t, 5.0))
    det, history = run(t, si)
    final = history[-1]
    assert final.settled
    # The ramp stops at 5 s; the window is quiet once it holds only the flat part, and the
    # tail rule once the ramp's last 0.1 s has left the middle window (d1 = 0.995 deg,
    # d2 = 0.405 deg, r / (1 - r) = 0.686: 0.28 deg < 0.5 deg at 6.1 s).
    assert 5.0 <= final.settle_time_s <= 6.1 + 1e-9
    assert final.elapsed_s == pytest.approx(final.settle_time_s + CRIT.hold_s, abs=1e-9)


def test_a_disturbance_during_the_hold_restarts_it():
    t, si = signals(16.0)
    bump_at = 4.0  # inside the first hold (2.8 s .. 4.8 s)
    si[t >= bump_at, 0] += 0.005  # 5 kPa step: someone knocked the weight
    det, history = run(t, si)
    final = history[-1]
    assert final.settled
    assert final.settle_time_s >= bump_at + CRIT.window_s - 1e-9
    assert final.elapsed_s == pytest.approx(final.settle_time_s + CRIT.hold_s, abs=1e-9)


def test_timeout_when_the_joint_keeps_creeping_and_wait_longer():
    crit = SettleCriteria(1.0, 2.0, 0.002, math.radians(0.5), timeout_s=5.0)
    t = np.arange(int(20 * RATE)) / RATE
    si = np.zeros((len(t), 6))
    si[:, 1] = 0.003 * t  # 3 kPa/s creep: range over 0.9 s of block centres is 2.7 kPa
    det, history = run(t, si, chunk=50, crit=crit)
    final = history[-1]
    assert final.timed_out and not final.settled
    assert final.elapsed_s == pytest.approx(5.0, abs=50 / RATE)
    # Block means 0.9 s apart on a 3 kPa/s ramp (to within one sample of block-edge rounding).
    assert final.pressure_spread_MPa == pytest.approx(0.003 * 0.9, abs=0.003 / RATE)
    det.extend_timeout()
    assert not det.status.timed_out
    rest = np.searchsorted(t, final.elapsed_s, side="right")
    s = det.update(t[rest : rest + int(4 * RATE)], si[rest : rest + int(4 * RATE)])
    assert not s.timed_out and not s.settled
    for a in range(rest + int(4 * RATE), len(t), 50):
        s = det.update(t[a : a + 50], si[a : a + 50])
        if s.timed_out:
            break
    # One more timeout of 5 s.
    assert s.timed_out and s.elapsed_s == pytest.approx(10.0, abs=50 / RATE)


def test_bad_criteria_are_refused_with_a_sentence():
    with pytest.raises(ValueError, match=r"^settling window_s must be positive, got 0.0$"):
        SettleCriteria(0.0, 1.0, 0.002, 0.01, 30.0)
    with pytest.raises(ValueError, match=r"^settling hold_s must be zero or positive, got -1.0$"):
        SettleCriteria(1.0, -1.0, 0.002, 0.01, 30.0)


def test_describe_states_the_rule_with_units():
    assert CRIT.describe() == (
        "range of 10 block means over 1 s and the tail extrapolated from 3 windows below 2 kPa"
        " (pressures) and 0.5 deg (angles) for 2 s"
    )


def test_time_unwrapper_crosses_the_32_bit_wrap():
    u = TimeUnwrapper()
    raw = (np.arange(0, 3_000_000, 5000, dtype=np.int64) + (1 << 32) - 1_000_000) % (1 << 32)
    parts = [u(raw[:100]), u(raw[100:250]), u(raw[250:])]
    t = np.concatenate(parts)
    assert np.allclose(np.diff(t), 0.005)
    assert t[0] == pytest.approx(((1 << 32) - 1_000_000) * 1e-6)


# The paper's protocol (protocols/takuma2014.toml [settling]) and the rig's pressure channel:
# counts of 0.305 kPa, 0.18 kPa of noise (0.5 count rms plus rounding).
PAPER = SettleCriteria(
    window_s=1.0, hold_s=12.0, pressure_spread_MPa=0.00031, angle_spread_rad=math.radians(0.1), timeout_s=45.0
)
COUNT_MPA = 0.000305
LEAK_MPA_PER_S = -3.6e-3 / 60  # 3.6 kPa/min: the leakiest chamber of the simulated rig's seed 3


def chamber(duration_s: float, pressure, seed: int):
    """Four chambers that read ``pressure(t)`` (MPa) through noise and counts; two still angles."""
    t = np.arange(int(duration_s * RATE)) / RATE
    rng = np.random.default_rng(seed)
    si = np.zeros((len(t), 6))
    si[:, :4] = (0.3 + pressure(t))[:, None] + rng.normal(0, 0.00018, (len(t), 4))
    si[:, :4] = np.round(si[:, :4] / COUNT_MPA) * COUNT_MPA
    return t, si


def run_leak(t, si, drift_mpa_per_s: float | None, crit=PAPER):
    drift = None if drift_mpa_per_s is None else (drift_mpa_per_s,) * 4 + (0.0, 0.0)
    det = SettleDetector(crit, [0, 1, 2, 3], [4, 5], drift_per_s=drift)
    for a in range(0, len(t), 40):
        s = det.update(t[a : a + 40], si[a : a + 40])
        if s.settled or s.timed_out:
            return s
    return s


def test_a_steady_leak_taken_out_settles_in_about_the_hold_time():
    # 3.6 kPa/min counted as a trend that never decays: TAIL_MAX windows of it, 0.24 kPa of the
    # 0.31 kPa limit, and the noise of single windows pushes it over, restarting the 12 s hold.
    earliest = TAIL_WINDOWS * PAPER.window_s + PAPER.hold_s
    counted = [run_leak(*chamber(60.0, lambda t: LEAK_MPA_PER_S * t, seed), None) for seed in range(6)]
    assert all(s.timed_out and not s.settled for s in counted)
    for seed in range(6):
        s = run_leak(*chamber(60.0, lambda t: LEAK_MPA_PER_S * t, seed), LEAK_MPA_PER_S)
        assert s.settled and s.elapsed_s <= earliest + 1.0


def test_a_decaying_tail_on_a_leak_is_still_waited_out():
    # The air's excess after a fast load (3 kPa relaxing with 3 s, the protocol's thermal time
    # constant) on the steady leak: taking the leak out leaves the exponential, waited as without it.
    excess, tau = 0.003, 3.0
    left_at_limit = tau * math.log(excess / PAPER.pressure_spread_MPa)  # 6.8 s
    for seed in range(4):
        alone = run_leak(*chamber(60.0, lambda t: excess * np.exp(-t / tau), seed), None)
        leaking = run_leak(
            *chamber(60.0, lambda t: excess * np.exp(-t / tau) + LEAK_MPA_PER_S * t, seed), LEAK_MPA_PER_S
        )
        for s in (alone, leaking):
            assert s.settled
            assert s.settle_time_s >= left_at_limit - 0.5  # the quiet began once what was left was small
            assert s.elapsed_s > TAIL_WINDOWS * PAPER.window_s + PAPER.hold_s + 2.0  # not at the earliest
        assert abs(leaking.settle_time_s - alone.settle_time_s) <= 1.0


def test_a_leak_that_steps_up_is_not_taken_away():
    # The hold check measured 3.6 kPa/min; 5 s into the wait the chamber loses three times as much
    # (a fitting gives): the change of rate is a trend the rule still sees, to the timeout.
    def stepped(t):
        return LEAK_MPA_PER_S * t + 2 * LEAK_MPA_PER_S * np.maximum(t - 5.0, 0.0)

    for seed in range(3):
        s = run_leak(*chamber(50.0, stepped, seed), LEAK_MPA_PER_S)
        assert s.timed_out and not s.settled


def test_a_drift_of_the_wrong_size_is_refused():
    det = SettleDetector(PAPER, [0, 1, 2, 3], [4, 5], drift_per_s=(LEAK_MPA_PER_S,) * 4)
    with pytest.raises(ValueError, match="4 channels, the samples 6"):
        det.update(np.arange(3) / RATE, np.zeros((3, 6)))
    with pytest.raises(ValueError, match="finite"):
        SettleDetector(PAPER, [0], [1], drift_per_s=(math.nan, 0.0))
