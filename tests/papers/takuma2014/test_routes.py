"""The route choice (models/routes.py): the stacking weight, the blend's standard error, the file."""

from __future__ import annotations

import json

import numpy as np
import pytest

from labcli.errors import ModelError
from labcli.papers.takuma2014.models import routes as rt
from labcli.papers.takuma2014.models.posture import PostureModel


def cv_errors(e_po: dict[str, np.ndarray], e_pa: dict[str, np.ndarray]) -> dict[str, dict[str, np.ndarray]]:
    """held_out_errors' layout: every trial reported by both forms."""
    return {
        "posture": e_po,
        "paper": e_pa,
        "posture_ok": {q: np.ones(len(v), bool) for q, v in e_po.items()},
        "paper_ok": {q: np.ones(len(v), bool) for q, v in e_pa.items()},
    }


def test_the_stacking_weight_is_the_least_squares_weight_and_stays_in_0_1():
    rng = np.random.default_rng(1)
    a, b = rng.normal(size=20_000), rng.normal(size=20_000)
    w = rt.stacking_weight(a, b)
    # The minimiser of sum (w a + (1 - w) b)^2, checked on a grid of step 0.001.
    grid = np.linspace(0, 1, 1001)
    sse = [np.sum((g * a + (1 - g) * b) ** 2) for g in grid]
    assert w == pytest.approx(grid[int(np.argmin(sse))], abs=1e-3)
    # Independent errors of equal spread: half each; a form with no error takes it all.
    assert w == pytest.approx(0.5, abs=0.05)
    assert rt.stacking_weight(np.zeros(10), b[:10]) == 1.0
    assert rt.stacking_weight(a[:10], np.zeros(10)) == 0.0
    # One form's errors a scaled copy of the other's: no blend helps, the better one alone.
    assert rt.stacking_weight(a, 2 * a) == 1.0 and rt.stacking_weight(2 * a, a) == 0.0
    assert rt.stacking_weight(a, a) == 1.0  # the same errors: the posture form


def test_independent_errors_blend_with_inverse_variance_weights():
    # For independent errors of spreads s_po, s_pa the best weight is s_pa^2 / (s_po^2 + s_pa^2),
    # and the blend's spread is below either form's.
    rng = np.random.default_rng(2)
    n = 200_000
    e_po, e_pa = 0.3 * rng.standard_normal(n), 0.4 * rng.standard_normal(n)
    routes, stats, blends = rt.choose_routes(
        cv_errors({q: e_po for q in rt.QUANTITIES}, {q: e_pa for q in rt.QUANTITIES}), {}
    )
    assert set(routes.values()) == {"blend"}
    w = blends["Fx"]["posture_weight"]
    assert w == pytest.approx(0.16 / 0.25, abs=0.01)
    assert blends["Fx"]["error_correlation"] == pytest.approx(0.0, abs=0.01)
    assert stats["Fx"]["rmse_stacked"] == pytest.approx(np.sqrt(0.09 * 0.16 / 0.25), rel=0.01)
    assert stats["Fx"]["rmse_stacked"] < min(stats["Fx"]["rmse_posture"], stats["Fx"]["rmse_paper"])
    # The standard error formula gives the spread the blend's errors really have.
    v, se = rt.blend_estimate(w, 0.0, np.zeros(1), np.array([0.3]), np.zeros(1), np.array([0.4]))
    assert se[0] == pytest.approx(np.std(w * e_po + (1 - w) * e_pa), rel=0.01)


def test_the_blend_standard_error_holds_correlated_errors():
    rng = np.random.default_rng(3)
    n = 200_000
    common = rng.standard_normal(n)
    e_po = 0.3 * (0.8 * common + 0.6 * rng.standard_normal(n))
    e_pa = 0.5 * (0.8 * common + 0.6 * rng.standard_normal(n))
    rho = rt.error_correlation(e_po, e_pa)
    assert rho == pytest.approx(0.64, abs=0.01)
    w = rt.stacking_weight(e_po, e_pa)
    _, se = rt.blend_estimate(w, rho, np.zeros(1), np.array([0.3]), np.zeros(1), np.array([0.5]))
    assert se[0] == pytest.approx(np.std(w * e_po + (1 - w) * e_pa), rel=0.01)


def test_the_paper_form_takes_no_part_where_it_misses_a_trial_or_is_over_the_limit():
    rng = np.random.default_rng(4)
    e_po, e_pa = 0.3 * rng.standard_normal(90), 0.3 * rng.standard_normal(90)
    cv = cv_errors({q: e_po for q in rt.QUANTITIES}, {q: e_pa for q in rt.QUANTITIES})
    cv["paper_ok"]["Fx"][5] = False  # the paper's form flags one trial the posture form reports
    routes, _, blends = rt.choose_routes(cv, {"Fy": 0.1})  # Fy: the paper's held-out RMSE is over 0.1 N
    assert routes["Fx"] == routes["Fy"] == "posture" and "Fx" not in blends
    assert routes["theta1"] == "blend"
    # Where the posture form reports nothing, the paper's form is taken alone.
    cv["posture_ok"]["Fy"][:] = False
    routes, _, _ = rt.choose_routes(cv, {})
    assert routes["Fy"] == "paper"


def test_a_weight_within_snap_of_0_or_1_is_the_one_form_alone():
    rng = np.random.default_rng(5)
    e_pa = rng.standard_normal(90)
    routes, _, blends = rt.choose_routes(
        cv_errors(
            {q: 1e-4 * e_pa + 1e-3 * rng.standard_normal(90) for q in rt.QUANTITIES}, {q: e_pa for q in rt.QUANTITIES}
        ),
        {},
    )
    assert set(routes.values()) == {"posture"} and blends == {}


@pytest.fixture(scope="module")
def straight_rig_table():
    """The straight protocol on the kind rig (seed 1), rest posture from the baseline pots: on the
    literature's rig the route choice takes each quantity from one form alone, and nothing blends."""
    from labcli.core.protocol import load_protocol
    from labcli.papers.takuma2014.protocol import load_plan
    from labcli.papers.takuma2014.sim.drive import simulate_weight_trials
    from labcli.papers.takuma2014.sim.nonideal import NonIdeal
    from labcli.papers.takuma2014.sim.rig import SimRig

    proto = load_protocol("takuma2014")
    table = simulate_weight_trials(
        SimRig(seed=1, nonideal=NonIdeal(realism="kind")), load_plan(proto), calibration=proto.calibration, settle_s=8.0
    )
    table["theta1_0_deg"], table["theta2_0_deg"] = 0.0, 0.0
    return proto, table


def test_a_blended_quantity_is_the_weighted_sum_and_round_trips(straight_rig_table, tmp_path):
    proto, table = straight_rig_table
    model = PostureModel(geometry=proto.settings.rig).fit(table)
    blended = [q for q in rt.QUANTITIES if model.route(q) == "blend"]
    assert blended, model.routes  # on the straight arm the torques and Eq. 36 err differently
    q = blended[0]
    v = table[table.set == "validation"]
    out = model.predict_table(v)
    plain = PostureModel(geometry=proto.settings.rig).fit(table, choose_routes=False).predict_table(v)
    paper = model.paper.predict_table(v)
    w = model.blends[q]["posture_weight"]
    assert 0.01 < w < 0.99
    ok = np.asarray(paper["ok"][q], bool)
    np.testing.assert_allclose(
        out[rt.VALUE_KEYS[q]][ok], w * plain[rt.VALUE_KEYS[q]][ok] + (1 - w) * paper[rt.VALUE_KEYS[q]][ok], rtol=1e-12
    )
    assert out["routes"][q] == "blend" and out["blends"][q] == model.blends[q]
    # The file keeps the weights; a bad one is one sentence.
    path = tmp_path / "m.json"
    path.write_text(model.to_json())
    back = PostureModel.from_dict(json.loads(path.read_text()))
    np.testing.assert_array_equal(back.predict_table(v)[rt.VALUE_KEYS[q]], out[rt.VALUE_KEYS[q]])
    d = json.loads(path.read_text())
    for change in (
        {"blends": {}},
        {"blends": {**d["blends"], q: {"posture_weight": 1.5, "error_correlation": 0.0}}},
        {"blends": {**d["blends"], q: {"posture_weight": 0.5}}},
    ):
        with pytest.raises(ModelError) as e:
            PostureModel.from_dict(d | change)
        assert str(e.value) == (
            "The model: key 'blends' must give each blended quantity, and no other, a "
            "posture_weight in [0, 1] and an error_correlation in [-1, 1]; refit with `labcli fit`."
        )
