"""The posture form's pressure-only prediction compiled for a few rows at a time: the run-time estimator's.

:meth:`PostureModel.predict <.posture.PostureModel.predict>` is written for tables: every
design is rebuilt from term names, every 2 x 2 product goes through :func:`.posture.einsum_2x2`,
and the paper's Eqs. 34-37 behind the blended quantities are a second model's ``predict``.
On the dozen-odd rows the estimator asks about per estimate (a centre and a step either side of
each pressure, :mod:`labcli.sensing.evaluate`) that is some 1,400 numpy calls, each on a
handful of numbers, where their cost is the call, not the arithmetic.  :class:`CompiledPosture` works out once, when the model is read, what
does not depend on the pressures:

* the angle designs as two gathers of ``[u, 1]`` (u = P0 / P - 1), so a linear term is
  ``u_i * 1`` and a quadratic one ``u_i * u_j``; the deflections, the reported theta1 and both
  leverages come from one product with their coefficients and (X^T X)^-1 side by side;
* the torque design likewise (``[dP, dP dtheta, dtheta]`` gathered to the kept terms), its
  coefficients and (X^T X)^-1 side by side, the prior's variances and the residual covariance
  as plain numbers, so the force posterior is written out element by element: the gain
  ``P J (J^T P J + S)^-1`` by the adjugate, the covariance's diagonal only;
* the paper's coefficients of Eqs. 34-37 and their covariances as block matrices, so Eqs. 36
  and 37 and their standard errors are one design, one product each;
* the sleeves' friction terms (``labcli fit``'s default) as two more torque columns, each
  pair's faded sign under the load less the one into its baseline (``motion_in``), the fade's
  width worked out once.

The arithmetic is the reference's (the same formulas; dF/d(dtheta) by a central step, where the
reference writes the derivative out, the two within 1e-8 of each other) and
tests/papers/takuma2014/test_sensing_fast.py holds the two together on random blocks, edge
cases included.  A row the table form treats specially (a pressure not positive, an arm
exactly straight for Eqs. 36-37, a posterior the adjugate cannot invert) makes
:meth:`CompiledPosture.predict` return None and the caller takes the reference; so does a
model this form does not cover (:meth:`CompiledPosture.compile`: a relieved run's terms, no force prior).

Units: pressures MPa, angles rad, forces N.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from . import routes as rt
from .posture import (
    ACTUATORS,
    FRICTION_TERMS,
    INV_2X2_RCOND,
    TORQUE_TERMS,
    PostureModel,
    friction_width,
    pair_motion,
)
from .takuma import TERMS

STEP = 1e-6  # rad: the central step for dF / d(dtheta) (PostureModel._force_covariance's FORCE_STEP)
# Columns of the 14 torque terms before the selection: dP (4), dP_a * dtheta_j (8, a-major), dtheta (2).
_PRODUCT_A = np.repeat(np.arange(4), 2)
_PRODUCT_J = np.tile(np.arange(2), 4)
# The deflections of the five evaluations: as they are, then a step up and down in each.
_OFFSETS = np.array([[0.0, 0.0], [STEP, 0.0], [-STEP, 0.0], [0.0, STEP], [0.0, -STEP]])[:, None, :]


def _angle_gather(terms: tuple[str, ...]) -> tuple[np.ndarray, np.ndarray]:
    """Per term the two columns of ``[u_L1, u_R1, u_L2, u_R2, 1]`` whose product it is."""
    idx = {a: k for k, a in enumerate(ACTUATORS)}
    first, second = [], []
    for t in terms:
        parts = [p[2:] for p in t.split("*")]
        first.append(idx[parts[0]])
        second.append(idx[parts[1]] if len(parts) > 1 else 4)
    return np.array(first, dtype=np.intp), np.array(second, dtype=np.intp)


def _padded(values: Any, rows: list[int], m: int, square: bool = False) -> np.ndarray:
    """``values`` (by the model's own terms) placed at ``rows`` (and, ``square``, columns) of the
    ``m`` terms of both angle designs, zeros elsewhere."""
    v = np.asarray(values, dtype=float)
    if square:
        out = np.zeros((m, m))
        out[np.ix_(rows, rows)] = v
    else:
        out = np.zeros((m, *v.shape[1:]))
        out[rows] = v
    return out


@dataclass(frozen=True)
class _Paper:
    """Eqs. 34-37 behind the paper-routed and blended quantities, as arrays."""

    quantities: tuple[int, ...]  # the quantities (0-3: theta1, theta2, Fx, Fy) on the paper's route or blended
    b1: np.ndarray  # (2,) Eq. 34 on u_L1, u_R1
    b2: np.ndarray  # (4,) Eq. 35
    forces: tuple[np.ndarray, np.ndarray]  # (6,) each: Eq. 36's coefficients, Eq. 37's
    cov_theta: tuple[np.ndarray, np.ndarray]  # (2, 2) and (4, 4): Eqs. 34-35's covariances (zeros if not asked)
    cov_forces: tuple[np.ndarray, np.ndarray]  # (6, 6) each
    variance: np.ndarray  # (4,) per quantity, the held-out variance (0 where the paper's form is not asked)
    max_amplification: float
    blended: np.ndarray  # the quantities blended, their posture weights and error correlations
    weight: np.ndarray
    correlation: np.ndarray
    taken: np.ndarray  # the quantities on the paper's route
    rest_weight: np.ndarray  # 1 - weight, and the blend's cross term 2 w (1 - w) rho (routes.blend_estimate's)
    cross: np.ndarray

    @classmethod
    def of(cls, model: PostureModel) -> _Paper:
        paper = model.paper
        assert paper is not None
        b = paper.coefficients

        def cov(q: str, p: int) -> np.ndarray:
            return np.asarray(paper.covariance[q], dtype=float) if q in model.paper_variance else np.zeros((p, p))

        weight = np.array([model.blends[q]["posture_weight"] for q in rt.QUANTITIES if model.route(q) == rt.BLEND])
        rho = np.array([model.blends[q]["error_correlation"] for q in rt.QUANTITIES if model.route(q) == rt.BLEND])
        return cls(
            tuple(k for k, q in enumerate(rt.QUANTITIES) if model.route(q) != rt.POSTURE),
            np.array([b[t] for t in TERMS["theta1"]]),
            np.array([b[t] for t in TERMS["theta2"]]),
            (np.array([b[t] for t in TERMS["Fx"]]), np.array([b[t] for t in TERMS["Fy"]])),
            (cov("theta1", 2), cov("theta2", 4)),
            (cov("Fx", 6), cov("Fy", 6)),
            np.array([model.paper_variance.get(q, 0.0) for q in rt.QUANTITIES], dtype=float),
            float(paper.max_amplification),
            np.array([k for k, q in enumerate(rt.QUANTITIES) if model.route(q) == rt.BLEND], dtype=np.intp),
            weight,
            rho,
            np.array([k for k, q in enumerate(rt.QUANTITIES) if model.route(q) == rt.PAPER], dtype=np.intp),
            1.0 - weight,
            2.0 * weight * (1.0 - weight) * rho,
        )


@dataclass(frozen=True)
class CompiledPosture:
    """A fitted :class:`PostureModel`'s pressure-only ``predict``, precomputed (module docstring)."""

    h2: float
    h3: float
    angle_first: np.ndarray  # gathers of [u, 1]: the angle terms, then theta1's
    angle_second: np.ndarray
    angle_weights: np.ndarray  # (m, 3 + 2m): deflection coefficients, theta1's, and both (X^T X)^-1
    angle_cov: tuple[float, float, float, float]  # the deflections' residual covariance, row-major
    theta1_var: float | None  # theta1's own residual variance (None: the shared design's)
    torque_select: np.ndarray  # the kept columns of the 14 torque terms
    torque_weights: np.ndarray  # (m_t, 2 + m_t): coefficients and (X^T X)^-1
    torque_cov: tuple[float, float, float]  # the torques' residual covariance: (0, 0), symmetrised (0, 1), (1, 1)
    torque_cov_matrix: np.ndarray  # the same as a (2, 2, 1) matrix
    prior: np.ndarray  # (2, 1): the force prior's variances, N^2
    limits: np.ndarray  # (4,) standard-error limits
    paper: _Paper | None  # Eqs. 34-37 where a quantity takes them (None: the posture form throughout)
    friction_width: np.ndarray | None = None  # (2,) each pair's fade, rad (None: no friction terms)
    # (4,) the plan's direction term of the posture form's variances (routes.held_out_variances; zeros: none)
    held_out: np.ndarray = field(default_factory=lambda: np.zeros(4))

    @classmethod
    def compile(cls, model: PostureModel) -> CompiledPosture | None:
        """The compiled form of ``model``, or None where it does not cover the model (a relieved
        run's terms; no force prior)."""
        known = TORQUE_TERMS + FRICTION_TERMS
        if not model.is_fitted or not model.force_prior_sd or not set(model.torque_terms) <= set(known):
            return None
        # The two designs side by side (a term in both is gathered twice: a file may even list one twice).
        union = model.angle_terms + model.theta1_terms
        m, ma = len(union), len(model.angle_terms)
        at = list(range(ma))
        weights = np.zeros((m, 3 + 2 * m))
        weights[:, :2] = _padded(model.angle_coefficients, at, m)
        weights[:, 3 : 3 + m] = _padded(model.angle_xtx_inv, at, m, square=True)
        if model.theta1_terms:
            t1 = list(range(ma, m))
            weights[:, 2] = _padded(model.theta1_coefficients, t1, m)
            weights[:, 3 + m :] = _padded(model.theta1_xtx_inv, t1, m, square=True)
        first, second = _angle_gather(union)
        mt = len(model.torque_terms)
        torque = np.empty((mt, 2 + mt))
        torque[:, :2] = np.asarray(model.torque_coefficients, dtype=float)
        torque[:, 2:] = np.asarray(model.torque_xtx_inv, dtype=float)
        routes = {model.route(q) for q in rt.QUANTITIES}
        sd = np.asarray(model.force_prior_sd, dtype=float) ** 2
        return cls(
            float(model.geometry["h2"]),
            float(model.geometry["h3"]),
            first,
            second,
            weights,
            _flat(model.angle_resid_cov),
            float(model.theta1_resid_var) if model.theta1_terms else None,
            np.array([known.index(t) for t in model.torque_terms], dtype=np.intp),
            torque,
            _symmetric(model.torque_resid_cov),
            _symmetric_matrix(model.torque_resid_cov),
            sd[:, None],
            np.array([model.limits.get(q, math.inf) for q in rt.QUANTITIES], dtype=float),
            _Paper.of(model) if routes - {rt.POSTURE} and model.paper is not None else None,
            friction_width(model.pair_motion_sd()) if model.uses_history else None,
            np.array([model.held_out_variance.get(q, 0.0) for q in rt.QUANTITIES], dtype=float),
        )

    def predict(
        self, P0: np.ndarray, P: np.ndarray, rest: np.ndarray, motion_in: np.ndarray | None = None
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
        """Values, standard errors and ``ok`` (n, 4) of theta1, theta2, Fx, Fy for (n, 4) pressures
        (MPa) and (n, 2) rest postures (rad), and for a model with the friction terms the joints'
        motion into each baseline (n, 2) rad (None: unknown), as ``PostureModel.predict(...,
        mode="pressure-only")`` gives them; None where a row needs the reference's special cases
        (module docstring)."""
        # NaN compares False and an infinity makes the sum one: a missing pressure lands here too.
        if not (((P0 > 0) & (P > 0)).all() and math.isfinite(float(P0.sum() + P.sum()))):
            return None
        n = len(P)
        th0 = np.where(np.isfinite(rest), rest, 0.0)
        u = P0 / P - 1.0
        dP = P0 - P
        values, se, valid = np.empty((n, 4)), np.empty((n, 4)), np.ones((n, 4), bool)
        weight = np.ones((n, 4))  # the posture form's weight in each estimate
        with np.errstate(over="ignore", invalid="ignore"):  # the paper's standard errors: as the reference's
            dth, cov_a = self._angles(u, values, se)
            if not self._forces(dP, th0, dth, cov_a, values, se, motion_in):
                return None
            if self.paper is not None and not self._paper_routes(u, dP, values, se, valid, weight):
                return None
        ok = (se <= self.limits) & valid
        if self.held_out.any():  # the intervals' direction term, after the flags (PostureModel.predict)
            se = np.sqrt(se * se + weight * weight * self.held_out)
        return values, se, ok

    def _angles(self, u: np.ndarray, values: np.ndarray, se: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """theta1 and the deflection theta2 into ``values``, their standard errors into ``se``; the
        deflections (n, 2) and their covariance (n, 4 row-major) returned for the forces."""
        ua = np.empty((len(u), 5))
        ua[:, :4] = u
        ua[:, 4] = 1.0
        X = ua[:, self.angle_first] * ua[:, self.angle_second]
        Y = X @ self.angle_weights
        m = X.shape[1]
        h = np.einsum("ni,ni->n", X, Y[:, 3 : 3 + m])
        cov = (1.0 + h)[:, None] * np.asarray(self.angle_cov)
        values[:, :2] = Y[:, :2]
        np.sqrt(cov[:, 3], out=se[:, 1])
        if self.theta1_var is None:
            np.sqrt(cov[:, 0], out=se[:, 0])
        else:
            values[:, 0] = Y[:, 2]
            np.sqrt(self.theta1_var * (1.0 + np.einsum("ni,ni->n", X, Y[:, 3 + m :])), out=se[:, 0])
        return Y[:, :2], cov

    def _forces(
        self,
        dP: np.ndarray,
        th0: np.ndarray,
        dth: np.ndarray,
        cov_a: np.ndarray,
        values: np.ndarray,
        se: np.ndarray,
        motion_in: np.ndarray | None = None,
    ) -> bool:
        """Fx, Fy into ``values`` and their standard errors into ``se``: the posterior at the
        deflections, and dF/d(dtheta) by the reference's central step, all five evaluations as one
        batch of rows, both force components as the rows of (2, 5n) arrays; False where the
        adjugate would not invert the posterior."""
        n = len(dP)
        dth5 = dth[None] + _OFFSETS  # (5, n, 2)
        width = 14 if self.friction_width is None else 16
        every = np.empty((5, n, width))
        every[:, :, :4] = dP
        np.multiply(dP[:, _PRODUCT_A], dth5[:, :, _PRODUCT_J], out=every[:, :, 4:12])
        every[:, :, 12:14] = dth5
        if self.friction_width is not None:
            every[:, :, 14:] = self._friction(dth5, motion_in)
        X = every.reshape(5 * n, width)[:, self.torque_select]
        Y = X @ self.torque_weights
        s = 1.0 + np.einsum("ni,ni->n", X, Y[:, 2:])
        th = th0 + dth5
        t = np.empty((2, 5 * n))
        t[0] = th[:, :, 0].ravel()
        np.add(t[0], th[:, :, 1].ravel(), out=t[1])
        cs = np.empty((2, 2, 5 * n))  # cos, sin of theta1 and theta1 + theta2
        np.cos(t, out=cs[0])
        np.sin(t, out=cs[1])
        J = np.empty((2, 2, 5 * n))  # J's first column (J11, J21), then its second
        np.multiply(-self.h3, cs[:, 1], out=J[1])
        np.multiply(-self.h2, cs[:, 0], out=J[0])
        J[0] += J[1]  # -h2 c - h3 c12: the second column's term is the first's too
        ja, jb = J
        PJ = self.prior * J
        pja, pjb = PJ
        # J^T P J + S, its off-diagonal symmetrised as inv_spd_2x2 does: every product of the two
        # columns summed over the components at once ((2, 2, 5n): a, b; -, d), then the residual term.
        JPJ = np.add.reduce(PJ[:, None] * J[None, :], axis=2)
        JPJ += s * self.torque_cov_matrix
        a, b, d = JPJ[0, 0], JPJ[0, 1], JPJ[1, 1]
        det = a * d - b * b
        if not ((det > INV_2X2_RCOND * a * d) & (np.minimum(a, d) > 0)).all():
            return False
        i00, i01, i11 = d / det, -b / det, a / det
        ka, kb = pja * i00 + pjb * i01, pja * i01 + pjb * i11  # the gain's columns
        F = ka * Y[:, 0] + kb * Y[:, 1]  # (2, 5n)
        own = self.prior - (ka[:, :n] * ja[:, :n] + kb[:, :n] * jb[:, :n]) * self.prior
        g1 = (F[:, n : 2 * n] - F[:, 2 * n : 3 * n]) / (2 * STEP)  # dF / d(dtheta1)
        g2 = (F[:, 3 * n : 4 * n] - F[:, 4 * n :]) / (2 * STEP)
        spread = g1 * g1 * cov_a[:, 0] + g1 * g2 * (cov_a[:, 1] + cov_a[:, 2]) + g2 * g2 * cov_a[:, 3]
        values[:, 2:] = F[:, :n].T
        se[:, 2:] = np.sqrt(np.maximum(own + spread, 0.0)).T
        return True

    def _friction(self, dth5: np.ndarray, motion_in: np.ndarray | None) -> np.ndarray:
        """The friction terms (5, n, 2) at the five evaluations' deflections (posture.friction_columns)."""
        from scipy.special import erf

        assert self.friction_width is not None
        now = np.empty_like(dth5)
        now[..., 0] = dth5[..., 0]
        np.add(dth5[..., 0], dth5[..., 1], out=now[..., 1])
        out = erf(np.nan_to_num(now, nan=0.0) / self.friction_width)
        if motion_in is not None:
            m = np.nan_to_num(np.asarray(motion_in, dtype=float), nan=0.0)
            out -= erf(pair_motion(m) / self.friction_width)
        return out

    def _paper_routes(
        self, u: np.ndarray, dP: np.ndarray, values: np.ndarray, se: np.ndarray, valid: np.ndarray, weight: np.ndarray
    ) -> bool:
        """The paper's estimates, or the blends with them, put in place (PostureModel._paper_routes),
        all blended quantities at once, and the posture form's ``weight`` in each; False where
        Eqs. 36-37 meet an arm exactly straight (the reference's stand-in posture)."""
        paper = self._paper_estimates(u, dP)
        if paper is None:
            return False
        v_pa, s_pa, ok_pa = paper
        pa = self.paper
        assert pa is not None
        b, r = pa.blended, pa.taken
        if len(b):
            # routes.blend_estimate's arithmetic, its constant factors worked out once (_Paper.of)
            v_po, s_po, sb = values[:, b], se[:, b], s_pa[:, b]
            var = (pa.weight * s_po) ** 2 + (pa.rest_weight * sb) ** 2 + pa.cross * s_po * sb
            v = pa.weight * v_po + pa.rest_weight * v_pa[:, b]
            sd = np.sqrt(np.maximum(var, 0.0))
            both = ok_pa[:, b] & np.isfinite(v) & np.isfinite(sd)
            values[:, b], se[:, b] = np.where(both, v, v_po), np.where(both, sd, s_po)
            weight[:, b] = np.where(both, pa.weight, 1.0)
        if len(r):
            values[:, r], se[:, r] = v_pa[:, r], s_pa[:, r]
            weight[:, r] = 0.0
            valid[:, r] &= ok_pa[:, r]
        return True

    def _paper_estimates(self, u: np.ndarray, dP: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
        """Values, standard errors (routes.paper_standard_errors) and ``ok`` (TakumaModel.predict's), (n, 4),
        of the paper's form in the columns it is asked for; None at an arm exactly straight."""
        pa = self.paper
        assert pa is not None
        n = len(u)
        sines = np.empty((n, 2))
        sines[:, 0] = u[:, :2] @ pa.b1
        sines[:, 1] = u @ pa.b2
        ok_t = ~(np.abs(sines) > 1.0)
        th = np.arcsin(np.minimum(np.maximum(sines, -1.0), 1.0))  # np.clip's, without its dispatch
        cos = np.cos(th)
        c1, c2, s2 = cos[:, 0], cos[:, 1], np.sin(th[:, 1])
        det = self.h2 * self.h3 * s2
        if not (det != 0.0).all():
            return None
        v, coef, ok = np.zeros((n, 4)), np.zeros((n, 4)), np.zeros((n, 4), bool)
        for q in pa.quantities:
            if q < 2:
                x = u[:, :2] if q == 0 else u
                coef[:, q] = np.einsum("ni,ij,nj->n", x, pa.cov_theta[q], x) / np.maximum(cos[:, q] ** 2, 1e-12)
                v[:, q], ok[:, q] = th[:, q], ok_t[:, q]
                continue
            X, amp = self._paper_design(q - 2, th, c1, c2, s2, det, dP)
            v[:, q] = X @ pa.forces[q - 2]
            coef[:, q] = np.einsum("ni,ij,nj->n", X, pa.cov_forces[q - 2], X)
            ok[:, q] = ok_t[:, 0] & ok_t[:, 1] & (amp <= pa.max_amplification)
        if not np.isfinite(v).all():
            return None
        return v, np.sqrt(pa.variance + np.where(np.isfinite(coef), np.maximum(coef, 0.0), np.inf)), ok

    def _paper_design(
        self,
        k: int,
        th: np.ndarray,
        c1: np.ndarray,
        c2: np.ndarray,
        s2: np.ndarray,
        det: np.ndarray,
        dP: np.ndarray,
    ) -> tuple[np.ndarray, np.ndarray]:
        """Eq. 36's (k = 0) or Eq. 37's (k = 1) design (n, 6) at the paper's angles (n, 2), and the
        force's amplification (models/takuma.py: force_design, geometry.force_amplification)."""
        h2, h3 = self.h2, self.h3
        t12 = th[:, 0] + th[:, 1]
        # Row k of (J^-1)^T = [[J11, -J10], [-J01, J00]] / det J (geometry.jstar).
        if k == 0:
            s12 = np.sin(t12)
            ja, jb = -h3 * s12 / det, -(-h2 * np.sin(th[:, 0]) - h3 * s12) / det
        else:
            c12 = np.cos(t12)
            ja, jb = -(-h3 * c12) / det, (-h2 * c1 - h3 * c12) / det
        frob2 = h2**2 + 2.0 * h3**2 + 2.0 * h2 * h3 * c2
        smax2 = 0.5 * (frob2 + np.sqrt(np.maximum(frob2**2 - 4.0 * np.abs(det) ** 2, 0.0)))
        # The six columns: each a weight (outer, outer, inner, inner, lower, lower) times a pressure drop.
        weights = np.empty((len(dP), 3))
        np.multiply(ja, c1, out=weights[:, 0])
        np.multiply(ja, c1 - c2, out=weights[:, 1])
        np.multiply(jb, c2, out=weights[:, 2])
        X = weights[:, _DESIGN_WEIGHT] * dP[:, _DESIGN_DROP]
        return X, np.sqrt(ja * ja + jb * jb) * np.sqrt(smax2)


# Eqs. 36-37's design columns: which of (outer, inner, lower) and which pressure drop each multiplies.
_DESIGN_WEIGHT = np.array([0, 0, 1, 1, 2, 2], dtype=np.intp)
_DESIGN_DROP = np.array([0, 1, 2, 3, 2, 3], dtype=np.intp)


def _flat(m: Any) -> tuple[float, float, float, float]:
    a = np.asarray(m, dtype=float)
    return float(a[0, 0]), float(a[0, 1]), float(a[1, 0]), float(a[1, 1])


def _symmetric(m: Any) -> tuple[float, float, float]:
    a = np.asarray(m, dtype=float)
    return float(a[0, 0]), 0.5 * (float(a[0, 1]) + float(a[1, 0])), float(a[1, 1])


def _symmetric_matrix(m: Any) -> np.ndarray:
    r00, r01, r11 = _symmetric(m)
    return np.array([[r00, r01], [r01, r11]])[:, :, None]
