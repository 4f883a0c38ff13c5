"""The friction terms' shortcuts give what the plain formulation gives, to the bit.

The fit makes the friction columns once and reads each fit trial's motion into its baseline from
its previous row without sorting a table already in trial order; validate reads a trial's history
from its previous trial's row alone.  Each is checked here against the plain formulation, a sort
and a dict of every id written out in full, on the sample runs (whose models keep a friction term) and on shuffled
tables with repeated ids and missing angles.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from labcli.errors import ModelError
from labcli.papers.takuma2014.analyses import _fit_form
from labcli.papers.takuma2014.models.history import previous_rows, rows_of
from labcli.papers.takuma2014.models.inputs import load_trial_source
from labcli.papers.takuma2014.models.metrics import _unplayed
from labcli.papers.takuma2014.models.posture import (
    ANGLE_COLUMNS,
    FRICTION_TERMS,
    RELIEVED_TERMS,
    REST_COLUMNS,
    TORQUE_TERMS,
    PostureModel,
    friction_family,
    table_arrays,
    torque_features,
)
from labcli.papers.takuma2014.models.takuma import select_set

SAMPLES = Path(__file__).resolve().parents[3] / "sample_runs"
RUNS = ("bent", "force")


def sorted_motion(trial: np.ndarray, theta0: np.ndarray, dtheta: np.ndarray) -> np.ndarray:
    """The motion into each baseline as it was computed: every row sorted by trial id, differenced."""
    order = np.argsort(trial, kind="stable")
    th0 = np.asarray(theta0, dtype=float)[order]
    loaded = th0 + np.asarray(dtheta, dtype=float)[order]
    moved = np.zeros_like(th0)
    moved[1:] = th0[1:] - loaded[:-1]
    out = np.empty_like(moved)
    out[order] = np.nan_to_num(moved, nan=0.0)
    return out


def whole_table_motion(table: pd.DataFrame) -> np.ndarray:
    """Every row's measured motion into its baseline, from whole-table columns."""
    r = np.column_stack(
        [np.asarray(table[c], dtype=float) if c in table else np.zeros(len(table)) for c in REST_COLUMNS]
    )
    theta0 = np.deg2rad(np.where(np.isfinite(r), r, 0.0))
    dtheta = np.deg2rad(np.column_stack([np.asarray(table[c], dtype=float) for c in ANGLE_COLUMNS]))
    return sorted_motion(np.asarray(table["trial"]), theta0, dtheta)


def sample(run: str) -> pd.DataFrame:
    return load_trial_source(SAMPLES / f"{run}.h5", None).table


def shuffled(table: pd.DataFrame, seed: int) -> pd.DataFrame:
    """The rows in another order, two trials sharing an id, and some angles and rest postures missing."""
    rng = np.random.default_rng(seed)
    out = table.iloc[rng.permutation(len(table))].reset_index(drop=True)
    out.loc[3, "trial"] = out.loc[7, "trial"]
    out.loc[rng.choice(len(out), 9, replace=False), "theta1_deg"] = np.nan
    if REST_COLUMNS[0] in out:
        out.loc[rng.choice(len(out), 5, replace=False), REST_COLUMNS[0]] = np.nan
    return out


@pytest.mark.parametrize("seed", range(6))
def test_previous_rows_are_the_stable_sort_s_neighbours(seed: int) -> None:
    rng = np.random.default_rng(seed)
    ids = rng.integers(0, 40, size=60)  # ties too
    for trial in (ids, np.sort(ids), np.arange(5), np.array([7]), np.array([], dtype=int)):
        order = np.argsort(trial, kind="stable")
        expected = np.full(len(trial), -1)
        expected[order[1:]] = order[:-1]
        assert np.array_equal(previous_rows(trial), expected)


@pytest.mark.parametrize("run", RUNS)
@pytest.mark.parametrize("seed", [None, 1, 2])
def test_the_fit_rows_motion_is_the_whole_table_s_to_the_bit(run: str, seed: int | None) -> None:
    table = sample(run) if seed is None else shuffled(sample(run), seed)
    expected = whole_table_motion(table)
    for rows in (None, np.asarray(table["set"] == "fit"), np.arange(len(table))[::-3]):
        got = table_arrays(table, rows, motion=True)["motion_in"]
        assert np.array_equal(got, expected if rows is None else expected[rows])
    assert np.any(expected != 0)


@pytest.mark.parametrize("friction, family", [(True, FRICTION_TERMS), ("relieved", RELIEVED_TERMS)])
def test_friction_columns_made_once_are_each_block_s_own(friction: bool | str, family: tuple[str, ...]) -> None:
    rng = np.random.default_rng(5)
    n = 1000
    dP, dth, moved = 0.1 * rng.normal(size=(n, 4)), 0.01 * rng.normal(size=(n, 2)), 0.01 * rng.normal(size=(n, 2))
    names = TORQUE_TERMS + family
    made = friction_family(friction, dth, moved)
    assert made is not None and made.shape == (n, len(family))
    for lo, hi in ((0, n), (0, 7), (300, 641)):
        own = torque_features(dP[lo:hi], dth[lo:hi], names, moved[lo:hi] if friction is True else None)
        assert np.array_equal(torque_features(dP[lo:hi], dth[lo:hi], names, made=made[lo:hi]), own)
    assert friction_family(False, dth, moved) is None
    with pytest.raises(ValueError, match="one friction family"):
        torque_features(dP, dth, TORQUE_TERMS + FRICTION_TERMS + RELIEVED_TERMS, made=made)


def dict_history_predict(model: PostureModel, rows: pd.DataFrame, whole: pd.DataFrame, mode: str) -> dict:
    """``predict_table(rows, history=whole)`` as it was: every trial's motion, then a dict of every id."""
    a, h = table_arrays(rows), table_arrays(whole)
    measured = mode == "measured-angles"
    est = model._angles(h["P0"], h["P"])[0]
    seen = np.where(np.isfinite(h["dtheta"]), h["dtheta"], est) if measured else est
    moved = sorted_motion(h["trial"], np.broadcast_to(h["theta0"], est.shape), seen)
    at = {int(t): i for i, t in enumerate(h["trial"].tolist())}
    moved = moved[[at[int(t)] for t in a["trial"].tolist()]]
    theta = a["dtheta"] if measured else None
    return model.predict(a["P0"], a["P"], a["theta0"], mode=mode, theta=theta, motion_in=moved)


def assert_same(got: object, expected: object, key: str) -> None:
    """Equal to the bit, arrays or dicts of them (NaN where NaN)."""
    if isinstance(expected, dict):
        assert isinstance(got, dict) and got.keys() == expected.keys(), key
        for k in expected:
            assert_same(got[k], expected[k], f"{key}.{k}")
        return
    if isinstance(expected, list):  # the flags: a list per trial
        assert got == expected, key
        return
    np.testing.assert_array_equal(np.asarray(got), np.asarray(expected), err_msg=key, strict=True)


@pytest.mark.parametrize("run", RUNS)
@pytest.mark.parametrize("seed", [None, 3])
def test_validate_s_history_is_the_dict_lookup_of_every_trial(run: str, seed: int | None) -> None:
    model = PostureModel.from_dict(json.loads((SAMPLES / f"{run}.model.json").read_text()))
    assert model.uses_history
    whole = _unplayed(model, sample(run) if seed is None else shuffled(sample(run), seed))
    rows = select_set(whole, "validation", run)
    for mode in ("pressure-only", "measured-angles"):
        got = model.predict_table(rows, mode=mode, history=whole)
        expected = dict_history_predict(model, rows, whole, mode)
        for key in ("theta1_rad", "theta2_rad", "Fx_N", "Fy_N", "se", "ok", "flags"):
            assert_same(got[key], expected[key], key)


def test_a_trial_missing_from_the_history_is_refused_in_a_sentence() -> None:
    assert np.array_equal(rows_of([5, 2, 5], [2, 5, 9, 5]), [3, 0, 3])  # a repeated id: its last row
    with pytest.raises(ModelError, match=r"Trial 4 is not in the run's history"):
        rows_of([2, 4], [2, 5, 9])


@pytest.mark.parametrize("run", RUNS)
def test_the_sample_runs_fit_to_the_models_beside_them(run: str) -> None:
    """What ``labcli fit`` makes of each sample run is the model file the sample run ships."""
    src = load_trial_source(SAMPLES / f"{run}.h5", None)
    with np.errstate(all="ignore"):
        got = _fit_form("posture", src, run).to_dict()
    kept = json.loads((SAMPLES / f"{run}.model.json").read_text())
    assert set(got["torque_terms"]) & set(FRICTION_TERMS)  # the history's path is the one taken
    for key in ("angle_terms", "torque_terms", "theta1_terms", "routes"):
        assert got[key] == kept[key], key
    for key in ("angle_coefficients", "angle_xtx_inv", "angle_resid_cov", "torque_coefficients"):
        np.testing.assert_allclose(got[key], kept[key], rtol=1e-12, atol=0, err_msg=key)
    for key in ("torque_xtx_inv", "torque_resid_cov", "theta1_coefficients", "theta1_xtx_inv"):
        np.testing.assert_allclose(got[key], kept[key], rtol=1e-12, atol=0, err_msg=key)
