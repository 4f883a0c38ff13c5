"""The fit's reading of the unloads' returns travels with the model (models/labels.py): a validation
table is corrected by the fit's decision whether the sleeves' friction held the arm, not its own."""

from __future__ import annotations

import math
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pandas as pd
import pytest

from labcli.errors import ModelError
from labcli.papers.takuma2014.models.labels import CLEAR_PLAYS, apply_play, fit_play, fitted_play, friction_holds
from labcli.papers.takuma2014.models.metrics import _unplayed
from labcli.papers.takuma2014.models.posture import PostureModel, force_model_from_json, load_force_model

B = math.radians(0.2)
HOLD = math.radians(0.7)  # the arm's friction holds it where a load of less than this left it
ROOT = Path(__file__).resolve().parents[3]


def _shafts(d_true: np.ndarray, hold: float = HOLD) -> tuple[np.ndarray, np.ndarray]:
    """Through play B, per load: the shaft's reading and where it stood at rest before the load
    (rad), on an arm that returns from a load only when it moved the joint by ``hold`` or more."""
    joint = shaft = 0.0
    read, rest = [], []
    for d in d_true:
        rest.append(shaft)
        joint += d
        shaft = min(max(shaft, joint - B / 2), joint + B / 2)
        read.append(shaft - rest[-1])
        joint -= d if abs(d) >= hold else 0.0
        shaft = min(max(shaft, joint - B / 2), joint + B / 2)
    return np.array(read), np.array(rest)


def _run() -> tuple[pd.DataFrame, np.ndarray, np.ndarray]:
    """A run of 140 loads: the first 100 with clear returns that friction held (loads between
    CLEAR_PLAYS plays and HOLD), the last 40 (the validation trials) with none such: their held
    loads are all inside CLEAR_PLAYS plays.  The table, the true deflections and a design."""
    rng = np.random.default_rng(4)
    sign = rng.choice([-1.0, 1.0], 140)
    size = np.radians(rng.uniform(0.3, 2.0, 140))
    late = np.radians(rng.choice([0.35, 0.42, 1.2, 1.8], 40))  # held ones short of 2.5 plays (0.5 deg)
    d_true = sign * np.concatenate([size[:100], late])
    read, rest = _shafts(d_true)
    table = pd.DataFrame(
        {
            "trial": np.arange(1, 141),
            "theta1_deg": np.degrees(read),
            "theta2_deg": np.degrees(read),
            "theta1_0_deg": np.degrees(rest) + 10.0,
            "theta2_0_deg": np.degrees(rest) - 5.0,
        }
    )
    design = np.column_stack([np.sin(d_true), -np.sin(d_true)]) / np.array([3.0, 1.6])
    return table, d_true, design


def test_a_validation_table_is_corrected_by_the_fits_friction_decision():
    table, d_true, design = _run()
    from labcli.papers.takuma2014.models.labels import shaft_returns

    n = len(table)
    returns = shaft_returns(table, np.arange(n))[:, 0]
    res, _ = fit_play(design, np.radians(table["theta1_deg"].to_numpy()), np.arange(n), np.ones(n, bool),
                      table["trial"].to_numpy(), returns=returns)  # fmt: skip
    assert res.holds  # the whole run has clear returns the friction held
    assert res.play_rad == pytest.approx(B, rel=0.05)
    valid = table.iloc[100:].reset_index(drop=True)
    moved = shaft_returns(valid, np.arange(len(valid)))[:, 0] / B
    assert not friction_holds(d_true[100:] / B, moved)  # alone, the validation trials say otherwise
    assert np.any(np.isfinite(moved) & (np.abs(moved) <= 0.25) & (np.abs(d_true[100:]) < CLEAR_PLAYS * B))
    # The model carries the fit's decision; validation labels read through it come out nearer the
    # true deflections than through the validation trials' own (a held unload read as a return that
    # stopped inside the play puts the next state a whole play off).
    model = SimpleNamespace(play={"play_deg": [0.2, 0.2], "friction_holds": [True, False]})
    fixed = _unplayed(model, valid)
    pd.testing.assert_frame_equal(fixed, apply_play(valid, (B, B), (True, False)))
    truth = np.degrees(d_true[101:])  # after the first, whose state before is not known
    held = np.abs(fixed["theta1_deg"].to_numpy()[1:] - truth)
    alone = np.abs(fixed["theta2_deg"].to_numpy()[1:] - truth)  # theta2: fitted as not held
    assert np.sum(held < 1e-6) >= 0.8 * len(truth) > np.sum(alone < 1e-6) + 8
    assert np.sqrt(np.mean(held**2)) < 0.6 * np.sqrt(np.mean(alone**2))
    # A model file without the decision (written before the fit kept it) decides from the table it
    # is given, as it did when it was written: here the validation trials' own "not held".
    model.play = {"play_deg": [0.2, 0.2]}
    assert fitted_play(model.play) == ((B, B), (None, None))
    older = _unplayed(model, valid)
    pd.testing.assert_frame_equal(older, apply_play(valid, (B, B), (None, None)))
    assert not np.allclose(older["theta1_deg"], fixed["theta1_deg"])


def test_the_sample_model_files_read_back_byte_for_byte():
    for name in ("force.model.json", "bent.model.json", "force-paper.model.json"):
        text = (ROOT / "sample_runs" / name).read_text()
        assert load_force_model(ROOT / "sample_runs" / name).to_json() == text


def test_the_fits_decision_is_read_back_and_a_file_from_before_it_decides_from_the_table():
    model = load_force_model(ROOT / "sample_runs" / "force.model.json")
    assert isinstance(model, PostureModel)
    # A file written before the decision was kept (no key): it reads back byte for byte, undecided.
    model.play = {k: v for k, v in model.play.items() if k != "friction_holds"}
    older = model.to_json()
    assert "friction_holds" not in older and force_model_from_json(older).to_json() == older
    assert fitted_play(force_model_from_json(older).play)[1] == (None, None)  # type: ignore[index]
    model.play = {**model.play, "friction_holds": [False, True]}
    back = force_model_from_json(model.to_json())
    assert back.play["friction_holds"] == [False, True]
    assert fitted_play(back.play)[1] == (False, True)  # type: ignore[index]
    assert back.to_json() == model.to_json() != older
    d = model.to_dict()
    for bad in ([True], "yes", [1, 0]):
        with pytest.raises(ModelError, match=r"key 'labels\.friction_holds' must list two booleans"):
            PostureModel.from_dict({**d, "labels": {**d["labels"], "friction_holds": bad}})


def test_the_fit_records_where_friction_held_the_arm():
    # The sample force run (the literature's rig): friction held the arm on some clear returns, and
    # the model file says so; its validation labels are then read with the held returns.
    from labcli.core.protocol import load_protocol
    from labcli.papers.takuma2014.models.takuma import TakumaModel
    from labcli.papers.takuma2014.records import load_trials

    proto, table = load_protocol("takuma2014"), load_trials(ROOT / "sample_runs" / "force.h5")
    model = TakumaModel(geometry=proto.settings.rig, protocol=proto.name).fit(table)
    assert model.to_dict()["labels"]["friction_holds"] == [True, True]
    # On a run whose friction never held a clear return the fit writes that decision too.
    steady = TakumaModel(geometry=proto.settings.rig, protocol=proto.name).fit(
        table.assign(theta1_0_deg=np.nan, theta2_0_deg=np.nan)
    )
    assert steady.to_dict()["labels"]["friction_holds"] == [False, False]
    valid = table[table["set"] == "validation"]
    widths = tuple(math.radians(w) for w in model.play["play_deg"])
    pd.testing.assert_frame_equal(_unplayed(model, valid), apply_play(valid, widths, (True, True)))  # type: ignore[arg-type]


def _short_returns(seed: int, hold_plays: float) -> tuple[np.ndarray, ...]:
    """Loads of 1.2-6 plays through play B on an arm whose friction holds it where a load of less
    than ``hold_plays`` plays left it (inside CLEAR_PLAYS: no clear return is held, so the run reads
    a shaft that stayed as a return that stopped inside the play).  The deflections, the design, the
    readings (with a 0.005 deg error), the shafts' returns and the states the shafts really had."""
    rng = np.random.default_rng(seed)
    n = 150
    d_true = rng.choice([-1.0, 1.0], n) * B * rng.uniform(1.2, 6.0, n)
    read_a, rest = _shafts(d_true, hold_plays * B)
    c_true = (d_true - read_a) / B
    returns = np.append(rest[1:] - rest[:-1] - read_a[:-1], np.nan)  # loaded reading to the next rest
    design = np.column_stack([np.sin(d_true), -np.sin(d_true)]) / np.array([3.0, 1.6])
    design += rng.normal(0.0, 1e-5, design.shape)
    return d_true, design, read_a + rng.normal(0.0, math.radians(0.005), n), returns, c_true


def test_the_states_the_run_determines_are_the_shafts_own():
    from labcli.papers.takuma2014.models.labels import _states

    for seed in range(4):
        d, _, _, returns, c_true = _short_returns(seed, 2.0)
        assert not friction_holds(d / B, returns / B)
        c, unsure = _states(d, B, returns, None)
        # Where the run pins the shaft (a shaft that moved, a load over the play) the state is
        # right to within the quarter play the shafts' motion is read to; only a state left open
        # (after a return that stayed inside the play, or before the first) can be wrong.
        assert np.max(np.abs(c - c_true)[~unsure]) <= 0.25 + 1e-9
        assert np.max(np.abs(c - c_true)[unsure]) > 0.5
        assert 0.1 < unsure.mean() < 0.6


def test_a_state_left_open_is_left_out_of_the_plays_fit(monkeypatch):
    # The held returns read as whole put a whole play of error into some of the play's column:
    # fitted with them, the width comes out short (a regressor's errors shorten its slope); left
    # out, it is the rig's.
    from labcli.papers.takuma2014.models import labels

    def widths() -> list[float]:
        out = []
        for seed in range(6):
            _, design, read, returns, _ = _short_returns(seed, 2.0)
            n = len(read)
            args = (design, read, np.arange(n), np.ones(n, bool), np.arange(1, n + 1))
            out.append(fit_play(*args, returns=returns)[0].play_rad / B)
        return out

    left_out = widths()
    np.testing.assert_allclose(left_out, 1.0, atol=0.02)
    with monkeypatch.context() as m:
        m.setattr(labels, "MIN_ERROR_TRIALS", 10**6)  # too few determined trials: every trial fitted
        with_open = widths()
    assert np.mean(with_open) < 0.85
    assert all(w < o for w, o in zip(with_open, left_out, strict=True))
