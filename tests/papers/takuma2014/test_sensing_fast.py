"""The run-time estimator's cheaper model call held to the reference arithmetic it replaces.

The force posterior's 2 x 2 inverse is the adjugate over the determinant where that is well
conditioned (``np.linalg.pinv`` for the rest), and the sensing adapter works each calibrated
range's ends out once per margin instead of every block.  Both must give what the reference
gives, to rounding, on the rig's own models and on the matrices where the shortcut stops.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from labcli.core.protocol import load_protocol
from labcli.papers.takuma2014.models import posture
from labcli.papers.takuma2014.sensing import MIN_PAD, TakumaSensing
from labcli.papers.takuma2014.sim import scenario as sc
from labcli.sensing.evaluate import Inputs2, evaluate


def reference_inverse(M: np.ndarray) -> np.ndarray:
    return np.linalg.pinv(M, hermitian=True)


def test_the_closed_form_inverse_is_the_pseudo_inverse_wherever_it_is_taken():
    rng = np.random.default_rng(7)
    A = rng.normal(size=(500, 2, 2))
    spd = A @ np.swapaxes(A, 1, 2) + 1e-3 * np.eye(2)
    np.testing.assert_allclose(posture.inv_spd_2x2(spd), reference_inverse(spd), rtol=1e-9, atol=0)


def test_near_singular_and_singular_matrices_take_the_pseudo_inverse():
    v = np.array([1.0, 2.0]) / math.sqrt(5.0)
    singular = np.outer(v, v)[None] * 3.0  # rank one: no inverse, a pseudo-inverse
    nearly = singular + 1e-12 * np.eye(2)[None]
    zero = np.zeros((1, 2, 2))
    M = np.concatenate([singular, nearly, zero, np.eye(2)[None]])
    got = posture.inv_spd_2x2(M)
    np.testing.assert_allclose(got[:3], reference_inverse(M[:3]), rtol=1e-12, atol=1e-12)
    np.testing.assert_array_equal(got[3], np.eye(2))
    assert np.all(np.isfinite(got))


@pytest.fixture(scope="module")
def sensing():
    return TakumaSensing(sc.calibrate(load_protocol("takuma2014"), 2))


def blocks(n: int, seed: int) -> list[Inputs2]:
    """What the estimator asks of the model over a session: idle and loaded blocks, small and large steps."""
    rng = np.random.default_rng(seed)
    out = []
    for i in range(n):
        P0 = rng.uniform(0.25, 0.35, 4)
        rest = np.radians(rng.uniform(-20, 20, 2))
        dP = rng.normal(0.0, 0.02, 4)
        var = rng.uniform(1e-8, 1e-4, 4)
        if i % 2:
            out.append(Inputs2(P0, rest, P0 - dP, var, P0 - dP, var))
        else:
            out.append(Inputs2(P0, rest, P0 - dP, var, P0 - 1.2 * dP, 2 * var))
    return out


def test_each_blocks_estimate_is_the_reference_arithmetics(sensing, monkeypatch):
    assert sensing.model.force_prior_sd, "the rig's models carry a force prior: the gain form is what is tested"
    inputs = blocks(60, 3)
    fast = [evaluate(sensing, x) for x in inputs]
    monkeypatch.setattr(posture, "inv_spd_2x2", reference_inverse)
    for x, (values, se, flags) in zip(inputs, fast, strict=True):
        ref_values, ref_se, ref_flags = evaluate(TakumaSensing(sensing.model, margin=sensing.margin), x)
        np.testing.assert_allclose(values, ref_values, rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(se, ref_se, rtol=1e-8, atol=1e-12)
        assert flags == ref_flags


def reference_outside(model: TakumaSensing, key: str, x: np.ndarray) -> np.ndarray:
    ranges = np.asarray(model.calibrated_range[key], dtype=float)
    lo, hi = ranges[:, 0], ranges[:, 1]
    pad = np.maximum(model.margin * (hi - lo), MIN_PAD.get(key, lambda r: 0.0)(ranges))
    return (x < lo - pad) | (x > hi + pad)


@pytest.mark.parametrize("margin", [0.0, 0.1, 0.5])
def test_the_range_flags_follow_the_margin_as_it_is_now(sensing, margin):
    model = TakumaSensing(sensing.model)
    model._outside(np.full((1, 4), 0.3), np.full((1, 4), 0.3), np.zeros((1, 2)), np.zeros((1, 4)))  # cached at 10 %
    model.margin = margin
    rng = np.random.default_rng(11)
    cr = model.calibrated_range
    spread = np.asarray(cr["dP_MPa"], dtype=float)
    P0 = np.full((400, 4), 0.3)
    span = np.ptp(spread, axis=1)
    P = P0 - rng.uniform(spread[:, 0] - span, spread[:, 1] + span, size=(400, 4))
    values = np.column_stack([np.radians(rng.uniform(-60, 60, (400, 2))), rng.uniform(-15, 15, (400, 2))])
    rest = np.radians(np.asarray(cr["rest_deg"], dtype=float).mean(axis=1))[None].repeat(400, axis=0)
    inputs, est = model._outside(P0, P, rest, values)
    want = reference_outside(model, "dP_MPa", P0 - P).any(axis=1) | reference_outside(model, "P0_MPa", P0).any(axis=1)
    want |= reference_outside(model, "rest_deg", np.degrees(rest)).any(axis=1)
    np.testing.assert_array_equal(inputs, want)
    np.testing.assert_array_equal(est[:, :2], reference_outside(model, "theta_deg", np.degrees(values[:, :2])))
    np.testing.assert_array_equal(est[:, 2:], reference_outside(model, "F_N", values[:, 2:]))
    assert 0 < inputs.sum() < 400
