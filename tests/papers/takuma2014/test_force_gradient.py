"""The posture form's dF/d(dtheta) in closed form held to central differences of the forces themselves.

``PostureModel._force_covariance`` carries the deflections' error into the forces through
dF/d(dtheta); written out (``_force_gradient``) it replaces five evaluations of the posterior
by one.  Here it must equal central differences of ``_forces`` on random models (every torque
term, random coefficients, leverages and residual covariances) and random inputs, within the
differences' own error; the covariance must equal the stepped one's; and a model it does not
cover (no force prior, friction terms) must take the stepped path.
"""

from __future__ import annotations

import numpy as np
import pytest

from labcli.papers.takuma2014.models.posture import (
    FRICTION_TERMS,
    TORQUE_TERMS,
    PostureModel,
)

GEOMETRY = {"h2": 0.13, "h3": 0.065}


def random_spd(rng: np.random.Generator, k: int, scale: float) -> list[list[float]]:
    A = rng.normal(size=(k, k))
    return (scale * (A @ A.T + 0.1 * np.eye(k))).tolist()


def random_model(seed: int, terms: tuple[str, ...] = TORQUE_TERMS, prior: bool = True) -> PostureModel:
    rng = np.random.default_rng(seed)
    p = len(terms)
    return PostureModel(
        geometry=GEOMETRY,
        torque_terms=terms,
        torque_coefficients=rng.normal(0.0, 0.3, (p, 2)).tolist(),
        torque_xtx_inv=random_spd(rng, p, 1e-3),
        torque_resid_cov=random_spd(rng, 2, 1e-4),
        force_prior_sd=rng.uniform(1.0, 5.0, 2).tolist() if prior else [],
    )


def random_inputs(seed: int, n: int) -> tuple[np.ndarray, ...]:
    rng = np.random.default_rng(seed)
    dP = rng.uniform(-0.1, 0.4, (n, 4))
    th0 = rng.uniform(-0.5, 0.5, (n, 2))
    dth = rng.normal(0.0, 0.2, (n, 2))
    A = rng.normal(0.0, 1e-2, (n, 2, 2))
    return dP, th0, dth, A @ np.swapaxes(A, 1, 2)


def stepped_gradient(model: PostureModel, dP, th0, dth, step: float = 1e-5) -> np.ndarray:
    G = np.empty((len(dP), 2, 2))
    for k in range(2):
        d = np.zeros(2)
        d[k] = step
        ahead, _ = model._forces(dP, th0, dth + d, want_cov=False)
        behind, _ = model._forces(dP, th0, dth - d, want_cov=False)
        G[:, :, k] = (ahead - behind) / (2 * step)
    return G


@pytest.mark.parametrize("seed", [1, 2, 3, 4])
def test_the_closed_form_derivative_is_the_central_differences(seed):
    model = random_model(seed)
    dP, th0, dth, _ = random_inputs(seed + 100, 2000)
    G = model._force_gradient(dP, th0, dth)
    assert G is not None
    ref = stepped_gradient(model, dP, th0, dth)
    # The differences' truncation (step^2 F''') and rounding (eps F / step) bound their own error.
    scale = np.abs(ref).max(axis=(1, 2))[:, None, None] + 1e-3
    assert np.max(np.abs(G - ref) / scale) < 1e-6
    # A wrong sign or a missing term would be far off: the derivative is not small.
    assert np.median(np.abs(ref)) > 1e-2


@pytest.mark.parametrize("terms", [TORQUE_TERMS[:4], TORQUE_TERMS[:4] + TORQUE_TERMS[12:], TORQUE_TERMS])
def test_the_covariance_is_the_stepped_ones_for_every_kind_of_term(terms):
    model = random_model(9, terms)
    dP, th0, dth, cov = random_inputs(10, 3000)
    F, C = model._force_covariance(dP, th0, dth, cov)
    F_ref, C_ref = model._force_covariance(dP, th0, dth, cov, closed_form=False)
    np.testing.assert_array_equal(F, F_ref)  # the forces themselves are computed as before
    scale = np.abs(C_ref).max(axis=(1, 2))[:, None, None]
    assert np.max(np.abs(C - C_ref) / scale) < 1e-7
    # The deflections' share is there: without it the covariance would be smaller.
    _, C_torque = model._forces(dP, th0, dth)
    assert np.median(np.trace(C - C_torque, axis1=1, axis2=2)) > 0


def test_models_without_a_prior_take_the_central_differences():
    dP, th0, dth, cov = random_inputs(5, 200)
    model = random_model(3, prior=False)
    assert model._force_gradient(dP, th0, dth) is None
    F, C = model._force_covariance(dP, th0, dth, cov)
    F_ref, C_ref = model._force_covariance(dP, th0, dth, cov, closed_form=False)
    np.testing.assert_array_equal(F, F_ref)
    np.testing.assert_array_equal(C, C_ref)


@pytest.mark.parametrize("sd", [None, (1e-3, 2e-3)])
def test_the_friction_terms_derivative_is_the_central_differences(sd):
    """The friction terms' faded signs are steep within their fade (0.1 deg, widened by the
    estimated motion's error): deflections there, and motions into the baseline either way."""
    rng = np.random.default_rng(6)
    model = random_model(4, TORQUE_TERMS + FRICTION_TERMS)
    dP, th0, _, cov = random_inputs(5, 2000)
    dth = rng.normal(0.0, 0.004, (2000, 2))
    moved = rng.normal(0.0, 0.01, (2000, 2))
    motion_sd = None if sd is None else np.array(sd)
    G = model._force_gradient(dP, th0, dth, moved, motion_sd)
    assert G is not None
    F, C = model._force_covariance(dP, th0, dth, cov, moved, motion_sd)
    F_ref, C_ref = model._force_covariance(dP, th0, dth, cov, moved, motion_sd, closed_form=False)
    np.testing.assert_array_equal(F, F_ref)
    scale = np.abs(C_ref).max(axis=(1, 2))[:, None, None]
    # Within the differences' own error (measured 1.6e-6 and 2.7e-6: the erf's curvature over a step
    # of 1e-6 within a fade of 2.5e-3, and rounding).
    assert np.max(np.abs(C - C_ref) / scale) < 1e-5
    # The terms' own share: without their slope the derivative would be another.
    plain = random_model(4, TORQUE_TERMS + FRICTION_TERMS)
    plain.torque_coefficients = [list(r) for r in np.asarray(model.torque_coefficients)[:-2]] + [[0.0, 0.0]] * 2
    assert np.median(np.abs(G - plain._force_gradient(dP, th0, dth, moved, motion_sd))) > 1e-2


def test_a_posterior_the_adjugate_cannot_invert_takes_the_central_differences():
    model = random_model(7)
    model.torque_resid_cov = [[0.0, 0.0], [0.0, 0.0]]
    model.force_prior_sd = [2.0, 0.0]  # J^T P J + S of rank one: no inverse
    dP, th0, dth, _ = random_inputs(8, 50)
    assert model._force_gradient(dP, th0, dth) is None
