"""The route choice's paper-form folds from each block's R factor equal the fold-by-fold fits.

models/paper_folds.py replaces ten fits of Eqs. 34-37 from the rows with least squares on the
blocks' R factors.  Checked against the fits it replaces (``held_out_errors`` without it, and the
whole posture fit with the shortcut switched off): the same held-out errors to 1e-9, the same
reported trials, the same routes and cross-validated figures, on contiguous and interleaved
splits, with trials the equations exclude and on rig data.
"""

from __future__ import annotations

import numpy as np
import pytest

from labcli.core.protocol import load_protocol
from labcli.errors import ModelError
from labcli.papers.takuma2014.analyses import limits_from_protocol
from labcli.papers.takuma2014.models import paper_folds, posture
from labcli.papers.takuma2014.models import routes as rt
from labcli.papers.takuma2014.models.posture import PostureModel
from labcli.papers.takuma2014.models.synthetic import add_sensor_noise, paper_trials
from labcli.papers.takuma2014.models.takuma import TakumaModel

RIG = load_protocol("takuma2014").settings.rig


def table(n: int, seed: int, split: str, damaged: bool = False):
    t = add_sensor_noise(paper_trials(n, seed=seed, noise=True), seed=seed, noise_counts=1.0)
    rows = np.arange(n)
    t["set"] = np.where(rows >= n * 4 // 5 if split == "contiguous" else rows % 6 == 5, "validation", "fit")
    if damaged:  # a missing angle, a missing force, a pressure not positive: each excluded by its equations
        rng = np.random.default_rng(seed)
        pick = rng.choice(n, size=3 * max(1, n // 200), replace=False).reshape(3, -1)
        t.loc[pick[0], "theta2_deg"] = np.nan
        t.loc[pick[1], "Fx_N"] = np.nan
        t.loc[pick[2], "P_L1"] = 0.0
    return t


def both(fit_rows):
    def posture_only(rows):
        return PostureModel(geometry=RIG, protocol="takuma2014").fit(rows, choose_routes=False, record_trials=False)

    def paper(rows):
        return TakumaModel(geometry=RIG, protocol="takuma2014", label_play="none").fit(rows, record_trials=False)

    template = TakumaModel(geometry=RIG, protocol="takuma2014", label_play="none")
    fast = rt.held_out_errors(
        fit_rows, posture_only, paper, lambda r, b: paper_folds.fold_models(template, r, b, "the table")
    )
    return fast, rt.held_out_errors(fit_rows, posture_only, paper)


@pytest.mark.parametrize(
    ("n", "seed", "split", "damaged"),
    [
        (600, 1, "contiguous", False),
        (900, 2, "interleaved", False),
        (1200, 3, "interleaved", True),
        (700, 4, "contiguous", True),
    ],
)
def test_the_folds_from_r_factors_give_the_fold_by_fold_held_out_errors(n, seed, split, damaged):
    t = table(n, seed, split, damaged)
    fast, slow = both(t[t["set"] == "fit"])
    for q in rt.QUANTITIES:
        assert np.array_equal(fast["paper_ok"][q], slow["paper_ok"][q])
        a, b = fast["paper"][q], slow["paper"][q]
        assert np.array_equal(np.isfinite(a), np.isfinite(b))
        ok = np.isfinite(b)
        assert np.allclose(a[ok], b[ok], rtol=1e-9, atol=1e-9 * np.max(np.abs(b[ok])))
        assert np.array_equal(fast["posture"][q], slow["posture"][q], equal_nan=True)


@pytest.mark.parametrize("split", ["contiguous", "interleaved"])
def test_the_posture_fit_chooses_the_same_routes_with_and_without_the_shortcut(monkeypatch, split):
    t = table(1500, 5, split, damaged=True)
    limits = limits_from_protocol(load_protocol("takuma2014"))
    fast = PostureModel(geometry=RIG, protocol="takuma2014", limits=limits).fit(t)
    monkeypatch.setattr(posture, "fold_models", lambda *a, **k: None)  # each fold fitted from its rows
    slow = PostureModel(geometry=RIG, protocol="takuma2014", limits=limits).fit(t)
    assert fast.routes == slow.routes
    assert fast.blends.keys() == slow.blends.keys()
    for q, b in slow.blends.items():
        assert fast.blends[q] == pytest.approx(b, rel=1e-9)
    for q, figures in slow.fit_stats["routes_cv"].items():
        assert fast.fit_stats["routes_cv"][q].keys() == figures.keys()
        for key, v in figures.items():  # None where a form reports no trial
            assert fast.fit_stats["routes_cv"][q][key] == (v if v is None else pytest.approx(v, rel=1e-9, abs=1e-12))
    assert fast.paper_variance == pytest.approx(slow.paper_variance, rel=1e-9)


def test_what_the_shortcut_cannot_take_falls_back_and_its_refusals_are_the_fits():
    t = table(300, 6, "contiguous")
    fit_rows = t[t["set"] == "fit"].reset_index(drop=True)
    blocks = [np.arange(k * 24, (k + 1) * 24) for k in range(10)]
    played = TakumaModel(geometry=RIG, protocol="takuma2014")  # labels corrected for play: rows needed
    assert paper_folds.fold_models(played, fit_rows, blocks, "t") is None
    twice = fit_rows.assign(trial=np.arange(len(fit_rows)) // 2)  # a trial number on two rows
    template = TakumaModel(geometry=RIG, protocol="takuma2014", label_play="none")
    assert paper_folds.fold_models(template, twice, blocks, "t") is None
    # A term zero in every trial but one block's: the folds that lose it are refused, as the fit refuses them.
    zero = fit_rows.copy()
    zero.loc[24:, "P_R1"] = zero.loc[24:, "P_R10"]  # no pressure drop on R1 after the first block
    with pytest.raises(ModelError):
        TakumaModel(geometry=RIG, protocol="takuma2014", label_play="none").fit(zero.iloc[24:])
    with pytest.raises(ModelError):
        paper_folds.fold_models(template, zero, blocks, "t")
