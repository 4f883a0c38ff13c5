"""ISO 6358 orifice flow into and out of a chamber against its closed forms and its own mass flow."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import quad

from labcli.core.sim import orifice as o

P_ATM = 101_325.0
VALVE = o.Orifice(0.1 * o.DM3_PER_S_BAR, 0.3)
V = 44e-6  # m^3, an outside chamber of the simulated rig with its tubing


def test_the_rate_is_the_choked_pressure_rise_per_second():
    k = float(VALVE.rate(V))
    # dP/dt = R T0 q_m / V with q_m = C p1 rho0 (choked): k p1 exactly.
    p1 = 4e5
    assert float(VALVE.mass_flow(p1, P_ATM)) * o.R_AIR * o.T0 / V == pytest.approx(k * p1, rel=1e-12)
    assert k == pytest.approx(1e-9 * 1.185 * 287.05 * 293.15 / 44e-6, rel=1e-12)


def test_the_flow_factor_is_choked_below_b_and_zero_at_equal_pressures():
    b = 0.3
    assert np.all(o.flow_factor([0.0, 0.1, 0.3], b) == 1.0)
    assert float(o.flow_factor(1.0, b)) == 0.0
    assert float(o.flow_factor(0.3 + 1e-9, b)) == pytest.approx(1.0, abs=1e-6)  # continuous at b
    u = (0.65 - b) / (1 - b)
    assert float(o.flow_factor(0.65, b)) == pytest.approx(math.sqrt(1 - u * u))
    assert float(VALVE.mass_flow(P_ATM, 4e5)) == -float(VALVE.mass_flow(4e5, P_ATM))  # reversed flow


def test_a_choked_fill_rises_linearly_and_the_whole_fill_ends_when_the_closed_form_says():
    ps, p0 = 0.30e6 + P_ATM, P_ATM
    k, b = float(VALVE.rate(V)), VALVE.b
    x0 = p0 / ps
    t_choked = (b - x0) / k  # dP/dt = k ps while p / ps <= b
    t = np.linspace(0.0, t_choked, 7)
    p = o.pressure_at(t, [p0], [ps], [k], b)[:, 0]
    np.testing.assert_allclose(p, p0 + k * ps * t, rtol=1e-12)
    t_full = t_choked + (1 - b) * math.pi / 2 / k  # then x = b + (1 - b) sin(k t' / (1 - b))
    assert t_full == pytest.approx(0.506, abs=0.001)
    assert float(o.pressure_at(t_full * (1 - 1e-6), [p0], [ps], [k], b)[0]) < ps
    after = o.pressure_at([t_full, t_full + 1.0, 100.0], [p0], [ps], [k], b)[:, 0]
    assert np.all(after == ps)  # steady state: the source's pressure, exactly
    half = t_choked + (1 - b) * math.asin(0.5) / k
    assert float(o.pressure_at(half, [p0], [ps], [k], b)[0]) == pytest.approx((b + (1 - b) * 0.5) * ps, rel=1e-12)


def test_a_choked_vent_decays_exponentially_then_reaches_the_atmosphere_in_finite_time():
    p0 = 0.60e6 + P_ATM
    k, b = float(VALVE.rate(V)), VALVE.b
    t_choked = math.log(p0 * b / P_ATM) / k  # dP/dt = -k P while P_ATM / P <= b
    t = np.linspace(0.0, t_choked, 9)
    p = o.pressure_at(t, [p0], [P_ATM], [k], b)[:, 0]
    np.testing.assert_allclose(p, p0 * np.exp(-k * t), rtol=1e-12)
    t_end = t_choked + float(o.empty_tau(1.0, b)) / k
    assert float(o.pressure_at(t_end * 0.999, [p0], [P_ATM], [k], b)[0]) > P_ATM
    assert np.all(o.pressure_at([t_end, t_end + 5.0], [p0], [P_ATM], [k], b) == P_ATM)


@pytest.mark.parametrize("b", [0.2, 0.5, 0.7])  # the three forms of the integral: b below, at and above 1/2
def test_the_subsonic_emptying_time_is_the_integral_of_its_rate(b):
    for y in (b + 0.01, 0.5 * (1 + b), 0.97, 1.0):
        if y <= b:
            continue
        # dtau = dy / (y phi(y)), from y = b
        expected = quad(lambda s: 1.0 / (s * float(o.flow_factor(s, b))), b, y, limit=200)[0]
        assert float(o.empty_tau(y, b)) == pytest.approx(expected, rel=1e-6)
    ys = np.linspace(b, 1.0, 50)
    np.testing.assert_allclose(o.empty_y(o.empty_tau(ys, b), b), ys, atol=1e-7)


@pytest.mark.parametrize(("p0", "ps"), [(P_ATM, 0.30e6 + P_ATM), (0.45e6 + P_ATM, P_ATM), (0.25e6, 0.32e6)])
def test_the_closed_form_conserves_the_air_the_orifice_lets_through(p0, ps):
    """The chamber's air ``P V / (R T0)`` changes by the integral of ISO 6358's mass flow at every
    instant: the closed form solves ``V dP/dt = R T0 q_m``."""
    k, b = float(VALVE.rate(V)), VALVE.b
    t = np.linspace(0.0, 1.5, 30001)
    p = o.pressure_at(t, [p0], [ps], [k], b)[:, 0]
    q = VALVE.mass_flow(ps, p)  # into the chamber
    added = np.concatenate([[0.0], np.cumsum(0.5 * (q[1:] + q[:-1]) * np.diff(t))])
    mass = p * V / (o.R_AIR * o.T0)
    np.testing.assert_allclose(mass - mass[0], added, atol=1e-6 * abs(mass[-1] - mass[0]))


def test_an_orifice_refuses_what_no_valve_has():
    for c, b in ((0.0, 0.3), (-1e-9, 0.3), (1e-9, 0.0), (1e-9, 1.0), (math.nan, 0.3)):
        with pytest.raises(ValueError, match="sonic conductance C > 0 and a critical pressure ratio 0 < b < 1"):
            o.Orifice(c, b)
