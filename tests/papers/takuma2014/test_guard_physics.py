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
    bent = prior(F, base, windows(UPRIGHT + least, SUPPLY, seed=2), floors)
    assert bent is not None and bent.share == pytest.approx(1.0, abs=0.02)
    # A load friction can hold is not judged at all.
    assert prior(pull(100, -60), base, windows(UPRIGHT, SUPPLY, seed=3), floors) is None


def test_a_protocol_of_another_rig_has_no_physics_prior():
    assert PhysicsPrior.of(load_protocol("rpam2015")) is None
