"""rPAM analysis: the stretch-test fit (Eq. 7, Fig. 6), the joint map (Fig. 8), JSON and figures."""

from __future__ import annotations

import json
import math

import numpy as np
import pandas as pd
import pytest
from scipy import stats
from support.rpam_runs import RAW, SETTINGS, joint_table, stretch_table

from labcli.core.protocol import check_document
from labcli.errors import ConfigError, ModelError
from labcli.papers.rpam2015.figures import figure8, figure_stretch
from labcli.papers.rpam2015.models import rpam
from labcli.papers.rpam2015.models.rpam_fit import (
    JointMapResult,
    StretchCorrection,
    StretchFit,
    analyse_joint_map,
    analyse_stretch,
    correction_actuator,
)
from labcli.papers.rpam2015.protocol import apply_overrides
from labcli.papers.rpam2015.sim.rig import RpamRig

ACT = SETTINGS.actuator
CHI2_999 = float(stats.chi2.ppf(0.999, 4))


@pytest.fixture(scope="module")
def stretch_run():
    # Seed 3: actuator a's true correction is 0.86 x the protocol's, so the default is wrong.
    rig = RpamRig(seed=3)
    table = stretch_table(rig)
    return rig, table, analyse_stretch(table, "rpam2015")


@pytest.fixture(scope="module")
def joint_run(stretch_run):
    rig, _, fit = stretch_run
    table = joint_table(rig)
    return table, analyse_joint_map(table, "rpam2015", fit)


def _chi2(model: StretchCorrection, coef) -> float:
    d = np.asarray(model.coefficients_N) - np.asarray(coef)
    return float(d @ np.linalg.solve(np.asarray(model.covariance_N2), d))


# --------------------------------------------------------------------------- stretch test


def test_simulated_stretch_test_recovers_the_true_correction(stretch_run):
    rig, table, fit = stretch_run
    truth = rig.true_stretch_coefficients_N["A"]
    m = fit.model
    assert m.n_points == len(table["mass_g"]) == 120 and m.dof == 116
    # The truth lies inside the fit's joint 99.9 % confidence region...
    assert _chi2(m, truth) < CHI2_999
    # ...and the protocol's default (which the rig does not follow) far outside it.
    assert _chi2(m, ACT.stretch_coefficients_N) > 100 * CHI2_999
    lam = np.linspace(*m.lambda_range, 50)
    true_curve = np.polynomial.polynomial.polyval(lam, truth)
    lo, hi = m.band(lam, level=0.999)
    assert np.all((lo <= true_curve) & (true_curve <= hi))
    # The scatter is the rig's friction (0.15 N rms per change), not a misfit.
    assert 0.1 < m.rmse_N < 0.25 and m.r2 > 0.999
    assert m.lambda_range[0] == pytest.approx(1.0, abs=0.01) and m.lambda_range[1] > 2.5


def test_each_point_is_eq7_force_balance(stretch_run):
    _, _, fit = stretch_run
    p = {k: np.asarray(v) for k, v in fit.points.items()}
    np.testing.assert_allclose(p["F_ext_N"], p["mass_kg"] * 9.80665)
    np.testing.assert_allclose(p["F_ext_N"], p["F_cons_N"] + p["F_int_N"] + p["F_stretch_N"], atol=1e-12)
    np.testing.assert_allclose(
        p["F_stretch_N"], rpam.stretch_residual(p["P_MPa"], p["L_m"], p["mass_kg"], ACT), atol=1e-12
    )
    np.testing.assert_allclose(p["lambda"], p["L_m"] / 0.07)
    np.testing.assert_allclose(p["residual_N"], p["F_stretch_N"] - p["fitted_N"], atol=1e-12)


def test_cubic_fit_closed_forms():
    lam = np.linspace(1.0, 2.5, 40)
    c = (3.0, -7.0, 2.5, 0.75)
    exact = np.polynomial.polynomial.polyval(lam, c)
    m = StretchCorrection().fit(lam, exact)
    np.testing.assert_allclose(m.coefficients_N, c, rtol=1e-8, atol=1e-8)
    assert m.rmse_N < 1e-9 and m.r2 == pytest.approx(1.0)
    # With noise: coefficients and covariance are the textbook OLS ones.
    rng = np.random.default_rng(0)
    y = exact + 0.2 * rng.standard_normal(lam.size)
    m = StretchCorrection().fit(lam, y)
    X = np.vander(lam, 4, increasing=True)
    beta, *_ = np.linalg.lstsq(X, y, rcond=None)
    r = y - X @ beta
    cov = (r @ r) / (lam.size - 4) * np.linalg.inv(X.T @ X)
    np.testing.assert_allclose(m.coefficients_N, beta, rtol=1e-7)
    np.testing.assert_allclose(np.asarray(m.covariance_N2), cov, rtol=1e-6)
    t = stats.t.ppf(0.975, lam.size - 4)
    np.testing.assert_allclose(np.asarray(m.ci95_N)[:, 1] - beta, t * np.sqrt(np.diag(cov)), rtol=1e-6)
    assert m.r2 == pytest.approx(1 - (r @ r) / np.sum((y - y.mean()) ** 2))


def test_stretch_table_may_give_kg_and_lambda():
    rng = np.random.default_rng(1)
    mass = np.repeat([0.0, 0.3, 1.0], 6)
    P = np.tile(np.linspace(0, 0.15, 6), 3)
    L = rpam.loaded_length(P, mass, ACT)
    a = analyse_stretch({"mass_g": mass * 1e3, "P_A": P, "L_m": L + 1e-5 * rng.standard_normal(L.size)})
    b = analyse_stretch(
        pd.DataFrame({"payload_kg": mass, "P_MPa": P, "lambda": (L + 1e-5 * rng.standard_normal(L.size)) / ACT.L0_m})
    )
    # The protocol's model produced these lengths: the fit finds its own default correction
    # (clamped at lambda 2.2 in the model, so compare inside the clamp).
    lam = np.linspace(1.0, 2.2, 20)
    for f in (a, b):
        inside = np.asarray(f.points["lambda"]) <= 2.2
        assert inside.sum() >= 5
    assert np.max(np.abs(a.model.predict(lam) - b.model.predict(lam))) < 0.5


def test_missing_values_are_skipped_and_listed():
    mass = [0.0, 100.0, 200.0, 300.0, 1000.0, 1300.0, 500.0]
    P = [0.05] * 7
    L = [float(rpam.loaded_length(0.05, m * 1e-3, ACT)) for m in mass]
    L[6] = float("nan")
    fit = analyse_stretch({"point": [10, 11, 12, 13, 14, 15, 16], "mass_g": mass, "P_A": P, "L_m": L})
    assert fit.skipped_rows == [16] and fit.model.n_points == 6
    assert fit.points["row"] == [10, 11, 12, 13, 14, 15]


@pytest.mark.parametrize(
    "table, message",
    [
        (
            {"mass_g": [], "P_A": [], "L_m": []},
            "The stretch table is empty; run the stretch test (payloads x pressures) first.",
        ),
        ({"mass_g": [0.0], "P_A": [0.1]}, "The stretch table needs a column 'L_m' or 'lambda'; it has mass_g, P_A."),
        (
            {"mass_g": [0, 100, 200, 300], "P_A": [0.1] * 4, "L_m": [0.08, 0.09, 0.1, 0.11]},
            "The stretch correction is a cubic and needs at least 5 points at 4 or more distinct stretches; "
            "the stretch test gave 4 points at 4 distinct stretches.",
        ),
        (
            {"mass_g": [0, 100, 200, 300, 400, 500], "P_A": [0.1] * 6, "L_m": [0.08, 0.08, 0.09, 0.09, 0.1, 0.1]},
            "The stretch correction is a cubic and needs at least 5 points at 4 or more distinct stretches; "
            "the stretch test gave 6 points at 3 distinct stretches.",
        ),
        (
            {"mass_g": [0, -100], "P_A": [0.1, 0.1], "L_m": [0.08, 0.09]},
            "Row 1 of the stretch table has payload = -0.1; a payload cannot be negative.",
        ),
        (
            {"mass_g": [0, 100], "P_A": [0.1, 0.1], "L_m": [0.08, 0.0]},
            "Row 1 of the stretch table has length = 0; an actuator length must be positive (m).",
        ),
        (
            {"mass_g": [float("nan")] * 2, "P_A": [0.1, 0.1], "L_m": [0.08, 0.09]},
            "Every one of the 2 rows of the stretch table misses a payload, pressure or length.",
        ),
        (
            {"mass_g": ["a", "b"], "P_A": [0.1, 0.1], "L_m": [0.08, 0.09]},
            "Column 'mass_g' of the stretch table must hold numbers.",
        ),
    ],
)
def test_stretch_errors_are_one_sentence(table, message):
    with pytest.raises(ModelError) as e:
        analyse_stretch(table)
    assert str(e.value) == message


def test_unfitted_and_foreign_records_are_refused():
    with pytest.raises(
        ModelError, match="^The stretch correction has not been fitted; fit it to a stretch test first.$"
    ):
        StretchCorrection().predict(1.5)
    with pytest.raises(ModelError) as e:
        StretchFit.from_json('{"kind": "rpam-joint-map"}')
    assert str(e.value) == "Expected a stretch-test analysis (kind 'rpam-stretch-fit'), got kind 'rpam-joint-map'."
    with pytest.raises(ModelError) as e:
        StretchCorrection.from_json("[1, 2")
    assert str(e.value).startswith("The stretch correction record is not valid JSON (")
    with pytest.raises(ModelError) as e:
        correction_actuator(ACT, [1.0, 2.0])
    assert str(e.value) == "A stretch correction is four finite coefficients c0..c3 in N, a stretch fit, or None."
    with pytest.raises(ConfigError, match="There is no shipped protocol named 'nope'"):
        analyse_stretch({"mass_g": [0], "P_A": [0], "L_m": [0.07]}, "nope")


def test_stretch_json_round_trip(stretch_run):
    _, _, fit = stretch_run
    text = fit.to_json()
    d = json.loads(text)
    assert d["kind"] == "rpam-stretch-fit" and d["model"]["kind"] == "rpam-stretch-correction"
    back = StretchFit.from_json(text)
    assert back.to_dict() == fit.to_dict()
    lam = np.linspace(1.0, 2.5, 7)
    np.testing.assert_array_equal(back.model.predict(lam), fit.model.predict(lam))
    np.testing.assert_array_equal(back.model.band(lam)[1], fit.model.band(lam)[1])
    m2 = StretchCorrection.from_json(fit.model.to_json())
    assert m2 == fit.model
    # The fit plugs into the protocol through --set style overrides.
    act = check_document(apply_overrides(RAW, fit.overrides())).settings.actuator
    assert act.stretch_coefficients_N == pytest.approx(fit.model.coefficients_N)
    assert act == fit.apply_to(ACT)


# --------------------------------------------------------------------------- joint map


def test_correction_brings_the_model_to_the_measured_map(joint_run):
    table, res = joint_run
    s = res.summary
    assert len(table["P_A"]) == 121
    # Fig. 8: without F_stretch the model is far off, with it close to the measurements.
    # (The rest of "with" is actuator b, about 10 % off actuator a on this rig, and friction.)
    assert s["with"]["rmse_deg"] < 3.0 < 8.0 < s["without"]["rmse_deg"]
    assert s["with"]["rmse_all_deg"] < s["without"]["rmse_all_deg"] / 4
    assert s["with"]["max_abs_error_deg"] < s["without"]["max_abs_error_deg"]
    # Without the correction the joint is too compliant: it runs onto the toggle far sooner.
    assert s["without"]["n_toggle"] > s["with"]["n_toggle"] + 20
    # Where the model compares, the uncorrected angles overshoot the measured ones.
    both = np.isfinite(res.model_deg["without"]) & (np.abs(res.measured_deg) > 3)
    ratio = res.model_deg["without"][both] / res.measured_deg[both]
    assert np.median(ratio) > 1.3
    # Where the corrected model toggles, the rig (nearly always) sits on its stop, on the
    # side the model's torque drives to; near-equal high pressures are the marginal cases.
    tog = res.toggle["with"]
    on_stop = np.abs(res.measured_deg[tog]) > 55
    assert tog.sum() > 40 and on_stop.mean() > 0.95
    side = np.sign(rpam.joint_torque(0.0, res.Pa_MPa[tog], res.Pb_MPa[tog], res.geometry, res.actuator))
    assert np.all(np.sign(res.measured_deg[tog][on_stop]) == side[on_stop])


def test_nominal_rig_reads_the_protocol_model_and_sources_are_labelled(stretch_run, joint_run):
    # A rig without variation is the protocol's model: its map is the corrected model's.
    nominal = analyse_joint_map(joint_table(RpamRig(seed=9, variation=False)), "rpam2015")
    assert nominal.correction_source == "protocol"
    assert nominal.summary["with"]["rmse_deg"] < 0.15
    assert nominal.summary["with"]["rmse_all_deg"] < 1.2  # the stop sits 1 deg short of the toggle
    assert nominal.summary["without"]["rmse_deg"] > 8.0
    table, fitted = joint_run
    assert fitted.correction_source == "fit"
    given = analyse_joint_map(table, "rpam2015", list(stretch_run[2].model.coefficients_N))
    assert given.correction_source == "given"
    np.testing.assert_allclose(given.model_deg["with"], fitted.model_deg["with"], atol=0.05)


def test_a_joint_measured_on_its_stop_where_the_model_balances_counts_apart():
    # Three pairs measured where the model says, one where the joint sat on its stop
    # (0.8 deg short of the toggle) although the model balances there: the paper's toggle
    # between two states, not a balance error.
    geom = SETTINGS.geometry
    Pa, Pb = np.array([0.05, 0.06, 0.07, 0.08]), np.array([0.05, 0.05, 0.05, 0.06])
    model = np.degrees(rpam.solve_equilibrium(Pa, Pb, geom, ACT).alpha_rad)
    assert np.all(np.isfinite(model))
    toggle = math.degrees(float(rpam.toggle_angle(geom)))
    measured = np.append(model[:3], toggle - 0.8)
    res = analyse_joint_map({"P_A": Pa, "P_B": Pb, "alpha_deg": measured})
    s = res.summary["with"]
    assert (s["n_compared"], s["n_toggle"], s["n_on_stop"]) == (3, 0, 1)
    assert s["rmse_deg"] == pytest.approx(0.0, abs=1e-9)
    # Counting every point, the stop point weighs in.
    assert s["rmse_all_deg"] == pytest.approx(abs(toggle - 0.8 - model[3]) / 2, rel=1e-9)
    # Just outside the band it is an ordinary (large) error.
    measured[3] = toggle - 2.5
    s = analyse_joint_map({"P_A": Pa, "P_B": Pb, "alpha_deg": measured}).summary["with"]
    assert (s["n_compared"], s["n_on_stop"]) == (4, 0) and s["max_abs_error_deg"] > 20


def test_grid_recovers_the_plan_from_noisy_pressures(joint_run):
    _, res = joint_run
    g = res.grid()
    assert g is not None
    pa, pb, cells = g
    Pa, Pb = np.array(SETTINGS.joint_map.Pa_MPa), np.array(SETTINGS.joint_map.Pb_MPa)
    np.testing.assert_allclose(pa, Pa, atol=0.5e-3)
    np.testing.assert_allclose(pb, Pb, atol=0.5e-3)
    assert cells["measured"].shape == (11, 11)
    # Rows index Pb, columns Pa: raising Pa (left to right) raises the angle.
    assert cells["measured"][0, -2] > cells["measured"][0, 0]
    scattered = analyse_joint_map({"P_A": [0.05, 0.06, 0.07], "P_B": [0.05, 0.05, 0.06], "alpha_deg": [0.0, 5.0, 3.0]})
    assert scattered.grid() is None


def test_joint_map_json_round_trip(joint_run):
    _, res = joint_run
    text = res.to_json()
    d = json.loads(text)  # strict JSON: toggles are null, not NaN
    assert "NaN" not in text
    assert d["points"]["with_deg"].count(None) == res.summary["with"]["n_toggle"]
    back = JointMapResult.from_json(text)
    assert back.to_dict() == d
    np.testing.assert_array_equal(back.model_deg["without"], res.model_deg["without"])
    assert back.actuator == res.actuator and back.geometry == res.geometry


@pytest.mark.parametrize(
    "table, message",
    [
        (
            {"P_A": [], "P_B": [], "alpha_deg": []},
            "The joint-map table is empty; measure the joint over a Pa x Pb grid first.",
        ),
        (
            {"P_A": [0.05], "alpha_deg": [1.0]},
            "The joint-map table needs a column 'P_B' or 'Pb_MPa'; it has P_A, alpha_deg.",
        ),
        (
            {"P_A": [0.05, -0.01], "P_B": [0.05, 0.05], "alpha_deg": [0.0, 1.0]},
            "Row 1 of the joint-map table has P_A = -0.01; the rPAM works with gauge pressures of 0 MPa or more, "
            "so a reading below -5 kPa points to a pressure sensor or its calibration.",
        ),
        (
            {"P_A": [0.05], "P_B": [0.05], "alpha_deg": [float("nan")]},
            "Every one of the 1 rows of the joint-map table misses a pressure or an angle.",
        ),
    ],
)
def test_joint_map_errors_are_one_sentence(table, message):
    with pytest.raises(ModelError) as e:
        analyse_joint_map(table)
    assert str(e.value) == message


# --------------------------------------------------------------------------- figures


def test_figures_are_written(tmp_path, stretch_run, joint_run):
    _, res = joint_run
    # Drawn from the JSON record alone, as a later `labcli` run would.
    p8 = figure8(JointMapResult.from_json(res.to_json()), tmp_path / "fig8.png")
    ps = figure_stretch(StretchFit.from_json(stretch_run[2].to_json()), tmp_path / "stretch.svg")
    assert p8.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and p8.stat().st_size > 50_000
    assert b"<svg" in ps.read_bytes()[:500]
    # A scattered (non-grid) map is drawn by triangulation.
    sub = {k: v[::3] for k, v in joint_run[0].items()}
    figure8(analyse_joint_map(sub, "rpam2015", stretch_run[2]), tmp_path / "fig8b.pdf")
    assert (tmp_path / "fig8b.pdf").read_bytes()[:4] == b"%PDF"
    with pytest.raises(ConfigError) as e:
        figure8(res, tmp_path / "fig8.jpg")
    assert str(e.value) == f"The plot file {tmp_path / 'fig8.jpg'} must end in .png, .pdf or .svg."
