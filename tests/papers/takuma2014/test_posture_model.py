"""The posture-aware force model (models/posture.py) against closed forms and exact-geometry data."""

from __future__ import annotations

import json
import math

import numpy as np
import pandas as pd
import pytest

from labcli.errors import ModelError
from labcli.papers.takuma2014.models.geometry import contact_point
from labcli.papers.takuma2014.models.posture import (
    TORQUE_TERMS,
    PostureModel,
    force_from_torque,
    load_force_model,
    load_torque,
    loo_residuals,
    torque_features,
)
from labcli.papers.takuma2014.models.takuma import TakumaModel

H2, H3 = 0.130, 0.065
GEOMETRY = {"h1": 0.355, "h2": H2, "h3": H3, "r1": 0.075, "r2": 0.035}


def test_a_pure_torque_about_joint_2_is_a_force_through_joint_1():
    # tau = (0, t2): no torque about the bottom joint, so the force's line passes through it
    # (F parallel to C), and its moment about the upper joint is t2.
    theta = np.array([[0.1, 0.3]])
    F = force_from_torque(theta, np.array([[0.0, 0.2]]), H2, H3)
    C = contact_point(theta[:, 0], theta[:, 1], H2, H3)[0]
    assert F[0, 0] * C[1] - F[0, 1] * C[0] == pytest.approx(0.0, abs=1e-12)
    # Upper joint at (-h2 sin t1, h2 cos t1); the load's moment about it is (C - O1) x F
    # (dC/dtheta2 = z x (C - O1), so tau_2 = (dC/dtheta2) . F = (C - O1) x F).
    O1 = np.array([-H2 * math.sin(0.1), H2 * math.cos(0.1)])
    r = C - O1
    assert r[0] * F[0, 1] - r[1] * F[0, 0] == pytest.approx(0.2, rel=1e-12)
    np.testing.assert_allclose(load_torque(theta, F, H2, H3), [[0.0, 0.2]], atol=1e-12)


def test_a_load_along_the_straight_arm_makes_no_torque_but_does_on_a_bent_one():
    along = np.array([[0.0, -5.0]])
    assert np.abs(load_torque(np.array([[0.0, 0.0]]), along, H2, H3)).max() < 1e-12
    bent = np.array([[0.0, math.radians(15.0)]])
    tau = load_torque(bent, along, H2, H3)
    # tau_2 = -h3 (cos t12 Fx + sin t12 Fy) in closed form
    assert tau[0, 1] == pytest.approx(-H3 * math.sin(math.radians(15.0)) * -5.0, rel=1e-12)
    np.testing.assert_allclose(force_from_torque(bent, tau, H2, H3), along, atol=1e-9)


def test_leave_one_out_residuals_equal_refitting_without_the_trial():
    rng = np.random.default_rng(3)
    X = rng.standard_normal((25, 4))
    X[0] *= 6.0  # a high-leverage trial, whose held-out residual is far above its own
    Y = X @ rng.standard_normal((4, 2)) + 0.1 * rng.standard_normal((25, 2))
    beta, *_ = np.linalg.lstsq(X, Y, rcond=None)
    loo = loo_residuals(X, Y - X @ beta, np.linalg.inv(X.T @ X))
    for i in (0, 7, 24):
        keep = np.arange(25) != i
        b_i, *_ = np.linalg.lstsq(X[keep], Y[keep], rcond=None)
        np.testing.assert_allclose(loo[i], Y[i] - X[i] @ b_i, rtol=1e-10)
    assert np.abs(loo[0]).sum() > 1.5 * np.abs((Y - X @ beta)[0]).sum()


def exact_table(n: int, theta0_deg: tuple[float, float], seed: int = 0, noise: float = 0.0) -> pd.DataFrame:
    """Trials that follow the posture form exactly (plus optional Gaussian torque / angle noise).

    The supply varies from trial to trial (+-30 %): at one supply the deflection is nearly a
    linear function of the pressure drops, and the torque terms dtheta_l and dP_j dtheta_l
    then nearly repeat the others, so no fit could tell their coefficients apart.
    """
    rng = np.random.default_rng(seed)
    P0 = np.tile([0.30, 0.30, 0.40, 0.20], (n, 1)) * rng.uniform(0.7, 1.3, (n, 1))
    dP = rng.normal(0.0, 0.004, (n, 4))
    P = P0 - dP
    u = P0 / P - 1.0
    A = np.array([[0.9, -0.3], [-1.1, 0.4], [0.3, 1.2], [-0.2, -1.3]])
    dth = u @ A + noise * 1e-3 * rng.normal(size=(n, 2))
    beta = rng.normal(0.0, 1.0, (len(TORQUE_TERMS), 2)) * np.r_[[40.0] * 4, [400.0] * 8, [2.0] * 2][:, None]
    tau = torque_features(dP, dth) @ beta + noise * 1e-3 * rng.normal(size=(n, 2))
    th0 = np.radians(np.tile(theta0_deg, (n, 1)))
    F = force_from_torque(th0 + dth, tau, H2, H3)
    sets = np.where(np.arange(n) < int(0.8 * n), "fit", "validation")
    return pd.DataFrame(
        {
            "trial": np.arange(1, n + 1),
            "set": sets,
            **{c: P0[:, k] for k, c in enumerate(("P_L10", "P_R10", "P_L20", "P_R20"))},
            **{c: P[:, k] for k, c in enumerate(("P_L1", "P_R1", "P_L2", "P_R2"))},
            "theta1_deg": np.degrees(dth[:, 0]),
            "theta2_deg": np.degrees(dth[:, 1]),
            "Fx_N": F[:, 0],
            "Fy_N": F[:, 1],
            "theta1_0_deg": theta0_deg[0],
            "theta2_0_deg": theta0_deg[1],
        }
    )


def test_round_trip_on_exact_geometry_data_recovers_the_forces():
    t = exact_table(120, (0.5, 14.0))
    model = PostureModel(geometry=GEOMETRY).fit(t)
    assert model.angle_terms[:4] == ("u_L1", "u_R1", "u_L2", "u_R2")
    assert sorted(model.torque_terms) == sorted(TORQUE_TERMS)  # every term carries its share
    v = t[t.set == "validation"]
    out = model.predict_table(v)
    np.testing.assert_allclose(out["Fx_N"], v.Fx_N, atol=1e-6)
    np.testing.assert_allclose(out["Fy_N"], v.Fy_N, atol=1e-6)
    np.testing.assert_allclose(np.degrees(out["theta2_rad"]), v.theta2_deg, atol=1e-8)
    assert all(out["ok"][q].all() for q in ("theta1", "theta2", "Fx", "Fy"))


def test_the_rest_posture_matters_and_absent_columns_mean_straight():
    t = exact_table(120, (0.0, 14.0))
    model = PostureModel(geometry=GEOMETRY).fit(t)
    v = t[t.set == "validation"]
    straight = model.predict_table(v.drop(columns=["theta1_0_deg", "theta2_0_deg"]))
    np.testing.assert_array_equal(straight["theta0_rad"], 0.0)
    # Read at the wrong posture (straight) the same torques give other forces.
    assert np.abs(straight["Fy_N"] - v.Fy_N.to_numpy()).max() > 1.0


def test_95_percent_intervals_cover_about_95_percent_with_known_noise():
    inside, total = 0, 0
    for seed in range(6):
        t = exact_table(400, (0.0, 15.0), seed=seed, noise=1.0)
        model = PostureModel(geometry=GEOMETRY, limits={"theta1": 1.0, "theta2": 1.0, "Fx": 1e3, "Fy": 1e3}).fit(t)
        v = t[t.set == "validation"]
        out = model.predict_table(v)
        for q, col in (("Fx", "Fx_N"), ("Fy", "Fy_N")):
            err = np.abs(out[f"{q}_N"] - v[col].to_numpy())
            inside += int(np.sum(err <= 1.96 * out["se"][q]))
            total += len(err)
    assert 0.90 <= inside / total <= 0.98, inside / total


def test_a_straight_arm_flags_the_force_along_it_by_its_standard_error():
    t = exact_table(120, (0.0, 15.0))
    model = PostureModel(geometry=GEOMETRY).fit(t)
    P0 = np.array([[0.30, 0.30, 0.40, 0.20]])
    P = P0 - 0.003
    bent = model.predict(P0, P, theta0=np.radians([[0.0, 15.0]]))
    straight = model.predict(P0, P, theta0=np.array([[0.0, 0.0]]) - bent["theta2_rad"][0] * np.array([[0, 1]]))
    assert bent["ok"]["Fy"][0] and bent["se"]["Fy"][0] < 1.0
    assert not straight["ok"]["Fy"][0] and straight["flags"][0] == ["uncertain"]
    assert math.isfinite(straight["Fy_N"][0])


def test_model_file_round_trip_and_form_dispatch(tmp_path):
    t = exact_table(120, (0.0, 12.0))
    model = PostureModel(geometry=GEOMETRY, protocol="takuma2014").fit(t)
    path = tmp_path / "m.json"
    path.write_text(model.to_json())
    back = load_force_model(path)
    assert isinstance(back, PostureModel) and json.loads(path.read_text())["form"] == "posture"
    v = t[t.set == "validation"]
    np.testing.assert_array_equal(back.predict_table(v)["Fy_N"], model.predict_table(v)["Fy_N"])
    with pytest.raises(ModelError, match="holds the 'posture' form, not the paper's Eqs. 34-37"):
        TakumaModel.load(path)
    d = json.loads(path.read_text())
    d["torque_resid_cov"] = [[1.0]]
    path.write_text(json.dumps(d))
    with pytest.raises(ModelError, match="key 'torque_resid_cov' must be a 2 x 2 table of finite numbers"):
        load_force_model(path)


def test_fitted_trials_are_ranges_and_older_one_by_one_lists_still_read(tmp_path):
    t = exact_table(120, (0.0, 12.0))
    model = PostureModel(geometry=GEOMETRY, protocol="takuma2014").fit(t)
    fit_ids = sorted(t.loc[t.set == "fit", "trial"].tolist())
    assert {i for lo, hi in model.fitted_trials for i in range(lo, hi + 1)} == set(fit_ids)
    d = json.loads(model.to_json())
    d["fitted_trials"] = fit_ids[::-1]  # as files written before ranges list them
    path = tmp_path / "old.json"
    path.write_text(json.dumps(d))
    assert load_force_model(path).fitted_trials == model.fitted_trials
    d["fitted_trials"] = [[3, 1]]
    path.write_text(json.dumps(d))
    with pytest.raises(ModelError) as e:
        load_force_model(path)
    assert str(e.value).endswith(
        "key 'fitted_trials' must list whole trial numbers, or [first, last] ranges of them; refit with `labcli fit`."
    )


def test_too_few_fit_trials_name_the_paper_form():
    with pytest.raises(ModelError, match="needs more than 4 usable fit trials, got 4.*--form paper"):
        PostureModel(geometry=GEOMETRY).fit(exact_table(5, (0.0, 12.0)))


def test_a_few_fit_trials_grow_no_more_terms_than_their_folds_can_judge():
    # 12 fit trials, 10 folds: each cross-validation fit keeps 10, so at most 9 terms are offered.
    model = PostureModel(geometry=GEOMETRY).fit(exact_table(15, (0.0, 12.0)), choose_routes=False)
    assert 4 <= len(model.torque_terms) <= 9 and 4 <= len(model.angle_terms) <= 9
    assert np.all(np.isfinite(model.torque_coefficients))


def test_torque_terms_the_data_do_not_support_are_left_out():
    # Torques that follow the pressure drops alone, plus noise: the products with the deflection
    # and the deflection itself predict nothing held out, and are not taken in.
    t = exact_table(200, (0.0, 14.0), seed=3)
    rng = np.random.default_rng(4)
    dP = t[["P_L10", "P_R10", "P_L20", "P_R20"]].to_numpy() - t[["P_L1", "P_R1", "P_L2", "P_R2"]].to_numpy()
    tau = dP @ np.array([[30.0, -5.0], [-28.0, 4.0], [6.0, 9.0], [-5.0, -10.0]]) + 2e-3 * rng.standard_normal(
        (len(t), 2)
    )
    th = np.radians(t[["theta1_0_deg", "theta2_0_deg"]].to_numpy() + t[["theta1_deg", "theta2_deg"]].to_numpy())
    t["Fx_N"], t["Fy_N"] = force_from_torque(th, tau, H2, H3).T
    model = PostureModel(geometry=GEOMETRY).fit(t, choose_routes=False)
    assert model.torque_terms == TORQUE_TERMS[:4]
    np.testing.assert_allclose(np.asarray(model.torque_coefficients)[:, 0], [30.0, -28.0, 6.0, -5.0], rtol=0.05)
    # A file names the terms it kept; an unknown or repeated one is refused in one sentence.
    back = PostureModel.from_dict(json.loads(model.to_json()))
    assert back.torque_terms == model.torque_terms
    for terms in (["dP_L1", "dP_X9"], ["dP_L1", "dP_L1", "dP_R1", "dP_L2"]):
        d = json.loads(model.to_json()) | {"torque_terms": terms}
        with pytest.raises(ModelError, match="names terms this labcli does not know"):
            PostureModel.from_dict(d)
    d = json.loads(model.to_json()) | {"torque_terms": list(TORQUE_TERMS)}
    with pytest.raises(ModelError, match="key 'torque_coefficients' must be a 14 x 2 table"):
        PostureModel.from_dict(d)


def test_files_without_torque_terms_are_read_with_all_fourteen():
    t = exact_table(120, (0.0, 12.0))
    model = PostureModel(geometry=GEOMETRY).fit(t, choose_routes=False)
    assert len(model.torque_terms) == len(TORQUE_TERMS)
    d = json.loads(model.to_json())
    del d["torque_terms"]  # as files written before the terms were chosen
    back = PostureModel.from_dict(d)
    v = t[t.set == "validation"]
    np.testing.assert_array_equal(back.predict_table(v)["Fx_N"], model.predict_table(v)["Fx_N"])


def test_classification_reads_the_pushes_rest_posture_into_the_posture_form():
    from labcli.papers.takuma2014.models.classify import _posture_and_force, _rest_posture

    t = exact_table(120, (0.0, 14.0))
    model = PostureModel(geometry=GEOMETRY).fit(t)
    v = t[t.set == "validation"].reset_index(drop=True)
    theta0 = _rest_posture(v)
    np.testing.assert_allclose(np.degrees(theta0), np.tile([0.0, 14.0], (len(v), 1)))
    _, pred = _posture_and_force(v, model, "pressure-only", theta0)
    np.testing.assert_allclose(pred["Fy_N"], v.Fy_N, atol=1e-6)
    assert _rest_posture(v.drop(columns=["theta1_0_deg"])) is None


def test_empty_rest_columns_mean_no_rest_posture():
    from labcli.papers.takuma2014.models.classify import _rest_posture

    t = pd.DataFrame({"theta1_0_deg": [np.nan, np.nan], "theta2_0_deg": [np.nan, np.nan]})
    assert _rest_posture(t) is None
    t = pd.DataFrame({"theta1_0_deg": [np.nan, 1.0], "theta2_0_deg": [12.0, np.nan]})
    np.testing.assert_allclose(np.degrees(_rest_posture(t)), [[0.0, 12.0], [1.0, 0.0]])


@pytest.fixture(scope="module")
def bent_rig_table() -> pd.DataFrame:
    """The bent protocol on the simulated rig (seed 1, its non-idealities on), rest posture columns blank."""
    from labcli.core.protocol import load_protocol
    from labcli.papers.takuma2014.protocol import load_plan
    from labcli.papers.takuma2014.sim.drive import simulate_weight_trials
    from labcli.papers.takuma2014.sim.rig import SimRig

    proto = load_protocol("takuma2014-bent")
    rig = SimRig(seed=1, supply_MPa=(0.15, 0.15, 0.45, 0.15))
    table = simulate_weight_trials(rig, load_plan(proto), calibration=proto.calibration, settle_s=8.0)
    table["theta1_0_deg"], table["theta2_0_deg"] = 0.0, 18.0
    return table


def test_routes_are_chosen_on_the_fit_trials_alone(bent_rig_table):
    from labcli.core.protocol import load_protocol

    rig = load_protocol("takuma2014-bent").settings.rig
    model = PostureModel(geometry=rig).fit(bent_rig_table)
    assert set(model.routes) == {"theta1", "theta2", "Fx", "Fy"}
    assert set(model.fit_stats["routes_cv"]) == set(model.routes)
    # Validation rows rewritten beyond recognition: not one number of the model moves.
    other = bent_rig_table.copy()
    val = other["set"] == "validation"
    other.loc[val, ["Fx_N", "Fy_N"]] *= -3.0
    other.loc[val, ["P_L1", "P_R2"]] *= 0.9
    other.loc[val, "theta1_deg"] += 5.0
    again = PostureModel(geometry=rig).fit(other)
    assert again.to_json() == model.to_json()
    # ... while a change to the fit rows does move it.
    other.loc[other["set"] == "fit", "theta1_deg"] *= 1.5
    assert PostureModel(geometry=rig).fit(other).to_json() != model.to_json()


def test_a_paper_routed_quantity_takes_the_paper_value_and_its_own_error(bent_rig_table):
    from labcli.core.protocol import load_protocol

    rig = load_protocol("takuma2014-bent").settings.rig
    model = PostureModel(geometry=rig).fit(bent_rig_table)
    # On this rig the inside pair carries theta1 only through friction: Eq. 34 predicts it better.
    assert model.route("theta1") == "paper"
    cv = model.fit_stats["routes_cv"]["theta1"]
    assert cv["rmse_paper"] < cv["rmse_posture"]
    # The posture form's paper route fits the labels the posture form fits: corrected for the play.
    paper = TakumaModel(geometry=rig, label_play="none").fit(PostureModel(geometry=rig)._unplayed(bent_rig_table, "t"))
    v = bent_rig_table[bent_rig_table.set == "validation"]
    out = model.predict_table(v)
    np.testing.assert_allclose(out["theta1_rad"], paper.predict_table(v)["theta1_rad"], rtol=1e-12)
    assert out["routes"]["theta1"] == "paper"
    # Its standard error is the held-out RMSE and the coefficients' share: above the former, near it.
    s_cv = math.sqrt(model.paper_variance["theta1"])
    assert np.all(out["se"]["theta1"] >= s_cv) and np.all(out["se"]["theta1"] < 1.5 * s_cv)
    # A quantity kept on the torque route is the posture form's, as without routes.
    plain = PostureModel(geometry=rig).fit(bent_rig_table, choose_routes=False)
    assert model.route("Fy") == "posture"
    np.testing.assert_array_equal(out["Fy_N"], plain.predict_table(v)["Fy_N"])


def test_routes_round_trip_and_bad_routes_are_one_sentence(bent_rig_table, tmp_path):
    from labcli.core.protocol import load_protocol

    model = PostureModel(geometry=load_protocol("takuma2014-bent").settings.rig).fit(bent_rig_table)
    path = tmp_path / "m.json"
    path.write_text(model.to_json())
    back = load_force_model(path)
    v = bent_rig_table[bent_rig_table.set == "validation"]
    assert back.routes == model.routes
    for key in ("theta1_rad", "Fx_N"):
        np.testing.assert_array_equal(back.predict_table(v)[key], model.predict_table(v)[key])
    d = json.loads(path.read_text())
    for change, message in (
        ({"routes": {"theta1": "direct"}}, "key 'routes' must map theta1"),
        ({"paper_variance": {}}, "key 'paper_variance' must give a finite variance"),
        ({"paper_variance": {"theta1": 10**400}}, "key 'paper_variance' must give a finite"),
        ({"paper_model": None}, "routes theta1.* to the paper's form but holds no 'paper_model'"),
    ):
        path.write_text(json.dumps(d | change))
        with pytest.raises(ModelError, match=message):
            load_force_model(path)


def test_theta1_has_its_own_equation_from_the_paper_s_terms():
    # theta1 follows the outside pair alone (Eq. 34's terms) plus noise: its own equation keeps
    # just those, while theta2 needs all four in the shared design.
    t = exact_table(200, (0.0, 14.0), seed=5, noise=1.0)
    u = t[["P_L10", "P_R10"]].to_numpy() / t[["P_L1", "P_R1"]].to_numpy() - 1.0
    rng = np.random.default_rng(9)
    t["theta1_deg"] = np.degrees(u @ [0.9, -1.1] + 2e-4 * rng.standard_normal(len(t)))
    model = PostureModel(geometry=GEOMETRY).fit(t, choose_routes=False)
    assert model.theta1_terms == ("u_L1", "u_R1")
    assert model.angle_terms[:4] == ("u_L1", "u_R1", "u_L2", "u_R2")
    np.testing.assert_allclose(model.theta1_coefficients, [0.9, -1.1], rtol=0.02)
    v = t[t.set == "validation"]
    out = model.predict_table(v)
    err = np.radians(v.theta1_deg.to_numpy()) - out["theta1_rad"]
    assert np.sqrt(np.mean(err**2)) < 3e-4 and np.all(out["se"]["theta1"] > 1.5e-4)
    d = model.to_dict()
    d["theta1_xtx_inv"] = [[1.0]]
    with pytest.raises(ModelError, match="the theta1 equation .* is incomplete or not finite"):
        PostureModel.from_dict(d)


def test_block_factors_give_the_held_out_residuals_of_a_refit_per_block():
    # The cross-validation works on R factors of contiguous blocks; it must equal fitting each
    # block's complement with lstsq on the rows themselves and predicting the block.
    from labcli.papers.takuma2014.models.posture import CV_FOLDS, _Blocks

    rng = np.random.default_rng(5)
    n, p = 1003, 5
    X = rng.normal(size=(n, p)) * [1.0, 10.0, 0.1, 3.0, 1e3]
    Y = X @ rng.normal(size=(p, 2)) + rng.normal(scale=0.3, size=(n, 2)) + X[:, :1] ** 2 * 0.2
    blocks = _Blocks.build(n, p, lambda lo, hi: np.column_stack([X[lo:hi], Y[lo:hi]]))
    edges = np.linspace(0, n, CV_FOLDS + 1).astype(int)
    for cols in ([0, 1, 2, 3, 4], [1, 3]):
        held = np.empty_like(Y)
        for lo, hi in zip(edges[:-1], edges[1:], strict=False):
            train = np.r_[0:lo, hi:n]
            beta, *_ = np.linalg.lstsq(X[train][:, cols], Y[train], rcond=None)
            held[lo:hi] = Y[lo:hi] - X[lo:hi][:, cols] @ beta
        np.testing.assert_allclose(blocks.cv_cov(cols), held.T @ held, rtol=1e-9)
        assert blocks.cv_error(cols) == pytest.approx(float(np.sum(held**2)), rel=1e-9)


def test_the_fit_from_block_factors_matches_least_squares_on_the_whole_design():
    from labcli.papers.takuma2014.models.posture import _Blocks, _shared_lstsq

    rng = np.random.default_rng(6)
    n, p = 500, 4
    X = rng.normal(size=(n, p))
    Y = X @ np.array([[1.0, -2.0], [0.5, 0.0], [0.0, 3.0], [-1.0, 1.0]]) + rng.normal(scale=0.1, size=(n, 2))
    fit = _shared_lstsq(
        _Blocks.build(n, p, lambda lo, hi: np.column_stack([X[lo:hi], Y[lo:hi]])), list(range(p)), "test"
    )
    beta, *_ = np.linalg.lstsq(X, Y, rcond=None)
    np.testing.assert_allclose(fit.beta, beta, rtol=1e-10)
    np.testing.assert_allclose(fit.xtx_inv, np.linalg.inv(X.T @ X), rtol=1e-10)
    resid = Y - X @ beta
    assert np.trace(fit.resid_cov) >= np.trace(resid.T @ resid / (n - p)) * (1 - 1e-12)


def test_routes_of_a_large_archive_are_chosen_on_an_even_sample_in_recorded_order(monkeypatch):
    from labcli.papers.takuma2014.models import routes as rt

    idx = np.arange(3, 3 + 2 * 50_001, 2)  # fit rows of a table interleaved with others
    sample = rt.route_sample(idx)
    assert len(sample) == rt.ROUTE_SAMPLE and sample[0] == idx[0] and sample[-1] == idx[-1]
    assert np.all(np.diff(sample) > 0) and np.isin(sample, idx).all()
    gaps = np.diff(np.searchsorted(idx, sample))
    assert gaps.min() >= 2 and gaps.max() <= 3  # evenly spread: every 2.5th fit trial
    small = np.arange(100)
    assert rt.route_sample(small) is small

    # A fit on more trials than the sample cross-validates both forms on the sample only.
    monkeypatch.setattr(rt, "ROUTE_SAMPLE", 120)
    seen = []
    real = rt.held_out_errors
    monkeypatch.setattr(rt, "held_out_errors", lambda rows, *a: seen.append(rows["trial"].to_numpy()) or real(rows, *a))
    t = exact_table(400, (0.0, 14.0), seed=3, noise=1.0)
    fit_trials = t.loc[t.set == "fit", "trial"].to_numpy()
    PostureModel(geometry=GEOMETRY).fit(t)
    assert len(seen) == 1 and len(seen[0]) == 120 and np.isin(seen[0], fit_trials).all()
    assert np.all(np.diff(seen[0]) > 0)


def test_torque_features_are_the_chosen_columns_of_every_term_element_for_element():
    from labcli.papers.takuma2014.models.posture import (
        FRICTION_TERMS,
        KNOWN_TORQUE_TERMS,
        RELIEVED_TERMS,
        friction_columns,
        relieved_columns,
    )

    rng = np.random.default_rng(8)
    dP, dth, moved = rng.normal(size=(40, 4)), rng.normal(size=(40, 2)), 0.01 * rng.normal(size=(40, 2))
    products = (dP[:, :, None] * dth[:, None, :]).reshape(40, 8)  # dP_a * dtheta_j, a outer, j inner
    every = np.column_stack([dP, products, dth, friction_columns(dth, moved), relieved_columns(dth)])
    mixed = ("dtheta2", "dP_R2*dtheta1", FRICTION_TERMS[1], RELIEVED_TERMS[2], "dP_L1", RELIEVED_TERMS[0])
    for terms in (TORQUE_TERMS, KNOWN_TORQUE_TERMS, mixed):
        got = torque_features(dP, dth, terms, moved)
        assert np.array_equal(got, every[:, [KNOWN_TORQUE_TERMS.index(t) for t in terms]])
