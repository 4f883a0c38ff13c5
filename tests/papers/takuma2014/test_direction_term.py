"""The fit plan's direction term (models/routes.py held_out_variances): the variance the posture
form's own standard errors lack at a load direction its fit never used, measured by the route
choice's folds (one direction held out at a time) and given to a new load at half the plan's widest
gap between directions.  It widens the intervals only: estimates and flags stay the trial's own."""

from __future__ import annotations

import copy
import json
import math

import numpy as np
import pytest

from labcli.errors import ModelError
from labcli.papers.takuma2014.models import routes as rt
from labcli.papers.takuma2014.models.posture import PostureModel, limits_from_protocol


def folds_cv(e: np.ndarray, s: np.ndarray, d: np.ndarray, fitted: np.ndarray) -> dict:
    """held_out_errors' layout for Fx alone (the other quantities' errors within their standard errors)."""
    n = len(e)
    small = {q: 0.5 * s for q in rt.QUANTITIES}
    return {
        "posture": {**small, "Fx": e},
        "posture_se": {q: s for q in rt.QUANTITIES},
        "posture_ok": {q: np.ones(n, bool) for q in rt.QUANTITIES},
        rt.DIRECTIONS: {"held_out": d, "fitted": fitted},
    }


def test_the_term_recovers_a_direction_variance_and_gives_it_at_half_the_widest_gap():
    # Ten directions 36 deg apart (the bent plan's), each held out in turn: every held-out trial lies
    # 36 deg from the nearest fitted one, where the error's variance is s^2 + c d^2.
    rng = np.random.default_rng(4)
    n, s, spacing = 20_000, 0.5, math.radians(36.0)
    c = 0.6 / spacing**2  # 0.6 N^2 more than the standard error says, at the folds' distance
    fitted = np.radians(np.arange(-162.0, 180.0, 36.0))
    e = rng.normal(0.0, math.sqrt(s**2 + c * spacing**2), n)
    cv = folds_cv(e, np.full(n, s), np.full(n, spacing), fitted)
    v = rt.held_out_variances(cv)
    assert set(v) == {"Fx"}  # errors the standard errors cover get no term
    # At half the widest gap (18 deg) the variance is a quarter of the folds' excess.
    assert v["Fx"] == pytest.approx(0.6 / 4, rel=0.05)
    # Errors the standard errors already cover: none.
    cv = folds_cv(rng.normal(0.0, 0.9 * s, n), np.full(n, s), np.full(n, spacing), fitted)
    assert rt.held_out_variances(cv) == {}


def test_trials_whose_direction_the_fold_saw_carry_no_direction_variance():
    # Half the held-out trials at a direction their fold was fitted on (d = 0) err as their standard
    # errors say; the rest, 30 deg away, err more.  Only the second half sets c.
    rng = np.random.default_rng(5)
    n, s, d = 20_000, 0.4, math.radians(30.0)
    dist = np.where(np.arange(n) % 2 == 0, 0.0, d)
    e = rng.normal(0.0, np.sqrt(s**2 + 0.5 * (dist / d) ** 2))
    v = rt.held_out_variances(folds_cv(e, np.full(n, s), dist, np.radians([0.0, 60.0, 120.0, 180.0, 240.0, 300.0])))
    assert v["Fx"] == pytest.approx(0.5, rel=0.06)  # half the widest gap, 30 deg, is the folds' distance


def test_the_straight_plans_folds_each_leave_out_a_direction_30_deg_from_the_rest():
    from labcli.core.protocol import load_protocol
    from labcli.papers.takuma2014.protocol import load_plan

    plan = load_plan(load_protocol("takuma2014"))
    fit = plan[plan["set"] == "fit"].reset_index(drop=True)
    got = rt.direction_distances(fit, rt._blocks(len(fit)))
    np.testing.assert_allclose(np.degrees(got["held_out"]), 30.0, atol=1e-9)
    # The plan has no load along the straight arm (+-90 deg): its widest gaps are 60 deg.
    assert math.degrees(rt.widest_half_gap(got["fitted"])) == pytest.approx(30.0)
    # A table without directions: distance 1 everywhere, the folds' own excess.
    bare = rt.direction_distances(fit.drop(columns="direction_deg"), rt._blocks(len(fit)))
    assert np.all(bare["held_out"] == 1.0) and rt.widest_half_gap(bare["fitted"]) == 1.0


@pytest.fixture(scope="module")
def literature_straight():
    """The straight protocol on the literature's rig (tuning seed 1), fitted as `labcli fit` fits it."""
    from labcli.core.protocol import load_protocol
    from labcli.papers.takuma2014.protocol import load_plan
    from labcli.papers.takuma2014.sim.drive import simulate_weight_trials
    from labcli.papers.takuma2014.sim.rig import SimRig

    proto = load_protocol("takuma2014")
    table = simulate_weight_trials(SimRig(seed=1), load_plan(proto), calibration=proto.calibration, settle_s=8.0)
    table["theta1_0_deg"], table["theta2_0_deg"] = 0.0, 0.0
    model = PostureModel(geometry=proto.settings.rig, limits=limits_from_protocol(proto), friction=True)
    return model.fit(table), table


def test_a_direction_held_out_errs_more_than_the_fit_says_and_the_intervals_widen(literature_straight, tmp_path):
    model, table = literature_straight
    # The straight arm's Fx misses held-out directions by more than its residuals say: a term.
    assert model.route("Fx") == rt.POSTURE and model.held_out_variance.get("Fx", 0.0) > 0.01
    v = table[table["set"] == "validation"]
    out = model.predict_table(v)
    own_model = copy.copy(model)
    own_model.held_out_variance = {}
    own = own_model.predict_table(v)
    # Same estimates and flags; each posture-route interval wider by exactly the term.
    for q in rt.QUANTITIES:
        np.testing.assert_array_equal(out[rt.VALUE_KEYS[q]], own[rt.VALUE_KEYS[q]])
        np.testing.assert_array_equal(out["ok"][q], own["ok"][q])
    assert out["flags"] == own["flags"]
    np.testing.assert_allclose(out["se"]["Fx"] ** 2 - own["se"]["Fx"] ** 2, model.held_out_variance["Fx"], rtol=1e-9)
    for q in rt.QUANTITIES:
        if model.route(q) == rt.PAPER:  # the paper's form's own held-out variance is in its standard error already
            np.testing.assert_array_equal(out["se"][q], own["se"][q])
    # The file keeps the term and reads back to the same intervals.
    path = tmp_path / "m.json"
    path.write_text(model.to_json())
    d = json.loads(path.read_text())
    assert d["held_out_variance"] == pytest.approx(model.held_out_variance)
    back = PostureModel.from_dict(d)
    np.testing.assert_array_equal(back.predict_table(v)["se"]["Fx"], out["se"]["Fx"])
    assert back.to_json() == model.to_json()
    # A file written before the term: none, its intervals as before, written back byte for byte.
    old = {k: val for k, val in d.items() if k != "held_out_variance"}
    before = PostureModel.from_dict(old)
    assert before.held_out_variance == {}
    np.testing.assert_array_equal(before.predict_table(v)["se"]["Fx"], own["se"]["Fx"])
    assert json.loads(before.to_json()) == old


@pytest.mark.parametrize("bad", [{"Fx": -0.1}, {"Fx": float("nan")}, {"Fz": 0.1}, {"Fx": True}, [0.1], "0.1"])
def test_a_bad_held_out_variance_is_one_sentence(literature_straight, bad):
    model, _ = literature_straight
    d = model.to_dict() | {"held_out_variance": bad}
    with pytest.raises(ModelError) as e:
        PostureModel.from_dict(d)
    assert str(e.value) == (
        "The model: key 'held_out_variance' must give theta1, theta2, Fx or Fy a finite variance "
        "of at least 0; refit with `labcli fit`."
    )
