"""The fit's shortcuts give the fit it gave before them: the cross-validation of all folds at once
against the fold-by-fold least squares it replaced, on several seeds, sizes and split shapes."""

from __future__ import annotations

from typing import Any

import numpy as np
import pandas as pd
import pytest

from labcli.papers.takuma2014.models.posture import PostureModel, _Blocks
from labcli.papers.takuma2014.models.synthetic import add_sensor_noise, paper_trials
from labcli.papers.takuma2014.models.takuma import TakumaModel

GEOMETRY = {"h1": 0.355, "h2": 0.130, "h3": 0.065, "r1": 0.075, "r2": 0.035}


def fold_by_fold_cv_cov(self: _Blocks, xs: list[int], ys: list[int] | None = None) -> np.ndarray:
    """``_Blocks.cv_cov`` as it was: per fold, lstsq on the stacked R's of the other blocks."""
    ys = self.responses(ys)
    out = np.zeros((len(ys), len(ys)))
    for f, r in enumerate(self.factors):

        def train(cols: list[int]) -> np.ndarray:
            return np.vstack([g[:, cols] for i, g in enumerate(self.factors) if i != f])

        beta, *_ = np.linalg.lstsq(train(xs), train(ys), rcond=None)
        e = r[:, ys] - r[:, xs] @ beta
        out += e.T @ e
    return out


@pytest.mark.parametrize("seed, n, p, k", [(0, 25, 3, 1), (1, 90, 6, 2), (2, 400, 14, 2), (3, 5000, 10, 2)])
def test_all_folds_at_once_give_the_fold_by_fold_held_out_errors(seed: int, n: int, p: int, k: int) -> None:
    rng = np.random.default_rng(seed)
    X = rng.standard_normal((n, p)) * np.logspace(-4, 0, p)  # columns of very different scales
    Y = X @ rng.standard_normal((p, k)) + 0.01 * rng.standard_normal((n, k))
    blocks = _Blocks.build(n, p, lambda lo, hi: np.column_stack([X[lo:hi], Y[lo:hi]]))
    for cols in ([0], list(range(p)), list(range(0, p, 2)), [p - 1, 0]):
        for ys in (None, [p]):
            np.testing.assert_allclose(
                blocks.cv_cov(cols, ys), fold_by_fold_cv_cov(blocks, cols, ys), rtol=1e-9, atol=1e-14
            )


def test_a_rank_deficient_fold_gets_lstsq_s_least_norm_answer() -> None:
    rng = np.random.default_rng(7)
    n = 200
    x = rng.standard_normal(n)
    X = np.column_stack([x, 2.0 * x, rng.standard_normal(n)])  # the second column repeats the first
    Y = (x + 0.1 * rng.standard_normal(n))[:, None]
    blocks = _Blocks.build(n, 3, lambda lo, hi: np.column_stack([X[lo:hi], Y[lo:hi]]))
    np.testing.assert_allclose(blocks.cv_cov([0, 1, 2]), fold_by_fold_cv_cov(blocks, [0, 1, 2]), rtol=1e-9)


def trial_table(n: int, seed: int, split: str, pool: int = 0) -> pd.DataFrame:
    """Eqs. 34-37 exact (``pool`` trials cycled, as tests/benchmarks/bench_tables.py makes them, if given)
    plus two ADC counts of noise; the validation set the last sixth or every sixth trial."""
    exact = paper_trials(pool or n, seed=seed, noise=False)
    table = add_sensor_noise(exact.iloc[np.arange(n) % len(exact)].reset_index(drop=True), seed=seed, noise_counts=2.0)
    table["trial"] = np.arange(n)
    rows = np.arange(n)
    table["set"] = np.where(rows >= n * 5 // 6 if split == "contiguous" else rows % 6 == 5, "validation", "fit")
    return table


def model_figures(model: PostureModel) -> dict[str, Any]:
    """Terms, coefficients, routes and the route choice's held-out figures (RMSE of each form, weights)."""
    return {"routes_cv": model.fit_stats["routes_cv"]} | {
        k: model.to_dict()[k]
        for k in (
            "angle_terms",
            "theta1_terms",
            "torque_terms",
            "angle_coefficients",
            "theta1_coefficients",
            "torque_coefficients",
            "torque_resid_cov",
            "angle_resid_cov",
            "routes",
            "blends",
            "paper_variance",
            "fitted_trials",
        )
    }


def assert_same(a: Any, b: Any) -> None:
    if isinstance(a, dict):
        assert a.keys() == b.keys()
        for key in a:
            assert_same(a[key], b[key])
    elif isinstance(a, (list, tuple)) and a and isinstance(a[0], str):
        assert list(a) == list(b)  # terms and routes: exactly the same
    elif isinstance(a, str):
        assert a == b
    else:
        np.testing.assert_allclose(np.asarray(a, dtype=float), np.asarray(b, dtype=float), rtol=1e-9, atol=1e-15)


@pytest.mark.parametrize(
    "n, seed, split, pool",
    [
        (108, 1, "contiguous", 0),
        (108, 2, "interleaved", 0),
        (600, 3, "interleaved", 0),
        (1200, 3, "contiguous", 400),  # trials repeated, as in the archive benchmark
        (1200, 4, "interleaved", 400),
    ],
)
def test_the_fit_its_terms_and_routes_are_those_of_the_fold_by_fold_cross_validation(
    n: int, seed: int, split: str, pool: int, monkeypatch: pytest.MonkeyPatch
) -> None:
    table = trial_table(n, seed, split, pool)
    now = PostureModel(geometry=GEOMETRY).fit(table)
    monkeypatch.setattr(_Blocks, "cv_cov", fold_by_fold_cv_cov)
    before = PostureModel(geometry=GEOMETRY).fit(table)
    assert_same(model_figures(now), model_figures(before))


def test_route_choice_fits_leave_out_only_the_trial_list() -> None:
    table = trial_table(600, 8, "interleaved")
    listed = TakumaModel(geometry=GEOMETRY).fit(table)
    unlisted = TakumaModel(geometry=GEOMETRY).fit(table, record_trials=False)
    assert unlisted.fitted_trials == {} and listed.fitted_trials["Fx"][:2] == [[0, 4], [6, 10]]
    assert unlisted.coefficients == listed.coefficients and unlisted.ci95 == listed.ci95


@pytest.mark.parametrize("n", [1, 108, 5000])
def test_the_2x2_products_are_einsum_s_to_rounding(n: int) -> None:
    from labcli.papers.takuma2014.models.posture import einsum_2x2

    rng = np.random.default_rng(n)
    JT = np.swapaxes(rng.normal(size=(n, 2, 2)), 1, 2)  # a view, as the posterior takes J^T
    prior, M, S, tau = (
        np.diag(rng.uniform(0.5, 2.0, 2) ** 2),
        rng.normal(size=(n, 2, 2)),
        rng.normal(size=(n, 2, 2)),
        rng.normal(size=(n, 2)),
    )
    for spec, ops in [
        ("nij,nj->ni", (M, tau)),
        ("nij,njk,nlk->nil", (M, S, M)),
        ("ij,nkj,nkl->nil", (prior, JT, M)),
        ("nij,jk,nlk->nil", (JT, prior, JT)),
        ("nij,njk,kl->nil", (M, JT, prior)),
    ]:
        np.testing.assert_allclose(einsum_2x2(spec, *ops), np.einsum(spec, *ops), rtol=1e-13, atol=1e-14)


def test_the_2x2_products_of_a_few_rows_are_those_of_many_to_the_bit() -> None:
    """A few rows (the run-time estimator's) are gathered at once, many taken column by column:
    the same products summed in the same order, so the same bits."""
    from labcli.papers.takuma2014.models.posture import GATHER_ROWS, einsum_2x2

    rng = np.random.default_rng(7)
    n = GATHER_ROWS + 40
    M, S, tau = rng.normal(size=(n, 2, 2)), rng.normal(size=(n, 2, 2)), rng.normal(size=(n, 2))
    prior = np.diag(rng.uniform(0.5, 2.0, 2) ** 2)
    for spec, ops in [
        ("nij,nj->ni", (M, tau)),
        ("nij,njk,nlk->nil", (M, S, M)),
        ("ij,nkj,nkl->nil", (prior, M, S)),
        ("nij,njk,kl->nil", (M, S, prior)),
    ]:
        many = einsum_2x2(spec, *ops)
        few = einsum_2x2(spec, *(op if op.ndim == 2 and op is prior else op[:9] for op in ops))
        assert np.array_equal(few, many[:9])


def test_predictions_and_routes_are_those_of_numpy_s_einsum(monkeypatch: pytest.MonkeyPatch) -> None:
    from labcli.papers.takuma2014.models import posture

    table = trial_table(600, 9, "interleaved")
    now = PostureModel(geometry=GEOMETRY).fit(table)
    out = now.predict_table(table)
    monkeypatch.setattr(posture, "einsum_2x2", np.einsum)
    before = PostureModel(geometry=GEOMETRY).fit(table)
    assert_same(model_figures(now), model_figures(before))
    was = before.predict_table(table)
    for key in ("theta1_rad", "theta2_rad", "Fx_N", "Fy_N"):
        np.testing.assert_allclose(out[key], was[key], rtol=1e-12, atol=1e-15)
    for q in out["se"]:
        np.testing.assert_allclose(out["se"][q], was["se"][q], rtol=1e-12, atol=1e-15)
        assert np.array_equal(out["ok"][q], was["ok"][q])
