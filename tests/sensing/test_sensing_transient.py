"""The transient model (labcli/sensing/transient.py) against closed forms and the simulated rig's physics."""

from __future__ import annotations

import numpy as np
import pytest
from support.sensing import response

from labcli.papers.takuma2014.sim.nonideal import thermal_excess
from labcli.sensing.config import EstimatorConfig
from labcli.sensing.transient import ResponseFit, heat, lag, onset


@pytest.mark.parametrize("tau", [0.7, 3.0, 1.2])
def test_the_heat_kernel_is_the_simulated_rigs_temperature_excess(tau):
    # nonideal.thermal_excess with no excess at the step, (kappa - 1) = 1 and a unit volume loss
    # (dlnV = -1) is the kernel itself; tau = 3.0 is the degenerate case tau = thermal_tau.
    s = np.linspace(0.0, 20.0, 401)
    sim = thermal_excess(s, np.zeros(1), np.array([-1.0]), 1.0, tau, 3.0)[:, 0]
    np.testing.assert_allclose(heat(s, tau, 3.0), sim, rtol=1e-12, atol=1e-15)


def test_the_heat_kernel_solves_its_differential_equation():
    # dx/dt = -d(lnV)/dt - x / thermal_tau with lnV = -lag(s): dx/dt = d(lag)/ds - x / 3.
    s = np.linspace(0.01, 15.0, 3000)
    x, h = heat(s, 0.7, 3.0), s[1] - s[0]
    lhs = np.gradient(x, h)
    rhs = np.gradient(lag(s, 0.7), h) - x / 3.0
    np.testing.assert_allclose(lhs[2:-2], rhs[2:-2], atol=1e-5)
    assert heat(np.array(0.0), 0.7, 3.0) == 0.0 and lag(np.array(-1.0), 0.7) == 0.0


def _fit(t0: float, k: int = 4) -> ResponseFit:
    c = EstimatorConfig()
    return ResponseFit(
        t0,
        k,
        taus=c.tau_s * np.array(c.tau_factors),
        shifts=c.block_s * np.array(c.onset_shifts_blocks),
        thermal_tau=c.thermal_tau_s,
        kappas=np.array(c.thermal_kappas),
        capacity=400,
    )


def test_a_noise_free_step_on_the_grid_is_recovered_exactly():
    A = np.array([0.003, -0.002, 0.008, -0.007])
    fit = _fit(10.0)
    for tc in 10.0 + 0.025 + 0.05 * np.arange(120):
        lg, h = response(np.array(tc - 10.0), 0.7, 3.0, 0.4)
        fit.add(tc, A * (lg + h), np.full(4, 1e-10))
    r = fit.solve()
    np.testing.assert_allclose(r.A, A, rtol=1e-6)
    np.testing.assert_allclose(r.B, 0.4 * A, rtol=1e-5)
    assert r.tau == pytest.approx(0.7, rel=1e-6)


@pytest.mark.parametrize("seconds", [0.5, 1.5, 3.0, 6.0])
def test_the_settled_value_is_inside_its_interval_about_as_often_as_it_says(seconds):
    # Lags off the grid (0.5-1.0 s), heat shares 0-0.6, steps off by up to a block: the 95 %
    # intervals of A (the fit's and the shape's share, as the estimator counts them) hold it
    # 90-100 % of the time at every stage of the transient.
    rng = np.random.default_rng(5)
    inside, n, rel = 0, 0, []
    for _ in range(60):
        A = rng.normal(0.0, 0.005, 4)
        tau, kappa, t0 = rng.uniform(0.5, 1.0), rng.uniform(0.0, 0.6), 10.0 + rng.uniform(-0.05, 0.05)
        fit = _fit(10.0)
        tcs = 10.0 + 0.025 + 0.05 * np.arange(int(seconds / 0.05))
        for tc in tcs:
            lg, h = response(np.array(tc - t0), tau, 3.0, kappa)
            fit.add(tc, A * (lg + h) + rng.normal(0.0, 5e-5, 4), np.full(4, 5e-5**2))
        r = fit.solve()
        sd = np.sqrt(r.var_A * max(1.0, r.misfit) + (EstimatorConfig().shape_sd * fit.step().unresolved(tcs[-1])) ** 2)
        inside += int(np.sum(np.abs(r.A - A) <= 1.96 * sd))
        n += 4
        rel += list(np.abs(r.A - A) / np.abs(A))
    assert 0.90 <= inside / n <= 1.0
    assert np.median(rel) < {0.5: 0.3, 1.5: 0.1, 3.0: 0.05, 6.0: 0.015}[seconds]


def test_the_onset_of_a_lagged_step_is_placed_within_a_block():
    rng = np.random.default_rng(2)
    tc = 0.025 + 0.05 * np.arange(80)
    z = np.zeros((80, 3))
    true = 2.013
    z += np.outer(1.0 - np.exp(-np.maximum(tc - true, 0.0) / 0.7), [4.0, -3.0, 1.0])
    t0, amp = onset(tc, z + rng.normal(0.0, 0.3, z.shape), 0.7, 0.05)
    assert abs(t0 - true) <= 0.05
    np.testing.assert_allclose(amp, [4.0, -3.0, 1.0], atol=0.3)
