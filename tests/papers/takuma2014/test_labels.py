"""Calibration labels without the potentiometers' play (models/labels.py, TakumaModel.fit)."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest

from labcli.core.protocol import load_protocol
from labcli.errors import ModelError
from labcli.papers.takuma2014.models.labels import apply_play, fit_play, play_states, ratio_error_var
from labcli.papers.takuma2014.models.takuma import TakumaModel
from labcli.papers.takuma2014.protocol import load_plan
from labcli.papers.takuma2014.sim.drive import simulate_weight_trials
from labcli.papers.takuma2014.sim.nonideal import NonIdeal
from labcli.papers.takuma2014.sim.rig import SimRig

B = math.radians(0.2)


def _read(d_true: np.ndarray, b: float) -> np.ndarray:
    """What a shaft with play b reads for these load-unload deflections (a direct hysteron)."""
    joint, shaft, out = 0.0, 0.0, []
    for d in d_true:
        before = shaft
        shaft = min(max(shaft, joint + d - b / 2), joint + d + b / 2)
        out.append(shaft - before)
        shaft = min(max(shaft, joint - b / 2), joint + b / 2)
    return np.array(out)


def test_states_read_short_by_the_whole_play_after_a_load_the_same_way():
    d = np.array([1.0, 1.0, -1.0, -1.0, 1.0]) * math.radians(1.0)
    c, trailing = play_states(d, B)
    # From the centre: half the play; then the same way again: all of it; a reversal: none.
    np.testing.assert_allclose(c, [0.5, 1.0, 0.0, -1.0, 0.0])
    assert trailing.tolist() == [True, True, False, True, False]
    np.testing.assert_allclose(_read(d, B), d - B * c, atol=1e-15)


def test_a_deflection_inside_the_play_reads_nothing():
    d = np.array([1.0, 0.1]) * math.radians(1.0)  # the second, 0.1 deg, is inside 0.2 deg of play
    assert _read(d, B)[1] == 0.0
    c, _ = play_states(d, B)
    assert c[1] == pytest.approx(d[1] / B)


def test_fit_play_recovers_the_play_and_the_true_deflections():
    rng = np.random.default_rng(5)
    n = 120
    design = rng.normal(0.0, 0.01, (n, 2))
    slope = np.array([1.5, -0.8])
    d_true = np.arcsin(design @ slope)
    read = _read(d_true, B) + rng.normal(0.0, math.radians(0.005), n)
    order = np.arange(n)
    res, corrected = fit_play(design, read, order, np.ones(n, bool), np.arange(1, n + 1))
    assert res.play_rad == pytest.approx(B, rel=0.05)
    assert res.se_rad < 0.1 * B
    keep = ~np.isin(np.arange(1, n + 1), res.stuck)
    assert np.sqrt(np.mean((corrected - d_true)[keep] ** 2)) < math.radians(0.01)
    # The readings as read are biased towards zero by a share of the play; the corrected ones are not.
    assert np.mean(np.abs(read)) < np.mean(np.abs(d_true)) - 0.3 * B
    assert abs(np.mean(np.abs(corrected[keep])) - np.mean(np.abs(d_true[keep]))) < 0.05 * B


def _noisy_play_run(seed: int, n: int, s: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """An antagonistic pair's ratios (one deflection moves both, opposite ways), read with a fresh
    error of sd ``s`` in each feature, and the shaft's readings of the true deflections with play B."""
    rng = np.random.default_rng(seed)
    x = rng.normal(0.0, 0.01, n)
    true = np.column_stack([x, -x + rng.normal(0.0, 0.002, n)])
    d_true = np.arcsin(true @ np.array([1.5, -0.8]))
    read = _read(d_true, B) + rng.normal(0.0, math.radians(0.005), n)
    return true + rng.normal(0.0, s, (n, 2)), read, d_true


def test_reading_errors_in_the_ratios_shorten_the_play_unless_corrected():
    s, n = 0.002, 300
    plain, corrected = [], []
    for seed in range(12):
        design, read, _ = _noisy_play_run(seed, n, s)
        args = (design, read, np.arange(n), np.ones(n, bool), np.arange(1, n + 1))
        plain.append(fit_play(*args)[0].play_rad / B)
        corrected.append(fit_play(*args, error_var=np.full(2, s**2))[0].play_rad / B)
    # Least squares takes the slopes' attenuation out of the play; the moment correction puts it back.
    assert np.mean(plain) < 0.85
    assert np.mean(corrected) == pytest.approx(1.0, abs=0.08)


def test_the_ratios_error_variance_is_read_from_the_pairs_common_mode():
    rng = np.random.default_rng(8)
    n = 90
    x1, x2 = rng.normal(0.0, 0.01, n), rng.normal(0.0, 0.01, n)
    # Each pair moves oppositely, with a curvature and a coupling the quadratic takes up.
    u = np.column_stack([x1, -x1 + 3 * x1**2, x2 + 0.5 * x1, -x2 - 0.5 * x1 + 2 * x2**2])
    assert np.all(ratio_error_var(u) < 1e-9)  # no reading error: nothing to correct
    s = 1.5e-3
    est = np.sqrt(ratio_error_var(u + rng.normal(0.0, s, u.shape)))
    np.testing.assert_allclose(est, s, rtol=0.2)
    assert np.all(ratio_error_var(u[:5]) == 0.0)  # too few trials to tell
    # Chambers not supplied together: a common mode scattering far past any reading error (5 %) is
    # not one, so nothing is corrected; one pair so, the other still read.
    loose = u.copy()
    loose[:, :2] += rng.normal(0.0, 0.05, n)[:, None]  # the pair's common supply drawn apart
    v = ratio_error_var(loose + rng.normal(0.0, s, u.shape))
    assert np.all(v[:2] == 0.0)
    np.testing.assert_allclose(np.sqrt(v[2:]), s, rtol=0.2)


def test_the_paper_form_recovers_the_papers_coefficients_from_its_own_equations():
    # Trials drawn from Eqs. 34-37 alone (no play, no reading error, the pairs' pressures drawn
    # apart): the default fit, play fit included, gives the paper's coefficients back exactly.
    from labcli.papers.takuma2014.models.synthetic import PAPER_GEOMETRY, paper_trials
    from labcli.papers.takuma2014.models.takuma import COEFFICIENT_NAMES, PAPER_COEFFICIENTS, fit

    model = fit(paper_trials(90, seed=11, noise=False), PAPER_GEOMETRY)
    worst = max(abs(model.coefficients[n] / PAPER_COEFFICIENTS[n] - 1) for n in COEFFICIENT_NAMES)
    assert worst < 1e-9


def test_a_correction_larger_than_the_scatter_is_bounded():
    design, read, _ = _noisy_play_run(3, 120, 0.002)
    args = (design, read, np.arange(120), np.ones(120, bool), np.arange(1, 121))
    # An error variance claimed far above the ratios' own scatter: no division by noise, the
    # directions it would swamp are fitted as least squares fits them.
    res, corrected = fit_play(*args, error_var=np.full(2, 1.0))
    plain, _ = fit_play(*args)
    assert res.play_rad == pytest.approx(plain.play_rad, rel=1e-6)
    assert np.all(np.isfinite(corrected))


def test_no_play_is_fitted_as_none():
    rng = np.random.default_rng(6)
    n = 100
    design = rng.normal(0.0, 0.01, (n, 2))
    d_true = np.arcsin(design @ np.array([1.5, -0.8]))
    res, corrected = fit_play(design, d_true, np.arange(n), np.ones(n, bool), np.arange(1, n + 1))
    assert res.play_rad < 1e-6
    np.testing.assert_allclose(corrected, d_true, atol=1e-6)


@pytest.fixture(scope="module")
def play_only_trials():
    """The plan's trials on a rig whose only non-ideality is the potentiometers' play."""
    proto = load_protocol("takuma2014")
    scales = {**NonIdeal.ideal().as_dict(), "backlash": 1.0}
    rig = SimRig(seed=2, nonideal=NonIdeal(**scales))
    return proto, simulate_weight_trials(rig, load_plan(proto), calibration=proto.calibration, settle_s=6.0)


def test_the_fit_estimates_the_rigs_play_and_unbiases_the_angles(play_only_trials):
    proto, table = play_only_trials
    fitted = TakumaModel(geometry=proto.settings.rig, protocol=proto.name).fit(table)
    as_read = TakumaModel(geometry=proto.settings.rig, protocol=proto.name, label_play="none").fit(table)
    # The simulated rig's play is 0.2 deg full width on each potentiometer.
    assert fitted.play["play_deg"] == pytest.approx([0.2, 0.2], abs=0.03)
    assert all(se < 0.03 for se in fitted.play["se_deg"])
    assert as_read.play == {}
    # Read as they are, the labels make every pressure-derived deflection short, by a share of the play.
    ours, theirs = fitted.predict_table(table), as_read.predict_table(table)
    for q in ("theta1_rad", "theta2_rad"):
        gain = np.mean(np.abs(ours[q])) - np.mean(np.abs(theirs[q]))
        assert math.radians(0.04) < gain < math.radians(0.2)
    excluded = {e["trial"] for e in fitted.excluded_trials["theta1"]}
    inside = set(fitted.play["inside_play"]["theta1"])
    assert inside <= excluded
    assert all(
        e["reason"] == "the potentiometer's reading did not leave its play"
        for e in fitted.excluded_trials["theta1"]
        if e["trial"] in inside
    )


def test_no_play_on_the_ideal_rig():
    proto = load_protocol("takuma2014")
    rig = SimRig(seed=3, nonideal=NonIdeal.ideal())
    table = simulate_weight_trials(rig, load_plan(proto), calibration=proto.calibration, settle_s=6.0)
    model = TakumaModel(geometry=proto.settings.rig, protocol=proto.name).fit(table)
    assert max(model.play["play_deg"]) < 0.02


def test_the_model_file_says_what_it_estimated(play_only_trials):
    proto, table = play_only_trials
    model = TakumaModel(geometry=proto.settings.rig, protocol=proto.name).fit(table)
    d = model.to_dict()
    assert d["labels"]["play"] == "fit"
    assert d["labels"]["play_deg"] == model.play["play_deg"]
    back = TakumaModel.from_json(model.to_json())
    assert back.label_play == "fit" and back.play["play_deg"] == model.play["play_deg"]
    older = {k: v for k, v in d.items() if k != "labels"}
    assert TakumaModel.from_dict(older).label_play == "none"
    with pytest.raises(ModelError, match="bad 'labels' entry"):
        TakumaModel.from_dict({**d, "labels": {"play": "maybe"}})


def test_apply_play_corrects_validation_labels_the_same_way(play_only_trials):
    proto, table = play_only_trials
    model = TakumaModel(geometry=proto.settings.rig, protocol=proto.name).fit(table)
    widths = tuple(math.radians(w) for w in model.play["play_deg"])
    fixed = apply_play(table, widths)
    assert (np.abs(fixed["theta1_deg"]) >= np.abs(table["theta1_deg"]) - 1e-12).all()
    assert not fixed["theta1_deg"].equals(table["theta1_deg"])
    assert apply_play(table, (0.0, 0.0))["theta2_deg"].equals(table["theta2_deg"])


def test_the_posture_form_fits_the_same_play_and_the_same_corrected_deflections(play_only_trials):
    from labcli.papers.takuma2014.models.posture import PostureModel, limits_from_protocol

    proto, table = play_only_trials
    rig, limits = proto.settings.rig, limits_from_protocol(proto)
    paper = TakumaModel(geometry=rig, protocol=proto.name).fit(table)
    fitted = PostureModel(geometry=rig, protocol=proto.name, limits=limits).fit(table)
    as_read = PostureModel(geometry=rig, protocol=proto.name, limits=limits, label_play="none").fit(table)
    # One operator, one answer: the posture form's play is the paper form's, the rig's 0.2 deg.
    assert fitted.play == paper.play
    assert fitted.play["play_deg"] == pytest.approx([0.2, 0.2], abs=0.03)
    assert as_read.play == {}
    # Fitted to the labels as read, every pressure-derived deflection comes out short (the slope
    # absorbs the short readings); corrected, they lengthen by a share of the play.
    ours, theirs = fitted.predict_table(table), as_read.predict_table(table)
    for q in ("theta1_rad", "theta2_rad"):
        gain = np.mean(np.abs(ours[q])) - np.mean(np.abs(theirs[q]))
        assert math.radians(0.04) < gain < math.radians(0.2)
    d = fitted.to_dict()
    assert d["labels"]["play"] == "fit" and d["labels"]["play_deg"] == fitted.play["play_deg"]
    back = PostureModel.from_dict(d)
    assert back.label_play == "fit" and back.play == fitted.play
    older = {k: v for k, v in d.items() if k != "labels"}
    assert PostureModel.from_dict(older).label_play == "none"
    with pytest.raises(ModelError, match="bad 'labels' entry"):
        PostureModel.from_dict({**d, "labels": {"play": "maybe"}})


NOISE = 0.35


def _noisy_regressors(seed: int) -> tuple[np.ndarray, ...]:
    """Trials whose deflections follow their loads exactly, read through play B, with a design whose
    pressure ratios carry reading errors of NOISE of their spread (joint 1 on the literature's rig)."""
    rng = np.random.default_rng(seed)
    n = 150
    F = rng.normal(0.0, 1.5, (n, 2))
    d_true = np.radians(F @ np.array([[0.3, -0.1], [0.1, 0.4]]))  # a compliance, rad per N (x deg)
    design_true = np.column_stack([np.sin(d_true[:, 0]), -np.sin(d_true[:, 0])]) / np.array([1.5, 0.8])
    noisy = design_true + rng.normal(0.0, NOISE * design_true.std(axis=0), design_true.shape)
    read = _read(d_true[:, 0], B) + rng.normal(0.0, math.radians(0.005), n)
    return noisy, read, F, d_true[:, 0]


def test_errors_in_the_pressures_shorten_the_least_squares_play_and_not_the_one_on_the_loads():
    from labcli.papers.takuma2014.models.labels import load_instruments

    ls, on_loads = [], []
    for seed in range(1, 9):
        design, read, F, _ = _noisy_regressors(seed)
        n = len(read)
        args = (design, read, np.arange(n), np.ones(n, bool), np.arange(1, n + 1))
        ls.append(fit_play(*args)[0].play_rad)
        on_loads.append(fit_play(*args, load_instruments(F))[0].play_rad)
    # Least squares on regressors with errors shortens their slope (the two ratios' mean by
    # 1 / (1 + NOISE^2 / 2)), and the play's column, which follows the deflection's sign, takes the
    # short part: the width comes out low on nearly every draw.
    assert np.median(ls) < 0.85 * B
    assert sum(w < B for w in ls) >= 7
    # The loads move the joint and not the readings' errors: on them the width is the rig's.
    assert np.median(on_loads) == pytest.approx(B, rel=0.1)


def test_the_play_on_the_loads_is_a_model_option_its_file_keeps(play_only_trials):
    proto, table = play_only_trials
    model = TakumaModel(geometry=proto.settings.rig, protocol=proto.name, label_play="loads").fit(table)
    assert model.play["play_deg"] == pytest.approx([0.2, 0.2], abs=0.03)
    back = TakumaModel.from_json(model.to_json())
    assert back.label_play == "loads" and back.play["play_deg"] == model.play["play_deg"]


def test_an_unknown_label_play_is_refused_in_one_sentence():
    proto = load_protocol("takuma2014")
    with pytest.raises(ModelError, match=r"^Unknown label play 'load'; use one of fit, loads, none\.$"):
        TakumaModel(geometry=proto.settings.rig, protocol=proto.name, label_play="load")


def test_the_corrected_play_is_longer_than_least_squares_on_a_noisy_run_and_loads_keep_their_method(monkeypatch):
    """The sample force run (its pressures read with the literature rig's repeatability): least
    squares on the ratios as read shortens the play, the correction for their reading errors and the
    loads do not; one fit trial without its force must not turn "loads" back into "fit" (the trial is
    left out of the instruments, not the method)."""
    from pathlib import Path

    from labcli.papers.takuma2014.models import labels
    from labcli.papers.takuma2014.records import load_trials

    run = Path(__file__).resolve().parents[3] / "sample_runs" / "force.h5"
    proto, table = load_protocol("takuma2014"), load_trials(run)

    def play(how: str, frame=table) -> list[float]:
        return TakumaModel(geometry=proto.settings.rig, protocol=proto.name, label_play=how).fit(frame).play["play_deg"]

    fitted = {how: play(how) for how in ("fit", "loads")}
    with monkeypatch.context() as m:
        m.setattr(labels, "ratio_error_var", lambda u: np.zeros(4))
        plain = play("fit")
    assert fitted["fit"][0] > plain[0] + 0.02
    assert fitted["loads"][0] > plain[0] + 0.02
    one_missing = table.copy()
    first_fit = one_missing.index[one_missing["set"] == "fit"][0]
    one_missing.loc[first_fit, "Fx_N"] = np.nan
    assert play("loads", one_missing)[0] == pytest.approx(fitted["loads"][0], abs=0.01)


def _loads_and_returns(d_true: np.ndarray, back: Any) -> tuple[list[float], list[float]]:
    """Through play B, per load: the reading, and how far the shaft moved from the loaded reading to
    the next rest when the unload takes the joint back by ``back(d)``."""
    joint = shaft = 0.0
    read, moved = [], []
    for d in d_true:
        rest = shaft
        joint += d
        shaft = min(max(shaft, joint - B / 2), joint + B / 2)
        read.append(shaft - rest)
        loaded = shaft
        joint -= back(d)
        shaft = min(max(shaft, joint - B / 2), joint + B / 2)
        moved.append(shaft - loaded)
    return read, moved


def _held_run(seed: int, hold: float) -> tuple[np.ndarray, ...]:
    """Loads read through play B on an arm whose friction holds it where a load of less than ``hold``
    (rad) left it (a larger one it lets return): the design, the readings, and how far the shaft
    moved from each loaded reading to the next rest reading (NaN after the last trial)."""
    rng = np.random.default_rng(seed)
    n = 120
    x = rng.normal(0.0, 1.0, n)
    d_true = np.sign(x) * np.radians(0.3 + 0.6 * np.abs(x))  # every load moves the joint past the play
    design = np.column_stack([np.sin(d_true), -np.sin(d_true)]) / np.array([3.0, 1.6])
    design += rng.normal(0.0, 1e-5, design.shape)
    read, moved = _loads_and_returns(d_true, lambda d: d if abs(d) >= hold else 0.0)
    noise = rng.normal(0.0, math.radians(0.005), (2, n))
    returns = np.append(np.array(moved[:-1]) + noise[1, :-1], np.nan)
    return design, np.array(read) + noise[0], returns


def test_a_shaft_that_stayed_after_the_unload_says_friction_held_the_arm():
    # Taken as a full return every time, the held unloads put the states wrong and the width far
    # short; with the shaft's own motion between the load and the next rest it is the rig's.
    as_returned, with_shafts = [], []
    for seed in range(6):
        design, read, returns = _held_run(seed, math.radians(0.7))
        n = len(read)
        args = (design, read, np.arange(n), np.ones(n, bool), np.arange(1, n + 1))
        as_returned.append(fit_play(*args)[0].play_rad / B)
        with_shafts.append(fit_play(*args, returns=returns)[0].play_rad / B)
    assert max(as_returned) < 0.5
    np.testing.assert_allclose(with_shafts, 1.0, atol=0.02)
    # An arm that always returns: the shafts' motion agrees with the operator as written.
    design, read, returns = _held_run(7, 0.0)
    n = len(read)
    args = (design, read, np.arange(n), np.ones(n, bool), np.arange(1, n + 1))
    assert fit_play(*args, returns=returns)[0].play_rad == pytest.approx(fit_play(*args)[0].play_rad, rel=1e-6)


def test_the_shafts_returns_are_read_from_the_rest_posture_in_trial_order():
    import pandas as pd

    from labcli.papers.takuma2014.models.labels import shaft_returns

    table = pd.DataFrame(
        {
            "trial": [2, 1, 3],
            "theta1_deg": [0.5, 1.0, -0.2],
            "theta2_deg": [0.0, 0.0, 0.0],
            "theta1_0_deg": [10.9, 10.0, 11.1],
            "theta2_0_deg": [5.0, 5.0, np.nan],
        }
    )
    order = np.argsort(table["trial"].to_numpy(), kind="stable")
    got = np.degrees(shaft_returns(table, order))
    # Trial 1 loaded read 11.0, trial 2 rested at 10.9: -0.1; trial 2 loaded 11.4, trial 3 rested 11.1.
    np.testing.assert_allclose(got[:, 0], [-0.3, -0.1, np.nan], atol=1e-12)
    assert np.isnan(got[0, 1]) and got[1, 1] == 0.0
    assert np.isnan(shaft_returns(table.drop(columns=["theta1_0_deg"]), order)).all()


def _short_run(seed: int, short: float) -> tuple[np.ndarray, ...]:
    """True deflections, readings through play B and the shafts' returns of an arm whose friction
    stops every return ``short`` (rad) before the rest it left (a kind rig's small band): the
    deflections, the states the rig's own shafts had, and the returns."""
    rng = np.random.default_rng(seed)
    d_true = rng.choice([-1.0, 1.0], 200) * B * rng.uniform(1.2, 6.0, 200)
    read, moved = _loads_and_returns(d_true, lambda d: d - math.copysign(short, d))
    c_true = (d_true - np.array(read)) / B
    return d_true, c_true, np.append(moved[:-1], np.nan)


def test_a_shaft_that_stayed_after_a_small_return_is_not_held_when_no_clear_return_was():
    # Friction that stops each return a little short leaves the shaft where a small return would
    # just have moved it: the joint stands inside the play near the far side, not where the load
    # left it, so the states are the whole return's to within the shortfall.
    d, c_true, returns = _short_run(3, 0.4 * B)
    stayed = (np.abs(returns) <= 0.25 * B) & (np.abs(d) > 1.4 * B)
    assert stayed.sum() >= 5  # small returns that a whole return would have pushed the shaft after
    c, _ = play_states(d, B, returns)
    np.testing.assert_allclose(c, c_true, atol=0.4 + 1e-9)
    # A run whose friction held the arm on a clear return keeps reading a stayed shaft as held.
    held = returns.copy()
    big = np.flatnonzero(np.abs(d[:-1]) > 3 * B)[0]
    held[big] = 0.0
    c_held, _ = play_states(d, B, held)
    after = np.flatnonzero(stayed[:-1])[0] + 1
    assert abs(c_held[after] - c[after]) > 0.4
