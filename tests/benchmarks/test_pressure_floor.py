"""The pressure sensors' floor (pressure_floor.py) on closed-form cases, and the N-capture protocol's
averaging (multi_capture.py)."""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))

import multi_capture as mc  # noqa: E402
import pressure_floor as pf  # noqa: E402

P_ATM = 101_325.0


def _chamber(k: float, theta0: float):
    """One closed chamber of volume V0 (1 + k theta): unknowns (ln air, theta); readings the
    absolute pressure at the known rest ``theta0`` and at theta; the quantity theta - theta0."""

    def readings(x: np.ndarray) -> np.ndarray:
        air, theta = math.exp(x[0]), x[1]
        return np.array([air / (1 + k * theta0), air / (1 + k * theta)])

    def quantity(x: np.ndarray) -> np.ndarray:
        return np.array([x[1] - theta0])

    return readings, quantity


def test_one_chamber_matches_boyle_closed_form_and_the_inverse_attains_it():
    k, theta0, theta, sd = -0.5, 0.01, 0.04, 330.0  # 1/rad; rad; Pa
    readings, quantity = _chamber(k, theta0)
    x = np.array([math.log(4.0e5 * (1 + k * theta0)), theta])
    var = pf.quantity_covariance(readings, quantity, x, np.array([1e-6, 1e-6]), np.array([sd, sd]))[""][0, 0]
    p0, p = readings(x)
    # d ln P / d theta = -k / (1 + k theta): each reading's relative error over that slope.
    closed = (sd**2 / p0**2 + sd**2 / p**2) / (k / (1 + k * theta)) ** 2
    assert var == pytest.approx(closed, rel=1e-5)
    # The exact inverse (theta from the ratio P0 / P) on noisy readings has that variance.
    rng = np.random.default_rng(7)
    n0, n1 = p0 + sd * rng.standard_normal(40000), p + sd * rng.standard_normal(40000)
    est = ((n0 / n1) * (1 + k * theta0) - 1) / k - theta0
    assert np.std(est) == pytest.approx(math.sqrt(closed), rel=0.03)
    assert np.mean(est) == pytest.approx(theta - theta0, abs=3 * math.sqrt(closed / 40000) + 1e-6)


def test_crb_of_a_linear_map_and_the_prior():
    a = np.array([[1.0, 0.0], [1.0, 1.0], [0.0, 2.0]])
    sd = np.array([1.0, 2.0, 0.5])
    w = np.diag(1 / sd**2)
    assert pf.crb(a, sd) == pytest.approx(np.linalg.inv(a.T @ w @ a))
    # A scalar reading of x with a prior: the information adds.
    assert pf.crb(np.array([[1.0]]), np.array([2.0]), np.array([1.0]))[0, 0] == pytest.approx(1 / (1 / 4 + 1))
    # The bound scales with the readings' error.
    assert pf.crb(a, 3 * sd) == pytest.approx(9 * pf.crb(a, sd))


def test_crb_refuses_what_the_readings_do_not_determine():
    with pytest.raises(ValueError, match="do not determine"):
        pf.crb(np.array([[1.0, 1.0], [2.0, 2.0]]), np.array([1.0, 1.0]))
    with pytest.raises(ValueError, match="positive"):
        pf.crb(np.eye(2), np.array([1.0, 0.0]))
    with pytest.raises(ValueError, match=r"\(m, k\)"):
        pf.crb(np.eye(2), np.array([1.0, 1.0, 1.0]))
    # A prior on the undetermined direction makes it finite, and no wider than the prior.
    cov = pf.crb(np.array([[1.0, 1.0], [2.0, 2.0]]), np.array([1.0, 1.0]), np.array([3.0, 3.0]))
    assert np.all(np.diag(cov) <= 9.0)


def test_rig_maps_reproduce_the_statics_and_friction_widens_the_floor():
    from labcli.papers.takuma2014.sim import physics as ph

    params = ph.varied_params(11)
    maps = pf.TrialMaps(params, ph.SUPPLY_MPA)
    force = np.array([3.0, -2.0])
    x = maps.statics_state(force)
    readings, q = maps.statics(x)
    closed = ph.Chambers("closed", amount=np.exp(maps.ln_air))
    eq = ph.solve_equilibrium(params, closed, ph.Weight(math.hypot(3, 2) / ph.G, math.atan2(-2, 3)))
    assert readings[4:8] == pytest.approx(eq.pressures_MPa, abs=1e-9)
    assert q[2:] == pytest.approx(force)
    # Zero friction in the friction map is the statics; the Boyle map sees the same postures.
    assert maps.statics(np.concatenate([x, np.zeros(4)]))[0] == pytest.approx(readings, abs=1e-12)
    assert maps.boyle(maps.boyle_state(force))[0] == pytest.approx(readings, abs=1e-9)
    band = maps.friction_band(0.02)
    floor = pf.trial_floor(maps, force, 3.3e-4, 1e-4, prior_N=5.0, band_N=band)
    # Fewer unknowns, smaller bound: the statics below the friction map and the Boyle map.
    assert np.all(floor["statics"][:2] < floor["friction"][:2])
    assert np.all(floor["statics"][:2] < floor["boyle"][:2])
    assert np.all(floor["boyle_air"] < floor["boyle"])
    assert np.all(floor["statics_prior"] <= floor["statics"] * (1 + 1e-9))


def test_averaged_captures_round_trip():
    plan = pd.DataFrame(
        {"trial": [1, 2], "set": ["fit", "validation"], "mass_g": [100.0, 200.0], "direction_deg": [0.0, 90.0]}
    )
    rep = mc.repeated_plan(plan, 3)
    assert list(rep["trial"]) == [1, 1, 1, 2, 2, 2]
    table = rep.copy()
    for i, c in enumerate(mc.AVERAGED):
        table[c] = np.arange(6, dtype=float) + i
    avg = mc.averaged(table, 3)
    assert list(avg["trial"]) == [1, 2] and list(avg["set"]) == ["fit", "validation"]
    assert avg["P_L1"].tolist() == pytest.approx([1.0 + mc.AVERAGED.index("P_L1"), 4.0 + mc.AVERAGED.index("P_L1")])
    assert mc.averaged(table, 1)["P_L1"].tolist() == table["P_L1"].tolist()
    with pytest.raises(ValueError, match="whole groups"):
        mc.averaged(table, 4)
    with pytest.raises(ValueError, match="at least 1"):
        mc.repeated_plan(plan, 0)
