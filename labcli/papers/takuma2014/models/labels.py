"""Calibration labels without the potentiometers' play (issue of label bias, Section 3.2).

Eqs. 34-35 are fitted against the joint deflections the potentiometers read.  A
potentiometer coupled with play (backlash of full width ``b``) reads a deflection short
whenever its shaft trails on the wrong side of the play: after a load that moved the joint
the same way as this one, the unload dragged the shaft to the far side, and the joint must
take up the whole play before the shaft follows.  The label then reads ``|d| - b`` instead of
``|d|`` (or nothing at all when ``|d| < b``); least squares through the origin absorbs those
short readings as a smaller slope, so every pressure-derived deflection reads low, and a
stiff object's small deformation (the steel can's 1.3 mm) comes out far too large.

The play operator (a hysteron per joint).  Write ``q`` for the shaft's offset from the joint
in units of the play, ``-1/2 <= q <= 1/2``.  A load moving the joint by ``d`` (``delta = d / b``)
leaves the shaft at ``q' = clip(q - delta, -1/2, 1/2)`` and the reading
``r = d + b (q' - q)``; the unload back to rest leaves ``q'' = clip(q' + delta, -1/2, 1/2)``.
Inverted, ``d = r + b c`` with ``c = q - q'``: linear in ``b`` once the sequence of states is
known.  So ``b`` is fitted jointly with the angle coefficients, one column ``-c`` beside
Eq. 34's (or 35's) design, and the states are rerun with the new ``b`` and the corrected
deflections until they stop changing (a few passes).  A reading that has hardly moved (``|r|``
under :data:`STUCK_SHARE` of the play) may be a shaft that never left the play, and says only
that ``|d| <= b``: such trials stay out of that joint's angle fit, with a reason, and the
pressures' own estimate (kept within the play) carries the state on to the next trial.

Trials are taken in their ``trial`` order, the order the plan ran them; the state before the
first is unknown and taken as the centre of the play.  With no play (an ideal rig, or a
potentiometer coupled without backlash) the fitted ``b`` is near zero and the labels are
unchanged to within its standard error.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

STUCK_SHARE = 0.25  # a trailing reading under this share of the play has not left the play
PASSES = 6  # state reruns; the play estimate settles in three or four
START_RAD = 1e-3  # the play the first pass assumes (0.06 deg): small against most deflections


@dataclass(frozen=True)
class PlayFit:
    """The play of one joint fitted with its angle equation: width (rad), its standard error, and
    the trials whose reading lay inside the play (left out of that joint's angle fit)."""

    play_rad: float
    se_rad: float
    trailing: int  # fit trials whose shaft trailed (read short)
    stuck: tuple[int, ...]  # trial ids whose reading did not leave the play


def play_states(dtheta_true: np.ndarray, play: float) -> tuple[np.ndarray, np.ndarray]:
    """For deflections (rad, in trial order) of one joint: ``c`` per trial (the reading is
    ``d - play * c``) and whether the shaft trailed (moved less than the joint)."""
    q = 0.0
    c = np.zeros(len(dtheta_true))
    if play <= 0:
        return c, np.zeros(len(dtheta_true), dtype=bool)
    for i, d in enumerate(np.nan_to_num(dtheta_true) / play):
        q_loaded = min(max(q - d, -0.5), 0.5)
        c[i] = q - q_loaded  # the reading is d + (q' - q) in units of the play
        q = min(max(q_loaded + d, -0.5), 0.5)
    return c, np.abs(c) > 1e-9


def _stuck(r: np.ndarray, c: np.ndarray, play: float) -> np.ndarray:
    """Readings that may not have left the play: under a share of it.  Whether the shaft trailed
    depends on the deflection's sign, which such a reading does not tell, so each counts as
    undetermined (``c`` is accepted for the callers' symmetry)."""
    if play <= 0:
        return np.zeros(len(r), dtype=bool)
    return np.abs(r) < STUCK_SHARE * play


def correct(dtheta_read: np.ndarray, c: np.ndarray, play: float) -> np.ndarray:
    """True deflections from the readings and the states: ``d = r + play * c``."""
    return dtheta_read + play * c


def load_instruments(F: np.ndarray) -> np.ndarray:
    """The instruments of the play's fit from the trials' known loads (n, 2) N: the force and its
    second-order products, which the deflection follows and the pressure readings' errors do not."""
    F = np.asarray(F, dtype=float)
    return np.column_stack([F, F[:, 0] ** 2, F[:, 1] ** 2, F[:, 0] * F[:, 1]])


def _solve(X: np.ndarray, y: np.ndarray, Z: np.ndarray | None) -> tuple[np.ndarray, np.ndarray]:
    """Coefficients and their unscaled covariance: least squares, or two-stage least squares on the
    instruments ``Z`` (X projected onto them first) when given."""
    if Z is not None:
        X = Z @ np.linalg.lstsq(Z, X, rcond=None)[0]
    beta, *_ = np.linalg.lstsq(X, y, rcond=None)
    return beta, np.linalg.pinv(X.T @ X)


def fit_play(
    design: np.ndarray,
    dtheta_read: np.ndarray,
    order: np.ndarray,
    fit_rows: np.ndarray,
    trial: np.ndarray,
    instruments: np.ndarray | None = None,
) -> tuple[PlayFit, np.ndarray]:
    """Fit one joint's play with its angle design (all rows in table order; ``order`` sorts them by
    trial; ``fit_rows`` the rows fitted).  Returns the fit and the corrected deflections (rad).

    ``instruments`` (n, m), e.g. :func:`load_instruments`: the width by two-stage least squares on
    them and the states.  The design's pressure ratios carry the sensors' reading errors (a fresh
    error in each reading, which no window averages away); least squares on such regressors
    shortens their slopes, and the short part of every deflection, which grows with it as the
    play's states do, is taken from the play (on the literature's rig, well short of the rig's
    width: tests/benchmarks/steel_deformation.py, docs/classify.md).  The loads move the joint but
    not the readings' errors, so the width fitted on them is free of that bias (the sleeves'
    friction, which the operator's return to the same rest leaves out, still shortens it).
    Opt-in (``TakumaModel(label_play="loads")``): its width still varies from seed to seed."""
    r = np.asarray(dtheta_read, dtype=float)
    ok = fit_rows & np.isfinite(r) & np.all(np.isfinite(design), axis=1)
    if instruments is not None:
        ok &= np.all(np.isfinite(instruments), axis=1)
    play = START_RAD  # a small play to start from: the states are then the readings' signs
    se = 0.0
    d_true = r.copy()
    use = ok
    c = np.zeros(len(r))
    for _ in range(PASSES):
        c_sorted, _ = play_states(d_true[order], play)
        c = np.empty(len(r))
        c[order] = c_sorted
        stuck = _stuck(r, c, play)
        use = ok & ~stuck
        X = np.column_stack([design[use], -c[use]])
        y = np.sin(r[use])
        Z = None if instruments is None else np.column_stack([instruments[use], -c[use]])
        beta, unscaled = _solve(X, y, Z)
        new_play = max(float(beta[-1]), 0.0)
        resid = y - X @ beta
        dof = max(len(y) - X.shape[1], 1)
        cov = unscaled * float(resid @ resid) / dof
        se = float(np.sqrt(max(cov[-1, -1], 0.0)))
        pred = np.arcsin(np.clip(design @ beta[:-1], -1.0, 1.0))
        d_true = np.where(np.isfinite(r), correct(r, c, new_play), pred)
        # A reading that never left the play: the pressures' own estimate, kept within it.
        if new_play > 0:
            inside = _stuck(r, c, new_play)
            d_true = np.where(inside, np.clip(pred, -new_play, new_play), d_true)
        converged = abs(new_play - play) < 1e-3 * max(new_play, 1e-6)
        play = new_play
        if converged:
            break
    c_sorted, trailing_sorted = play_states(d_true[order], play)
    c = np.empty(len(r))
    c[order] = c_sorted
    trailing = np.empty(len(r), dtype=bool)
    trailing[order] = trailing_sorted
    stuck = ok & _stuck(r, c, play)
    d_final = np.where(stuck, d_true, correct(r, c, play))
    d_final = np.where(np.isfinite(r), d_final, np.nan)
    result = PlayFit(play, se, int((trailing & ok).sum()), tuple(int(t) for t in trial[stuck]))
    return result, d_final


def apply_play(table: Any, play_rad: tuple[float, float]) -> Any:
    """A copy of the trial table with each joint's deflection corrected for the given play (the
    validation trials of a model fitted with :func:`fit_play`: the same states, the same widths)."""
    out = table.copy()
    order = np.argsort(np.asarray(table["trial"], dtype=int), kind="stable")
    for k, col in enumerate(("theta1_deg", "theta2_deg")):
        if col not in table.columns or play_rad[k] <= 0:
            continue
        r = np.radians(np.asarray(table[col], dtype=float))
        d = r.copy()
        for _ in range(2):  # states from the readings, then from the corrected deflections
            c_sorted, _ = play_states(d[order], play_rad[k])
            c = np.empty(len(r))
            c[order] = c_sorted
            d = correct(r, c, play_rad[k])
        out[col] = np.degrees(d)
    return out
