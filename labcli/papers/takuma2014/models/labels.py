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

The unload's return.  The operator as written takes the joint back by its whole deflection after
each load; with the sleeves' friction it often is not: static friction holds the arm where a small
load left it, or stops it short of its rest (the rig's friction equilibrium).  On the literature's
rig, taken as a full return, that put the state wrong on 8-26 of 107 trials a joint (tuning seeds
1-5, against the rig's own shafts) and the width short (median over tuning seeds 1-10, theta2 0.15
deg of 0.2; 0.20 with the shafts' returns below, theta1 0.18 either way: a return that stops inside
the play is not seen).  The run records
where the shaft stood at every rest (``theta1_0_deg``, ``theta2_0_deg``), so the shaft's own motion
from each loaded reading to the next rest reading tells the state after the unload
(:func:`shaft_returns`): a shaft that moved (more than :data:`STUCK_SHARE` of the play) was pushed
by the joint and lies on the far side of the play from the motion; a shaft that stayed where a whole
return would have moved it says the joint did not come back, and the state is the loaded one.  A
return that stayed inside the play either way is still taken as whole, and the state it leaves
is not known: the joint may have stopped anywhere from where the load left it to its rest.  That reading of a shaft that
stayed needs a rig whose friction holds the arm, and the run shows whether it does
(:func:`friction_holds`): on the literature's rig the shaft stays after 2-22 % of the clear returns
(loads over :data:`CLEAR_PLAYS` plays; tuning seeds 1-10), on the kind rig after none, and there a
shaft that stayed after a small return is a joint that stopped just short of pushing it, near the
far side of the play.  Read as held, that put 26 more theta1 states wrong on the straight arm (84 of
1080 against 58, tuning seeds 1-10, against the rig's own shafts) and the validation labels with
them (theta1 RMSE 0.057 -> 0.066 deg); so without a held clear return the returns rule only moves
the states of shafts that moved.  Without the rest posture
(a table that does not record it) the states are the operator's as written.

States the run leaves open are left out of the width's fit.  The play's column ``-c`` is a
regressor, and a state taken wrong is an error in it of up to a whole play; errors in a regressor
shorten its slope (the attenuation below), and the width is that slope.  Before the first trial
(the centre assumed) and after a return that stayed inside the play (taken as whole), the shaft
may stand anywhere in a span of states; :func:`play_states` carries that span along (a shaft that
moved, or a load over the play, pins it), and a trial whose ``c`` the span leaves uncertain by more
than :data:`STUCK_SHARE` corrects its label with the state taken but does not enter the width.  On
the literature's rig those are about a quarter of the fit trials, and the states of the rest were
wrong on 1-6 trials a joint against 4-12 with every trial (tuning seeds 1-10, against the rig's own
shafts); the width's median over held-out seeds 11-30 went 0.171 -> 0.184 deg (theta1) and 0.129 ->
0.160 (theta2) of the rig's 0.2 (tests/benchmarks/steel_deformation.py).

The pressure ratios carry the sensors' repeatability (a fresh error in every reading, which no
window averages away), and least squares on such regressors shortens their slopes; the short part
of each deflection follows its sign, as the play's states do, so the play's column takes it and the
width comes out short (on the literature's rig 0.07 deg of the rig's 0.2 for theta1,
tests/benchmarks/steel_deformation.py).  The width is therefore fitted by corrected least squares
(the errors-in-variables moment correction, Fuller 1987, Sec. 2.2: ``X'X - n diag(s2)``), with the
reading errors' variance ``s2`` measured on the run itself (:func:`ratio_error_var`): an
antagonistic pair's common mode ``u_L + u_R`` hardly moves with the posture (one muscle shortens as
the other lengthens), so its scatter about a smooth function of both pairs' differential modes is
the readings' own error.  On a rig without repeatability error that scatter is near zero and the fit
is least squares.

Trials are taken in their ``trial`` order, the order the plan ran them; the state before the
first is unknown and taken as the centre of the play.  With no play (an ideal rig, or a
potentiometer coupled without backlash) the fitted ``b`` is near zero and the labels are
unchanged to within its standard error.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..records import check_relief_sides
from ..tables import REST

STUCK_SHARE = 0.25  # a trailing reading under this share of the play has not left the play
# A load over this many plays is a clear return: a whole one pushes the shaft well over the play.
CLEAR_PLAYS = 2.5
PASSES = 6  # state reruns; the play estimate settles in three or four
START_RAD = 1e-3  # the play the first pass assumes (0.06 deg): small against most deflections
# A direction of the design whose scatter is more reading error than this share of signal is left
# as least squares fits it: correcting it would divide by noise (tuning seeds 1-10: clipping such a
# direction's correction at a fifth instead let the bent arm's theta2 play run to 0.65 deg of 0.2).
MIN_KEPT_SHARE = 0.5
MIN_ERROR_TRIALS = 12  # fewer fit trials than this give no error variance (its six-term fit needs them)
# A pair's common mode scattering more than this (a ratio's standard deviation: 3 kPa at 0.3 MPa, nine
# times the literature rig's 0.33 kPa repeatability) is not the sensors' reading error but chambers
# not supplied together (trials drawn from Eqs. 34-37 alone, models/synthetic.py): nothing to correct.
MAX_RATIO_ERROR_SD = 0.015
READ_COLUMNS = ("theta1_deg", "theta2_deg")
# The relief's swing: venting L, the R actuators swing both joints the negative way by degrees (seed 1:
# -15 and -7 deg on the straight arm, -10 and -19 on the bent one), and supplied again the arm comes
# back the positive way, its last motion into the rest, which leaves each shaft on the far side of its
# play; venting R, the other way.  The swing's size is not recorded: any return past the play reads
# alike (play_states), so it is given as a degree.
RELIEF_RETURNS = {"L": np.radians(1.0), "R": -np.radians(1.0)}


@dataclass(frozen=True)
class PlayFit:
    """The play of one joint fitted with its angle equation: width (rad), its standard error, and
    the trials whose reading lay inside the play (left out of that joint's angle fit)."""

    play_rad: float
    se_rad: float
    trailing: int  # fit trials whose shaft trailed (read short)
    stuck: tuple[int, ...]  # trial ids whose reading did not leave the play
    holds: bool = False  # whether the sleeves' friction held the arm on a clear return (friction_holds)


def play_states(
    dtheta_true: np.ndarray, play: float, returns: np.ndarray | None = None, holds: bool | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """For deflections (rad, in trial order) of one joint: ``c`` per trial (the reading is
    ``d - play * c``) and whether the shaft trailed (moved less than the joint).

    ``returns`` (rad, in trial order; NaN where not known, :func:`shaft_returns`): how far the shaft
    moved from each trial's loaded reading to the next trial's rest reading.  Without it the joint
    is taken to return by its whole deflection.  With it, a shaft that moved (more than
    :data:`STUCK_SHARE` of the play) was pushed there by the joint and lies on the far side of
    the play; a shaft that stayed where a whole return would have moved it says the joint did not
    return: the sleeves' friction held the arm where the load left it, if the run shows that it
    ever does (:func:`friction_holds`; module docstring).  ``holds`` gives that decision instead
    (a fitted model's, for its validation trials); None decides it from these trials."""
    c, _ = _states(dtheta_true, play, returns, holds)
    return c, np.abs(c) > 1e-9


def _clip(q: float) -> float:
    return min(max(q, -0.5), 0.5)


def _states(
    dtheta_true: np.ndarray, play: float, returns: np.ndarray | None, holds: bool | None
) -> tuple[np.ndarray, np.ndarray]:
    """:func:`play_states`'s ``c``, and per trial whether the run leaves its state undetermined.

    Beside the state it takes, the loop carries the span of states the run allows: the whole play
    before the first trial, and after a return that stayed inside the play the span from held to
    whole (the joint may have stopped anywhere between); a shaft that moved pins it at a side of
    the play, and a load over the play clips it.  A trial's ``c`` is undetermined when the span
    gives it values more than :data:`STUCK_SHARE` apart."""
    c = np.zeros(len(dtheta_true))
    unsure = np.zeros(len(dtheta_true), dtype=bool)
    if play <= 0:
        return c, unsure
    moved = np.full(len(c), np.nan) if returns is None else np.asarray(returns, dtype=float) / play
    if holds is None:
        holds = friction_holds(np.asarray(dtheta_true, dtype=float) / play, moved)
    q, lo, hi = 0.0, -0.5, 0.5
    for i, d in enumerate(np.nan_to_num(dtheta_true) / play):
        q_loaded, lo_l, hi_l = _clip(q - d), _clip(lo - d), _clip(hi - d)
        c[i] = q - q_loaded  # the reading is d + (q' - q) in units of the play
        unsure[i] = abs((hi - hi_l) - (lo - lo_l)) > STUCK_SHARE
        q, lo, hi = _clip(q_loaded + d), _clip(lo_l + d), _clip(hi_l + d)
        if np.isfinite(moved[i]):
            whole = q - q_loaded - d  # how far a whole return would have moved the shaft
            if abs(moved[i]) > STUCK_SHARE:
                q = lo = hi = -0.5 if moved[i] > 0 else 0.5
            elif holds and abs(whole) > STUCK_SHARE:
                # Taken as held and as determined: leaving these open too (a return may have stopped
                # anywhere inside the play) left fewer trials and let the width scatter more (tuning
                # seeds 1-10, literature rig: theta1 0.10-0.41 deg against 0.11-0.27).
                q, lo, hi = q_loaded, lo_l, hi_l
            else:  # stayed inside the play: anywhere from held to whole
                lo, hi = min(lo, lo_l), max(hi, hi_l)
    return c, unsure


def friction_holds(delta: np.ndarray, moved: np.ndarray) -> bool:
    """Whether the sleeves' friction held the arm on any of the run's clear returns: a load that
    moved the joint over :data:`CLEAR_PLAYS` plays (``delta``, in plays) after which the shaft
    (``moved``, in plays) stayed within :data:`STUCK_SHARE` of the play, where a whole return would
    have pushed it well over the play."""
    clear = np.isfinite(moved) & (np.abs(np.nan_to_num(delta)) > CLEAR_PLAYS)
    return bool(np.any(clear & (np.abs(np.nan_to_num(moved)) <= STUCK_SHARE)))


def shaft_returns(table: Any, order: np.ndarray) -> np.ndarray:
    """Per row (n, 2) rad, table order: how far each potentiometer's shaft moved from the trial's
    loaded reading to the next trial's rest reading (``theta1_0_deg``, ``theta2_0_deg``), in the
    order ``order`` gives; NaN for the last trial and wherever the rest posture is not recorded.

    The net motion is read as the unload's return.  Where the next trial was relieved (a side
    vented before its baseline, its ``relief_vent``), the arm's last motion into that rest is the
    return from the relief's swing instead, and it is given as that return (:data:`RELIEF_RETURNS`):
    it names the vented side of the play, whatever the unload did.  On rows averaging several
    captures the net motion is the captures' mean (docs/calibration-labels.md)."""
    n = len(table)
    out = np.full((n, 2), np.nan)
    if n < 2:
        return out
    moved = np.full((n, 2), np.nan)
    if all(c in table.columns for c in REST):
        rest = np.radians(np.column_stack([np.asarray(table[c], dtype=float) for c in REST]))[order]
        read = np.radians(np.column_stack([np.asarray(table[c], dtype=float) for c in READ_COLUMNS]))[order]
        moved[:-1] = rest[1:] - (rest[:-1] + read[:-1])
    if "relief_vent" in table.columns:
        check_relief_sides(table)
        swung = np.array([RELIEF_RETURNS.get(str(v), np.nan) for v in np.asarray(table["relief_vent"])[order]])
        moved[:-1] = np.where(np.isfinite(swung[1:, None]), swung[1:, None], moved[:-1])
    out[order] = moved
    return out


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


def ratio_error_var(u: np.ndarray) -> np.ndarray:
    """The reading errors' variance of each pressure-ratio feature (4,), from the fit rows' features
    ``u`` (n, 4; L1, R1, L2, R2): per pair, half the residual variance of its common mode
    ``u_L + u_R`` about a quadratic in both pairs' differential modes (the two channels' errors are
    independent, so the common mode carries both and the differential modes' errors do not enter
    it).  Zeros when too few finite rows, and for a pair whose common mode scatters more than a
    reading error can (:data:`MAX_RATIO_ERROR_SD`)."""
    u = np.asarray(u, dtype=float)
    u = u[np.all(np.isfinite(u), axis=1)]
    out = np.zeros(4)
    if len(u) < MIN_ERROR_TRIALS:
        return out
    d1, d2 = u[:, 0] - u[:, 1], u[:, 2] - u[:, 3]
    X = np.column_stack([np.ones(len(u)), d1, d2, d1**2, d2**2, d1 * d2])
    for a in (0, 2):
        common = u[:, a] + u[:, a + 1]
        resid = common - X @ np.linalg.lstsq(X, common, rcond=None)[0]
        var = float(resid @ resid) / (len(u) - X.shape[1]) / 2.0
        out[a : a + 2] = var if var <= MAX_RATIO_ERROR_SD**2 else 0.0
    return out


def _corrected(X: np.ndarray, error_var: np.ndarray | None) -> np.ndarray | None:
    """``X'X`` less the reading errors' share of it (zero for the play's column, which has no reading
    error), in each direction of the design whose scatter keeps at least :data:`MIN_KEPT_SHARE` of
    its own after the correction; the others are left uncorrected (nearly all error, they carry
    nothing to correct).  None when there is nothing to correct."""
    if error_var is None or not np.any(error_var > 0):
        return None
    m = len(error_var)
    A = X.T @ X
    S = np.zeros_like(A)
    S[:m, :m] = np.diag(len(X) * np.asarray(error_var, dtype=float))
    try:
        L = np.linalg.cholesky(A)
    except np.linalg.LinAlgError:  # a column without scatter (no play states yet): least squares
        return None
    Li = np.linalg.inv(L)
    # In A's own metric each direction keeps the share 1 - (its error variance over its scatter).
    kept, V = np.linalg.eigh(np.eye(len(A)) - Li @ S @ Li.T)
    M = (V * np.where(kept >= MIN_KEPT_SHARE, kept, 1.0)) @ V.T
    return L @ M @ L.T


def _solve(
    X: np.ndarray, y: np.ndarray, Z: np.ndarray | None, error_var: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Coefficients and their unscaled covariance: least squares, two-stage least squares on the
    instruments ``Z`` (X projected onto them first) when given, or else corrected least squares
    when the design's leading columns carry reading errors of variance ``error_var``."""
    if Z is not None:
        X = Z @ np.linalg.lstsq(Z, X, rcond=None)[0]
    else:
        A = _corrected(X, error_var)
        if A is not None:
            return np.linalg.solve(A, X.T @ y), np.linalg.inv(A)
    beta, *_ = np.linalg.lstsq(X, y, rcond=None)
    return beta, np.linalg.pinv(X.T @ X)


def fit_play(
    design: np.ndarray,
    dtheta_read: np.ndarray,
    order: np.ndarray,
    fit_rows: np.ndarray,
    trial: np.ndarray,
    instruments: np.ndarray | None = None,
    error_var: np.ndarray | None = None,
    returns: np.ndarray | None = None,
) -> tuple[PlayFit, np.ndarray]:
    """Fit one joint's play with its angle design (all rows in table order; ``order`` sorts them by
    trial; ``fit_rows`` the rows fitted).  Returns the fit and the corrected deflections (rad).

    ``error_var`` (m,): the reading errors' variance of each design column (:func:`ratio_error_var`),
    taken out of the moment matrix (corrected least squares, the module docstring).
    ``returns`` (n,): the shaft's motion from each trial's load to the next rest
    (:func:`shaft_returns`), which tells the states after the unloads (:func:`play_states`).
    ``instruments`` (n, m), e.g. :func:`load_instruments`: instead, the width by two-stage least
    squares on them and the states; the loads move the joint but not the readings' errors (the
    sleeves' friction, which the operator's return to the same rest leaves out, still shortens it).
    Opt-in (``TakumaModel(label_play="loads")``): its width varies more from seed to seed."""
    r = np.asarray(dtheta_read, dtype=float)
    ok = fit_rows & np.isfinite(r) & np.all(np.isfinite(design), axis=1)
    if instruments is not None:
        ok &= np.all(np.isfinite(instruments), axis=1)
    play = START_RAD  # a small play to start from: the states are then the readings' signs
    se = 0.0
    d_true = r.copy()
    use = ok
    c = np.zeros(len(r))
    back = None if returns is None else np.asarray(returns, dtype=float)[order]
    for _ in range(PASSES):
        c_sorted, unsure_sorted = _states(d_true[order], play, back, None)
        c, unsure = np.empty(len(r)), np.empty(len(r), dtype=bool)
        c[order], unsure[order] = c_sorted, unsure_sorted
        stuck = _stuck(r, c, play)
        use = ok & ~stuck
        if np.count_nonzero(use & ~unsure) >= MIN_ERROR_TRIALS:
            use &= ~unsure  # a state the run leaves open is an error in the play's column: left out
        X = np.column_stack([design[use], -c[use]])
        y = np.sin(r[use])
        Z = None if instruments is None else np.column_stack([instruments[use], -c[use]])
        beta, unscaled = _solve(X, y, Z, error_var)
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
    holds = play > 0 and back is not None and friction_holds(d_true[order] / play, back / play)
    c_sorted, trailing_sorted = play_states(d_true[order], play, back, holds)
    c = np.empty(len(r))
    c[order] = c_sorted
    trailing = np.empty(len(r), dtype=bool)
    trailing[order] = trailing_sorted
    stuck = ok & _stuck(r, c, play)
    d_final = np.where(stuck, d_true, correct(r, c, play))
    d_final = np.where(np.isfinite(r), d_final, np.nan)
    result = PlayFit(play, se, int((trailing & ok).sum()), tuple(int(t) for t in trial[stuck]), bool(holds))
    return result, d_final


def apply_play(table: Any, play_rad: tuple[float, float], holds: tuple[bool | None, bool | None] = (None, None)) -> Any:
    """A copy of the trial table with each joint's deflection corrected for the given play (the
    validation trials of a model fitted with :func:`fit_play`: the same states, the same widths).

    ``holds``: per joint, whether the fit found the sleeves' friction holding the arm on a clear
    return (:attr:`PlayFit.holds`, the model file's ``labels.friction_holds``).  It is the fit's
    decision, not this table's: a validation table alone, with fewer clear returns, may decide
    otherwise, and its labels would then be corrected by other states than the fit's.  None (a
    model file written before the fit kept its decision) decides from this table."""
    out = table.copy()
    order = np.argsort(np.asarray(table["trial"], dtype=int), kind="stable")
    returns = shaft_returns(table, order)[order]
    for k, col in enumerate(READ_COLUMNS):
        if col not in table.columns or play_rad[k] <= 0:
            continue
        r = np.radians(np.asarray(table[col], dtype=float))
        d = r.copy()
        for _ in range(2):  # states from the readings, then from the corrected deflections
            c_sorted, _ = play_states(d[order], play_rad[k], returns[:, k], holds[k])
            c = np.empty(len(r))
            c[order] = c_sorted
            d = correct(r, c, play_rad[k])
        out[col] = np.degrees(d)
    return out


def fitted_play(play: Any) -> tuple[tuple[float, float], tuple[bool | None, bool | None]] | None:
    """From a model's ``labels`` entry (``play`` of TakumaModel and PostureModel): the widths (rad)
    and the fit's friction decision per joint, for :func:`apply_play`; None when it fitted no play.
    Every fit writes ``friction_holds``; a file without it was written before the fit kept its
    decision, and its validation decides from the table given (None), as it did then."""
    widths = (play or {}).get("play_deg")
    if not widths or not all(isinstance(w, (int, float)) and math.isfinite(w) for w in widths):
        return None
    holds = (play or {}).get("friction_holds")
    decided = (None, None) if holds is None else (bool(holds[0]), bool(holds[1]))
    return (math.radians(widths[0]), math.radians(widths[1])), decided
