"""The paper's regression (Eqs. 34-37): fit, predict, accuracy, JSON, Figure 7.

Data come from the paper's own equations and Section 3.3 coefficients (labcli.papers.takuma2014.models.synthetic)
read through 12-bit sensors, so the fit must give the paper's numbers back within what that
quantisation allows, and exactly without it.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pandas as pd
import pytest

from labcli.core import idranges
from labcli.errors import ConfigError, ModelError
from labcli.papers.takuma2014.models.metrics import error_metrics, evaluate, evaluation_to_dict
from labcli.papers.takuma2014.models.synthetic import (
    ANGLE_LSB_DEG,
    PAPER_GEOMETRY,
    PRESSURE_LSB_MPA,
    add_sensor_noise,
    paper_trials,
)
from labcli.papers.takuma2014.models.takuma import (
    COEFFICIENT_NAMES,
    PAPER_COEFFICIENTS,
    TERMS,
    TakumaModel,
    fit,
    force_amplification,
    jacobian_cond,
    jstar,
    theta2_threshold,
)

G = PAPER_GEOMETRY
H2, H3 = G["h2"], G["h3"]


@pytest.fixture(scope="module")
def clean() -> pd.DataFrame:
    return paper_trials(90, seed=11, noise=False)


@pytest.fixture(scope="module")
def noisy(clean: pd.DataFrame) -> pd.DataFrame:
    return add_sensor_noise(clean, seed=5)  # rounding to the 12-bit count grid


@pytest.fixture(scope="module")
def noisy_model(noisy: pd.DataFrame) -> TakumaModel:
    return fit(noisy, G)


@pytest.fixture(scope="module")
def validation() -> pd.DataFrame:
    return paper_trials(60, seed=13, set_name="validation", start_id=1001)


def paper_model() -> TakumaModel:
    return TakumaModel(geometry=G, coefficients=dict(PAPER_COEFFICIENTS))


def printed_jacobian(t1: float, t2: float) -> np.ndarray:
    return np.array(
        [
            [-H2 * math.cos(t1) - H3 * math.cos(t1 + t2), -H3 * math.cos(t1 + t2)],
            [-H2 * math.sin(t1) - H3 * math.sin(t1 + t2), -H3 * math.sin(t1 + t2)],
        ]
    )


# ----------------------------------------------------------------------------- geometry


def test_jstar_is_the_inverse_transpose_of_the_printed_jacobian() -> None:
    rng = np.random.default_rng(0)
    th = np.column_stack([rng.uniform(-0.5, 0.5, 20), rng.choice([-1, 1], 20) * rng.uniform(0.05, 1.2, 20)])
    js = jstar(th, H2, H3)
    for k, (t1, t2) in enumerate(th):
        J = printed_jacobian(t1, t2)
        assert np.linalg.det(J) == pytest.approx(H2 * H3 * math.sin(t2), rel=1e-12)
        np.testing.assert_allclose(js[k], np.linalg.inv(J).T, rtol=1e-12)


def test_jacobian_condition_number_and_singular_threshold() -> None:
    t2 = np.radians([0.5, 2.0, 10.0, 45.0, -30.0])
    expected = [np.linalg.cond(printed_jacobian(0.3, t)) for t in t2]
    np.testing.assert_allclose(jacobian_cond(t2, H2, H3), expected, rtol=1e-10)
    assert jacobian_cond(np.array(0.0), H2, H3) == np.inf
    thr = theta2_threshold(H2, H3, 100.0)
    assert jacobian_cond(np.array(thr), H2, H3) == pytest.approx(100.0, rel=1e-9)
    # small-angle closed form: |sin theta2*| = ((h2+h3)^2 + h3^2) k / ((k^2+1) h2 h3)
    approx = ((H2 + H3) ** 2 + H3**2) * 100.0 / ((100.0**2 + 1) * H2 * H3)
    assert math.sin(thr) == pytest.approx(approx, rel=1e-3)
    assert math.degrees(thr) == pytest.approx(2.86, abs=0.01)


def test_synthetic_trials_obey_the_paper_equations(clean: pd.DataFrame) -> None:
    b = PAPER_COEFFICIENTS
    for _, r in clean.head(15).iterrows():
        P0 = r[["P_L10", "P_R10", "P_L20", "P_R20"]].to_numpy(float)
        P = r[["P_L1", "P_R1", "P_L2", "P_R2"]].to_numpy(float)
        t1, t2 = math.radians(r.theta1_deg), math.radians(r.theta2_deg)
        u, dP = P0 / P - 1, P0 - P
        assert math.sin(t1) == pytest.approx(b["beta_theta1_L1"] * u[0] + b["beta_theta1_R1"] * u[1], abs=1e-11)
        # Eq. 31's plus sign with Section 3.3's -2.972 (Eq. 35's printed minus is a misprint).
        s2 = 1.359 * u[0] + 1.094 * u[1] + 0.766 * u[2] + (-2.972) * u[3]
        assert math.sin(t2) == pytest.approx(s2, abs=1e-11)
        js = np.linalg.inv(printed_jacobian(t1, t2)).T
        c1, c2 = math.cos(t1), math.cos(t2)
        for row, eq, col in ((0, "Fx", "Fx_N"), (1, "Fy", "Fy_N")):
            k = [b[n] for n in TERMS[eq]]
            F = (
                k[0] * js[row, 0] * c1 * dP[0]
                + k[1] * js[row, 0] * c1 * dP[1]
                + k[2] * js[row, 0] * (c1 - c2) * dP[2]
                + k[3] * js[row, 0] * (c1 - c2) * dP[3]
                + k[4] * js[row, 1] * c2 * dP[2]
                + k[5] * js[row, 1] * c2 * dP[3]
            )
            assert F == pytest.approx(r[col], abs=1e-9)


# ----------------------------------------------------------------------------- fitting


def test_zero_noise_recovers_the_paper_coefficients_exactly(clean: pd.DataFrame) -> None:
    m = fit(clean, G)
    for name in COEFFICIENT_NAMES:
        assert m.coefficients[name] == pytest.approx(PAPER_COEFFICIENTS[name], rel=1e-9)
        assert m.standard_errors[name] <= 1e-9 * abs(PAPER_COEFFICIENTS[name])
    for eq in ("theta1", "theta2", "Fx", "Fy"):
        assert m.fit_stats[eq]["r2"] == pytest.approx(1.0, abs=1e-12)
        assert m.fit_stats[eq]["n"] == 90
    assert m.fit_stats["Fx"]["dof"] == 84 and m.fit_stats["theta1"]["dof"] == 88


def test_quantised_data_give_the_paper_coefficients_within_their_standard_errors(noisy_model: TakumaModel) -> None:
    m = noisy_model
    for name in COEFFICIENT_NAMES:
        se = m.standard_errors[name]
        # Sensible: a 0.3 kPa quantisation determines each coefficient to better than 15 %
        # but not to float precision.
        assert 1e-5 < se / abs(PAPER_COEFFICIENTS[name]) < 0.15, name
        # Noise in the regressors (errors in variables) pulls the force coefficients 1-2 %
        # towards zero, beyond the least-squares standard error; hence 5 there.
        allowed = 4.0 if name.startswith("beta_theta") else 5.0
        assert abs(m.coefficients[name] - PAPER_COEFFICIENTS[name]) < allowed * se, name
        lo, hi = m.ci95[name]
        assert hi - lo == pytest.approx(2 * m.fit_stats[_eq(name)]["t_975"] * se, rel=1e-12)
    st = m.fit_stats
    assert st["theta1"]["r2"] > 0.999 and st["theta2"]["r2"] > 0.999
    # Angles: fitted in sine space, reported in degrees as well; a 0.083 deg potentiometer count.
    assert 0.01 < st["theta1"]["rmse_native"] < 0.2
    assert st["theta1"]["rmse_native"] == pytest.approx(math.degrees(st["theta1"]["rmse"]), rel=0.05)
    assert st["Fx"]["r2"] > 0.95 and st["Fy"]["r2"] > 0.85
    assert all(1.0 <= st[eq]["design_cond"] < 1e3 for st_ in [st] for eq in st_)


def _eq(name: str) -> str:
    return next(eq for eq, names in TERMS.items() if name in names)


def test_standard_errors_match_the_spread_over_repeated_noise(clean: pd.DataFrame) -> None:
    fits = [fit(add_sensor_noise(clean, seed=s, noise_counts=1.0), G) for s in range(40)]
    for name in COEFFICIENT_NAMES:
        values = np.array([f.coefficients[name] for f in fits])
        mean_se = np.mean([f.standard_errors[name] for f in fits])
        ratio = values.std(ddof=1) / mean_se
        assert 0.6 < ratio < 1.6, (name, ratio)


def test_covariance_is_symmetric_and_carries_the_standard_errors(noisy_model: TakumaModel) -> None:
    for eq, names in TERMS.items():
        cov = np.array(noisy_model.covariance[eq])
        np.testing.assert_allclose(cov, cov.T, rtol=1e-10, atol=0)
        np.testing.assert_allclose(np.sqrt(np.diag(cov)), [noisy_model.standard_errors[n] for n in names], rtol=1e-12)
        assert np.all(np.linalg.eigvalsh(cov) > 0)


# ----------------------------------------------------------------------------- validation


def _propagated_rmse(model: TakumaModel, table: pd.DataFrame, mode: str) -> dict[str, float]:
    """RMSE expected from 12-bit rounding of the 8 pressures (and of the observed angle)."""
    P0 = table[["P_L10", "P_R10", "P_L20", "P_R20"]].to_numpy(float)
    P = table[["P_L1", "P_R1", "P_L2", "P_R2"]].to_numpy(float)
    th = np.radians(table[["theta1_deg", "theta2_deg"]].to_numpy(float))
    sigma = PRESSURE_LSB_MPA / math.sqrt(12.0)
    base = model.predict(P0, P, mode=mode, theta=th)
    keys = {"theta1": "theta1_rad", "theta2": "theta2_rad", "Fx": "Fx_N", "Fy": "Fy_N"}
    var = {q: np.zeros(len(P)) for q in keys}
    h = 1e-7
    for which in range(8):
        A0, A = P0.copy(), P.copy()
        (A0 if which < 4 else A)[:, which % 4] += h
        out = model.predict(A0, A, mode=mode, theta=th)
        for q, k in keys.items():
            scale = math.degrees(1) if q.startswith("theta") else 1.0
            var[q] += ((out[k] - base[k]) / h * scale * sigma) ** 2
    obs_var = (ANGLE_LSB_DEG / math.sqrt(12.0)) ** 2
    var["theta1"] += obs_var
    var["theta2"] += obs_var
    if mode == "measured-angles":  # the forces also see the rounded potentiometer angles
        for q in ("Fx", "Fy"):
            for j in range(2):
                t = th.copy()
                t[:, j] += 1e-7
                out = model.predict(P0, P, mode=mode, theta=t)
                var[q] += ((out[keys[q]] - base[keys[q]]) / 1e-7 * math.radians(ANGLE_LSB_DEG) / math.sqrt(12)) ** 2
    return {q: float(np.sqrt(np.mean(v))) for q, v in var.items()}


@pytest.mark.parametrize("mode", ["pressure-only", "measured-angles"])
def test_validation_errors_sit_at_the_quantisation_noise_floor(
    noisy_model: TakumaModel, validation: pd.DataFrame, mode: str
) -> None:
    ev = evaluate(noisy_model, validation, mode=mode)
    expected = _propagated_rmse(paper_model(), validation, mode)
    for q in ("theta1", "theta2", "Fx", "Fy"):
        m = ev["metrics"][q]
        assert m["n"] == 60 and m["n_flagged"] == 0
        assert 0.5 < m["rmse"] / expected[q] < 2.0, (q, m["rmse"], expected[q])
        assert abs(m["bias"]) < 3 * m["rmse"] / math.sqrt(m["n"]) + 0.02 * m["rmse"] + 1e-3
    assert ev["metrics"]["theta1"]["r2"] > 0.999


def test_zero_noise_validation_is_exact(clean: pd.DataFrame) -> None:
    m = fit(clean, G)
    val = paper_trials(12, seed=21, noise=False, set_name="validation", start_id=500)
    ev = evaluate(m, val)
    for q in ("theta1", "theta2", "Fx", "Fy"):
        assert ev["metrics"][q]["max_abs"] < 1e-8


def test_error_metrics_known_answer() -> None:
    m = error_metrics([0.0, 1.0, 2.0, 3.0], [0.0, 1.0, 2.0, 5.0])
    assert m["n"] == 4
    assert m["rmse"] == pytest.approx(1.0)
    assert m["mae"] == pytest.approx(0.5)
    assert m["max_abs"] == pytest.approx(2.0)
    assert m["bias"] == pytest.approx(0.5)
    assert m["r2"] == pytest.approx(1 - 4 / 5)
    assert m["pct_range"] == pytest.approx(100 / 3)
    one = error_metrics([2.0], [2.5])
    assert one["r2"] is None and one["pct_range"] is None and one["rmse"] == pytest.approx(0.5)


# ----------------------------------------------------------------------------- edge cases


def test_force_amplification_per_component() -> None:
    th = np.radians([[7.0, 0.8], [-5.0, -1.5], [0.0, 0.5], [3.0, 20.0], [7.0, 0.1]])
    amp = force_amplification(th, H2, H3)
    for k, (t1, t2) in enumerate(th):
        J = printed_jacobian(t1, t2)
        rows = np.linalg.norm(np.linalg.inv(J).T, axis=1) * np.linalg.norm(J, 2)
        np.testing.assert_allclose(amp[k], rows, rtol=1e-10)
        assert max(amp[k]) <= np.linalg.cond(J) * (1 + 1e-12)
    # upright arm: Fx stays determined, Fy (along the arm) is lost
    assert amp[2, 0] < 10 and amp[2, 1] > 500
    assert np.all(force_amplification(np.array([[0.1, 0.0]]), H2, H3) == np.inf)


def test_force_amplification_is_numpys_row_norm_to_the_bit() -> None:
    # The fit's exclusions compare it with a cut: the rows' norms written out must be numpy's own.
    from labcli.papers.takuma2014.models.geometry import _smax2_det, jstar

    rng = np.random.default_rng(12)
    th = rng.uniform(-1.6, 1.6, (20_000, 2))
    th[:50, 1] = 0.0  # singular: inf
    with np.errstate(all="ignore"):
        js = jstar(th, H2, H3)
        ref = np.linalg.norm(js, axis=2) * np.sqrt(_smax2_det(th[:, 1], H2, H3)[0])[:, None]
    ref = np.where(np.abs(H2 * H3 * np.sin(th[:, 1]))[:, None] > 0, ref, np.inf)
    np.testing.assert_array_equal(force_amplification(th, H2, H3), ref)
    np.testing.assert_array_equal(force_amplification(th, H2, H3, js), ref)


def test_near_singular_trials_are_left_out_of_the_force_fit_and_flagged(clean: pd.DataFrame) -> None:
    near = paper_trials(4, seed=4, noise=False, start_id=900, theta2_values_deg=[0.8, -1.5, 2.5, 0.1])
    amp = force_amplification(np.radians(near[["theta1_deg", "theta2_deg"]].to_numpy()), H2, H3)
    assert np.all(amp[:, 1] > 100) and amp[3, 0] > 100 and np.all(amp[:3, 0] < 100)
    m = fit(pd.concat([clean, near]), G)
    fy = {e["trial"]: e["reason"] for e in m.excluded_trials["Fy"]}
    assert sorted(fy) == [900, 901, 902, 903]
    assert fy[900] == f"singular Jacobian: |theta2| = 0.80 deg, Fy amplification {amp[0, 1]:.3g} > 100"
    assert [e["trial"] for e in m.excluded_trials["Fx"]] == [903]
    assert m.excluded_trials["theta2"] == [] and idranges.contains(m.fitted_trials["theta2"], [900]).all()
    assert m.fit_stats["Fx"]["n"] == 93 and m.fit_stats["Fy"]["n"] == 90 and m.fit_stats["theta1"]["n"] == 94
    # the near-singular trials obey the equations too: the fit stays exact
    assert m.coefficients["beta_Fx3"] == pytest.approx(PAPER_COEFFICIENTS["beta_Fx3"], rel=1e-9)

    P0 = near[["P_L10", "P_R10", "P_L20", "P_R20"]].to_numpy(float)
    P = near[["P_L1", "P_R1", "P_L2", "P_R2"]].to_numpy(float)
    out = m.predict(P0, P)
    assert list(out["ok"]["Fy"]) == [False] * 4 and list(out["ok"]["Fx"]) == [True, True, True, False]
    assert all(out["ok"]["theta2"])
    assert all(f == ["singular-jacobian"] for f in out["flags"])
    # flagged values are still the model's own answer (here exact, the data being noise-free)
    np.testing.assert_allclose(out["Fy_N"], near["Fy_N"], rtol=1e-6)
    # exactly straight upper joint: a finite stand-in, flagged
    out = m.predict(P0[:1], P[:1], mode="measured-angles", theta=[[0.05, 0.0]])
    assert np.isfinite(out["Fx_N"][0]) and np.isfinite(out["Fy_N"][0])
    assert out["flags"] == [["singular-jacobian"]] and not out["ok"]["Fx"][0]


def test_arcsin_argument_outside_unit_range_is_clipped_and_flagged() -> None:
    m = paper_model()
    # P_R1 tripled under the load: u_R1 = -2/3, sin(theta1) = -1.587 * -0.667 > 1
    out = m.predict([[0.3, 0.3, 0.3, 0.3]], [[0.3, 0.9, 0.3, 0.3]])
    assert out["theta1_rad"][0] == pytest.approx(math.pi / 2)
    assert "theta1-clipped" in out["flags"][0]
    assert not out["ok"]["theta1"][0] and not out["ok"]["Fx"][0]
    assert np.isfinite(out["Fx_N"][0])


def test_bad_pressures_are_flagged_not_propagated() -> None:
    out = paper_model().predict([[0.3, 0.3, 0.3, 0.3], [0.3] * 4], [[0.0, 0.3, 0.3, 0.3], [0.29] * 4])
    assert out["flags"][0] == ["bad-pressure"]
    assert not out["ok"]["theta1"][0] and out["ok"]["theta1"][1]
    assert all(np.isfinite(out[k]).all() for k in ("theta1_rad", "theta2_rad", "Fx_N", "Fy_N"))


def test_too_few_fit_trials(clean: pd.DataFrame) -> None:
    with pytest.raises(ModelError) as e:
        fit(clean.head(6), G, source="run.h5")
    assert str(e.value) == (
        "The Fx equation needs at least 7 usable fit trials for its 6 coefficients, "
        "but run.h5 has 6; record more fit trials."
    )


def test_too_few_after_singular_exclusions(clean: pd.DataFrame) -> None:
    near = paper_trials(2, seed=4, noise=False, start_id=900, theta2_values_deg=[0.8, -1.5])
    with pytest.raises(ModelError) as e:
        fit(pd.concat([clean.head(6), near]), G, source="run.h5")
    assert str(e.value).startswith(
        "The Fy equation needs at least 7 usable fit trials for its 6 "
        "coefficients, but run.h5 has 6 (2 excluded: singular Jacobian: "
    )


def test_a_term_that_never_varies_is_reported(clean: pd.DataFrame) -> None:
    t = clean.copy()
    t["P_L1"] = t["P_L10"]
    with pytest.raises(ModelError) as e:
        fit(t, G)
    assert str(e.value) == (
        "The theta1 fit cannot determine beta_theta1_L1: its term is zero in every "
        "usable fit trial; record fit trials that load every actuator."
    )


def test_collinear_features_are_reported(clean: pd.DataFrame) -> None:
    t = clean.copy()
    t["P_R1"] = t["P_R10"] * t["P_L1"] / t["P_L10"]  # u_R1 == u_L1 in every trial
    with pytest.raises(ModelError) as e:
        fit(t, G)
    msg = str(e.value)
    assert msg.startswith("The theta1 design matrix is collinear (condition number ")
    assert msg.endswith(
        "> 1e+08, weakest direction mostly beta_theta1_L1); record fit trials with "
        "more varied force directions and postures."
    ) or msg.endswith(
        "> 1e+08, weakest direction mostly beta_theta1_R1); record fit trials with more varied "
        "force directions and postures."
    )


def test_no_fit_trials_and_empty_validation_set(clean: pd.DataFrame, noisy_model: TakumaModel) -> None:
    t = clean.copy()
    t["set"] = ""
    with pytest.raises(ModelError) as e:
        fit(t, G, source="trials.csv")
    assert str(e.value) == (
        "trials.csv has no fit trials (no row with set = 'fit'); assign trials with "
        "`labcli split` (or fill the `set` column)."
    )
    with pytest.raises(ModelError) as e:
        evaluate(noisy_model, clean, source="run.h5")
    assert str(e.value) == (
        "run.h5 has no validation trials (no row with set = 'validation'); assign "
        "trials with `labcli split` (or fill the `set` column)."
    )


def test_model_from_another_protocol_or_geometry_is_refused(noisy_model: TakumaModel) -> None:
    with pytest.raises(ModelError) as e:
        noisy_model.check_compatible("rpam2015", G, model_name="the model file m.json", run_name="run.h5")
    assert str(e.value) == (
        "The model file m.json was fitted for protocol 'takuma2014' but run.h5 uses "
        "protocol 'rpam2015'; fit a model on a run of this protocol."
    )
    other = dict(G, h3_m=0.08)
    other.pop("h3")
    with pytest.raises(ModelError) as e:
        noisy_model.check_compatible("takuma2014", other, model_name="the model file m.json", run_name="run.h5")
    assert str(e.value) == (
        "The model file m.json was fitted for h3 = 0.065 m but run.h5 has h3 = 0.08 m; fit a model for this rig."
    )
    noisy_model.check_compatible("takuma2014", {f"{k}_m": v for k, v in G.items()})


def test_unfitted_model_and_bad_modes() -> None:
    with pytest.raises(ModelError) as e:
        TakumaModel(geometry=G).predict([[0.3] * 4], [[0.3] * 4])
    assert str(e.value) == "The model has no coefficients yet; fit it on a run first (`labcli fit RUN.h5`)."
    with pytest.raises(ModelError) as e:
        paper_model().predict([[0.3] * 4], [[0.3] * 4], mode="measured-angles")
    assert str(e.value) == "The measured-angles mode needs the measured joint angles."
    with pytest.raises(ModelError) as e:
        TakumaModel(geometry={"h2": 0.13})
    assert str(e.value).startswith("The rig geometry needs a positive length 'h3' in m")


# ----------------------------------------------------------------------------- JSON


def test_json_round_trip_is_exact(noisy_model: TakumaModel) -> None:
    text = noisy_model.to_json()
    back = TakumaModel.from_json(text)
    assert back == noisy_model
    assert back.to_json() == text
    d = json.loads(text)
    assert d["schema"] == "labcli-takuma-model" and d["version"] == 1
    assert d["units"]["force_coefficients"] == "N m / MPa"
    assert d["coefficients"]["beta_theta2_R2"] == noisy_model.coefficients["beta_theta2_R2"]
    assert d["settings"]["theta2_threshold_deg"] == pytest.approx(2.86, abs=0.01)
    assert "-2.972" in d["sign_convention"]
    np.testing.assert_array_equal(
        back.predict([[0.3] * 4], [[0.31, 0.29, 0.3, 0.305]])["Fx_N"],
        noisy_model.predict([[0.3] * 4], [[0.31, 0.29, 0.3, 0.305]])["Fx_N"],
    )


def test_json_that_is_not_a_model_is_refused(tmp_path) -> None:
    with pytest.raises(ModelError) as e:
        TakumaModel.from_json('{"schema": "labcli-run"}', name="the model file x.json")
    assert str(e.value) == (
        "The model file x.json is not a labcli Takuma model (schema 'labcli-run', "
        "expected 'labcli-takuma-model'); pass a file written by `labcli fit`."
    )
    with pytest.raises(ModelError) as e:
        TakumaModel.from_json("{not json", name="the model file x.json")
    assert (
        str(e.value)
        == "The model file x.json is not valid JSON (line 1, column 2: Expecting property name enclosed in double quotes)."
    )
    with pytest.raises(ModelError) as e:
        TakumaModel.load(tmp_path / "none.json")
    assert str(e.value) == f"The model file {tmp_path / 'none.json'} does not exist; write one with `labcli fit`."


# ----------------------------------------------------------------------------- Figure 7


def test_figure7_png_and_pdf(noisy_model: TakumaModel, validation: pd.DataFrame, tmp_path) -> None:
    from labcli.papers.takuma2014.figures import figure7

    near = paper_trials(2, seed=4, set_name="validation", start_id=900, theta2_values_deg=[0.8, -1.5])
    ev = evaluate(noisy_model, pd.concat([validation, near]))
    assert ev["metrics"]["Fy"]["n_flagged"] == 2 and ev["metrics"]["Fx"]["n_flagged"] == 0
    png = figure7(ev, tmp_path / "fig7.png")
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and png.stat().st_size > 20_000
    pdf = figure7(ev, tmp_path / "fig7.pdf")
    assert pdf.read_bytes()[:5] == b"%PDF-"
    with pytest.raises(ConfigError) as e:
        figure7(ev, tmp_path / "fig7.jpg")
    assert str(e.value) == f"The plot file {tmp_path / 'fig7.jpg'} must end in .png, .pdf or .svg."
    d = evaluation_to_dict(ev)
    flagged = [t for t in d["trials"] if t["flags"]]
    assert [t["trial"] for t in flagged] == [900, 901]
    assert flagged[0]["calculated"]["Fy"] is None and flagged[0]["calculated"]["Fx"] is not None
    assert flagged[0]["flags"][0]["flag"] == "singular-jacobian"
    json.dumps(d, allow_nan=False)


# --------------------------------------------------------------------------- a fit that overflows


def test_a_fit_whose_numbers_overflow_is_refused_before_anything_is_written():
    """Second line of defence behind the table reader: Fx_N = 1e308 squares to inf."""
    from labcli.papers.takuma2014.analyses import refuse_non_finite

    table = paper_trials(12, seed=1)
    table.loc[1, "Fx_N"] = 1e308
    with np.errstate(all="ignore"):
        model = TakumaModel(geometry=PAPER_GEOMETRY).fit(table)
    with pytest.raises(
        ModelError,
        match=r"^The Fx fit on t\.csv gives no finite value for beta_Fx1, .*"
        r"largest \|Fx_N\| is 1e\+308 N\); check the table",
    ):
        refuse_non_finite(model, table, "t.csv")
    healthy = TakumaModel(geometry=PAPER_GEOMETRY).fit(paper_trials(12, seed=1))
    refuse_non_finite(healthy, table, "t.csv")  # finite coefficients pass whatever the table holds


@pytest.mark.parametrize("n_flagged", [3, 61])
def test_the_validation_report_lists_few_flagged_trials_and_counts_many_by_reason(capsys, n_flagged):
    from labcli.core.report import report_console
    from labcli.papers.takuma2014.report import FLAGGED_LIST_LIMIT, _print_flagged

    n = 100
    flags = [["uncertain"] if i < n_flagged else [] for i in range(n)]
    flags[0] = ["bad-pressure", "uncertain"]
    ok = {q: np.array([not f for f in flags]) for q in ("theta1", "theta2", "Fx", "Fy")}
    ev = {"trial": np.arange(1000, 1000 + n), "flags": flags, "ok": ok}
    _print_flagged(report_console(), ev)
    out = capsys.readouterr().out
    if n_flagged <= FLAGGED_LIST_LIMIT:
        assert out.count("  trial 10") == n_flagged and "trial 1002: theta1, theta2, Fx, Fy = —" in out
    else:
        assert "  trial 10" not in out
        assert f"{n_flagged} of {n} trials flagged" in out and "--json lists every trial" in out
        assert f"  {n_flagged} x " in out and "trials 1000, 1001, 1002" in out and f"({n_flagged - 10} more)" in out
        assert "  1 x " in out  # the bad pressure, on trial 1000 alone


def test_figure7_names_its_run_and_shows_intervals_and_every_flagged_trial(validation: pd.DataFrame) -> None:
    """The posture form's straight-arm run: Fy flagged on every trial, drawn where it lies, explained."""
    from labcli.papers.takuma2014.figures import figure7_panel, figure7_title
    from labcli.papers.takuma2014.models.posture import PostureModel

    rows = paper_trials(90, seed=1)
    model = PostureModel(geometry=G).fit(rows)
    ev = evaluate(model, validation)
    title = figure7_title(ev, "runs/force.h5", "takuma2014", model.form)
    assert title.endswith("run force.h5, protocol takuma2014, posture form")
    assert "calculated angles" in title
    fx = figure7_panel(ev, "Fx")
    assert fx["error_95"] is not None and len(fx["error_95"]) == len(fx["observed"]) > 0
    assert np.allclose(fx["error_95"], 1.96 * np.asarray(ev["se"]["Fx"])[ev["ok"]["Fx"]])
    lo, hi = fx["limits"]
    assert lo <= np.min(fx["calculated"] - fx["error_95"]) and np.max(fx["calculated"] + fx["error_95"]) <= hi
    # The paper's form near a straight upper joint flags Fy: drawn where the estimates lie.
    near = paper_trials(2, seed=4, set_name="validation", start_id=900, theta2_values_deg=[0.8, -1.5])
    ev = evaluate(fit(rows, G), pd.concat([validation, near]))
    fy = figure7_panel(ev, "Fy")
    flagged = np.concatenate([fy["flagged_observed"], fy["flagged_calculated"]])
    lo, hi = fy["limits"]
    assert len(fy["flagged_observed"]) == 2 and lo <= flagged.min() and flagged.max() <= hi
    assert fy["error_95"] is None and fy["note"] == ""  # the paper's form gives no standard errors
    # No trial reported at all: the panel says why.
    ev["metrics"]["Fy"] = {**ev["metrics"]["Fy"], "n": 0, "n_flagged": 62}
    assert "straight arm" in figure7_panel(ev, "Fy")["note"]
