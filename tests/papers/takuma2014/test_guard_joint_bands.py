"""The load check's friction allowance per joint where the relief vents the side each load pulls
(guard_prior.PhysicsPrior.joint_bands): one band on a joint the load pulls the vented way, two on a
joint it pulls the other way, as some directions do on the bent arm."""

from __future__ import annotations

import math

import numpy as np
import pytest

from labcli.core.protocol import load_protocol, loads_protocol
from labcli.papers.takuma2014.guard_prior import PhysicsPrior
from labcli.papers.takuma2014.sim import physics as ph

BENT_POSTURE = np.radians([-0.2, 17.4])  # the bent arm's rest on its supply (seed 1 of the simulated rig)
BENT_SUPPLY = np.array([0.15, 0.15, 0.45, 0.15])  # MPa gauge, P_L1, P_R1, P_L2, P_R2


def pull(mass_g: float, direction_deg: float) -> np.ndarray:
    d = math.radians(direction_deg)
    return mass_g / 1000 * 9.80665 * np.array([math.cos(d), math.sin(d)])


def prior(name: str, vent: str, posture: np.ndarray, supply: np.ndarray) -> PhysicsPrior:
    """The prior of a shipped protocol with the relief venting ``vent``, its last accepted baseline at
    ``posture`` on ``supply`` (one trial learnt: the run has not shown its friction yet)."""
    lines = f'friction_relief_s = 3.0\nfriction_relief_vent_s = 2.0\nfriction_relief_vent = "{vent}"\n'
    p = PhysicsPrior.of(loads_protocol(load_protocol(name).text.replace("[acquisition]\n", "[acquisition]\n" + lines)))
    assert p is not None
    p.learn_change(pull(300, -60), [*supply, *posture], [0.0] * 6)
    assert not p.refined
    return p


def own_sides(p: PhysicsPrior, posture: np.ndarray, load: np.ndarray) -> list[str]:
    """Each joint's side, from the rig's geometry alone: the side whose actuator the joint's own
    frictionless motion under ``load`` shortens (L1 for joint 1, L2's part over joint 2)."""
    K, tau, _ = p._statics(posture, BENT_SUPPLY, load)
    moved = np.linalg.solve(K, tau)
    g = ph.path_gradients(posture, p.params.geometry)
    return ["L" if g[0, 0] * moved[0] < 0 else "R", "L" if g[2, 1] * moved[1] < 0 else "R"]


def test_a_bent_arm_direction_pulls_the_joints_opposite_ways_and_the_far_one_gets_two_bands(monkeypatch):
    per_load = prior("takuma2014-bent", "load", BENT_POSTURE, BENT_SUPPLY)
    load = pull(1500, -80)  # heavy enough to move both joints past their bands
    # The load as a whole pulls R, so R is vented; joint 2 alone is pulled towards L, towards its lean.
    assert per_load.pulled_side(load) == "R" and own_sides(per_load, BENT_POSTURE, load) == ["R", "L"]
    K, tau, _ = per_load._statics(BENT_POSTURE, BENT_SUPPLY, load)
    assert per_load.joint_bands(BENT_POSTURE, K, tau, load).tolist() == [1.0, 2.0]
    new = per_load.least_motion(BENT_POSTURE, BENT_SUPPLY, load)
    # The torque left past friction on each joint: joint 1's as with one band, joint 2's as with two.
    two = prior("takuma2014-bent", "R", BENT_POSTURE, BENT_SUPPLY).least_motion(BENT_POSTURE, BENT_SUPPLY, load)
    monkeypatch.setattr(PhysicsPrior, "joint_bands", lambda self, *a: np.ones(2))
    one = per_load.least_motion(BENT_POSTURE, BENT_SUPPLY, load)
    assert (K @ new)[0] == pytest.approx((K @ one)[0], abs=1e-12) and (K @ new)[1] == pytest.approx((K @ two)[1])
    assert 0 < abs((K @ new)[1]) < abs((K @ one)[1])  # two bands hold more of joint 2's torque back
    assert abs((K @ new)[0]) > 0


@pytest.mark.parametrize("direction", [-150, -120, -60, 0, 60, 120, 180])
def test_on_the_upright_arm_every_load_pulls_both_joints_the_vented_way(direction):
    upright = prior("takuma2014", "load", np.zeros(2), np.full(4, 0.3))
    load = pull(500, direction)
    side = upright.pulled_side(load)
    K, tau, _ = upright._statics(np.zeros(2), np.full(4, 0.3), load)
    assert own_sides(upright, np.zeros(2), load) == [side, side]
    assert upright.joint_bands(np.zeros(2), K, tau, load).tolist() == [1.0, 1.0]


def test_a_run_venting_one_side_for_every_trial_allows_two_bands_on_both_joints():
    vent_l = prior("takuma2014-bent", "L", BENT_POSTURE, BENT_SUPPLY)
    load = pull(500, -80)
    K, tau, _ = vent_l._statics(BENT_POSTURE, BENT_SUPPLY, load)
    assert vent_l.bands == 2 and vent_l.joint_bands(BENT_POSTURE, K, tau, load).tolist() == [2.0, 2.0]
