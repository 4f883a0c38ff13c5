"""The run-time estimator's cheaper model call held to the reference arithmetic it replaces.

* The force posterior's 2 x 2 inverse is the adjugate over the determinant where that is well
  conditioned (``np.linalg.pinv`` for the rest).
* The sensing adapter works each calibrated range's ends out once per margin instead of every block.
* The posture form's pressure-only predict compiled for a few rows (models/posture_fast.py),
  which the adapter takes for the estimator's calls: values to 1e-12, standard errors to 1e-8
  (dF/d(dtheta) is a difference over a 1e-6 rad step, so rounding in F is magnified a millionfold
  there) and flags exactly, against the model's own predict (``TakumaSensing(fast=False)``), on
  the rig's models and on files with every route, term and shape the form reads; on random
  blocks, on inputs outside the calibrated range, on the straight arm (Fy unobservable), on the
  wide load guesses of a transient, on the rows it hands back to the reference, and over a whole
  session through the estimator.

Each must give what the reference gives, to rounding, and where the shortcut stops, the reference.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from labcli.core.protocol import load_protocol
from labcli.papers.takuma2014.models import posture, posture_fast
from labcli.papers.takuma2014.models.posture import PostureModel
from labcli.papers.takuma2014.models.posture_fast import CompiledPosture
from labcli.papers.takuma2014.sensing import MIN_PAD, TakumaSensing
from labcli.papers.takuma2014.sim import scenario as sc
from labcli.sensing import Estimate, Event
from labcli.sensing.estimator import MAX_VAR
from labcli.sensing.evaluate import Inputs2, evaluate
from labcli.sensing.offline import replay


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


def same_estimates(fast, reference, inputs):
    """Each block's estimate by both adapters: values, standard errors and flags as the module docstring says."""
    for x in inputs:
        values, se, flags = evaluate(fast, x)
        ref_values, ref_se, ref_flags = evaluate(reference, x)
        np.testing.assert_allclose(values, ref_values, rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(se, ref_se, rtol=1e-8, atol=1e-12)
        assert flags == ref_flags


def test_each_blocks_estimate_is_the_reference_arithmetics(sensing, monkeypatch):
    assert sensing.model.force_prior_sd, "the rig's models carry a force prior: the gain form is what is tested"
    inputs = blocks(60, 3)
    table_form = TakumaSensing(sensing.model, margin=sensing.margin, fast=False)
    fast = [evaluate(table_form, x) for x in inputs]
    monkeypatch.setattr(posture, "inv_spd_2x2", reference_inverse)
    for x, (values, se, flags) in zip(inputs, fast, strict=True):
        ref_values, ref_se, ref_flags = evaluate(TakumaSensing(sensing.model, margin=sensing.margin, fast=False), x)
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


# --------------------------------------------------------------------------- the compiled posture form


def variant(model: PostureModel, **changes) -> PostureModel:
    """The model with some of its file's keys changed, read back as a file is (every check applied)."""
    d = model.to_dict() | changes
    return PostureModel.from_dict(d, name="a test model")


def every_route(model: PostureModel) -> list[PostureModel]:
    """The rig's model as fitted, and files that route, blend and grow its terms every way the form reads."""
    d = model.to_dict()
    paper_var = {"theta1": 2e-6, "theta2": 3e-6, "Fx": 0.09, "Fy": 0.2}
    # Two more angle terms, one of them listed twice (a hand-edited file), and no theta1 equation of its own.
    m = len(d["angle_terms"])
    grown = d["angle_terms"] + ["u_L1*u_R2", d["angle_terms"][-1]]
    inv = np.eye(m + 2) * 0.3
    inv[:m, :m] = np.asarray(d["angle_xtx_inv"])
    # All 14 torque terms, on the fitted ones' scales (N m per MPa, per MPa rad, per rad).
    rng = np.random.default_rng(2)
    drops = np.asarray(d["torque_coefficients"])[:4]
    torque = np.vstack([drops, rng.normal(0.0, 500.0, (8, 2)), rng.normal(0.0, 10.0, (2, 2))])
    return [
        model,
        variant(model, routes={q: "posture" for q in paper_var}, blends={}, paper_variance={}, paper_model=None),
        variant(
            model,
            routes={"theta1": "paper", "theta2": "blend", "Fx": "paper", "Fy": "blend"},
            paper_variance=paper_var,
            blends={
                q: {"posture_weight": w, "error_correlation": r}
                for q, w, r in (("theta2", 0.3, 0.6), ("Fy", 0.8, -0.2))
            },
            # The fit plan's direction term on every quantity: none on the paper's route, w^2 of it in a blend.
            held_out_variance={"theta1": 1e-6, "theta2": 2e-6, "Fx": 0.1, "Fy": 0.2},
        ),
        variant(
            model,
            angle_terms=grown,
            angle_coefficients=d["angle_coefficients"] + [[0.02, -0.05], [-0.01, 0.03]],
            angle_xtx_inv=inv.tolist(),
            theta1_terms=[],
            theta1_coefficients=[],
            theta1_xtx_inv=[],
            torque_terms=list(posture.TORQUE_TERMS),
            torque_coefficients=torque.tolist(),
            torque_xtx_inv=np.diag([2e6] * 4 + [1e8] * 8 + [4e3] * 2).tolist(),
        ),
    ]


@pytest.fixture(scope="module")
def models():
    protocol = load_protocol("takuma2014")
    return [m for seed in (2, 5) for m in every_route(sc.calibrate(protocol, seed))]


def pairs(models, margin=0.1):
    for m in models:
        fast = TakumaSensing(m, margin=margin)
        assert fast._compiled is not None
        yield fast, TakumaSensing(m, margin=margin, fast=False)


def test_the_compiled_form_gives_the_models_own_estimates_on_random_blocks(models):
    for fast, reference in pairs(models):
        same_estimates(fast, reference, blocks(40, 4))


def test_the_compiled_form_gives_the_models_own_rows(models):
    """Whole Predictions (every sigma row, not only what a block reads), inputs in and far out of range."""
    rng = np.random.default_rng(9)
    n = 80
    P0 = rng.uniform(0.15, 0.45, (n, 4))
    P = P0 - rng.normal(0.0, 0.04, (n, 4)) * np.repeat([0.1, 0.3, 1.0, 2.0], n // 4)[:, None]
    rest = np.radians(rng.uniform(-40, 40, (n, 2)))
    raised = set()
    for fast, reference in pairs(models, margin=0.0):
        got, want = fast.predict(P0, P, rest), reference.predict(P0, P, rest)
        np.testing.assert_allclose(got.values, want.values, rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(got.se, want.se, rtol=1e-8, atol=1e-12)
        assert got.flags == want.flags
        raised |= {f for row in got.flags for f in row}
    # The rows reach the flags a block can raise: inputs and estimates out of range, components unreported.
    assert {"out-of-range", "unobservable:Fy", "unobservable:theta1"} <= raised
    assert any(f.startswith("out-of-range:") for f in raised), raised


def test_on_the_straight_arm_fy_is_unobservable_as_the_reference_says(models):
    rng = np.random.default_rng(12)
    inputs = []
    for _ in range(20):
        P0 = rng.uniform(0.28, 0.32, 4)
        dP = rng.normal(0.0, 0.003, 4)
        var = rng.uniform(1e-8, 1e-6, 4)
        inputs.append(Inputs2(P0, np.zeros(2), P0 - dP, var, P0 - dP, var))
    for fast, reference in pairs(models):
        same_estimates(fast, reference, inputs)
    flags = [evaluate(TakumaSensing(models[0]), x)[2] for x in inputs]
    assert sum("unobservable:Fy" in f for f in flags) >= 15, flags


def test_a_transients_wide_load_guess_is_the_references(models):
    """The first blocks of a change: the load's pressures barely known (MAX_VAR), steps capped, far from the state's."""
    rng = np.random.default_rng(13)
    inputs = []
    for i in range(30):
        P0 = rng.uniform(0.25, 0.35, 4)
        rest = np.radians(rng.uniform(-15, 15, 2))
        P_state = P0 - rng.normal(0.0, 0.01, 4)
        var_state = rng.uniform(1e-7, 1e-5, 4)
        P_load = P_state - rng.normal(0.0, 0.03, 4)
        var_load = np.full(4, MAX_VAR) if i % 2 else rng.uniform(1e-6, MAX_VAR, 4)
        var_state[i % 4] = 0.0  # a channel whose step is nil: its slope is taken as 0
        inputs.append(Inputs2(P0, rest, P_state, var_state, P_load, var_load))
    for fast, reference in pairs(models):
        same_estimates(fast, reference, inputs)


@pytest.mark.parametrize(
    "P0, P",
    [
        # No change at all: Eqs. 36-37's arm is exactly straight (the posture form alone takes it in its stride).
        ([0.3, 0.3, 0.3, 0.3], [0.3, 0.3, 0.3, 0.3]),
        ([0.3, 0.3, 0.3, 0.3], [0.3, np.nan, 0.29, 0.31]),  # a pressure missing
        ([0.3, 0.3, 0.3, 0.3], [0.3, 0.0, 0.29, 0.31]),  # a pressure not positive
        ([0.3, 0.3, np.inf, 0.3], [0.3, 0.31, 0.29, 0.31]),
    ],
)
def test_rows_the_compiled_form_leaves_to_the_reference_get_its_answer(models, P0, P):
    P0 = np.array([P0, [0.3, 0.31, 0.29, 0.3]])
    P = np.array([P, [0.29, 0.3, 0.3, 0.31]])
    rest = np.zeros((2, 2))
    straight = np.array_equal(P0[0], P[0])
    for fast, reference in pairs(models):
        declined = fast._compiled.predict(P0, P, rest) is None
        assert declined or (straight and fast._compiled.paper is None)
        got, want = fast.predict(P0, P, rest), reference.predict(P0, P, rest)
        np.testing.assert_allclose(got.values, want.values, rtol=1e-12 * (not declined), atol=1e-12 * (not declined))
        np.testing.assert_allclose(got.se, want.se, rtol=1e-8 * (not declined), atol=1e-12 * (not declined))
        assert got.flags == want.flags


def test_a_posterior_the_adjugate_cannot_invert_goes_to_the_reference(models, monkeypatch):
    fast, reference = next(pairs(models[:1]))
    x = blocks(1, 5)[0]
    monkeypatch.setattr(posture_fast, "INV_2X2_RCOND", 1.0)  # det / (a d) <= 1 always: every row declined
    assert fast._compiled.predict(np.atleast_2d(x.P0), np.atleast_2d(x.P_state), np.atleast_2d(x.rest)) is None
    assert evaluate(fast, x)[2] == evaluate(reference, x)[2]


def test_the_forms_the_compiled_form_does_not_cover_take_the_models_own_predict(models):
    rng = np.random.default_rng(3)
    base = models[0]
    relieved = variant(
        base,
        torque_terms=list(base.torque_terms) + ["friction_rest"],
        torque_coefficients=base.torque_coefficients + [[0.01, -0.02]],
        torque_xtx_inv=np.eye(len(base.torque_terms) + 1).tolist(),
    )
    no_prior = variant(base, force_prior_sd=[])
    for m in (relieved, no_prior):
        assert CompiledPosture.compile(m) is None
        assert TakumaSensing(m)._compiled is None
    assert CompiledPosture.compile(PostureModel(geometry=base.geometry)) is None  # not fitted
    # A table (``labcli predict``) takes the model's own predict, to the last bit.
    n = 100
    P0 = rng.uniform(0.25, 0.35, (n, 4))
    P = P0 - rng.normal(0.0, 0.02, (n, 4))
    rest = np.radians(rng.uniform(-20, 20, (n, 2)))
    got, want = TakumaSensing(base).predict(P0, P, rest), TakumaSensing(base, fast=False).predict(P0, P, rest)
    np.testing.assert_array_equal(got.values, want.values)
    np.testing.assert_array_equal(got.se, want.se)


def test_a_whole_session_through_the_estimator_is_the_references(sensing):
    """Idle, a load's transient, settled, released: every estimate and event of the stream, both ways."""
    protocol = load_protocol("takuma2014")
    from labcli.papers.takuma2014.sim.script import parse_script

    script = parse_script(
        {
            "air": {"supply_s": 0.0, "close_s": 6.0},
            "load": [{"at_s": 25.0, "hold_s": 12.0, "mass_g": 600.0, "direction_deg": -40.0}],
            "idle": [{"from_s": 50.0, "to_s": 55.0}],
        }
    )
    s = sc.run_session(sensing.model, protocol, script, 2)
    cal = protocol.calibration
    cols = [cal.index(n) for n in ("P_L1", "P_R1", "P_L2", "P_R2", "POT1", "POT2")]
    runs = [
        replay(m, s.t_s, s.si[:, cols], rate_hz=200.0, batch=10)
        for m in (sensing, TakumaSensing(sensing.model, fast=False))
    ]
    got, want = runs
    assert [(type(i), getattr(i, "kind", None)) for i in got] == [(type(i), getattr(i, "kind", None)) for i in want]
    estimates = [(a, b) for a, b in zip(got, want, strict=True) if isinstance(a, Estimate)]
    assert len(estimates) > 300 and {a.state for a, _ in estimates} >= {"idle", "loading", "loaded"}
    assert any("transient" in a.flags for a, _ in estimates)
    for a, b in estimates:
        assert a.flags == b.flags and a.state == b.state
        np.testing.assert_allclose(list(a.values.values()), list(b.values.values()), rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(list(a.se.values()), list(b.se.values()), rtol=1e-8, atol=1e-12)
    assert sum(isinstance(i, Event) for i in got) >= 2


def test_the_friction_terms_compiled_read_the_motion_into_the_baseline_as_the_model_does(models):
    """The sleeves' friction terms (both pairs) on every route: the compiled form, given each row's
    motion into its baseline or none, is the model's own predict; its dF/d(dtheta) by the central
    step where the model writes the faded signs' slope out, the two within 1e-6 (the step's error on
    the erf's curvature within its 0.1 deg fade)."""
    rng = np.random.default_rng(14)
    n = 80
    P0 = rng.uniform(0.15, 0.45, (n, 4))
    P = P0 - rng.normal(0.0, 0.004, (n, 4))  # deflections of a few tenths of a degree: within and past the fade
    rest = np.radians(rng.uniform(-20, 20, (n, 2)))
    moved = rng.normal(0.0, np.radians(0.5), (n, 2))
    shifted = 0
    for base in models:
        m = variant(
            base,
            torque_terms=list(base.torque_terms) + ["friction1", "friction2"],
            torque_coefficients=base.torque_coefficients + [[0.05, -0.02], [-0.01, 0.04]],
            torque_xtx_inv=np.diag(np.r_[np.diag(np.asarray(base.torque_xtx_inv)), 0.05, 0.05]).tolist(),
        )
        fast, reference = TakumaSensing(m), TakumaSensing(m, fast=False)
        assert fast._compiled is not None and fast.uses_history
        for motion in (moved, None):
            got, want = fast.predict(P0, P, rest, motion), reference.predict(P0, P, rest, motion)
            np.testing.assert_allclose(got.values, want.values, rtol=1e-12, atol=1e-12)
            np.testing.assert_allclose(got.se, want.se, rtol=1e-6, atol=1e-12)
            assert got.flags == want.flags
        shifted += np.max(np.abs(fast.predict(P0, P, rest, moved).values - fast.predict(P0, P, rest).values)) > 0.05
    assert shifted == len(models)  # the motion into the baseline moves the forces on every model
