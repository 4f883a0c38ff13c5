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


def _shafts(d_true: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Through play B, per load: the shaft's reading and where it stood at rest before the load
    (rad), on an arm that returns from a load only when it moved the joint by HOLD or more."""
    joint = shaft = 0.0
    read, rest = [], []
    for d in d_true:
        rest.append(shaft)
        joint += d
        shaft = min(max(shaft, joint - B / 2), joint + B / 2)
        read.append(shaft - rest[-1])
        joint -= d if abs(d) >= HOLD else 0.0
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
    # A model file without the decision (written before it) reads no held return.
    model.play = {"play_deg": [0.2, 0.2]}
    assert fitted_play(model.play) == ((B, B), (False, False))
    pd.testing.assert_frame_equal(_unplayed(model, valid), apply_play(valid, (B, B)))


def test_the_sample_model_files_read_back_byte_for_byte():
    for name in ("force.model.json", "bent.model.json", "force-paper.model.json"):
        text = (ROOT / "sample_runs" / name).read_text()
        assert load_force_model(ROOT / "sample_runs" / name).to_json() == text


def test_the_fits_decision_is_written_only_where_friction_held_and_read_back():
    model = load_force_model(ROOT / "sample_runs" / "force.model.json")
    assert isinstance(model, PostureModel)
    # A file written before the decision was kept (no key): it reads back byte for byte, as not held.
    model.play = {k: v for k, v in model.play.items() if k != "friction_holds"}
    older = model.to_json()
    assert "friction_holds" not in older and force_model_from_json(older).to_json() == older
    assert fitted_play(force_model_from_json(older).play)[1] == (False, False)  # type: ignore[index]
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
    valid = table[table["set"] == "validation"]
    widths = tuple(math.radians(w) for w in model.play["play_deg"])
    pd.testing.assert_frame_equal(_unplayed(model, valid), apply_play(valid, widths, (True, True)))  # type: ignore[arg-type]
