"""The history of loads the sleeves' friction terms read: each trial's joint motion into its baseline.

A trial's baseline is approached from the previous trial's loaded posture (the previous trial id
in the table, whichever set it is in), and the friction the sleeves hold at the baseline opposes
that motion (models/posture.py, ``friction_columns``).  Tables are recorded in trial order, so the
previous trial is nearly always the row before: that case is recognised in one pass over the ids
and no sort is made.  Angles in rad.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ....errors import ModelError


def previous_rows(trial: Any) -> np.ndarray:
    """Per row, the row of the trial before it in id order (ties in row order, as a stable sort
    puts them), -1 for the first."""
    trial = np.asarray(trial)
    n = len(trial)
    if n and not np.all(trial[1:] >= trial[:-1]):
        order = np.argsort(trial, kind="stable")
        prev = np.empty(n, dtype=np.int64)
        prev[order[0]] = -1
        prev[order[1:]] = order[:-1]
        return prev
    return np.arange(-1, n - 1, dtype=np.int64)


def motion_from(
    theta0_at: np.ndarray, before_at: np.ndarray, dtheta_before: np.ndarray, first: np.ndarray
) -> np.ndarray:
    """The motion (n, 2) rad from the previous trial's loaded posture (its rest ``before_at`` plus its
    deflection ``dtheta_before``) to each trial's baseline posture ``theta0_at``; 0 where ``first``
    (no trial before) and where a posture is unknown."""
    moved = theta0_at - (before_at + dtheta_before)
    moved[first] = 0.0
    return np.nan_to_num(moved, nan=0.0)


def motion_into_baseline(trial: np.ndarray, theta0: np.ndarray, dtheta: np.ndarray) -> np.ndarray:
    """Each trial's joint motion (n, 2) rad from the previous trial's loaded posture (the previous
    trial id in the table: theta0 + dtheta) to its own baseline posture; 0 for the first trial and
    where a posture is unknown."""
    th0 = np.asarray(theta0, dtype=float)
    d = np.asarray(dtheta, dtype=float)
    prev = previous_rows(trial)
    first = prev < 0
    at = np.where(first, 0, prev)
    return motion_from(th0, th0[at], d[at], first)


def rows_of(trial: Any, among: Any) -> np.ndarray:
    """The row of ``among`` (trial ids) holding each id of ``trial``: the last such row where an id
    repeats.  ModelError for an id ``among`` lacks."""
    among = np.asarray(among)
    order = np.argsort(among, kind="stable")
    ordered = among[order]
    trial = np.asarray(trial)
    at = np.searchsorted(ordered, trial, side="right") - 1
    found = (at >= 0) & (ordered[np.clip(at, 0, None)] == trial) if len(ordered) else np.zeros(len(trial), bool)
    if not np.all(found):
        missing = trial[~found][0]
        raise ModelError(f"Trial {missing} is not in the run's history; the motion into its baseline is unknown.")
    return order[at]
