"""The play's states on a relieved run read from the side each trial's relief vented (labels.shaft_returns)."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest

from labcli.errors import ConfigError
from labcli.papers.takuma2014.models.labels import RELIEF_RETURNS, play_states, shaft_returns

B = math.radians(0.2)
SWING = {"L": math.radians(-15.0), "R": math.radians(15.0)}  # venting L, the R actuators swing the joint negative


def _relieved_run(d: np.ndarray, sides: list[str], held: np.ndarray) -> tuple[pd.DataFrame, np.ndarray]:
    """A shaft with play B on one joint through relieved trials: before each baseline the relief swings
    the joint to the side away from the one vented and back to its rest, then the load moves it by ``d``
    and the unload brings it back by all but ``held`` of that.  The trial table (both joints alike) and
    each trial's true ``c`` (the reading is ``d - B c``)."""
    joint, shaft = 0.0, 0.0

    def move(to: float) -> None:
        nonlocal joint, shaft
        joint, shaft = to, min(max(shaft, to - B / 2), to + B / 2)

    rows, c = [], []
    for di, side, h in zip(d, sides, held, strict=True):
        rest = joint
        move(rest + SWING[side])
        move(rest)
        at_rest = shaft
        move(rest + di)
        read = shaft - at_rest
        c.append((di - read) / B)
        move(rest + h * di)  # friction holds a share of the load's motion
        rows.append({"trial": len(rows) + 1, "theta1_deg": math.degrees(read), "theta1_0_deg": math.degrees(at_rest)})
    table = pd.DataFrame(rows)
    table["theta2_deg"], table["theta2_0_deg"], table["relief_vent"] = table["theta1_deg"], table["theta1_0_deg"], sides
    return table, np.array(c)


def test_the_rest_after_a_relief_is_read_from_the_side_it_vented():
    rng = np.random.default_rng(5)
    d = rng.choice([-1.0, 1.0], 40) * np.radians(rng.uniform(0.05, 1.0, 40))
    sides = ["L" if x < 0 else "R" for x in rng.normal(size=40)]
    held = rng.uniform(0.0, 0.6, 40)
    table, c_true = _relieved_run(d, sides, held)
    order = np.arange(len(table))
    back = shaft_returns(table, order)
    # Every rest but the first follows a relief: its return is the relief's, not the unload's net motion.
    np.testing.assert_array_equal(back[:-1, 0], [RELIEF_RETURNS[s] for s in sides[1:]])
    assert np.isnan(back[-1]).all()
    c, _ = play_states(d, B, back[:, 0])
    np.testing.assert_allclose(c[1:], c_true[1:], atol=1e-9)  # the first starts from the centre assumed
    # From the shafts' net motion alone, the states after the unloads held by friction come out wrong.
    c_net, _ = play_states(d, B, shaft_returns(table.drop(columns=["relief_vent"]), order)[:, 0])
    assert np.sum(np.abs(c_net[1:] - c_true[1:]) > 0.5) >= 5


def test_a_load_towards_the_vented_side_reads_short_by_the_whole_play():
    """Venting L, the arm comes back the positive way: a positive load reads whole, a negative one a play short."""
    d = np.radians([0.5, -0.5, 0.5, -0.5])
    table, c_true = _relieved_run(d, ["L", "L", "R", "R"], np.zeros(4))
    c, _ = play_states(d, B, shaft_returns(table, np.arange(4))[:, 0])
    np.testing.assert_allclose(c[1:], [-1.0, 1.0, 0.0])
    np.testing.assert_allclose(c_true[1:], [-1.0, 1.0, 0.0])


def test_rows_without_a_side_keep_the_shafts_net_motion():
    table = pd.DataFrame(
        {
            "trial": [1, 2, 3],
            "theta1_deg": [0.5, 0.5, 0.5],
            "theta2_deg": [0.5, 0.5, 0.5],
            "theta1_0_deg": [0.0, 0.3, 0.4],
            "theta2_0_deg": [0.0, 0.3, 0.4],
            "relief_vent": ["", "", "L"],
        }
    )
    back = shaft_returns(table, np.arange(3))
    np.testing.assert_allclose(back[0], np.radians([0.3 - 0.5] * 2))
    np.testing.assert_allclose(back[1], [RELIEF_RETURNS["L"]] * 2)


def test_a_table_naming_another_side_is_refused_in_one_sentence():
    """fit and validate read a CSV table without importing it: a side other than L, R or empty is
    refused, naming the trial, where it would be read as no relief; a missing cell is no relief."""
    table = pd.DataFrame(
        {
            "trial": [4, 5, 6],
            "theta1_deg": [0.5, 0.5, 0.5],
            "theta2_deg": [0.5, 0.5, 0.5],
            "relief_vent": ["L", np.nan, "left"],
        }
    )
    with pytest.raises(ConfigError) as err:
        shaft_returns(table, np.arange(3))
    assert str(err.value) == "trial 6: relief_vent must be L, R or empty, got 'left'."
    table.loc[2, "relief_vent"] = "R"
    np.testing.assert_allclose(shaft_returns(table, np.arange(3))[1], [RELIEF_RETURNS["R"]] * 2)
