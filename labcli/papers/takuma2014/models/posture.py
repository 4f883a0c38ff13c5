"""The posture-aware force model: torques at the arm's true posture, forces by (J^T)^-1, with errors.

Eqs. 34-37 evaluate the Jacobian at the deflection theta, as if the arm rested straight; a real
arm rests at some posture theta0 (the potentiometers at the trial's baseline), and on a straight
arm (det J = h2 h3 sin theta2 = 0) a force along the arm makes no torque at all.  This form
regresses the load's joint torques and maps them to a force at the estimated posture::

    tau = J(theta0 + dtheta)^T F                       (the load's generalised force, N m)
    tau_k = sum_j a_kj dP_j + sum_j,l b_kjl dP_j dtheta_l + sum_l g_kl dtheta_l      (k = 1, 2)
    F = (J(theta0 + dtheta)^T)^-1 tau                  (Eq. 14, at the true posture)

Derivation (Eqs. 16-33).  Each tendon pulls with f_ij on a path of length s_ij(theta); the
actuators' joint torques are sum_ij f_ij ds_ij/dtheta (Eqs. 15-19 are this with the paper's
moment arms m_ij = ds_ij/dtheta).  In equilibrium before and after the load,
J^T F = -(sum f_ij(P) m_ij(theta) - sum f_ij(P0) m_ij(theta0)), so

    J^T F = -sum m_ij(theta) (f_ij - f_ij0) - sum (m_ij(theta) - m_ij(theta0)) f_ij0.

Eqs. 20-29 make the tension change linear in the pressure drop, f_ij - f_ij0 = k_ij (beta_ij -
dl_ij0) dP_ij (the paper's beta_F).  Expanding the moment arms about the rest posture,
m_ij(theta) = m_ij(theta0) + dm_ij/dtheta dtheta, gives the three groups above: dP_j alone (the
paper's terms, with the moment arms at theta0 instead of the paper's cos-products at dtheta), dP_j
dtheta_l (the moment arms turning with the deflection), and dtheta_l alone (the rest tensions
f_ij0 on the changed moment arms; the links' weight on the changed lever adds to the same term).
No intercept: no load, no torque.  Of these 14 terms the fit keeps the pressure drops and those
others that cut the two torques' cross-validated error by CV_MIN_GAIN (select_torque_terms): the
products carry small moment-arm changes, and fitted on 90 trials all of them take in friction's
hysteresis instead.  The regression is on the torques, not the forces, because the
torques are what the pressures see: near theta2 = 0 a force along the arm gives none, and the
force's uncertainty (below) says so instead of a fixed cut.  Regressing J^T F with the load's
sign also settles the sign question of Eq. 14 (docs/errata.md).

Angles: the deflection dtheta_k is linear in u_ij = P_ij0 / P_ij - 1 (Eqs. 30-31 with sin
dropped, Eq. 29's Boyle relation), plus the quadratic terms u_i u_j the data support: forward
selection on the cross-validated error of both angle equations (the same terms in both; this
deflection feeds the forces).  The theta1 reported has its own equation, grown the same way from
Eq. 34's terms (THETA1_BASE).

Routes.  The paper's Eqs. 34-37 are fitted beside on the same fit trials, and each quantity
takes this form, the paper's, or a weighted blend of both, whichever predicts held-out blocks of
fit trials best (models/routes.py); the validation trials never enter that choice.

Uncertainty.  Both torque equations share one design X, so the coefficients' covariance is
S_tau (x) (X^T X)^-1 with S_tau the 2x2 residual covariance (from leave-one-trial-out
residuals when that is the larger: a fit partly absorbs a trial's friction error; the angles'
from held-out blocks of trials); a new trial's torque error has
covariance (1 + x^T (X^T X)^-1 x) S_tau (coefficients and residual), and likewise its angle.
The force is the posterior mean given the torques and a Gaussian prior on F whose spread is
the fit loads' RMS per component: where J^T is well conditioned this is (J^T)^-1 tau, and along a
straight arm, where the torques say nothing, it falls back to the prior (0 +- the load spread)
instead of blowing up.  Its covariance is the posterior's, (J S^-1 J^T + Lambda)^-1, plus
G Sigma_dtheta G^T with G = dF / d(dtheta) through both the Jacobian and the torque's dtheta terms
(numerically).  A trial's
estimate is flagged when this standard error exceeds the protocol's ``[sensing]`` limit.  The
interval then adds what these residuals cannot show, the error at a load direction the fit never
used (``held_out_variance``, measured by the route choice's folds: models/routes.py); it widens the
interval and leaves the estimate and its flags as they are.

Units: pressures MPa, angles rad, torques N m, forces N.
"""

from __future__ import annotations

import functools
import itertools
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, NoReturn

import numpy as np

from ....core import idranges
from ....core.arrays import rows_all, stack_columns
from ....core.jsontext import dumps_indented
from ....core.nogc import paused_gc
from ....errors import ModelError
from . import routes as rt
from .calibrated import baseline_dict, calibrated_range, captures_dict, check_baseline, check_captures, check_range
from .geometry import jacobian
from .history import motion_from, motion_into_baseline, previous_rows, rows_of
from .labels import apply_play, fitted_play
from .paper_folds import fold_models
from .takuma import (
    ANGLE_COLUMNS,
    BASELINE_COLUMNS,
    FORCE_COLUMNS,
    LOADED_COLUMNS,
    MAX_COEFFICIENT,
    QR_ROWS,
    SCHEMA,
    SCHEMA_VERSION,
    TakumaModel,
    _clean,
    cap,
    check_label_play,
    labels_from_dict,
    normalise_geometry,
    pressure_arrays,
    qr_r,
    set_mask,
)

FORM = "posture"
REST_COLUMNS = ("theta1_0_deg", "theta2_0_deg")
ACTUATORS = ("L1", "R1", "L2", "R2")
ANGLE_LINEAR = tuple(f"u_{a}" for a in ACTUATORS)
ANGLE_QUADRATIC = tuple(f"u_{ACTUATORS[i]}*u_{ACTUATORS[j]}" for i in range(4) for j in range(i, 4))
TORQUE_TERMS = (
    tuple(f"dP_{a}" for a in ACTUATORS)
    + tuple(f"dP_{a}*dtheta{j}" for a in ACTUATORS for j in (1, 2))
    + ("dtheta1", "dtheta2")
)
# Sleeve friction's share of the load torque (PostureModel(friction=True), :func:`friction_columns`):
# one term per actuator pair, offered to the torque fit beside TORQUE_TERMS.
FRICTION_TERMS = ("friction1", "friction2")
# The same friction on a run whose baselines are all approached from one side (the protocol's
# friction relief by venting, ``acquisition.friction_relief_vent_s``; PostureModel(friction=
# "relieved"), :func:`relieved_columns`): per pair the sign of its motion under the load, and one
# constant, the friction every baseline keeps.
RELIEVED_TERMS = ("friction1_load", "friction2_load", "friction_rest")
KNOWN_TORQUE_TERMS = TORQUE_TERMS + FRICTION_TERMS + RELIEVED_TERMS
FRICTION_MODES = (False, True, "relieved")  # PostureModel(friction=...): none, from the history, relieved
# On a relieved run every baseline is the same posture on the same regulated air, so a trial's P0
# may be the mean of its own baseline and the ones before it (PostureModel(baseline_mean=k),
# :func:`running_baseline`): the pressure sensors' repeatability, a fresh error in each reading,
# averages out of P0.  Chosen on seeds 1-10 of the literature's rig (3, 5 and 10 tried).
RELIEVED_BASELINES = 5
# A motion this large (rad) is a motion: the friction's sign follows it; below it tanh fades the
# term out, where the pots' play (0.2 deg) and the angle estimate's error hide its direction.
FRICTION_MOTION_RAD = math.radians(0.1)
# Standard errors above these flag an estimate (the protocol's [sensing] keys override them):
# 1 N tells the plan's 50-1000 g loads (0.5-9.8 N) apart by about 2 N at 95 %; 0.5 deg is several
# times the potentiometers' backlash.
DEFAULT_LIMITS = {"theta1": math.radians(0.5), "theta2": math.radians(0.5), "Fx": 1.0, "Fy": 1.0}


def limits_from_protocol(protocol: Any) -> dict[str, float]:
    """The standard-error limits (rad, N) of a protocol's ``[sensing]`` table, defaults elsewhere."""
    s = getattr(getattr(protocol, "settings", None), "sensing", None) or {}
    out = dict(DEFAULT_LIMITS)
    if "max_angle_se_deg" in s:
        out["theta1"] = out["theta2"] = math.radians(float(s["max_angle_se_deg"]))
    if "max_force_se_N" in s:
        out["Fx"] = out["Fy"] = float(s["max_force_se_N"])
    return out


# --------------------------------------------------------------------------- features


def angle_features(P0: np.ndarray, P: np.ndarray, terms: tuple[str, ...]) -> np.ndarray:
    """Columns ``terms`` (names from ANGLE_LINEAR + ANGLE_QUADRATIC) of u = P0/P - 1, (n, len(terms))."""
    u = np.asarray(P0, dtype=float) / np.asarray(P, dtype=float) - 1.0
    idx = {a: k for k, a in enumerate(ACTUATORS)}
    cols = []
    for t in terms:
        parts = [p[2:] for p in t.split("*")]
        cols.append(np.prod([u[:, idx[p]] for p in parts], axis=0))
    return stack_columns(cols) if cols else np.empty((len(u), 0))


def torque_features(
    dP: np.ndarray,
    dtheta: np.ndarray,
    terms: tuple[str, ...] = TORQUE_TERMS,
    motion_in: np.ndarray | None = None,
    motion_sd: np.ndarray | None = None,
    made: np.ndarray | None = None,
) -> np.ndarray:
    """Columns ``terms`` (default all 14 of TORQUE_TERMS; FRICTION_TERMS too) from pressure drops
    (n, 4) MPa and deflections (n, 2) rad; ``motion_in`` (n, 2) rad, the joints' motion into the
    baseline, for the friction terms (:func:`friction_columns`; None: unknown), ``motion_sd`` (2,)
    rad the standard error of the pairs' motions when they are estimated.  ``made``: the columns
    of the one friction family ``terms`` offers, made already (:func:`friction_family`), for a
    design built block by block, which would otherwise make them again in every block."""
    dP = np.atleast_2d(dP)
    dtheta = np.atleast_2d(dtheta)
    wants = any(t in FRICTION_TERMS for t in terms), any(t in RELIEVED_TERMS for t in terms)
    if made is not None and all(wants):
        raise ValueError("made columns stand for one friction family; these terms offer both")
    friction = (friction_columns(dtheta, motion_in, motion_sd) if made is None else made) if wants[0] else None
    relieved = (relieved_columns(dtheta, motion_sd) if made is None else made) if wants[1] else None
    # Only the terms asked for, each written into its own column (Fortran order: every write is
    # contiguous); at the validation's 10^6 rows the stack of all fourteen and a copy of the
    # chosen ones took a second.
    out = np.empty((len(dP), len(terms)), order="F", dtype=np.result_type(dP, dtheta, float))
    for k, term in enumerate(terms):
        at = KNOWN_TORQUE_TERMS.index(term)
        if at < 4:  # a pressure drop
            out[:, k] = dP[:, at]
        elif at < 12:  # a pressure drop times a deflection, in TORQUE_TERMS' order
            np.multiply(dP[:, (at - 4) // 2], dtheta[:, (at - 4) % 2], out=out[:, k])
        elif at < 14:  # a deflection
            out[:, k] = dtheta[:, at - 12]
        elif at < 16:  # a friction term read from the history of loads
            assert friction is not None
            out[:, k] = friction[:, at - 14]
        else:  # a relieved run's friction term
            assert relieved is not None
            out[:, k] = relieved[:, at - 16]
    return out


def friction_family(friction: bool | str, dtheta: np.ndarray, motion_in: np.ndarray | None) -> np.ndarray | None:
    """The columns of the friction terms a fit offers (PostureModel(friction=...)): FRICTION_TERMS'
    (n, 2) from the measured deflections and motions into the baselines, RELIEVED_TERMS' (n, 3), or None."""
    if friction is True:
        return friction_columns(dtheta, motion_in)
    return relieved_columns(dtheta) if friction == "relieved" else None


def pair_motion(dtheta: np.ndarray) -> np.ndarray:
    """How far each actuator pair's tendons move for a joint motion (n, 2) rad, in units of its
    pulley radius: the outside pair spans the bottom joint only, the inside pair both (Eqs. 4-7:
    its path changes by r2 (dtheta1 + dtheta2))."""
    d = np.atleast_2d(np.asarray(dtheta, dtype=float))
    return stack_columns([d[:, 0], d[:, 0] + d[:, 1]])


def friction_width(motion_sd: Any = None) -> np.ndarray:
    """Each pair's fade sqrt(2 (sd^2 + FRICTION_MOTION_RAD^2)) rad of :func:`friction_columns`' faded
    signs, ``motion_sd`` the pairs' motions' standard errors (None: measured, 0)."""
    return np.sqrt(
        2.0 * (np.asarray(0.0 if motion_sd is None else motion_sd, dtype=float) ** 2 + FRICTION_MOTION_RAD**2)
    )


def friction_columns(
    dtheta: np.ndarray, motion_in: np.ndarray | None = None, motion_sd: np.ndarray | None = None
) -> np.ndarray:
    """The friction terms (n, 2): per pair, the sign of its motion under the load less the sign of
    its motion into the baseline, each faded in over FRICTION_MOTION_RAD.

    A sleeve's Coulomb friction (a share of its pressure force, Tondu & Lopez 2000) opposes the
    actuator's motion, and an arm that moved stops with it at its limit: under the load it holds
    against the deflection, at the baseline against the motion that brought the arm back from
    the previous load.  The pressures see the tension less that friction, so the load torque is the
    pressures' torque plus a pair's friction torque times (sign now - sign before).  The
    magnitude (about the share times the pressure force times the pulley radius) is the term's
    coefficient, fitted; an arm that did not move leaves the term near 0, friction unknown.

    Where the motions are estimated from the pressures (``motion_sd``, the pairs' standard
    errors), a sign is as likely wrong as the estimate is uncertain: each sign is replaced by its
    expectation, erf(m / sqrt(2 (sd^2 + fade^2))), the fade FRICTION_MOTION_RAD standing in for tanh's.
    """
    from scipy.special import erf

    width = friction_width(motion_sd)

    def sign(m: np.ndarray) -> np.ndarray:
        return erf(np.nan_to_num(pair_motion(m), nan=0.0) / width)

    now = sign(dtheta)
    return now if motion_in is None else now - sign(motion_in)


def friction_slopes(dtheta: np.ndarray, motion_sd: np.ndarray | None = None) -> np.ndarray:
    """d/dm of each pair's faded sign erf(m / width) of :func:`friction_columns` at its motion m (n, 2)."""
    width = friction_width(motion_sd)
    z = np.nan_to_num(pair_motion(dtheta), nan=0.0) / width
    return 2.0 / math.sqrt(math.pi) * np.exp(-(z**2)) / width


def relieved_columns(dtheta: np.ndarray, motion_sd: np.ndarray | None = None) -> np.ndarray:
    """The relieved run's friction terms (n, 3): per pair the sign of its motion under the load
    (faded in as in :func:`friction_columns`), and 1.

    Vented before each baseline, the sleeves lose their friction (it is a share of the pressure
    force); supplied again, the arm rises from the same vented posture every time and stops short
    of its rest on that side.  Each pair then keeps at its baseline the same friction, in the same
    direction, whatever the last load was: the term ``sign(now) - sign(before)`` of
    :func:`friction_columns` becomes ``sign(now)`` plus a constant.  A load along the approach
    moves the arm at once and the pressures read it whole; a load against it must first undo the
    friction held and then overcome its own, and reads two frictions short.  The constant is that
    baseline friction; an arm that did not move (a load within that band) is given its middle.
    """
    now = friction_columns(dtheta, None, motion_sd)
    return stack_columns([now, np.ones(len(now))])


def running_baseline(trial: np.ndarray, P0: np.ndarray, k: int) -> np.ndarray:
    """Each trial's P0 (n, 4) as the mean of its own baseline and the ``k - 1`` before it (in trial
    id order, those in the table), each chamber over the readings it has."""
    trial = np.asarray(trial)
    order = np.argsort(trial, kind="stable")
    p = np.asarray(P0, dtype=float)[order]
    known = np.isfinite(p)
    csum, ccount = np.cumsum(np.where(known, p, 0.0), axis=0), np.cumsum(known, axis=0)
    total, count = csum.copy(), ccount.copy()
    lag = np.arange(len(p)) - k
    before = lag >= 0
    total[before] -= csum[lag[before]]
    count[before] -= ccount[lag[before]]
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = np.where(known, total / np.maximum(count, 1), np.nan)
    out = np.empty_like(mean)
    out[order] = mean
    return out


def load_torque(theta: np.ndarray, F: np.ndarray, h2: float, h3: float) -> np.ndarray:
    """tau = J(theta)^T F (n, 2) in N m for absolute angles theta (n, 2) rad and forces (n, 2) N."""
    J = jacobian(theta[:, 0], theta[:, 1], h2, h3)
    return np.einsum("nij,ni->nj", J, F)


def inv_spd_2x2(M: np.ndarray) -> np.ndarray:
    """The pseudo-inverse of symmetric positive semi-definite 2 x 2 matrices (n, 2, 2): the adjugate
    over the determinant where that is well conditioned (the force posterior's prior and torque
    noise make it so), ``np.linalg.pinv(hermitian=True)`` for the rest.  The run-time estimator
    calls the model once a block; an eigendecomposition per call was a fifth of that call."""
    a, b, d = M[:, 0, 0], 0.5 * (M[:, 0, 1] + M[:, 1, 0]), M[:, 1, 1]
    det = a * d - b * b
    good = (det > INV_2X2_RCOND * a * d) & (a > 0) & (d > 0)
    with np.errstate(divide="ignore", invalid="ignore"):
        out = np.stack([np.stack([d, -b], axis=-1), np.stack([-b, a], axis=-1)], axis=-2) / det[:, None, None]
    if not good.all():
        out[~good] = np.linalg.pinv(M[~good], hermitian=True)
    return out


INV_2X2_RCOND = 1e-6  # det / (a d) below this (a condition number beyond ~4e6): the pseudo-inverse


def einsum_2x2(spec: str, *operands: np.ndarray) -> np.ndarray:
    """``np.einsum(spec, *operands)`` for the force posterior's per-trial 2 x 2 products, term by term.

    ``n`` indexes the trials (the first index of an operand that has it); every other index runs
    over 0, 1.  Each output element is the sum over the other indices in index order, each term
    the operands' product left to right: einsum's own arithmetic, whose loop order (and so the
    last bit) varies with the operands' layout; tests/papers/takuma2014/test_fit_equivalence.py
    holds the two to rounding and the fits' routes to the same choices.  numpy's general loop
    took a second over the 200,000 predictions of an archive's validation, a column product per
    term a tenth of that.  For a few rows (the run-time estimator's, a dozen calls per estimate)
    every term of every output element is gathered at once (:func:`_plan_2x2`) and multiplied
    and summed in the same order: a dozen whole-array steps instead of a hundred.
    """
    subs, shape, gathers = _plan_2x2(spec)
    n = next(op.shape[0] for sub, op in zip(subs, operands, strict=True) if sub.startswith("n"))
    flats = [
        np.asarray(op, dtype=float).reshape((n, -1) if sub.startswith("n") else (1, -1))
        for sub, op in zip(subs, operands, strict=True)
    ]
    if n > GATHER_ROWS:  # many trials: one element at a time, each term a column product
        out = np.empty((n, len(gathers[0])))
        for o in range(out.shape[1]):
            total = None
            for t in range(gathers[0].shape[1]):
                term = None
                for flat, idx in zip(flats, gathers, strict=True):
                    factor = flat[:, idx[o, t]]
                    term = factor if term is None else term * factor
                total = term if total is None else total + term
            out[:, o] = total
        return out.reshape((n, *shape))
    factors = [flat[:, idx] for flat, idx in zip(flats, gathers, strict=True)]  # (n or 1, outputs, terms)
    term = factors[0]
    for f in factors[1:]:
        term = term * f
    summed = term[:, :, 0]
    for j in range(1, term.shape[2]):
        summed = summed + term[:, :, j]
    return np.broadcast_to(summed, (n, summed.shape[1])).reshape((n, *shape)).copy()


FORCE_STEP = 1e-6  # rad: the central differences' step for dF / d(dtheta) where it is not in closed form
GATHER_ROWS = 256  # up to this many trials every term is gathered at once; beyond, column by column


@functools.cache
def _plan_2x2(spec: str) -> tuple[tuple[str, ...], tuple[int, ...], tuple[np.ndarray, ...]]:
    """For :func:`einsum_2x2`: the operands' subscripts, the output's 2 x 2 shape, and per operand
    the flat index (its trial axis left out) of each output element's terms, (outputs, terms)."""
    inputs, output = spec.split("->")
    subs = tuple(inputs.split(","))
    if any("n" in sub[1:] for sub in subs) or "n" in output[1:] or not output.startswith("n"):
        raise ValueError(f"einsum_2x2 takes the trial index n first, got {spec!r}")
    summed = sorted(set("".join(subs)) - set(output) - {"n"})
    free = [c for c in output if c != "n"]
    gathers = []
    for sub in subs:
        axes = [c for c in sub if c != "n"]
        rows = []
        for values in itertools.product((0, 1), repeat=len(free)):
            row = []
            for more in itertools.product((0, 1), repeat=len(summed)):
                at = dict(zip(free, values, strict=True)) | dict(zip(summed, more, strict=True))
                row.append(sum(at[c] << (len(axes) - 1 - k) for k, c in enumerate(axes)))
            rows.append(row)
        gathers.append(np.array(rows, dtype=np.intp))
    return subs, (2,) * len(free), tuple(gathers)


def force_from_torque(theta: np.ndarray, tau: np.ndarray, h2: float, h3: float) -> np.ndarray:
    """F = (J(theta)^T)^-1 tau (n, 2) in N; a straight arm (det J = 0) gets the least-norm force."""
    JT = np.swapaxes(jacobian(theta[:, 0], theta[:, 1], h2, h3), 1, 2)
    return np.einsum("nij,nj->ni", np.linalg.pinv(JT), tau)


# --------------------------------------------------------------------------- least squares

CV_FOLDS = rt.CV_FOLDS  # the folds of the route choice: one plan stretch each
# A quadratic term is kept only if it cuts the cross-validated error by this share: on the
# simulated rig smaller gains in the fit set turned into losses on new directions.
CV_MIN_GAIN = 0.10


@dataclass
class _Shared:
    """Least squares of several responses on one design: coefficients, (X^T X)^-1, residual covariance."""

    beta: np.ndarray  # (p, k)
    xtx_inv: np.ndarray  # (p, p)
    resid_cov: np.ndarray  # (k, k)
    dof: int


@dataclass
class _Blocks:
    """The R factors of [X | Y] over contiguous blocks of trials (the cross-validation's folds).

    Each block's rows are X_f | Y_f = Q_f R_f with Q_f orthonormal, so a least squares on any
    union of blocks and any subset of X's columns has the solution, singular values and
    residual norms of the same least squares on the stacked R's (at most p + k rows each):
    the trials are read once, and no copy of the design as large as the table is ever made.
    """

    factors: list[np.ndarray]  # one (<= p + k, p + k) R per block
    p: int  # columns of X; Y is the last k columns
    n: int  # trials
    width: int  # p + k
    rows: Any = None  # rows(lo, hi): the rows again, for leave-one-out residuals
    _folds: tuple[np.ndarray, np.ndarray, np.ndarray] | None = field(default=None, repr=False)

    @classmethod
    def build(cls, n: int, p: int, block: Any) -> _Blocks:
        """``block(lo, hi)`` gives the rows lo..hi of [X | Y]; blocks are contiguous (a plan groups
        its trials by pulley position), as many as CV_FOLDS."""
        edges = np.linspace(0, n, min(CV_FOLDS, n) + 1).astype(int)

        def factor(lo: int, hi: int) -> np.ndarray:
            # A long block is built and factored QR_ROWS rows at a time, as qr_r would factor it
            # whole (the same R), but its columns are made while those rows are in cache.
            if hi - lo <= 2 * QR_ROWS:
                return qr_r(block(lo, hi))
            return qr_r(np.vstack([qr_r(block(a, min(a + QR_ROWS, hi))) for a in range(lo, hi, QR_ROWS)]))

        factors = [factor(lo, hi) for lo, hi in zip(edges[:-1], edges[1:], strict=False)]
        return cls(factors, p, n, factors[0].shape[1] if factors else p, block)

    def responses(self, ys: list[int] | None = None) -> list[int]:
        """The columns of the responses: ``ys`` or all of Y."""
        return list(range(self.p, self.width)) if ys is None else list(ys)

    def folds(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Per fold f, zero-padded to (folds, p + k, p + k): the R of every other block's rows (the
        fold's training set), the block's own R (its held-out trials), and the training rows' count.

        Computed once: the term selection scores dozens of column subsets on the same folds, and a
        subset's least squares on the training R's columns is the one on the training trials
        (zero rows add nothing).
        """
        if self._folds is None:
            k, w = len(self.factors), self.width
            train, held, rows = np.zeros((k, w, w)), np.zeros((k, w, w)), np.zeros(k, dtype=np.int64)
            for f, r in enumerate(self.factors):
                stacked = np.vstack([g for i, g in enumerate(self.factors) if i != f])
                t = qr_r(stacked)
                train[f, : len(t)], held[f, : len(r)], rows[f] = t, r, len(stacked)
            self._folds = (train, held, rows)
        return self._folds

    def cv_cov(self, xs: list[int], ys: list[int] | None = None) -> np.ndarray:
        """Summed outer product of the held-out residuals, (k, k): each block predicted by a fit on the others.

        Every fold at once: the training least squares by the SVD of the fold's training R
        (``numpy.linalg.lstsq``'s own method and cut-off for small singular values, on the
        matrix it would have reduced to), the held-out residuals from the block's R.
        """
        ys = self.responses(ys)
        train, held, rows = self.folds()
        U, s, Vt = np.linalg.svd(train[:, :, xs], full_matrices=False)
        # lstsq (rcond=None) takes singular values below eps * max(rows, columns) * the largest as 0.
        keep = s > np.finfo(float).eps * np.maximum(rows, len(xs))[:, None] * s[:, :1]
        inv = np.divide(1.0, s, out=np.zeros_like(s), where=keep)
        beta = np.swapaxes(Vt, 1, 2) @ (inv[:, :, None] * (np.swapaxes(U, 1, 2) @ train[:, :, ys]))
        e = held[:, :, ys] - held[:, :, xs] @ beta
        return np.einsum("fwi,fwj->ij", e, e)

    def cv_error(self, xs: list[int], ys: list[int] | None = None) -> float:
        """Summed squared held-out error of the contiguous-block cross-validation."""
        return float(np.trace(self.cv_cov(xs, ys)))

    def loo_cov(self, xs: list[int], ys: list[int] | None, beta: np.ndarray, xtx_inv: np.ndarray) -> np.ndarray:
        """Summed outer product of the leave-one-trial-out residuals of the fit ``beta``, (k, k),
        block by block from the rows again (no copy of the whole design)."""
        ys = self.responses(ys)
        edges = np.linspace(0, self.n, len(self.factors) + 1).astype(int)
        out = np.zeros((len(ys), len(ys)))
        for lo, hi in zip(edges[:-1], edges[1:], strict=False):
            z = self.rows(lo, hi)
            loo = loo_residuals(z[:, xs], z[:, ys] - z[:, xs] @ beta, xtx_inv)
            out += loo.T @ loo
        return out

    def whole(self) -> np.ndarray:
        """One R of all the trials' [X | Y]."""
        return qr_r(np.vstack(self.factors))


def _shared_lstsq(
    blocks: _Blocks, xs: list[int], what: str, by_trial: bool = False, ys: list[int] | None = None
) -> _Shared:
    """Least squares of Y (or its columns ``ys``) on the columns ``xs`` of X, from the blocks' R factors."""
    n, p = blocks.n, len(xs)
    if n <= p:
        raise ModelError(
            f"The posture form's {what} fit needs more than {p} usable fit trials, got {n}; "
            "record more fit trials, or fit the paper's Eqs. 34-37 with --form paper."
        )
    R = blocks.whole()
    X, Y = R[:, xs], R[:, blocks.responses(ys)]
    scale = np.linalg.norm(X, axis=0)  # the columns' norms over the trials: Q keeps lengths
    if not np.all(scale > 0):
        raise ModelError(
            f"The {what} fit has a term that is zero in every fit trial; record fit trials that load every actuator."
        )
    U, s, Vt = np.linalg.svd(X / scale, full_matrices=False)
    if not s[-1] > s[0] * 1e-12:
        raise ModelError(f"The {what} design matrix is singular; record fit trials with more varied force directions.")
    beta = (Vt.T @ ((U.T @ Y) / s[:, None])) / scale[:, None]
    resid = Y - X @ beta  # the residuals' Gram matrix, the trials' own through Q
    dof = n - p
    xtx_inv = ((Vt.T / s**2) @ Vt) / np.outer(scale, scale)
    # The residual covariance from held-out residuals when that is larger than the in-sample
    # one: friction's hysteresis and the pots' play leave errors a trial's own fit partly
    # absorbs.  Divided by 1 + p/n because prediction adds the coefficients' share (1 + h)
    # again.  Held out by contiguous blocks (one pulley position each) for the angles, whose
    # error follows the pots' play and so the load's direction; by single trials
    # (``by_trial``) for the torques: leaving a block out asks for a direction 36 deg from the
    # nearest fitted one, while a plan checks loads between fitted directions, and on the
    # bent protocol that put Fx's and Fy's 95 % intervals at 99-100 % coverage and Fy's
    # standard error over the 1 N limit on nearly every trial (tests/benchmarks/sensing_accuracy.py).
    held = blocks.loo_cov(xs, ys, beta, xtx_inv) if by_trial else blocks.cv_cov(xs, ys)
    held_out = held / n / (1.0 + p / n)
    in_sample = resid.T @ resid / dof
    return _Shared(beta, xtx_inv, held_out if np.trace(held_out) > np.trace(in_sample) else in_sample, dof)


def loo_residuals(X: np.ndarray, resid: np.ndarray, xtx_inv: np.ndarray) -> np.ndarray:
    """Leave-one-out residuals e_i / (1 - h_ii) of a least-squares fit (PRESS), without refitting.

    ``X`` (n, p) the design, ``resid`` (n, k) its in-sample residuals, ``xtx_inv`` = (X^T X)^-1.
    Equal to the residual of trial i under the fit without trial i (Sherman-Morrison).
    """
    h = np.einsum("ni,ij,nj->n", X, xtx_inv, X)
    return resid / np.clip(1.0 - h, 1e-12, None)[:, None]


ANGLE_TERMS = ANGLE_LINEAR + ANGLE_QUADRATIC


def angle_blocks(P0: np.ndarray, P: np.ndarray, dtheta: np.ndarray) -> _Blocks:
    """The blocks of [every angle term | dtheta] (ANGLE_TERMS, then the two deflections)."""
    return _Blocks.build(
        len(P),
        len(ANGLE_TERMS),
        lambda lo, hi: stack_columns([angle_features(P0[lo:hi], P[lo:hi], ANGLE_TERMS), dtheta[lo:hi]]),
    )


def select_angle_terms(
    blocks: _Blocks, base: tuple[str, ...] = ANGLE_LINEAR, ys: list[int] | None = None
) -> tuple[str, ...]:
    """The ``base`` terms and the others that lower the cross-validated error, added greedily.

    ``ys``: the deflections the terms must predict together (default both).  Cross-validation over
    contiguous blocks of trials (a plan groups its trials by pulley position) asks whether a
    term predicts directions it was not fitted on; BIC, which trusts the residual to be
    independent noise, takes in terms that fit friction's hysteresis.
    """
    index = {t: k for k, t in enumerate(ANGLE_TERMS)}
    return _grow(base, ANGLE_TERMS, lambda terms: blocks.cv_error([index[t] for t in terms], ys), blocks.n)


# The torque fit starts from the pressure drops (the paper's own terms, Eqs. 36-37); their
# products with the deflection and the deflection alone enter where the held-out error says they
# predict (the same rule as the angles' quadratic terms).  All 14 of the derivation's terms,
# fitted on 90 trials, let friction's hysteresis into the product coefficients.  Chosen on rig
# seeds 1-10; on the held-out seeds 11-30 the bent arm's Fx RMSE is 0.222 N [0.186, 0.272] with
# all of them and 0.171 N [0.159, 0.184] with those grown this way (95 % intervals over seeds;
# tests/benchmarks/heldout_choices.py terms).
TORQUE_BASE = TORQUE_TERMS[:4]


def select_torque_terms(blocks: _Blocks, names: tuple[str, ...] = TORQUE_TERMS) -> tuple[str, ...]:
    """The pressure drops and the other torque terms that lower the held-out error, added greedily.

    Both torques share one design, so a term is judged by the two torques' held-out errors
    together, each relative to its error with the pressure drops alone: the sum does not depend
    on their units, and tau1's lever is longer than tau2's.
    """

    def held_out(terms: tuple[str, ...] | list[str]) -> np.ndarray:
        return np.diag(blocks.cv_cov([names.index(t) for t in terms]))

    if len(TORQUE_BASE) >= _room(blocks.n):
        return TORQUE_BASE  # too few trials to judge any term (the fit itself says so)
    base = held_out(TORQUE_BASE)
    if not np.all(base > 0):
        return TORQUE_BASE  # the pressure drops already predict exactly
    return _grow(TORQUE_BASE, names, lambda terms: float(np.sum(held_out(terms) / base)), blocks.n)


def _room(n: int) -> int:
    """How many terms a cross-validation on ``n`` trials can judge: fewer than any fold's fit keeps."""
    return n - int(math.ceil(n / min(CV_FOLDS, max(n, 1)))) - 1


def _grow(base: tuple[str, ...], names: tuple[str, ...], score: Any, n: int) -> tuple[str, ...]:
    """Forward selection: add the name that lowers ``score(terms)`` most while it cuts it by CV_MIN_GAIN.

    ``n`` trials: a term is offered only while every cross-validation fit (without its largest
    block) keeps more trials than terms, so that no score comes from an underdetermined fit.
    """
    terms, room = list(base), _room(n)
    if len(terms) >= room:
        return tuple(terms)
    best = score(terms)
    pool = [t for t in names if t not in terms]
    while pool and len(terms) < room:
        value, term = min((score(terms + [t]), t) for t in pool)
        if not value < (1.0 - CV_MIN_GAIN) * best:
            break
        best = value
        terms.append(term)
        pool.remove(term)
    return tuple(terms)


# The reported theta1 has its own equation, starting from Eq. 34's terms (the outside pair):
# the inside pair's pressures reach theta1 only through friction and the links' coupling and
# enter only where cross-validation says they predict it.  On the bent rig they did not: chosen
# on rig seeds 1-10, and on the held-out seeds 11-30 the posture form's theta1 RMSE is 0.153 deg
# [0.144, 0.162] with the shared terms against 0.147 [0.144, 0.150] with these two
# (tests/benchmarks/heldout_choices.py theta1).  The forces keep the deflection of the shared design:
# with it their standard errors stayed under the limit on more trials.
THETA1_BASE = ("u_L1", "u_R1")


# --------------------------------------------------------------------------- the model


@dataclass
class PostureModel:
    """Torques at the true posture, forces by (J^T)^-1, every estimate with its standard error.

    Example::

        model = PostureModel(geometry=protocol.settings.rig).fit(table)
        out = model.predict(P0, P, theta0)     # deflections, forces, standard errors, flags
    """

    geometry: dict[str, float]
    protocol: str = "takuma2014"
    limits: dict[str, float] = field(default_factory=lambda: dict(DEFAULT_LIMITS))
    angle_terms: tuple[str, ...] = ()
    angle_coefficients: list[list[float]] = field(default_factory=list)  # (p_a, 2)
    angle_xtx_inv: list[list[float]] = field(default_factory=list)
    angle_resid_cov: list[list[float]] = field(default_factory=list)
    # The torque terms kept (select_torque_terms); absent in older files: all 14 of TORQUE_TERMS.
    torque_terms: tuple[str, ...] = TORQUE_TERMS
    torque_coefficients: list[list[float]] = field(default_factory=list)  # (len(torque_terms), 2)
    torque_xtx_inv: list[list[float]] = field(default_factory=list)
    torque_resid_cov: list[list[float]] = field(default_factory=list)
    force_prior_sd: list[float] = field(default_factory=list)  # N, (Fx, Fy): the fit loads' RMS
    # The reported theta1's own equation (THETA1_BASE); absent in older files: the shared design's.
    theta1_terms: tuple[str, ...] = ()
    theta1_coefficients: list[float] = field(default_factory=list)
    theta1_xtx_inv: list[list[float]] = field(default_factory=list)
    theta1_resid_var: float = 0.0  # rad^2
    fit_stats: dict[str, Any] = field(default_factory=dict)
    fitted_trials: list[list[int]] = field(default_factory=list)  # [first, last] ranges (core.idranges)
    source: str = ""
    # Per quantity "posture", "paper" or "blend" (models/routes.py); absent means posture.  The
    # paper's Eqs. 34-37 fitted on the same trials, kept only when some quantity takes them, the
    # held-out squared error (rad^2, N^2) behind those quantities' standard errors, and each
    # blend's posture weight and error correlation.
    routes: dict[str, str] = field(default_factory=dict)
    paper_model: dict[str, Any] | None = None
    paper_variance: dict[str, float] = field(default_factory=dict)
    blends: dict[str, dict[str, float]] = field(default_factory=dict)
    # Per quantity the variance (rad^2, N^2) its standard errors lack at a load direction the fit
    # never used (routes.held_out_variances); absent in older files: none.
    held_out_variance: dict[str, float] = field(default_factory=dict)
    fitted_on: dict[str, Any] | None = None  # the run it was fitted on (labcli.core.provenance)
    # Offer the sleeves' friction terms to the torque fit: a fit option (FRICTION_MODES); True
    # offers FRICTION_TERMS (read from the history of loads), "relieved" RELIEVED_TERMS (a run
    # relieved by venting before each baseline).  The terms kept are in torque_terms like any other.
    friction: bool | str = False
    # How many relieved baselines make a trial's P0 (RELIEVED_BASELINES on a relieved run; 1: its own).
    baseline_mean: int = 1
    captures_per_load: int = 1  # captures each fit row averaged (.calibrated); its standard errors are such a mean's
    # The fit trials' span, and how their P0 was taken (models/calibrated.py, models/leak.py).
    calibrated_range: dict[str, list[list[float]]] = field(default_factory=dict)
    p0_leak_corrected: bool = False
    baseline_gap_s: float | None = None
    # The potentiometers' play, fitted as the paper's form fits it (models/labels.py): "fit" or
    # "loads" fit the form to the labels corrected by the play fitted that way, "none" to the
    # labels as read.
    label_play: str = "fit"
    play: dict[str, Any] = field(default_factory=dict)

    form = FORM

    def __post_init__(self) -> None:
        self.geometry = normalise_geometry(self.geometry)
        self.angle_terms = tuple(self.angle_terms)
        self.theta1_terms = tuple(self.theta1_terms)
        self.torque_terms = tuple(self.torque_terms)
        self._paper: TakumaModel | None = None

    @property
    def is_fitted(self) -> bool:
        return bool(self.torque_coefficients) and bool(self.angle_coefficients)

    # ---------------------------------------------------------------- fitting
    def fit(
        self, table: Any, source: str = "the trial table", choose_routes: bool = True, *, record_trials: bool = True
    ) -> PostureModel:
        """Least squares on the table's fit trials (``set == 'fit'``); returns self, fitted.

        ``choose_routes`` also fits the paper's Eqs. 34-37 and picks, per quantity, the posture
        form, the paper's or their blend by the cross-validated error on the fit trials
        (models/routes.py).  ``record_trials=False`` leaves ``fitted_trials`` empty: the route
        choice's cross-validation fits predict one block and are thrown away, and on a random
        split listing their trials was a tenth of the fit.
        """
        if self.friction not in FRICTION_MODES:
            raise ModelError(f"Unknown friction terms {self.friction!r}; use one of {FRICTION_MODES}.")
        check_label_play(self.label_play)
        # Which rows are fit trials, worked out once: the play's correction keeps every row and
        # its set, and each pass of set_mask over 10^6 trials' set names took 16-20 ms.
        fit_rows = set_mask(table, "fit", source)
        table = self._unplayed(table, source, fit_rows)
        self._fit_posture(table, source, record_trials, fit_rows)
        self.routes, self.paper_model, self.paper_variance, self.blends = {}, None, {}, {}
        self.held_out_variance = {}
        self._paper = None
        if choose_routes:
            # After the posture fit has returned: its arrays (a copy of the fit trials) are freed
            # before the paper's form reads them again (at 10^6 trials, 100 MB of the peak).
            self._choose_routes(table, source, fit_rows)
        return self

    def _unplayed(self, table: Any, source: str, fit_rows: np.ndarray | None = None) -> Any:
        """The table with its angle labels corrected for the potentiometers' play, fitted with the
        paper's Eqs. 34-35 designs exactly as that form fits it (models/labels.py), so that both
        forms learn the same deflections.  Play under-reads a deflection after a load the same way
        and least squares takes it as a smaller slope: the posture form fitted to the labels as read
        put the steel can's k at 0.44-0.45 of true on tuning seeds 1-2 (0.85-0.92 corrected).  Every
        label is corrected from its reading and the play's states alone, as the validation labels
        are (:func:`~.labels.apply_play`): the paper form's fit gives a reading that never left the
        play the pressures' own estimate, and fitted to those the posture form's residuals, and so
        its standard errors, came out too small (95 % intervals covering 61-83 % of the angles)."""
        self.play = {}
        if self.label_play == "none":
            return table
        probe = TakumaModel(geometry=self.geometry, protocol=self.protocol, label_play=self.label_play)
        probe._unplayed(table, set_mask(table, "fit", source) if fit_rows is None else fit_rows)
        self.play = probe.play
        fitted = fitted_play(self.play)  # the widths and the fit's own friction decision
        return table if fitted is None else apply_play(table, *fitted)

    def _fit_posture(self, table: Any, source: str, record_trials: bool, fit_rows: np.ndarray) -> None:
        a = table_arrays(table, fit_rows, motion=self.friction is True, baseline_mean=self.baseline_mean)
        use = (
            rows_all(np.isfinite(a["P0"]) & (a["P0"] > 0))
            & rows_all(np.isfinite(a["P"]) & (a["P"] > 0))
            & rows_all(np.isfinite(a["dtheta"]))
            & rows_all(np.isfinite(a["F"]))
        )
        taken: dict[str, np.ndarray] = {}  # the fit rows' columns as read, for the calibrated range
        if not use.all():
            a = {k: v[use] for k, v in a.items()}
        else:
            # Only the pressures as read (a running baseline's P0 is not) and the forces (columns
            # a table lacks are left to calibrated_range, which leaves their key out).
            parts = [("P", LOADED_COLUMNS), ("F", FORCE_COLUMNS)]
            parts += [("P0", BASELINE_COLUMNS)] if self.baseline_mean == 1 else []
            taken = {c: a[key][:, k] for key, names in parts for k, c in enumerate(names)}
        P0, P, th0, dth, F = (a[k] for k in ("P0", "P", "theta0", "dtheta", "F"))
        h2, h3 = self.geometry["h2"], self.geometry["h3"]
        angles = angle_blocks(P0, P, dth)
        self.angle_terms = select_angle_terms(angles)
        ang = _shared_lstsq(angles, [ANGLE_TERMS.index(t) for t in self.angle_terms], "deflection")
        theta1 = [angles.p]  # the first deflection column
        self.theta1_terms = select_angle_terms(angles, THETA1_BASE, theta1)
        own = _shared_lstsq(angles, [ANGLE_TERMS.index(t) for t in self.theta1_terms], "deflection", ys=theta1)
        self.theta1_coefficients, self.theta1_xtx_inv = own.beta[:, 0].tolist(), own.xtx_inv.tolist()
        self.theta1_resid_var = float(own.resid_cov[0, 0])
        names = TORQUE_TERMS + {True: FRICTION_TERMS, "relieved": RELIEVED_TERMS}.get(self.friction, ())
        # The friction columns and the load torques once for the fit: the blocks are built twice
        # (their R factors, then the leave-one-out residuals), the selection's folds reuse them.
        made = friction_family(self.friction, dth, a.pop("motion_in", None))
        tau = load_torque(th0 + dth, F, h2, h3)
        torques = _Blocks.build(
            len(P),
            len(names),
            lambda lo, hi: stack_columns(
                [
                    torque_features(
                        P0[lo:hi] - P[lo:hi], dth[lo:hi], names, made=None if made is None else made[lo:hi]
                    ),
                    tau[lo:hi],
                ]
            ),
        )
        # In TORQUE_TERMS' order: a file with all 14 reads the same as one written before the choice.
        self.torque_terms = tuple(sorted(select_torque_terms(torques, names), key=names.index))
        tq = _shared_lstsq(torques, [names.index(t) for t in self.torque_terms], "torque", by_trial=True)
        self.angle_coefficients, self.angle_xtx_inv = ang.beta.tolist(), ang.xtx_inv.tolist()
        self.angle_resid_cov = ang.resid_cov.tolist()
        self.torque_coefficients, self.torque_xtx_inv = tq.beta.tolist(), tq.xtx_inv.tolist()
        self.torque_resid_cov = tq.resid_cov.tolist()
        self.force_prior_sd = np.sqrt(np.mean(F**2, axis=0)).tolist()
        self.fitted_trials = idranges.to_ranges(a["trial"]) if record_trials else []
        self.fit_stats = {
            "n": len(P),
            "angle_dof": ang.dof,
            "torque_dof": tq.dof,
            "theta0_deg": np.degrees(np.median(th0, axis=0)).tolist(),
            "angle_rmse_deg": [
                math.degrees(math.sqrt(self.theta1_resid_var)),
                math.degrees(math.sqrt(ang.resid_cov[1, 1])),
            ],
            "torque_rmse_Nm": np.sqrt(np.diag(tq.resid_cov)).tolist(),
        }
        self.source = source
        self.calibrated_range = calibrated_range(table, fit_rows, taken)

    def _choose_routes(self, table: Any, source: str, fit_rows: np.ndarray) -> None:
        """Cross-validate both forms on the fit trials; keep the paper's where it predicts better."""

        def posture_only(rows: Any) -> PostureModel:
            return PostureModel(
                geometry=self.geometry,
                protocol=self.protocol,
                limits=self.limits,
                friction=self.friction,
                label_play="none",  # the rows' labels are corrected already
            ).fit(rows, choose_routes=False, record_trials=False)

        def paper(
            rows: Any, record_trials: bool = False, calibrated: Any = None, fit_rows: np.ndarray | None = None
        ) -> TakumaModel:
            # The rows' labels as the posture form fits them (play corrected, or as read): both
            # forms are judged on the same labels.
            return TakumaModel(geometry=self.geometry, protocol=self.protocol, label_play="none").fit(
                rows, record_trials=record_trials, calibrated=calibrated, fit_rows=fit_rows
            )

        try:
            rows = rt.route_sample(np.flatnonzero(fit_rows))
            template = TakumaModel(geometry=self.geometry, protocol=self.protocol, label_play="none")
            folds = functools.partial(fold_models, template, source=source)
            cv = rt.held_out_errors(table.iloc[rows], posture_only, paper, folds)
            # The same table and fit rows as the posture fit's (its labels taken as they are): the
            # same calibrated range.
            full = paper(table, record_trials=True, calibrated=self.calibrated_range, fit_rows=fit_rows)
        except ModelError:
            # Too few trials, or a block whose absence leaves a design singular: the posture form alone.
            self.routes = {q: rt.POSTURE for q in rt.QUANTITIES}
            return
        self.routes, self.fit_stats["routes_cv"], self.blends = rt.choose_routes(cv, self.limits)
        self.held_out_variance = rt.held_out_variances(cv)
        if set(self.routes.values()) - {rt.POSTURE}:
            self.paper_model = self._share_ranges(full.to_dict())
            self.paper_variance = rt.paper_residual_variances(cv, self.routes)
            self._paper = full

    def _share_ranges(self, paper_model: dict[str, Any]) -> dict[str, Any]:
        """``paper_model`` with each equation's trial ranges that are the posture form's own taken as
        that one list: written once, on one line (on a random split of 10^6 trials, 10^5 pairs).

        Read back from a file, the paper part's ranges are the ones its model parsed
        (:func:`~labcli.core.idranges.parse`): as the file's plain lists they were written one
        number a line (40 MB, 2.4 s a model on a random split of 10^6 rows).
        """
        shared = dict(paper_model.get("fitted_trials", {}))
        same: dict[int, bool] = {}  # one list shared by the equations is compared once (10^5 pairs)
        for eq, ranges in shared.items():
            if id(ranges) not in same:
                same[id(ranges)] = ranges == self.fitted_trials
            if same[id(ranges)]:
                shared[eq] = self.fitted_trials
        return {**paper_model, "fitted_trials": shared} if "fitted_trials" in paper_model else paper_model

    @property
    def paper(self) -> TakumaModel | None:
        """The paper's Eqs. 34-37 behind the paper-routed quantities (None when none is)."""
        if self._paper is None and self.paper_model is not None:
            self._paper = TakumaModel.from_dict(self.paper_model, name="the model's paper-form part")
        return self._paper

    def route(self, quantity: str) -> str:
        """``"posture"``, ``"paper"`` or ``"blend"``: which estimate ``quantity`` (theta1, theta2, Fx, Fy) takes."""
        return self.routes.get(quantity, rt.POSTURE)

    # ---------------------------------------------------------------- prediction
    def _angles(self, P0: np.ndarray, P: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        X = angle_features(P0, P, self.angle_terms)
        h = np.einsum("ni,ij,nj->n", X, np.asarray(self.angle_xtx_inv), X)
        cov = (1.0 + h)[:, None, None] * np.asarray(self.angle_resid_cov)[None]
        return X @ np.asarray(self.angle_coefficients), cov

    def _theta1(
        self, P0: np.ndarray, P: np.ndarray, shared: np.ndarray, shared_var: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """The reported theta1 (rad) and its variance from its own equation (the shared design's if none)."""
        if not self.theta1_terms:
            return shared, shared_var
        X = angle_features(P0, P, self.theta1_terms)
        h = np.einsum("ni,ij,nj->n", X, np.asarray(self.theta1_xtx_inv), X)
        return X @ np.asarray(self.theta1_coefficients), self.theta1_resid_var * (1.0 + h)

    def _forces(
        self,
        dP: np.ndarray,
        theta0: np.ndarray,
        dth: np.ndarray,
        motion_in: np.ndarray | None = None,
        motion_sd: np.ndarray | None = None,
        want_cov: bool = True,
    ) -> tuple[np.ndarray, np.ndarray | None]:
        """Forces (n, 2) and their covariance from the torque error alone (n, 2, 2; None unless ``want_cov``).

        tau = J^T F + e with e ~ N(0, (1 + h) S_tau); with the fit loads' spread as a prior on F
        (``force_prior_sd``) the estimate is the posterior mean, which is (J^T)^-1 tau wherever the
        torques determine F and stays bounded along a straight arm, where they do not.
        """
        X = torque_features(dP, dth, self.torque_terms, motion_in, motion_sd)
        tau = X @ np.asarray(self.torque_coefficients)
        h2, h3 = self.geometry["h2"], self.geometry["h3"]
        th = theta0 + dth
        JT = np.swapaxes(jacobian(th[:, 0], th[:, 1], h2, h3), 1, 2)
        h = np.einsum("ni,ij,nj->n", X, np.asarray(self.torque_xtx_inv), X)
        S = (1.0 + h)[:, None, None] * np.asarray(self.torque_resid_cov)[None]
        if not self.force_prior_sd:
            A = np.linalg.pinv(JT)
            return einsum_2x2("nij,nj->ni", A, tau), einsum_2x2("nij,njk,nlk->nil", A, S, A) if want_cov else None
        # Gain form of the posterior (P J (J^T P J + S)^-1): stable when S is tiny or J^T singular.
        prior = np.diag(np.asarray(self.force_prior_sd) ** 2)
        K = einsum_2x2(
            "ij,nkj,nkl->nil",
            prior,
            JT,
            inv_spd_2x2(einsum_2x2("nij,jk,nlk->nil", JT, prior, JT) + S),
        )
        F = einsum_2x2("nij,nj->ni", K, tau)
        return F, prior - einsum_2x2("nij,njk,kl->nil", K, JT, prior) if want_cov else None

    def pair_motion_sd(self) -> np.ndarray:
        """The standard error (2,) rad of the pairs' motions (:func:`pair_motion`) estimated from pressures."""
        c = np.asarray(self.angle_resid_cov, dtype=float)
        if c.shape != (2, 2):
            return np.zeros(2)
        return np.sqrt(np.maximum([c[0, 0], c[0, 0] + c[1, 1] + 2.0 * c[0, 1]], 0.0))

    def deflections(self, P0: Any, P: Any) -> np.ndarray:
        """The posture form's own deflections (n, 2) rad from pressures (MPa), routes aside: what
        the friction terms' history of loads reads (:meth:`predict_table`, ``labcli predict`` and
        the run-time estimator alike)."""
        P0, P = pressure_arrays(P0, P)
        return angle_features(P0, P, self.angle_terms) @ np.asarray(self.angle_coefficients)

    def predict(
        self,
        P0: Any,
        P: Any,
        theta0: Any = None,
        mode: str = "pressure-only",
        theta: Any = None,
        motion_in: Any = None,
    ) -> dict[str, Any]:
        """Deflections (rad), forces (N) and their standard errors from pressures (MPa, (n, 4)).

        ``theta0`` (n, 2) rad is the rest posture (default 0, 0).  ``mode="measured-angles"``
        uses the measured deflections ``theta`` for the forces instead of the estimated ones.
        ``motion_in`` (n, 2) rad, the joints' motion into each baseline
        (:func:`motion_into_baseline`), for a model with friction terms (None: unknown).
        """
        if not self.is_fitted:
            raise ModelError("The model has no coefficients yet; fit it on a run first (`labcli fit RUN.h5`).")
        P0, P = pressure_arrays(P0, P)
        n = len(P)
        th0 = np.zeros((n, 2)) if theta0 is None else np.broadcast_to(np.asarray(theta0, dtype=float), (n, 2))
        th0 = np.where(np.isfinite(th0), th0, 0.0)
        bad = ~(rows_all(np.isfinite(P0) & (P0 > 0)) & rows_all(np.isfinite(P) & (P > 0)))
        P0 = np.where(bad[:, None], 1.0, P0)
        P = np.where(bad[:, None], 1.0, P)
        with paused_gc():  # a list per trial: 10^6 of them, no cycles
            flags: list[list[str]] = [["bad-pressure"] if b else [] for b in bad.tolist()]
        dth, cov_a = self._angles(P0, P)
        theta1, var1 = self._theta1(P0, P, dth[:, 0], cov_a[:, 0, 0])
        if mode == "measured-angles":
            if theta is None:
                raise ModelError("The measured-angles mode needs the measured joint angles.")
            meas = np.atleast_2d(np.asarray(theta, dtype=float))
            known = rows_all(np.isfinite(meas))
            for i in np.flatnonzero(~known):
                flags[i].append("missing-angle")
            dth_f, cov_f = np.where(known[:, None], meas, dth), np.where(known[:, None, None], 0.0, cov_a)
        elif mode == "pressure-only":
            known, dth_f, cov_f = np.ones(n, bool), dth, cov_a
        else:
            raise ModelError(f"Unknown prediction mode '{mode}'; use pressure-only or measured-angles.")
        moved = None if motion_in is None else np.broadcast_to(np.asarray(motion_in, dtype=float), (n, 2))
        F, cov_F = self._force_covariance(
            P0 - P, th0, dth_f, cov_f, moved, self.pair_motion_sd() if mode == "pressure-only" else None
        )
        # The gain form can leave a rounding-level negative variance where the data fix F exactly.
        se = {
            "theta1": np.sqrt(var1),
            "theta2": np.sqrt(cov_a[:, 1, 1]),
            "Fx": np.sqrt(np.maximum(cov_F[:, 0, 0], 0.0)),
            "Fy": np.sqrt(np.maximum(cov_F[:, 1, 1], 0.0)),
        }
        value = {"theta1": theta1, "theta2": dth[:, 1], "Fx": F[:, 0], "Fy": F[:, 1]}
        valid = {q: known if q in ("Fx", "Fy") else np.ones(n, bool) for q in se}
        weight = self._paper_routes(P0, P, mode, theta, value, se, valid, flags)
        ok = {}
        for q, s in se.items():
            within = s <= self.limits.get(q, math.inf)
            ok[q] = ~bad & within & valid[q]
            for i in np.flatnonzero(~within & ~bad):
                if "uncertain" not in flags[i]:
                    flags[i].append("uncertain")
        # The plan's direction term widens the intervals, not the flags: those judge the trial's own
        # pressures (routes.held_out_variances).  It is the posture form's, so it enters in its weight.
        for q, v in self.held_out_variance.items():
            se[q] = np.sqrt(se[q] ** 2 + weight.get(q, 1.0) ** 2 * v)
        return {
            "theta1_rad": value["theta1"],
            "theta2_rad": value["theta2"],
            "Fx_N": value["Fx"],
            "Fy_N": value["Fy"],
            "se": se,
            "ok": ok,
            "flags": flags,
            "mode": mode,
            "form": FORM,
            "theta0_rad": th0,
            "routes": {q: self.route(q) for q in rt.QUANTITIES},
            "blends": {q: dict(b) for q, b in self.blends.items()},
        }

    def _paper_routes(
        self,
        P0: np.ndarray,
        P: np.ndarray,
        mode: str,
        theta: Any,
        value: dict[str, np.ndarray],
        se: dict[str, np.ndarray],
        valid: dict[str, np.ndarray],
        flags: list[list[str]],
    ) -> dict[str, Any]:
        """Put the paper's estimates (or the blends with them), standard errors and flags in place;
        returns the posture form's weight in each quantity it does not take alone (per trial or one)."""
        paper = self.paper
        mine = [q for q in rt.QUANTITIES if self.route(q) != rt.POSTURE]
        weight: dict[str, Any] = {}
        if paper is None or not mine:
            return weight
        pred = paper.predict(P0, P, mode=mode, theta=theta)
        th_force = (
            stack_columns([pred["theta1_rad"], pred["theta2_rad"]])
            if mode == "pressure-only"
            else np.nan_to_num(np.atleast_2d(np.asarray(theta, dtype=float)), nan=0.0)
        )
        paper_se = rt.paper_standard_errors(paper, pred, P0, P, th_force, self.paper_variance)
        for q in mine:
            v_pa, ok_pa = np.asarray(pred[rt.VALUE_KEYS[q]], dtype=float), np.asarray(pred["ok"][q], dtype=bool)
            if self.route(q) == rt.BLEND:
                # Where the paper's form has no estimate the posture form's stands alone.
                b = self.blends[q]
                v, s = rt.blend_estimate(
                    b["posture_weight"], b["error_correlation"], value[q], se[q], v_pa, paper_se[q]
                )
                both = ok_pa & np.isfinite(v) & np.isfinite(s)
                value[q], se[q] = np.where(both, v, value[q]), np.where(both, s, se[q])
                weight[q] = np.where(both, b["posture_weight"], 1.0)
                continue
            value[q], se[q], weight[q] = v_pa, paper_se[q], 0.0
            valid[q] = valid[q] & ok_pa
            why = f"{q}-clipped" if q.startswith("theta") else "singular-jacobian"
            for i in np.flatnonzero(~ok_pa):
                if why in pred["flags"][i] and why not in flags[i]:
                    flags[i].append(why)
        return weight

    def _force_covariance(
        self,
        dP: np.ndarray,
        th0: np.ndarray,
        dth: np.ndarray,
        cov_dth: np.ndarray,
        motion_in: np.ndarray | None = None,
        motion_sd: np.ndarray | None = None,
        closed_form: bool = True,
    ) -> tuple[np.ndarray, np.ndarray]:
        """Forces and their covariance: torque error through (J^T)^-1, angle error through dF/d(dtheta).

        dF/d(dtheta) is the derivative of the posterior mean in closed form (:meth:`_force_gradient`)
        where the model has a force prior and no relieved run's terms, by central differences (a step of
        FORCE_STEP) otherwise or unless ``closed_form``.
        """
        G = self._force_gradient(dP, th0, dth, motion_in, motion_sd) if closed_form else None
        if G is not None:
            F, cov = self._forces(dP, th0, dth, motion_in, motion_sd)
            assert cov is not None
            return F, cov + einsum_2x2("nij,njk,nlk->nil", G, cov_dth, G)
        # The forces at the angles and a step either side of each, in one call (five blocks of rows).
        n, step = len(dP), FORCE_STEP
        d = np.array([[0.0, 0.0], [step, 0.0], [-step, 0.0], [0.0, step], [0.0, -step]])
        moved = None if motion_in is None else np.tile(motion_in, (5, 1))
        F5, cov5 = self._forces(
            np.tile(dP, (5, 1)), np.tile(th0, (5, 1)), np.tile(dth, (5, 1)) + np.repeat(d, n, axis=0), moved, motion_sd
        )
        assert cov5 is not None
        F, cov, G = F5[:n], cov5[:n], np.empty((n, 2, 2))
        for k in range(2):
            ahead, behind = F5[(1 + 2 * k) * n : (2 + 2 * k) * n], F5[(2 + 2 * k) * n : (3 + 2 * k) * n]
            G[:, :, k] = (ahead - behind) / (2 * step)
        cov = cov + einsum_2x2("nij,njk,nlk->nil", G, cov_dth, G)
        if not self.force_prior_sd:
            # A straight arm: without a prior the force along it is not determined at all.
            cov[np.abs(np.sin(th0[:, 1] + dth[:, 1])) < 1e-9] = np.inf
        return F, cov

    def _force_gradient(
        self,
        dP: np.ndarray,
        th0: np.ndarray,
        dth: np.ndarray,
        motion_in: np.ndarray | None = None,
        motion_sd: np.ndarray | None = None,
    ) -> np.ndarray | None:
        """dF/d(dtheta) (n, 2, 2), ``[:, i, k]`` = dF_i / d(dtheta_k), of :meth:`_forces`' posterior mean
        F = P J y with y = M^-1 tau and M = J^T P J + (1 + h) S_tau; None where it is not written out
        here (no force prior, a relieved run's terms, or a posterior the adjugate does not invert).
        The friction terms' columns move with the deflections through their faded signs
        (:func:`friction_slopes`).

        For each deflection k: dF = P dJ y + K (dtau - dM y), K = P J M^-1 the gain, with
        dM y = dJ^T F + J^T P dJ y + dh S_tau y, dtau = dX beta, dh = 2 x^T (X^T X)^-1 dx.  One
        evaluation where the central differences took five (at validation's 2 x 10^5 trials, 0.08 s
        of CPU against 0.36 s); the two agree within the differences' own error
        (tests/papers/takuma2014/test_force_gradient.py).
        """
        if not self.force_prior_sd:
            return None
        at = [KNOWN_TORQUE_TERMS.index(t) for t in self.torque_terms]
        if any(a >= len(TORQUE_TERMS) + len(FRICTION_TERMS) for a in at):
            return None
        n = len(dP)
        dP, dth = np.atleast_2d(dP), np.atleast_2d(dth)
        slope = friction_slopes(dth, motion_sd) if any(a >= len(TORQUE_TERMS) for a in at) else None
        X = torque_features(dP, dth, self.torque_terms, motion_in, motion_sd)
        beta = np.asarray(self.torque_coefficients, dtype=float)
        tau = X @ beta
        A = np.asarray(self.torque_xtx_inv, dtype=float)
        XA = X @ (0.5 * (A + A.T))  # symmetric, so that dh = 2 x^T A dx
        h = np.einsum("ni,ni->n", XA, X)
        S0 = np.asarray(self.torque_resid_cov, dtype=float)
        pr = np.asarray(self.force_prior_sd, dtype=float) ** 2
        h2, h3 = self.geometry["h2"], self.geometry["h3"]
        t1 = th0[:, 0] + dth[:, 0]
        t12 = t1 + th0[:, 1] + dth[:, 1]
        c1, s1, c12, s12 = np.cos(t1), np.sin(t1), np.cos(t12), np.sin(t12)
        j01, j11 = -h3 * c12, -h3 * s12
        j00, j10 = -h2 * c1 + j01, -h2 * s1 + j11
        # M = J^T P J + (1 + h) S_tau, symmetric; its adjugate over the determinant (inv_spd_2x2's good rows).
        s = 1.0 + h
        m00 = pr[0] * j00 * j00 + pr[1] * j10 * j10 + s * S0[0, 0]
        m01 = pr[0] * j00 * j01 + pr[1] * j10 * j11 + s * 0.5 * (S0[0, 1] + S0[1, 0])
        m11 = pr[0] * j01 * j01 + pr[1] * j11 * j11 + s * S0[1, 1]
        det = m00 * m11 - m01 * m01
        if not ((det > INV_2X2_RCOND * m00 * m11) & (m00 > 0) & (m11 > 0)).all():
            return None
        i00, i01, i11 = m11 / det, -m01 / det, m00 / det
        y0, y1 = i00 * tau[:, 0] + i01 * tau[:, 1], i01 * tau[:, 0] + i11 * tau[:, 1]
        F0, F1 = pr[0] * (j00 * y0 + j01 * y1), pr[1] * (j10 * y0 + j11 * y1)
        Sy0, Sy1 = S0[0, 0] * y0 + S0[0, 1] * y1, S0[1, 0] * y0 + S0[1, 1] * y1
        # The gain K = P J M^-1.
        k00, k01 = pr[0] * (j00 * i00 + j01 * i01), pr[0] * (j00 * i01 + j01 * i11)
        k10, k11 = pr[1] * (j10 * i00 + j11 * i01), pr[1] * (j10 * i01 + j11 * i11)
        # dJ / d(dtheta1): the whole arm turns (t1 and t12 move); dJ / d(dtheta2): the outer link alone.
        dJ = ((-j10, -j11, j00, j01), (h3 * s12, h3 * s12, -h3 * c12, -h3 * c12))
        G = np.empty((n, 2, 2))
        for k, (d00, d01, d10, d11) in enumerate(dJ):
            dX = np.zeros_like(X)
            for col, a in enumerate(at):
                if 4 <= a < 12 and (a - 4) % 2 == k:  # dP_a * dtheta_k
                    dX[:, col] = dP[:, (a - 4) // 2]
                elif a == 12 + k:  # dtheta_k
                    dX[:, col] = 1.0
                elif a >= 14 and (a == 15 or k == 0):  # a friction term: the pair moves with dtheta_k
                    assert slope is not None
                    dX[:, col] = slope[:, a - 14]
            dtau = dX @ beta
            dh = 2.0 * np.einsum("ni,ni->n", XA, dX)
            dy0, dy1 = d00 * y0 + d01 * y1, d10 * y0 + d11 * y1  # dJ y
            # dtau - dM y, dM y = dJ^T F + J^T P dJ y + dh S_tau y
            u0 = dtau[:, 0] - (d00 * F0 + d10 * F1) - (j00 * pr[0] * dy0 + j10 * pr[1] * dy1) - dh * Sy0
            u1 = dtau[:, 1] - (d01 * F0 + d11 * F1) - (j01 * pr[0] * dy0 + j11 * pr[1] * dy1) - dh * Sy1
            G[:, 0, k] = pr[0] * dy0 + k00 * u0 + k01 * u1
            G[:, 1, k] = pr[1] * dy1 + k10 * u0 + k11 * u1
        return G

    @property
    def uses_history(self) -> bool:
        """Do the torques read the joints' motion into each baseline (the friction terms)?"""
        return any(t in FRICTION_TERMS for t in self.torque_terms)

    def predict_table(self, table: Any, mode: str = "pressure-only", history: Any = None) -> dict[str, Any]:
        """``predict`` on a trial table (rest posture from theta1_0_deg, theta2_0_deg; absent = 0).

        ``history``: the whole run's table, when ``table`` holds only some of its trials (the
        validation trials): each trial's motion into its baseline is from the trial before it in
        the run, whichever set that one is in.
        """
        a = table_arrays(table, baseline_mean=self.baseline_mean)
        moved = None
        if self.uses_history and history is not None:
            moved = self._motion_from_history(history, a["trial"], mode == "measured-angles")
        elif self.uses_history:
            # The motion into each baseline from the previous trial's loaded posture.
            moved = self.motion_in_of(
                a["trial"], a["P0"], a["P"], a["theta0"], a["dtheta"] if mode == "measured-angles" else None
            )
        out = self.predict(
            a["P0"],
            a["P"],
            a["theta0"],
            mode=mode,
            theta=a["dtheta"] if mode == "measured-angles" else None,
            motion_in=moved,
        )
        out["trial"] = a["trial"]
        return out

    def motion_in_of(self, trial: Any, P0: Any, P: Any, theta0: Any, dtheta: Any = None) -> np.ndarray | None:
        """The joints' motion into each baseline (n, 2) rad that the friction terms need, from the
        previous trial's (or push's, by ``trial`` id) loaded posture: its deflection as
        :meth:`predict` sees it, ``dtheta`` where measured and finite, else estimated from the
        pressures.  None for a model without friction terms."""
        if not self.uses_history:
            return None
        est = self.deflections(P0, P)
        seen = est if dtheta is None else np.where(np.isfinite(dtheta), dtheta, est)
        return motion_into_baseline(trial, np.broadcast_to(np.asarray(theta0, dtype=float), est.shape), seen)

    def _motion_from_history(self, history: Any, trial: np.ndarray, measured: bool) -> np.ndarray:
        """:meth:`motion_in_of` of the trials ``trial`` read from the whole run's table ``history``:
        only their own rows and their previous trials' are read, and only the previous trials'
        deflections estimated (at 10^6 trials, every row's estimate and a dict of every id took
        most of validate's history)."""
        ids = np.asarray(history["trial"]).astype(int)
        own = rows_of(trial, ids)
        before = previous_rows(ids)[own]
        first = before < 0
        h = table_arrays(history, np.concatenate([own, np.where(first, 0, before)]), baseline_mean=self.baseline_mean)
        k = len(own)
        est = self.deflections(h["P0"][k:], h["P"][k:])
        seen = np.where(np.isfinite(h["dtheta"][k:]), h["dtheta"][k:], est) if measured else est
        return motion_from(h["theta0"][:k], h["theta0"][k:], seen, first)

    def check_compatible(
        self, protocol: str, geometry: Mapping[str, Any], model_name: str = "the model", run_name: str = "the run"
    ) -> None:
        """ModelError unless the run has this model's protocol name and rig geometry."""
        TakumaModel.check_compatible(self, protocol, geometry, model_name, run_name)  # type: ignore[arg-type]

    # ---------------------------------------------------------------- plain data
    def to_dict(self) -> dict[str, Any]:
        return _clean(
            {
                "schema": SCHEMA,
                "version": SCHEMA_VERSION,
                "form": FORM,
                "protocol": self.protocol,
                "geometry": self.geometry,
                "units": {"pressure": "MPa (gauge)", "angle": "rad", "torque": "N m", "force": "N"},
                "limits": self.limits,
                "angle_terms": list(self.angle_terms),
                "angle_coefficients": self.angle_coefficients,
                "angle_xtx_inv": self.angle_xtx_inv,
                "angle_resid_cov": self.angle_resid_cov,
                "theta1_terms": list(self.theta1_terms),
                "theta1_coefficients": self.theta1_coefficients,
                "theta1_xtx_inv": self.theta1_xtx_inv,
                "theta1_resid_var": self.theta1_resid_var,
                "torque_terms": list(self.torque_terms),
                "torque_coefficients": self.torque_coefficients,
                "torque_xtx_inv": self.torque_xtx_inv,
                "torque_resid_cov": self.torque_resid_cov,
                "force_prior_sd": self.force_prior_sd,
                "fit_stats": self.fit_stats,
                "fitted_trials": self.fitted_trials,
                "source": self.source,
                "fitted_on": self.fitted_on,
                "routes": {q: self.route(q) for q in rt.QUANTITIES},
                "paper_model": self.paper_model,
                "paper_variance": self.paper_variance,
                "blends": self.blends,
                "calibrated_range": self.calibrated_range,
                "baseline": baseline_dict(self.p0_leak_corrected, self.baseline_gap_s),
                "baseline_mean": self.baseline_mean,
                "labels": {"play": self.label_play, **self.play},
                **captures_dict(self.captures_per_load),
                # Only where there is one: a file written before it reads back byte for byte.
                **({"held_out_variance": self.held_out_variance} if self.held_out_variance else {}),
            }
        )

    def to_json(self) -> str:
        """The model as JSON (schema ``labcli-takuma-model``, form ``posture``)."""
        return dumps_indented(self.to_dict(), allow_nan=False) + "\n"

    @classmethod
    def from_dict(cls, d: Mapping[str, Any], name: str = "the model") -> PostureModel:
        required = (
            "protocol",
            "geometry",
            "angle_terms",
            "angle_coefficients",
            "angle_xtx_inv",
            "angle_resid_cov",
            "torque_coefficients",
            "torque_xtx_inv",
            "torque_resid_cov",
        )
        missing = [k for k in required if k not in d]
        if missing:
            raise ModelError(f"{cap(name)} lacks the key(s) {', '.join(missing)}; refit with `labcli fit`.")
        torque_terms = d.get("torque_terms", list(TORQUE_TERMS))
        torque_terms = torque_terms if isinstance(torque_terms, list) else [torque_terms]
        unknown = [str(t) for t in d["angle_terms"] if t not in ANGLE_TERMS] + [
            str(t) for t in torque_terms if t not in KNOWN_TORQUE_TERMS
        ]
        if unknown or not torque_terms or len(set(torque_terms)) < len(torque_terms):
            raise ModelError(
                f"{cap(name)} names terms this labcli does not know "
                f"({', '.join(unknown) or 'torque_terms'}); refit with `labcli fit`."
            )
        _check_tables(d, len(d["angle_terms"]), len(torque_terms), name)
        _check_theta1(d, name)
        prior = d.get("force_prior_sd", [])
        if prior and not (
            isinstance(prior, list) and len(prior) == 2 and all(isinstance(v, (int, float)) and v > 0 for v in prior)
        ):
            raise ModelError(
                f"{cap(name)}: key 'force_prior_sd' must list two positive forces in N; refit with `labcli fit`."
            )
        routes, variance, blends = _routes_from_dict(d, name)

        def bad(key: str, what: str) -> NoReturn:
            raise ModelError(f"{cap(name)}: key '{key}' {what}; refit with `labcli fit`.")

        fitted = idranges.parse(d.get("fitted_trials", []), "fitted_trials", bad)
        keys = required + (
            "limits",
            "force_prior_sd",
            "fit_stats",
            "source",
            "fitted_on",
            "theta1_terms",
            "theta1_coefficients",
            "theta1_xtx_inv",
            "theta1_resid_var",
        )
        model = cls(
            **{k: d[k] for k in keys if k in d},
            torque_terms=tuple(torque_terms),
            fitted_trials=fitted,
            routes=routes,
            paper_variance=variance,
            blends=blends,
            held_out_variance=_held_out_from_dict(d.get("held_out_variance"), name),
        )
        if variance:
            model._paper = TakumaModel.from_dict(d["paper_model"], name=f"{name}'s paper-form part")
            part = d["paper_model"]
            if "fitted_trials" in part:  # as parsed: ranges, as a fit writes them
                part = {**part, "fitted_trials": model._paper.fitted_trials}
            model.paper_model = model._share_ranges(part)
        model.calibrated_range = check_range(d.get("calibrated_range"), name)
        model.p0_leak_corrected, model.baseline_gap_s = check_baseline(d.get("baseline"), name)
        k = d.get("baseline_mean", 1)
        if not isinstance(k, int) or isinstance(k, bool) or not 1 <= k <= 100:
            bad("baseline_mean", "must be a whole number of baselines, 1 to 100")
        model.baseline_mean = k
        model.captures_per_load = check_captures(d.get("captures_per_load"), name)
        model.label_play, model.play = labels_from_dict(d.get("labels"), name)
        return model


def _routes_from_dict(
    d: Mapping[str, Any], name: str
) -> tuple[dict[str, str], dict[str, float], dict[str, dict[str, float]]]:
    """The routes, paper-form variances and blends of a model file, checked (absent: the posture form throughout)."""
    routes = d.get("routes") or {}
    if not (
        isinstance(routes, Mapping)
        and set(routes) <= set(rt.QUANTITIES)
        and all(r in (rt.POSTURE, rt.PAPER, rt.BLEND) for r in routes.values())
    ):
        raise ModelError(
            f"{cap(name)}: key 'routes' must map theta1, theta2, Fx, Fy to 'posture', "
            "'paper' or 'blend'; refit with `labcli fit`."
        )
    variance = d.get("paper_variance") or {}
    paper_q = sorted(q for q, r in routes.items() if r != rt.POSTURE)

    def finite(v: Any, lo: float = 0.0, hi: float = math.inf) -> bool:
        try:  # a 400-digit integer is no float
            return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(float(v)) and lo <= v <= hi
        except OverflowError:
            return False

    if not (isinstance(variance, Mapping) and sorted(variance) == paper_q and all(map(finite, variance.values()))):
        raise ModelError(
            f"{cap(name)}: key 'paper_variance' must give a finite variance for each quantity "
            "routed to the paper's form or blended with it, and no other; refit with `labcli fit`."
        )
    if paper_q and not isinstance(d.get("paper_model"), Mapping):
        raise ModelError(
            f"{cap(name)} routes {', '.join(paper_q)} to the paper's form but holds no "
            "'paper_model'; refit with `labcli fit`."
        )
    blends = d.get("blends") or {}
    blend_q = sorted(q for q, r in routes.items() if r == rt.BLEND)
    if not (
        isinstance(blends, Mapping)
        and sorted(blends) == blend_q
        and all(
            isinstance(b, Mapping)
            and set(b) == {"posture_weight", "error_correlation"}
            and finite(b["posture_weight"], 0.0, 1.0)
            and finite(b["error_correlation"], -1.0, 1.0)
            for b in blends.values()
        )
    ):
        raise ModelError(
            f"{cap(name)}: key 'blends' must give each blended quantity, and no other, a "
            "posture_weight in [0, 1] and an error_correlation in [-1, 1]; refit with `labcli fit`."
        )
    return (
        dict(routes),
        {q: float(v) for q, v in variance.items()},
        {q: {k: float(v) for k, v in b.items()} for q, b in blends.items()},
    )


def _held_out_from_dict(value: Any, name: str) -> dict[str, float]:
    """A model file's ``held_out_variance``, checked (absent, as in files written before it: none)."""
    if value is None:
        return {}
    if not (
        isinstance(value, Mapping)
        and set(value) <= set(rt.QUANTITIES)
        and all(
            isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(float(v)) and v >= 0
            for v in value.values()
        )
    ):
        raise ModelError(
            f"{cap(name)}: key 'held_out_variance' must give theta1, theta2, Fx or Fy a finite variance "
            "of at least 0; refit with `labcli fit`."
        )
    return {q: float(v) for q, v in value.items()}


def _check_tables(d: Mapping[str, Any], n_angle: int, n_torque: int, name: str) -> None:
    """The model file's coefficient and covariance tables: each of its shape, finite."""
    shapes = {
        "angle_coefficients": (n_angle, 2),
        "angle_xtx_inv": (n_angle,) * 2,
        "angle_resid_cov": (2, 2),
        "torque_coefficients": (n_torque, 2),
        "torque_xtx_inv": (n_torque,) * 2,
        "torque_resid_cov": (2, 2),
    }
    for key, shape in shapes.items():
        try:
            arr = np.asarray(d[key], dtype=float)
        except (TypeError, ValueError):
            arr = np.empty(0)
        if arr.shape != shape or not np.all(np.isfinite(arr)):
            raise ModelError(
                f"{cap(name)}: key '{key}' must be a {shape[0]} x {shape[1]} table of finite "
                "numbers; refit with `labcli fit`."
            )
        if key.endswith("_coefficients") and not np.all(np.abs(arr) <= MAX_COEFFICIENT):
            raise ModelError(
                f"{cap(name)}: key '{key}' holds {np.max(np.abs(arr)):g}, beyond the {MAX_COEFFICIENT:g} a "
                "fitted coefficient can reach; refit with `labcli fit`."
            )


def _check_theta1(d: Mapping[str, Any], name: str) -> None:
    """ModelError unless the optional theta1 equation is whole: known terms, matching shapes, finite numbers."""
    terms = d.get("theta1_terms", [])
    if not terms and not d.get("theta1_coefficients"):
        return
    p = len(terms) if isinstance(terms, list) else -1
    try:
        beta = np.asarray(d.get("theta1_coefficients"), dtype=float)
        inv = np.asarray(d.get("theta1_xtx_inv"), dtype=float)
        var = float(d.get("theta1_resid_var"))  # type: ignore[arg-type]  # None: the TypeError below
    except (TypeError, ValueError, OverflowError):
        beta, inv, var = np.empty(0), np.empty(0), math.nan
    if not (
        p > 0
        and all(t in ANGLE_LINEAR + ANGLE_QUADRATIC for t in terms)
        and beta.shape == (p,)
        and inv.shape == (p, p)
        and np.all(np.isfinite(beta))
        and np.all(np.isfinite(inv))
        and math.isfinite(var)
        and var >= 0
    ):
        raise ModelError(
            f"{cap(name)}: the theta1 equation (keys theta1_terms, theta1_coefficients, "
            "theta1_xtx_inv, theta1_resid_var) is incomplete or not finite; refit with `labcli fit`."
        )


def load_force_model(path: Any) -> TakumaModel | PostureModel:
    """A model file of either form: ``form = "posture"`` or the paper's Eqs. 34-37 (the default)."""
    from ....core.files import read_input

    p = Path(path)
    try:
        text = read_input(p, "a model file", label=f"The model file {p}", error=ModelError).decode("utf-8")
    except (OSError, UnicodeDecodeError):
        return TakumaModel.load(p)  # its one-sentence errors for a missing or unreadable file
    return force_model_from_json(text, name=f"the model file {p}")


def force_model_from_json(text: str, name: str = "the model") -> TakumaModel | PostureModel:
    """A model of either form from its JSON text (a file's, or one a run file records)."""
    from ....core.jsontext import JSONDepthError, loads_bounded

    try:
        d = loads_bounded(text)
    except (JSONDepthError, ValueError):
        return TakumaModel.from_json(text, name=name)  # its one-sentence errors for bad JSON
    if isinstance(d, Mapping) and d.get("form") == FORM and d.get("schema") == SCHEMA:
        return PostureModel.from_dict(d, name=name)
    return TakumaModel.from_json(text, name=name)


def table_arrays(
    table: Any, rows: np.ndarray | None = None, motion: bool = False, baseline_mean: int = 1
) -> dict[str, np.ndarray]:
    """Trial ids, pressures (MPa), rest posture and deflections (rad), forces (N) of a trial table.

    ``rows``: a boolean mask or the indices of the rows wanted (default all), taken column by column so
    the table itself is never copied.  ``motion``: also each trial's measured motion into its
    baseline (``motion_in``, :func:`motion_into_baseline`).  ``baseline_mean`` > 1: each P0 the
    mean of that many baselines (:func:`running_baseline`), over every row of the table.
    """
    n = len(table) if rows is None else int(np.count_nonzero(rows)) if rows.dtype == bool else len(rows)

    def values(c: str) -> np.ndarray:
        v = np.asarray(table[c], dtype=float)
        return v if rows is None else v[rows]

    def col(names: tuple[str, ...], default: float = math.nan) -> np.ndarray:
        return stack_columns([values(c) if c in table.columns else np.full(n, default) for c in names])

    missing = [c for c in BASELINE_COLUMNS + LOADED_COLUMNS if c not in table.columns]
    if missing:
        raise ModelError(
            f"The trial table lacks the column(s) {', '.join(missing)}; "
            "see the trial-table format (P_L10..P_R20, P_L1..P_R2 in MPa)."
        )
    rest = col(REST_COLUMNS, 0.0)
    trial = np.asarray(table["trial"])
    out = {
        "trial": (trial if rows is None else trial[rows]).astype(int),
        "P0": col(BASELINE_COLUMNS),
        "P": col(LOADED_COLUMNS),
        "theta0": np.deg2rad(np.where(np.isfinite(rest), rest, 0.0)),
        "dtheta": np.deg2rad(col(ANGLE_COLUMNS)),
        "F": col(FORCE_COLUMNS),
    }
    if motion:
        out["motion_in"] = _measured_motion(table, trial, rows, out["theta0"])
    if baseline_mean > 1:
        every = stack_columns([np.asarray(table[c], dtype=float) for c in BASELINE_COLUMNS])
        mean = running_baseline(trial, every, baseline_mean)
        out["P0"] = mean if rows is None else mean[rows]
    return out


def _measured_motion(table: Any, trial: np.ndarray, rows: np.ndarray | None, theta0: np.ndarray) -> np.ndarray:
    """The measured motion into the baselines (:func:`~.history.motion_into_baseline`) of the rows
    ``rows`` (default all), whose rest postures are ``theta0``.  The previous trial of a fit trial
    may be one that ``rows`` leaves out: it is looked up among every row, and only those read."""
    prev = previous_rows(trial)
    before = prev if rows is None else prev[rows]
    first = before < 0
    before = np.where(first, 0, before)

    def at(names: tuple[str, ...], default: float) -> np.ndarray:
        return stack_columns(
            [
                np.asarray(table[c], dtype=float)[before] if c in table.columns else np.full(len(before), default)
                for c in names
            ]
        )

    r = at(REST_COLUMNS, 0.0)
    rest = np.deg2rad(np.where(np.isfinite(r), r, 0.0))
    return motion_from(theta0, rest, np.deg2rad(at(ANGLE_COLUMNS, math.nan)), first)
