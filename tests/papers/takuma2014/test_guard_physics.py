"""The load check's physics prior (guard_prior.PhysicsPrior) against the rig's statics."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest

import labcli.papers.takuma2014.guard_prior as gp
from labcli.core.guard import PRIOR_SHARE, Watch
from labcli.core.protocol import load_protocol
from labcli.papers.takuma2014.guard_prior import PhysicsPrior
from labcli.papers.takuma2014.sim import physics as ph

PROTOCOL = load_protocol("takuma2014")
UPRIGHT = np.zeros(2)
SUPPLY = np.full(4, 0.30)
STEP = 1.01 * gp.SHARE_MAX / (len(gp._SHARES) - 1)  # the grid the friction a trial shows is read on


def pull(mass_g: float, direction_deg: float) -> np.ndarray:
    a = math.radians(direction_deg)
    return mass_g / 1000.0 * ph.G * np.array([math.cos(a), math.sin(a)])


@pytest.fixture
def prior() -> PhysicsPrior:
    p = PhysicsPrior.of(PROTOCOL)
    assert p is not None
    return p


def test_without_friction_the_least_motion_is_the_closed_rigs_deflection(prior, monkeypatch):
    # Small loads on the symmetric design rig, valves closed at 0.30 MPa: the linear response
    # K^-1 J^T F agrees with the full nonlinear equilibrium to a few percent.
    monkeypatch.setattr(gp, "FRICTION_SHARE", 0.0)
    params = ph.nominal_params(ph.Geometry())
    chambers = ph.Chambers.closed_at(ph.actuator_lengths(UPRIGHT, params), SUPPLY * 1e6, params)
    for mass, direction in ((200, 0), (300, -60), (500, 135)):
        solved = ph.solve_equilibrium(params, chambers, ph.Weight(mass / 1000, math.radians(direction))).theta_rad
        least = prior.least_motion(UPRIGHT, SUPPLY, pull(mass, direction))
        assert np.allclose(least, solved, rtol=0.1, atol=math.radians(0.02)), (mass, direction)


def test_friction_takes_its_band_off_and_holds_a_light_load_entirely(prior, monkeypatch):
    sizes = []
    for share in (0.0, 0.01, 0.025):
        monkeypatch.setattr(gp, "FRICTION_SHARE", share)
        sizes.append(float(np.linalg.norm(prior.least_motion(UPRIGHT, SUPPLY, pull(800, -60)))))
    assert sizes[0] > sizes[1] > sizes[2] > 0
    monkeypatch.setattr(gp, "FRICTION_SHARE", 0.025)
    assert np.all(prior.least_motion(UPRIGHT, SUPPLY, pull(100, -60)) == 0.0)
    # The symmetric rig upright: a pull the other way bends it the other way.
    assert np.allclose(
        prior.least_motion(UPRIGHT, SUPPLY, -pull(800, -60)), -prior.least_motion(UPRIGHT, SUPPLY, pull(800, -60))
    )


def windows(theta_rad: np.ndarray, pressures_MPa: np.ndarray, n: int = 50, seed: int = 0) -> pd.DataFrame:
    """A window of frames in the protocol's channel order (SI), with a little noise."""
    rng = np.random.default_rng(seed)
    names = PROTOCOL.calibration.names
    row = dict(zip(("P_L1", "P_R1", "P_L2", "P_R2"), pressures_MPa, strict=True)) | {
        "POT1": theta_rad[0],
        "POT2": theta_rad[1],
    }
    data = np.array([row[n] for n in names]) + 1e-5 * rng.standard_normal((n, len(names)))
    return pd.DataFrame(data, columns=range(len(names)))


def test_a_trial_that_did_not_move_reads_nothing_and_one_that_did_reads_its_share(prior):
    watch = Watch.of(PROTOCOL)
    base = windows(UPRIGHT, SUPPLY)
    F = pull(800, -60)
    least = prior.least_motion(UPRIGHT, SUPPLY, F)
    floors = watch.floors(base, base)
    still = prior(F, base, windows(UPRIGHT, SUPPLY, seed=1), floors)
    assert still is not None and abs(still.share) < PRIOR_SHARE and still.least == PRIOR_SHARE
    assert still.seen.startswith("the joints moved 0.00 deg of the at least ")
    # Bent as far as the least motion, the closed chambers' pressures following it (Boyle's law).
    followed = SUPPLY + prior.pressure_change(UPRIGHT, SUPPLY, least)
    bent = prior(F, base, windows(UPRIGHT + least, followed, seed=2), floors)
    assert bent is not None and bent.share == pytest.approx(1.0, abs=0.02)
    # Before the run refines the prior the pressures count too: bent with the pressures left as
    # they were, the reading is the angles' share only, well short of all of it.
    unfollowed = prior(F, base, windows(UPRIGHT + least, SUPPLY, seed=2), floors)
    assert unfollowed is not None and 0.3 < unfollowed.share < 0.9
    # A load friction can hold is not judged at all.
    assert prior(pull(100, -60), base, windows(UPRIGHT, SUPPLY, seed=3), floors) is None


def test_a_protocol_of_another_rig_has_no_physics_prior():
    assert PhysicsPrior.of(load_protocol("rpam2015")) is None


def test_the_friction_a_trial_shows_is_the_share_whose_statics_match_its_motion(prior, monkeypatch):
    F = pull(800, -60)
    for share in (0.004, 0.012, 0.03):
        monkeypatch.setattr(gp, "FRICTION_SHARE", share)
        moved = prior.least_motion(UPRIGHT, SUPPLY, F)
        assert prior.shown_share(UPRIGHT, SUPPLY, F, moved) == pytest.approx(share, abs=STEP)
    # A joint that moved as far as the frictionless rig, or further, shows none.
    monkeypatch.setattr(gp, "FRICTION_SHARE", 0.0)
    free = prior.least_motion(UPRIGHT, SUPPLY, F)
    assert prior.shown_share(UPRIGHT, SUPPLY, F, 1.5 * free) == 0.0
    # One that did not move (or moved back) shows the share that holds the whole load: its least
    # motion there is nothing, and a hair less friction lets it move.
    held = prior.shown_share(UPRIGHT, SUPPLY, F, -0.1 * free)
    assert held == prior.shown_share(UPRIGHT, SUPPLY, F, np.zeros(2))
    monkeypatch.setattr(gp, "FRICTION_SHARE", held)
    assert np.all(prior.least_motion(UPRIGHT, SUPPLY, F) == 0.0)
    monkeypatch.setattr(gp, "FRICTION_SHARE", held - STEP)
    assert np.linalg.norm(prior.least_motion(UPRIGHT, SUPPLY, F)) > 0.0
    assert prior.shown_share(UPRIGHT, SUPPLY, np.zeros(2), np.zeros(2)) is None  # no load, nothing shown


def test_the_runs_trials_set_the_friction_allowed_for_from_the_second_on(prior):
    F = pull(800, -60)
    base = windows(UPRIGHT, SUPPLY)
    assert not prior.refined and prior.friction_share == gp.FRICTION_SHARE
    shown = []
    for i, share in enumerate((0.002, 0.006, 0.004)):
        K, tau, held = prior._statics(UPRIGHT, SUPPLY, F)
        moved = prior._motion(K, tau, held, np.array([share]))[0]
        prior.learn(F, base, windows(UPRIGHT + moved, SUPPLY, seed=i + 1))
        shown.append(share)
        if i + 1 < gp.LEARN_MIN:
            assert not prior.refined and prior.friction_share == gp.FRICTION_SHARE
        else:
            assert prior.refined
            expected = max(gp.LEARN_FLOOR, gp.LEARN_MARGIN * max(shown))
            assert prior.friction_share == pytest.approx(expected, abs=gp.LEARN_MARGIN * STEP)
    # Less friction than the prior's own allowance: a light load is now judged, and its least
    # motion is the statics past the run's friction.
    assert prior.friction_share < gp.FRICTION_SHARE
    light = prior.least_motion(UPRIGHT, SUPPLY, pull(300, -60))
    assert np.linalg.norm(light) > 0.0
    floors = Watch.of(PROTOCOL).floors(base, base)
    missed = prior(pull(300, -60), base, windows(UPRIGHT, SUPPLY, seed=9), floors)
    assert missed is not None and missed.share < missed.least == gp.WEAK_FRACTION
    assert "past the friction this run's trials show" in missed.seen
    done = prior(pull(300, -60), base, windows(UPRIGHT + light, SUPPLY, seed=10), floors)
    assert done is not None and done.share == pytest.approx(1.0, abs=0.05)


def test_a_rig_with_more_friction_than_the_prior_allows_for_is_judged_by_what_it_shows(prior):
    # Trials that each moved only as far as 4 % friction lets them (it holds the upper joint): the
    # allowance grows past the prior's own, so a trial moving that little is no alarm.
    F = pull(800, -60)
    base = windows(UPRIGHT, SUPPLY)
    K, tau, held = prior._statics(UPRIGHT, SUPPLY, F)
    moved = prior._motion(K, tau, held, np.array([0.04]))[0]
    assert np.linalg.norm(moved) > 0.0
    little = windows(UPRIGHT + 0.1 * moved, SUPPLY, seed=5)
    floors = Watch.of(PROTOCOL).floors(base, base)
    before = prior(F, base, little, floors)  # the prior's own allowance: too little motion
    assert before is not None and before.share < before.least
    for i in range(gp.LEARN_MIN):
        prior.learn(F, base, windows(UPRIGHT + moved, SUPPLY, seed=i + 1))
    assert prior.friction_share > gp.FRICTION_SHARE
    after = prior(F, base, little, floors)
    assert after is None or after.share >= after.least


def test_a_resumed_run_allows_for_the_friction_its_stored_trials_showed():
    """The stored trials' table teaches the resumed check what their windows taught the live one."""
    from pathlib import Path

    from labcli.core.store import RunFile
    from labcli.papers.takuma2014.acquisition import _baselines, _history
    from labcli.papers.takuma2014.session import _resumed_guard

    run = RunFile.open(Path(__file__).resolve().parents[3] / "sample_runs" / "force.h5")
    try:
        table = run.records.table().head(12)
        live = PhysicsPrior.of(PROTOCOL)
        assert live is not None
        for rid, fx, fy in zip(table["trial"], table["Fx_N"], table["Fy_N"], strict=True):
            raw = run.records.read(int(rid))["raw"]
            live.learn((fx, fy), raw["baseline"], raw["load"])
        history, baselines = _history(run, PROTOCOL), _baselines(run, PROTOCOL)
    finally:
        run.close()
    resumed = _resumed_guard(PROTOCOL, history[:12], baselines[:12]).prior
    assert isinstance(resumed, PhysicsPrior) and resumed.refined
    assert resumed.friction_share == pytest.approx(live.friction_share, abs=gp.LEARN_MARGIN * STEP)
    # A table whose rows do not pair with the baselines teaches nothing.
    assert not _resumed_guard(PROTOCOL, history[:12], baselines[:11]).prior.refined


def test_the_runs_allowance_never_falls_below_its_floor(prior):
    # Trials that moved as far as the frictionless rig show no friction at all; the first trials can
    # hide the rig's, so the allowance stays at the floor.
    F = pull(800, -60)
    base = windows(UPRIGHT, SUPPLY)
    K, tau, held = prior._statics(UPRIGHT, SUPPLY, F)
    free = prior._motion(K, tau, held, np.zeros(1))[0]
    for i in range(3):
        prior.learn(F, base, windows(UPRIGHT + free, SUPPLY, seed=i + 1))
    assert max(prior._shown) <= STEP  # the windows' noise alone
    assert prior.refined and prior.friction_share == gp.LEARN_FLOOR


def test_the_pressures_a_motion_makes_keep_each_closed_chambers_air(prior):
    # Boyle's law: P_abs (V + V_dead) stays each closed chamber's own; no motion, no change; an
    # actuator a motion lengthens loses volume below 54.7 deg of braid, so its pressure rises.
    params, theta0, moved = prior.params, np.radians([-2.0, 2.0]), np.radians([-0.1, -2.0])
    assert np.allclose(prior.pressure_change(theta0, SUPPLY, np.zeros(2)), 0.0, atol=1e-12)
    dP = prior.pressure_change(theta0, SUPPLY, moved)
    before, after = (ph.actuator_lengths(t, params) for t in (theta0, theta0 + moved))
    amount = [
        (p * 1e6 + ph.P_ATM) * (ph.mckibben_volume(L, params.b, params.n) + params.V_dead)
        for p, L in ((SUPPLY, before), (SUPPLY + dP, after))
    ]
    assert np.allclose(amount[0], amount[1], rtol=1e-9)
    assert np.all(np.sign(dP) == np.sign(after - before)) and np.abs(dP).max() > 1e-3  # over a kPa for 2 deg


@pytest.mark.parametrize("direction", [-150, -120, -60, -30, 0, 30, 60, 135, 180])
def test_the_side_a_load_pulls_towards_is_the_side_its_equilibrium_shortens(prior, direction):
    # The closed design rig's own equilibrium under the load (no friction): the actuators of the side
    # named shorten, the other side's lengthen; the relief vents that side, so the baseline leans
    # the other way and the load pulls the arm away from the lean.
    params = ph.nominal_params(ph.Geometry())
    rest = ph.actuator_lengths(UPRIGHT, params)
    chambers = ph.Chambers.closed_at(rest, SUPPLY * 1e6, params)
    theta = ph.solve_equilibrium(params, chambers, ph.Weight(0.3, math.radians(direction))).theta_rad
    change = dict(zip(("L1", "R1", "L2", "R2"), ph.actuator_lengths(theta, params) - rest, strict=True))
    side = prior.pulled_side(pull(300, direction))
    other = {"L": "R", "R": "L"}[side]
    assert change[f"{side}1"] + change[f"{side}2"] < 0 < change[f"{other}1"] + change[f"{other}2"]
    # The mirror load pulls towards the other side.
    assert prior.pulled_side(-pull(300, direction)) == other


def test_a_load_that_bends_the_upright_arm_by_nothing_pulls_towards_no_side(prior):
    # Straight up or down along the upright arm: no torque on either joint (tau = J^T F).
    assert prior.pulled_side(pull(500, 90)) is None and prior.pulled_side(pull(500, -90)) is None
    assert prior.pulled_side(np.array([np.nan, 1.0])) is None and prior.pulled_side(np.array([1.0])) is None


def relieved_prior(vent: str | None) -> PhysicsPrior:
    """The prior of the shipped protocol with the relief before every trial venting ``vent`` (no
    relief: None)."""
    from labcli.core.protocol import loads_protocol

    lines = (
        ""
        if vent is None
        else f'friction_relief_s = 3.0\nfriction_relief_vent_s = 2.0\nfriction_relief_vent = "{vent}"\n'
    )
    prior = PhysicsPrior.of(loads_protocol(PROTOCOL.text.replace("[acquisition]\n", "[acquisition]\n" + lines)))
    assert prior is not None
    return prior


@pytest.mark.parametrize("vent, bands", [("load", 1), ("L", 2), ("R", 2), (None, 2)])
def test_venting_the_side_each_load_pulls_towards_leaves_one_friction_band_before_the_run_says(vent, bands):
    prior = relieved_prior(vent)
    assert prior.bands == bands and prior.friction_share == pytest.approx(gp.FRICTION_SHARE * bands / 2)
    # One band held back asks more motion of a light load than two: 300 g at -60 deg.
    one, two = (np.linalg.norm(p.least_motion(UPRIGHT, SUPPLY, pull(300, -60))) for p in (prior, relieved_prior("L")))
    assert one > two if bands == 1 else one == two
