"""A change while a load is on: the load coming off, or another load on top of it.

The estimator sees the change as a lagged step of the pressures, ``step`` (MPa per chamber,
:func:`lagged_step`), on top of what the loads so far have moved them by, ``total``.  It is the
release when any of four readings says the rig is coming back to rest:

* **It points back** (:func:`points_back`): the change takes back what is on the rig, within
  ``release_cosine`` of the way back to the baseline and at most ``release_overshoot`` times the
  load's size (read from the first blocks of a lagged change, the heat makes it look larger).
* **It is a partial return, give or take the sensors' new readings** (:func:`partial_return`).
  The sleeves' friction may hold the arm anywhere between where the load held it and where it
  rested, and every change of the rig gives each pressure sensor a new reading, off the last by
  up to ``reread_MPa`` rms (0.5 kPa: on the literature's simulated rig each reading is off by
  0.33 kPa rms, two readings' difference by 0.47 kPa).
  For a small load the new readings are a large share of the way back, or all of it when
  friction holds the arm where the load left it.  So the change is the release when the
  pressures after it, ``total + step``, lie within the sensors' new readings of a point between
  the loaded pressures and the baseline: ``min over a in [0, 1] of |step + a total|^2`` in units
  of ``reread_MPa`` (common mode removed, as the detector has it) under the chi-square 99 %
  point of one degree of freedom fewer than the chambers (:func:`chi2_99`: 3 for the paper's
  four muscles, 1 for the rPAM paper's antagonistic pair).  Within that bound any change small
  enough (under 1.7 kPa on four chambers) is near the loaded point whatever its direction, so
  the direction decides: a change further out along the load than the new readings reach
  (``AWAY_Z`` of their spread, one-sided 99 %) is another weight on it, not its release.
* **The force reads zero** (:func:`force_at_zero`): the model, given the pressures after the
  change against the baseline, reads every load quantity it reports within ``release_force_se``
  standard errors of zero (the estimator gives the model the sensors' new readings as the
  pressures' doubt, not the change's size: that doubt grows with the change and would make any
  large load read as none).  A load held by friction (along the arm, where it makes little
  torque) may let the arm slide to another rest when it comes off: the pressures then move away
  from the baseline's, in the muscles' own way, which the model reads as the posture it is and
  no force.

* **The joints slide on, the way they came back** (:func:`slides_back`, the potentiometers):
  the sleeves' friction may hold the arm short of its rest when a load comes off, and a small
  load after it (one that did not move the joints, or one along the arm) changes nothing.  When
  that load comes off, the jolt lets the arm slide on towards its rest: the joints move on the
  way they came back from the load before (the motion into the baseline that the friction terms
  read, :mod:`.estimator`), and the pressures, read against that friction-held baseline, show a
  force.  So a change on a load that left the joints where they were, whose joints then move
  (beyond their noise) within ``release_cosine`` of the way they came back, is the release.  A
  load that moved the joints is left to the pressures: a new load on one whose release went
  unseen may move them any way, that way too (on seeds 1-10 one did, seed 3 at 112 s).

A load put on top of another is taken for the release when it leaves the pressures where one of
these readings puts a rig at rest: a load whose change is within the sensors' repeatability, or
that leaves no force the model can tell from zero, cannot be told from a release by the
pressures (nor, for a small one, by the potentiometers: friction holds the arm).  The settings
were tuned on seeds 1-10 of tests/benchmarks/sensing_closing.py (docs/sensing.md, "Release or load").
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable

import numpy as np

from .config import EstimatorConfig
from .detector import whiten
from .evaluate import Inputs2, evaluate
from .model import LOAD, UNOBSERVABLE, SensingModel
from .transient import lag

# A change further out along the load than this many spreads of the new readings is a load (one-sided 99 %).
AWAY_Z = 2.33
# The joints moved when their change exceeds this many standard deviations of a block's reading.
MOVED_Z = 4.0


@functools.cache
def chi2_99(dof: int) -> float:
    """The chi-square 99 % point of ``dof`` (>= 1) degrees of freedom (6.635 for 1, 11.345 for 3).

    The survival function in closed form (Abramowitz & Stegun 26.4.4-26.4.5: a finite sum for
    an integer ``dof``), solved by bisection: the estimator needs it once per chamber count."""
    if dof < 1:
        raise ValueError(f"a chi-square needs at least one degree of freedom, got {dof}")

    def survival(x: float) -> float:
        h = x / 2.0
        if dof % 2 == 0:
            term, total = 1.0, 1.0
            for j in range(1, dof // 2):
                term *= h / j
                total += term
            return math.exp(-h) * total
        r = math.sqrt(x)
        term, total = r, 0.0
        for j in range(1, (dof - 1) // 2 + 1):
            total += term
            term *= x / (2 * j + 1)
        return math.erfc(r / math.sqrt(2.0)) + math.sqrt(2.0 / math.pi) * math.exp(-h) * total

    lo, hi = 0.0, 10.0 * dof + 50.0
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if survival(mid) > 0.01 else (lo, mid)
    return 0.5 * (lo + hi)


def lagged_step(tcs: np.ndarray, raw: np.ndarray, t1: float, tau: float) -> np.ndarray:
    """The settled size of a change begun at ``t1``: least squares of the residuals ``raw`` (n, p)
    at the blocks' times ``tcs`` on the muscles' lag ``1 - exp(-(t - t1)/tau)`` (p,)."""
    phi = lag(tcs - t1, tau)
    return phi @ raw / max(float(phi @ phi), 1e-300)


def points_back(step: np.ndarray, total: np.ndarray, var: np.ndarray, cosine: float, overshoot: float) -> bool:
    """Does the change take back what is on the rig (module docstring)?  ``var``: the chambers'
    noise variance (p,), by which both are whitened alike."""
    amp, load = whiten(step, var), whiten(total, var)
    size, held = float(np.linalg.norm(amp)), float(np.linalg.norm(load))
    back = -float(amp @ load) / max(size * held, 1e-300)
    return back >= cosine and size <= overshoot * held


def partial_return(step: np.ndarray, total: np.ndarray, reread_MPa: float, away: float = AWAY_Z) -> bool:
    """Are the pressures after the change within the sensors' new readings of a point between
    the loaded ones and the baseline, and not further out along the load than they reach
    (module docstring)?"""
    var = np.full(len(step), reread_MPa**2)
    d, t = whiten(step, var), whiten(total, var)
    held = float(t @ t)
    a = float(np.clip(-(d @ t) / max(held, 1e-300), 0.0, 1.0))
    miss = d + a * t
    if float(miss @ miss) > chi2_99(len(step) - 1):  # the common mode removed: one degree fewer
        return False
    # Any change within the new readings' reach of the loaded point passes the bound, whatever its
    # direction (under 1.7 kPa on four chambers): its direction decides.  A share of the new
    # readings points away from the baseline (their component along the load has unit spread
    # here); further out than that is another weight on the load.
    return float(d @ t) <= away * math.sqrt(held)


def force_at_zero(model: SensingModel, x: Inputs2, z: float) -> bool:
    """Does the model read the pressures ``x.P_load`` against ``x.P0`` as no load: every load
    quantity it reports within ``z`` standard errors of zero (and at least one reported)?"""
    values, se, flags = evaluate(model, x)
    seen = False
    for q, kind, v, s in zip(model.quantities, model.kinds, values, se, strict=True):
        if kind != LOAD or f"{UNOBSERVABLE}:{q}" in flags or not np.isfinite(v):
            continue
        seen = True
        if abs(float(v)) > z * float(s):
            return False
    return seen


def slides_back(moved: np.ndarray, came: np.ndarray, loaded: np.ndarray, noise: float, cosine: float) -> bool:
    """Do the joints, at a change on a load that did not move them, slide on the way they came
    into its baseline (module docstring)?  ``moved``: the joints' settled change (rad), ``came``:
    their motion into the baseline, ``loaded``: the load's own deflection of them, ``noise``: a
    reading's standard deviation (rad).  The load left them within ``MOVED_Z`` of it (friction
    held the arm); they moved beyond that, within ``cosine`` of the way they came."""
    size, way = float(np.linalg.norm(moved)), float(np.linalg.norm(came))
    if float(np.linalg.norm(loaded)) > MOVED_Z * noise or size <= MOVED_Z * noise or way <= 0.0:
        return False
    return float(moved @ came) >= cosine * size * way


def is_release(
    step: np.ndarray, total: np.ndarray, var: np.ndarray, config: EstimatorConfig, at_zero: Callable[[], bool]
) -> bool:
    """Three of the four readings (module docstring; the joints' slide is ``Estimator._slid_back``),
    the pressures' first; ``at_zero`` asks the model (:func:`force_at_zero`) only when they do not
    say.  Its standard errors include the fit plan's direction term (routes.held_out_variances),
    which widens the band of forces read as none."""
    c = config
    if points_back(step, total, var, c.release_cosine, c.release_overshoot):
        return True
    if c.reread_MPa > 0 and partial_return(step, total, c.reread_MPa):
        return True
    return c.release_force_se > 0 and at_zero()
