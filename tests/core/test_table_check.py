"""The store's check of a record against its exchange table, made without a DataFrame.

The store refuses a record that ``labcli export`` could not write (labcli.core.store.rows.exportable).
It checks each record's row with :func:`labcli.core.tables.columns_problems` on the record type's
``table_columns``; ``labcli export`` checks the run's table with :func:`~labcli.core.tables.frame_problems`
on ``table`` (a DataFrame).  Both must give the same verdict and the same sentence for every row, good
or bad: each case below is fed to both, and so are random rows (hypothesis).
"""

from __future__ import annotations

import math
from types import SimpleNamespace
from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from labcli.core.store.rows import exportable
from labcli.core.tables import columns_problems, frame_problems
from labcli.errors import StoreError
from labcli.papers.rpam2015.records import RECORD_TYPES as RPAM
from labcli.papers.takuma2014.records import RECORD_TYPES as MCKIBBEN

RUN = SimpleNamespace(split=SimpleNamespace(set_of=lambda: {1: "fit", 2: "validation"}))
TRIALS, PUSHES = MCKIBBEN["force"], MCKIBBEN["push"]
STRETCH, JOINT = RPAM["rpam-stretch"], RPAM["rpam-joint"]

# Values a cell may meet: good ones, and each way a value leaves a table's bounds.
ODD = [0.3, 0.0, -0.01, 1.5, 1e300, -1e300, math.nan, math.inf, -math.inf, 2.0 * math.pi, 1e-320, 12.5, -400.0]


def trial_cols(n: int = 1, **over: Any) -> dict[str, Any]:
    cols: dict[str, Any] = {
        "P0": np.full((n, 4), 0.2),
        "P": np.full((n, 4), 0.25),
        "theta": np.full((n, 2), 0.1),
        "F": np.full((n, 2), 0.5),
        "mass": np.full(n, 0.3),
        "direction": np.full(n, 0.5),
    }
    cols.update({k: np.asarray(v, dtype=np.float64) for k, v in over.items()})
    return cols


def push_cols(n: int = 1, **over: Any) -> dict[str, Any]:
    cols: dict[str, Any] = {
        "object": np.array(["sponge"] * n, dtype=object),
        "category": np.array(["soft"] * n, dtype=object),
        "R": np.full(n, 0.02),
        "d": np.full(n, 0.01),
        "phi": np.full(n, 0.3),
        "true_stiffness": np.full(n, 400.0),
        "P0": np.full((n, 4), 0.2),
        "P": np.full((n, 4), 0.25),
    }
    cols.update({k: (np.asarray(v, dtype=object if k in ("object", "category") else None)) for k, v in over.items()})
    return cols


def point_cols(n: int = 1, **over: Any) -> dict[str, Any]:
    cols: dict[str, Any] = {
        "P": np.full((n, 2), 0.2),
        "P0": np.full((n, 2), 0.0),
        "mass": np.full(n, 0.5),
        "L": np.full(n, 0.1),
        "lambda": np.full(n, 1.1),
        "alpha": np.full(n, 0.2),
        "pot0": np.full(n, math.nan),
        "plan_mass_g": np.full(n, math.nan),
        "plan_P_A_kPa": np.full(n, 200.0),
        "plan_P_B_kPa": np.full(n, math.nan),
    }
    cols.update({k: np.asarray(v, dtype=np.float64) for k, v in over.items()})
    return cols


def both(rt: Any, cols: dict[str, Any], ids: list[int]) -> list[tuple[int, str | None, str]]:
    """The two verdicts, held equal; the one they share."""
    by_frame = frame_problems(rt.table(RUN, ids, cols), rt.table_spec)
    by_columns = columns_problems(rt.table_columns(RUN, ids, cols), rt.table_spec)
    assert by_columns == by_frame
    return by_columns


CASES = [
    (TRIALS, trial_cols(), None),
    (TRIALS, trial_cols(P=[[0.2, 0.2, 1.5, 0.2]]), ("P_L2", "1.5 MPa is outside the sensor span 0 to 1 MPa")),
    (TRIALS, trial_cols(P0=[[0.2, -0.01, 0.2, 0.2]]), ("P_R10", "-0.01 MPa is not a positive gauge pressure")),
    (
        TRIALS,
        trial_cols(F=[[1e300, 0.0]]),
        ("Fx_N", "1e+300 N is outside the range of a force at the tip, -1000 to 1000 N"),
    ),
    (TRIALS, trial_cols(theta=[[0.1, math.inf]]), ("theta2_deg", "'inf' is not a number")),
    (TRIALS, trial_cols(F=[[math.nan, 0.0]]), ("Fx_N", "is empty; a number is required")),
    (TRIALS, trial_cols(mass=[math.nan], direction=[math.nan]), None),
    (TRIALS, trial_cols(mass=[-0.001]), ("mass_g", None)),
    (TRIALS, trial_cols(pot0=[[0.1, 0.2]]), None),
    (TRIALS, trial_cols(pot0=[[0.1, math.nan]]), None),
    (PUSHES, push_cols(), None),
    (PUSHES, push_cols(R=[-1.0]), ("R_m", None)),
    (PUSHES, push_cols(object=[""]), ("object", "is empty; an object name is required")),
    (PUSHES, push_cols(P=[[0.2, 0.2, 0.2, 7.0]]), ("P_R2", None)),
    (PUSHES, push_cols(phi=[math.nan], true_stiffness=[math.nan]), None),
    (STRETCH, point_cols(), None),
    (STRETCH, point_cols(P=[[0.2, 1e300]]), ("P_B", None)),
    (STRETCH, point_cols(mass=[math.nan]), ("mass_g", None)),
    (JOINT, point_cols(), None),
    (JOINT, point_cols(P0=[[math.nan, 0.0]]), ("P_A0", None)),  # a pair half empty: the header's problem
    (JOINT, point_cols(alpha=[math.inf]), ("alpha_deg", None)),
]


@pytest.mark.parametrize(("rt", "cols", "verdict"), CASES)
def test_the_store_and_export_give_one_verdict_and_one_sentence(rt: Any, cols: dict, verdict: Any) -> None:
    problems = both(rt, cols, [1])
    if verdict is None:
        assert problems == []
        return
    assert problems[0][1] == verdict[0]
    if verdict[1] is not None:
        assert problems[0][2] == verdict[1]


@pytest.mark.parametrize(("rt", "cols", "verdict"), CASES)
def test_the_store_refuses_what_export_refuses_in_the_same_words(rt: Any, cols: dict, verdict: Any) -> None:
    # exportable takes the rows the store writes: one value per column, as record_row makes them.
    row = {name: v[0] for name, v in cols.items()}
    if verdict is None:
        exportable(rt, [row], [1], ["record 1"], RUN)
        return
    by_frame = frame_problems(rt.table(RUN, [1], cols), rt.table_spec)[0]
    with pytest.raises(StoreError) as e:
        exportable(rt, [row], [1], ["record 1"], RUN)
    assert str(e.value) == (
        f"record 1 was not stored: column {by_frame[1]}: {by_frame[2]}, which a {rt.table_spec.label} table "
        "cannot hold (the rig or its link is not measuring)."
    )


def test_a_batch_is_checked_row_by_row_in_both() -> None:
    cols = trial_cols(3, F=[[0.0, 0.0], [2e3, 0.0], [0.0, -2e3]])
    problems = both(TRIALS, cols, [1, 2, 3])
    assert [(i, c) for i, c, _ in problems] == [(1, "Fx_N"), (2, "Fy_N")]


def test_no_rows_no_problems() -> None:
    assert both(TRIALS, trial_cols(0), []) == []
    assert both(PUSHES, push_cols(0), []) == []


values = st.sampled_from(ODD) | st.floats(allow_nan=True, allow_infinity=True)


@settings(max_examples=150, deadline=None)
@given(st.lists(values, min_size=18, max_size=18), st.integers(1, 3))
def test_random_trial_rows_get_one_verdict(v: list[float], n: int) -> None:
    cols = trial_cols(
        n,
        P0=np.tile(v[0:4], (n, 1)),
        P=np.tile(v[4:8], (n, 1)),
        theta=np.tile(v[8:10], (n, 1)),
        F=np.tile(v[10:12], (n, 1)),
        mass=[v[12]] * n,
        direction=[v[13]] * n,
        pot0=np.tile(v[14:16], (n, 1)),
    )
    with np.errstate(over="ignore"):  # a huge angle in radians overflows in degrees: an empty cell in both
        both(TRIALS, cols, list(range(1, n + 1)))


@settings(max_examples=100, deadline=None)
@given(st.lists(values, min_size=10, max_size=10), st.sampled_from([STRETCH, JOINT]))
def test_random_points_get_one_verdict(v: list[float], rt: Any) -> None:
    cols = point_cols(
        1,
        P=[v[0:2]],
        P0=[v[2:4]],
        mass=[v[4]],
        L=[v[5]],
        alpha=[v[6]],
        plan_mass_g=[v[7]],
        plan_P_A_kPa=[v[8]],
        plan_P_B_kPa=[v[9]],
    )
    both(rt, cols, [1])


@settings(max_examples=100, deadline=None)
@given(st.lists(values, min_size=12, max_size=12), st.sampled_from(["sponge", "", " ", "a,b", 'q"uote']))
def test_random_pushes_get_one_verdict(v: list[float], name: str) -> None:
    cols = push_cols(
        1,
        object=[name],
        R=[v[0]],
        d=[v[1]],
        phi=[v[2]],
        true_stiffness=[v[3]],
        P0=[v[4:8]],
        P=[v[8:12]],
    )
    both(PUSHES, cols, [1])
