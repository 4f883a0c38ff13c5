"""The second forward model (tests/support/second_rig.py): its physics, and its tables read by labcli."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest
from support import second_rig as sr

from labcli.papers.takuma2014.tables import read_push_csv, read_trial_csv


def test_the_model_does_not_use_the_simulated_rig():
    source = open(sr.__file__, encoding="utf-8").read()
    assert "labcli" not in "".join(line for line in source.splitlines() if line.startswith(("import", "from")))


def test_lengths_follow_eqs_2_to_7_and_their_small_angle_form():
    rig = sr.SecondRig()
    th = np.radians([1.0, -0.5])
    dl = rig.lengths(th) - rig.l_ref
    # Eq. 2 exactly
    assert dl[1] == pytest.approx(
        math.hypot(rig.h1 + rig.r1 * math.sin(th[0]), rig.r1 - rig.r1 * math.cos(th[0])) - rig.h1
    )
    # Eqs. 9 and 13 (small extensions): the differences of the pairs give the angles
    assert (dl[1] - dl[0]) / (2 * rig.r1) == pytest.approx(math.sin(th[0]), rel=1e-3)
    t2 = (dl[3] - dl[2]) / (2 * rig.r2) - (dl[1] - dl[0]) / (2 * rig.r1)
    assert t2 == pytest.approx(th[1], rel=2e-3)


def test_rest_is_balanced_and_bent_and_boyle_holds_under_load():
    arm = sr.Arm(sr.SecondRig(), seed=3)
    assert 5.0 < math.degrees(arm.rest[1]) < 25.0  # the inside pair's unequal supply bends the arm
    np.testing.assert_allclose(arm.pressures(arm.rest) / 1e6, sr.SecondRig().supply_MPa, atol=1e-12)
    F = np.array([-9.80665, 0.0])
    th = arm.loaded(lambda t: F)
    assert th[0] > arm.rest[0]  # a push towards -x turns the arm counter-clockwise
    p_abs = arm.pressures(th) + sr.P_ATM
    np.testing.assert_allclose(p_abs * arm.rig.volume(arm.rig.lengths(th)), arm.gas, rtol=1e-12)
    # virtual work: the muscles' torque balances J^T F
    rig = arm.rig
    muscle = -rig.length_jacobian(th).T @ rig.tension(rig.lengths(th), arm.pressures(th))
    np.testing.assert_allclose(muscle, -rig.contact_jacobian(th).T @ F, atol=1e-6)


def test_a_push_deforms_the_object_by_the_force_over_its_stiffness():
    pushes = sr.push_table(seed=5, pushes_per_object=1, phi_known=True)
    rig, arm = sr.SecondRig(), sr.Arm(sr.SecondRig(), seed=5)
    steel = pushes[pushes["object"] == "can-steel-1"].iloc[0]
    assert steel["true_stiffness_N_per_m"] == 8000.0
    # the softer the object the less the arm moves for the same push distance
    moved = pushes.set_index("object")[["theta1_deg", "theta2_deg"]].abs().sum(axis=1)
    assert moved["pet-1"] < moved["can-al-1"] < moved["can-steel-1"]
    assert rig.contact(arm.rest)[1] == pytest.approx(
        rig.h1 + rig.h2 * math.cos(arm.rest[0]) + rig.h3 * math.cos(arm.rest.sum())
    )


def test_tables_read_through_labcli(tmp_path):
    plan = pd.DataFrame(
        {"trial": [1, 2, 3], "set": ["fit"] * 3, "mass_g": [500.0, 800.0, 300.0], "direction_deg": [0.0, 90.0, -135.0]}
    )
    trials = sr.weight_trials(plan, seed=1)
    trials.to_csv(tmp_path / "t.csv", index=False)
    back = read_trial_csv(tmp_path / "t.csv")
    assert len(back) == 3 and back["Fy_N"].iloc[1] == pytest.approx(0.8 * 9.80665)
    pushes = sr.push_table(seed=1, pushes_per_object=1)
    pushes.drop(columns=["true_category"]).to_csv(tmp_path / "p.csv", index=False)
    read = read_push_csv(tmp_path / "p.csv")
    assert read["phi_deg"].isna().all() and len(read) == len(sr.OBJECTS)


def test_the_bent_arm_barely_shows_fy_in_its_pressures():
    # The Cramer-Rao floor of one push's force, knowing the rig's physics exactly: Fx about 1.2 N,
    # Fy about 9 N at 0.5 kPa of pressure noise per capture, against the pushes' Fy of well under
    # 1 N.  No estimator finds the push direction from these pressures; the potentiometers help.
    floor = sr.force_floor()
    assert 0.8 < floor[0] < 2.0 and floor[1] > 5.0
    pushes = sr.push_table(1001, pushes_per_object=3)
    assert floor[1] > 5 * np.sqrt(np.mean(pushes["true_Fy_N"] ** 2))
    assert sr.force_floor(pots=True)[1] < floor[1] / 4
    # The bound is linear in the noise, and a reading without noise gives the force exactly.
    np.testing.assert_allclose(sr.force_floor(sr.harsher(None, p_noise_kPa=0.05)), floor / 10, rtol=1e-9)
    assert np.all(sr.force_floor(sr.harsher(None, p_noise_kPa=0.0)) == 0.0)


def test_without_noise_the_posture_form_finds_each_push_direction():
    # The second rig's geometry and muscles are not the protocol's, yet on noiseless readings the
    # posture form fitted on its own weight trials gives every push's force direction: the
    # direction error on the noisy rig is the noise's, not a fault of the fit or of the geometry.
    from labcli.core.protocol import load_protocol
    from labcli.papers.takuma2014.models.posture import PostureModel
    from labcli.papers.takuma2014.protocol import load_plan

    proto = load_protocol("takuma2014-bent")
    quiet = sr.harsher(None, p_noise_kPa=0.0, pot_noise_deg=0.0)
    model = PostureModel(geometry=proto.settings.rig, protocol="takuma2014-stiffness").fit(
        sr.weight_trials(load_plan(proto), 1, quiet)
    )
    pushes = sr.push_table(1001, quiet, pushes_per_object=3)
    p0 = pushes[["P_L10", "P_R10", "P_L20", "P_R20"]].to_numpy()
    p = pushes[["P_L1", "P_R1", "P_L2", "P_R2"]].to_numpy()
    got = model.predict(p0, p, theta0=np.radians(pushes[["theta1_0_deg", "theta2_0_deg"]].to_numpy()))
    off = np.arctan2(got["Fy_N"], got["Fx_N"]) - np.arctan2(pushes["true_Fy_N"], pushes["true_Fx_N"])
    assert np.degrees(np.abs(np.angle(np.exp(1j * off)))).max() < 0.5
