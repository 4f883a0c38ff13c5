"""The two-link arm of Takuma et al. (2014): contact point C(theta) and Jacobian J(theta).

Origin at the bottom joint, x to the right, y up, angles counter-clockwise; lengths in m,
angles in rad.  The force regression (Eqs. 36-37) needs ``(J^-1)^T`` and how well it is
conditioned; the stiffness construction of Section 4 needs C and J themselves.

The simulated rig (``labcli.papers.takuma2014.sim.physics``) keeps its own copy on purpose: it is the ground truth
these models are checked against, so a slip here must not be shared by it.
"""

from __future__ import annotations

import numpy as np


def contact_point(theta1: np.ndarray, theta2: np.ndarray, h2: float, h3: float) -> np.ndarray:
    """Contact point C(theta1, theta2), shape (n, 2) in m (Section 4)."""
    t1 = np.asarray(theta1, dtype=float)
    t12 = t1 + np.asarray(theta2, dtype=float)
    x = -h2 * np.sin(t1) - h3 * np.sin(t12)
    y = h2 * np.cos(t1) + h3 * np.cos(t12)
    return np.stack(np.broadcast_arrays(x, y), axis=-1).reshape(-1, 2)


def jacobian(theta1: np.ndarray, theta2: np.ndarray, h2: float, h3: float) -> np.ndarray:
    """dC/dtheta, shape (n, 2, 2): the matrix J of Section 2.2.2 (tau = J^T F)."""
    t1 = np.atleast_1d(np.asarray(theta1, dtype=float))
    t12 = t1 + np.atleast_1d(np.asarray(theta2, dtype=float))
    t1, t12 = np.broadcast_arrays(t1, t12)
    J = np.empty(t1.shape + (2, 2))
    # The outer link's terms once each (the same numbers as writing them out twice).
    c12, s12 = -h3 * np.cos(t12), -h3 * np.sin(t12)
    J[..., 0, 0] = -h2 * np.cos(t1) + c12
    J[..., 0, 1] = c12
    J[..., 1, 0] = -h2 * np.sin(t1) + s12
    J[..., 1, 1] = s12
    return J


def jstar(theta: np.ndarray, h2: float, h3: float) -> np.ndarray:
    """Elements of ``(J^-1)^T`` (1/m), shape (n, 2, 2), for angles (n, 2) in rad.

    Infinite where sin(theta2) = 0; callers keep such postures out (see jacobian_cond).
    """
    theta = np.atleast_2d(np.asarray(theta, dtype=float))
    J = jacobian(theta[:, 0], theta[:, 1], h2, h3)
    # det J in closed form: exactly 0 at theta2 = 0, where the product formula leaves rounding noise.
    det = h2 * h3 * np.sin(theta[:, 1])
    out = np.empty_like(J)
    with np.errstate(divide="ignore", invalid="ignore"):
        # (J^-1)^T = [[J22, -J21], [-J12, J11]] / det J
        out[:, 0, 0] = J[:, 1, 1] / det
        out[:, 0, 1] = -J[:, 1, 0] / det
        out[:, 1, 0] = -J[:, 0, 1] / det
        out[:, 1, 1] = J[:, 0, 0] / det
    return out


def _smax2_det(theta2: np.ndarray, h2: float, h3: float) -> tuple[np.ndarray, np.ndarray]:
    """Largest squared singular value of J and |det J|; both depend on theta2 only."""
    frob2 = h2**2 + 2.0 * h3**2 + 2.0 * h2 * h3 * np.cos(theta2)
    det = np.abs(h2 * h3 * np.sin(theta2))
    smax2 = 0.5 * (frob2 + np.sqrt(np.maximum(frob2**2 - 4.0 * det**2, 0.0)))
    return smax2, det


def jacobian_cond(theta2: np.ndarray, h2: float, h3: float) -> np.ndarray:
    """2-norm condition number of J; depends on theta2 only (inf at theta2 = 0)."""
    smax2, det = _smax2_det(np.asarray(theta2, dtype=float), h2, h3)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(det > 0, smax2 / det, np.inf)


def force_amplification(theta: np.ndarray, h2: float, h3: float, js: np.ndarray | None = None) -> np.ndarray:
    """Per-component amplification ``||row_k (J^-1)^T|| ||J||`` (n, 2) for Fx, Fy (inf if singular).

    ``js``: ``jstar(theta, h2, h3)`` when the caller has it already.
    """
    theta = np.atleast_2d(np.asarray(theta, dtype=float))
    smax2, det = _smax2_det(theta[:, 1], h2, h3)
    js = jstar(theta, h2, h3) if js is None else js
    with np.errstate(invalid="ignore"):
        # Each row's norm written out: numpy's norm along a 2-wide axis sums these same two squares
        # (the same bits), at ten times the cost.
        amp = np.sqrt(js[:, :, 0] * js[:, :, 0] + js[:, :, 1] * js[:, :, 1]) * np.sqrt(smax2)[:, None]
    return np.where(det[:, None] > 0, amp, np.inf)
