"""The simulated rPAM rig: channels, calibration, lag, physics of the joint and the stretch stand."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
from support.imports import MODULES, reachable
from support.rpam_runs import capture

from labcli.core.device import Device
from labcli.core.sim import make_rig, modes
from labcli.papers.rpam2015.models import rpam
from labcli.papers.rpam2015.protocol import load_rpam
from labcli.papers.rpam2015.sim import rpam_physics as physics
from labcli.papers.rpam2015.sim.rig import (
    ADC_MAX,
    CALIBRATION,
    CHANNELS,
    STOP_MARGIN_DEG,
    RpamRig,
    counts_to_si,
    si_to_counts,
)

KPA = 1e-3
SIM, MODEL = "labcli.papers.rpam2015.sim", "labcli.papers.rpam2015.models"
# The model the rig is there to check, built from the same protocol.
SETTINGS = load_rpam("rpam2015").settings
GEOM = SETTINGS.geometry
ACT = SETTINGS.actuator


def model_actuator(rig: RpamRig, which: str = "A") -> rpam.Actuator:
    """The model's actuator with the rig's true, unclamped stretch correction."""
    return replace(ACT, stretch_coefficients_N=rig.true_stretch_coefficients_N[which], stretch_lambda_range=(0.0, 1e6))


def test_sim_url_selects_the_rpam_rig_and_id_names_its_channels():
    assert "rpam" in modes()
    assert isinstance(make_rig("rpam", seed=4), RpamRig)
    with Device.open("sim://?mode=rpam&seed=2") as dev:
        assert dev.info.device == "rpam-joint-sim"
        assert dev.info.channels == ("P_A", "P_B", "POT", "LEN")
        dev.rig.set_pressures(0.08, 0.06)
        dev.set_rate(200)
        dev.start()
        values, t_us = [], 0
        while t_us < 5_000_000:  # virtual clock: 5 s of rig time, several lag constants
            batch = dev.read(timeout=1.0)
            values.append(batch.values)
            t_us = int(batch.t_us[-1])
        dev.stop()
    values = np.concatenate(values)
    assert values.shape[1] == 4
    si = counts_to_si(values[-20:]).mean(axis=0)
    assert si[0] == pytest.approx(0.08, abs=0.5e-3)
    assert si[1] == pytest.approx(0.06, abs=0.5e-3)


def test_calibration_zeros_are_exact_and_round_trip():
    assert CHANNELS == ("P_A", "P_B", "POT", "LEN")
    zero = [CALIBRATION[c]["zero_counts"] for c in CHANNELS]
    assert zero == [819.0, 819.0, 2048.0, 0.0]
    np.testing.assert_allclose(counts_to_si([819, 819, 2048, 0]), 0.0, atol=1e-15)
    # Full scale of the PSE530 (5 V = 4095 counts) is 1 MPa; of the draw-wire sensor 0.3 m.
    full = counts_to_si([ADC_MAX, ADC_MAX, ADC_MAX, ADC_MAX])
    assert full[0] == pytest.approx(1.0) and full[3] == pytest.approx(0.300)
    assert math.degrees(full[2]) == pytest.approx((ADC_MAX - 2048) * 340 / 4095)
    x = np.array([[0.041, 0.138, math.radians(-37.0), 0.123]])
    np.testing.assert_allclose(counts_to_si(si_to_counts(x)), x, rtol=1e-12)


def test_counts_are_12_bit_integers_and_seeded():
    a, b = RpamRig(seed=7), RpamRig(seed=7)
    for r in (a, b):
        r.set_pressures(0.09, 0.05)
    ta, ca = a.samples(500, 100.0)
    tb, cb = b.samples(500, 100.0)
    assert ca.dtype == np.int64 and ca.shape == (500, 4)
    assert ca.min() >= 0 and ca.max() <= ADC_MAX
    np.testing.assert_array_equal(ca, cb)
    np.testing.assert_array_equal(ta, tb)
    assert ta[0] == 10_000 and np.all(np.diff(ta) == 10_000)
    assert a.time_s == pytest.approx(5.0)
    c = RpamRig(seed=8)
    assert c.true_stretch_coefficients_N != a.true_stretch_coefficients_N


def test_equal_pressures_on_the_symmetric_joint_give_zero_angle():
    rig = RpamRig(seed=1, variation=False)
    for p_kpa in (0.0, 41.0, 70.0, 96.0):
        rig.set_pressures(p_kpa * KPA, p_kpa * KPA)
        v = capture(rig)
        # Noise of 0.7 count = 0.06 deg per sample, averaged over 50: far below 0.05 deg.
        assert math.degrees(v[2]) == pytest.approx(0.0, abs=0.05), p_kpa
        # LEN reads actuator a's length at alpha = 0 (Eq. 4).
        assert v[3] == pytest.approx(float(rpam.actuator_lengths(0.0, GEOM)[0]), abs=0.1e-3)


def test_joint_angle_rises_with_pa_and_falls_with_pb():
    rig = RpamRig(seed=5)
    up = []
    for pa in np.linspace(50, 90, 6) * KPA:
        rig.set_pressures(pa, 0.07)
        up.append(math.degrees(capture(rig)[2]))
    down = []
    for pb in np.linspace(50, 90, 6) * KPA:
        rig.set_pressures(0.07, pb)
        down.append(math.degrees(capture(rig)[2]))
    assert np.all(np.diff(up) > 1.0), up
    assert np.all(np.diff(down) < -1.0), down
    # The varied rig is near-symmetric: swapping the pressures roughly negates the angle.
    assert up[0] == pytest.approx(-down[0] + 2 * math.degrees(rig.pot_offset_rad), abs=3.0)


def test_the_joint_balances_eq6_of_the_true_actuators():
    rig = RpamRig(seed=3, variation=False)
    rig.set_pressures(0.08, 0.06)
    truth = rig.true_state()
    alpha = truth["target_alpha_rad"]
    assert truth["status"] == "ok" and 0 < alpha < rig.stop_rad
    assert abs(float(rig.joint_torque(alpha, 0.08, 0.06))) < 1e-9
    # The nominal rig is the protocol's model: same angle as the model's solver.
    assert alpha == pytest.approx(rpam.equilibrium_angle(0.08, 0.06, GEOM, ACT), abs=1e-9)


def test_the_rigs_own_stress_integration_gives_the_models_energy_force():
    # Two derivations of one force: the model differentiates the potential (wall strain
    # energy and gas volume over R^2, models/rpam_force.py), the rig integrates the
    # wall's Cauchy stresses over the current radius and adds the thread's statics.
    rig = RpamRig(seed=0, variation=False)
    tube = rig.actuators[0]
    L = np.linspace(0.05, 0.20, 31)
    for p in (0.0, 0.002, 0.006, 0.041, 0.096, 0.138, 0.19):  # slack cage below ~10 kPa, then on it
        model = rpam.external_force(p, L, model_actuator(rig))
        np.testing.assert_allclose(physics.tension(tube, p, L), model, rtol=1e-6, atol=1e-6)
    # The printed Eq. 2's wall term is what the stresses rule out: about P A0 / lambda apart.
    lam = 0.1336 / ACT.L0_m
    old = float(rpam.external_force(0.096, 0.1336, ACT)) + 0.096e6 * ACT.A0_m2 / lam
    assert float(physics.tension(tube, 0.096, 0.1336)) == pytest.approx(old - 10.4, abs=0.05)


def test_the_rigs_cross_product_torque_is_eq6_with_the_models_moment_arms():
    rig = RpamRig(seed=0, variation=False)
    alpha = np.linspace(-1.3, 1.3, 27)  # both sides of both toggles
    La, Lb = rpam.actuator_lengths(alpha, GEOM)
    np.testing.assert_allclose(rig.links.lengths(alpha), (La, Lb), rtol=1e-13)
    for pa, pb in ((0.041, 0.041), (0.096, 0.041), (0.0, 0.138)):
        np.testing.assert_allclose(
            rig.joint_torque(alpha, pa, pb), rpam.joint_torque(alpha, pa, pb, GEOM, ACT), rtol=1e-7, atol=1e-9
        )
    assert rig.toggle_rad == pytest.approx(float(rpam.toggle_angle(GEOM)), abs=1e-15)


def test_the_rig_does_not_use_the_model_it_checks():
    # Every import of the stand's modules (inside functions and relative ones too), followed
    # through the modules they name: its own physics and the protocol, never the model.
    stand = {name for name in MODULES if name.startswith(SIM)}
    assert {f"{SIM}.rig", f"{SIM}.rpam_physics"} <= stand
    assert f"{SIM}.rpam_physics" in reachable(f"{SIM}.rig")
    assert f"{MODEL}.rpam_force" in reachable(f"{MODEL}.rpam_optimize")  # the graph does see the model
    for name in sorted(stand):
        used = sorted(m for m in reachable(name) if m == MODEL or m.startswith(MODEL + "."))
        assert not used, f"{name} reaches {used}"


def test_a_large_pressure_difference_leaves_the_joint_on_its_stop():
    rig = RpamRig(seed=3, variation=False)
    rig.set_pressures(0.138, 0.041)
    v = capture(rig)
    t = rig.true_state()
    assert t["status"] == "stop"
    assert t["target_alpha_rad"] == pytest.approx(rig.toggle_rad - math.radians(STOP_MARGIN_DEG), abs=1e-12)
    assert math.degrees(v[2]) == pytest.approx(math.degrees(rig.stop_rad), abs=0.1)
    # The model has no balance there: the joint runs onto the toggle.
    with pytest.raises(rpam.ModelError):
        rpam.equilibrium_angle(0.138, 0.041, GEOM, ACT)


def test_posture_and_pressures_follow_a_first_order_lag():
    rig = RpamRig(seed=2, noise=0.0, variation=False)
    rig.set_pressures(0.06, 0.06)
    rig.advance(10.0)
    a0, p0 = rig.true_state()["alpha_rad"], rig.true_state()["pressures_MPa"][0]
    rig.set_pressures(0.08, 0.06)
    t = rig.true_state()
    tau, target = t["tau_s"], t["target_alpha_rad"]
    assert 0.7 * 0.7 <= tau <= 0.7 * 1.4
    rig.advance(tau)
    s = rig.true_state()
    assert s["alpha_rad"] == pytest.approx(target + (a0 - target) * math.exp(-1), rel=1e-9)
    assert s["pressures_MPa"][0] == pytest.approx(0.08 + (p0 - 0.08) * math.exp(-1), rel=1e-9)
    rig.advance(20 * tau)
    assert rig.true_state()["alpha_rad"] == pytest.approx(target, abs=1e-9)


def test_stretch_stand_length_is_the_loaded_length_of_the_true_actuator():
    rig = RpamRig(seed=0, variation=False, experiment="stretch")
    for mass, p in ((0.0, 0.0), (0.3, 0.1), (1.3, 0.19)):
        rig.hang_payload(mass)
        rig.set_pressures(p, 0.0)
        v = capture(rig)
        want = float(rpam.loaded_length(p, mass, model_actuator(rig)))
        assert v[3] == pytest.approx(want, abs=0.05e-3)
        assert v[0] == pytest.approx(p, abs=0.3e-3)
        assert math.degrees(v[2]) == pytest.approx(0.0, abs=0.05)  # joint locked on the stand
    assert rig.true_state()["lambda"] > 2.0
    # The true correction is never clamped: at lambda beyond the protocol's range it still grows.
    tube = rig.actuators[0]
    coef = rig.true_stretch_coefficients_N["A"]
    assert float(
        physics.tension(tube, 0.1, 3.0 * tube.L0_m) - rpam.external_force(0.1, 3.0 * tube.L0_m, ACT, stretch=False)
    ) == pytest.approx(np.polyval(coef[::-1], 3.0), abs=1e-6)


def test_heavier_payload_and_higher_pressure_both_lengthen_the_actuator():
    rig = RpamRig(seed=6, experiment="stretch")
    lengths = []
    for mass in (0.0, 0.2, 1.0):
        rig.hang_payload(mass)
        row = []
        for p in (0.0, 0.05, 0.1, 0.15):
            rig.set_pressures(p, 0.0)
            row.append(capture(rig)[3])
        lengths.append(row)
    L = np.array(lengths)
    assert np.all(np.diff(L, axis=0) > 0) and np.all(np.diff(L, axis=1) > 0)


def test_operator_hooks_reject_impossible_requests():
    rig = RpamRig(seed=0)
    with pytest.raises(ValueError, match="call set_experiment\\('stretch'\\) first"):
        rig.hang_payload(0.1)
    with pytest.raises(ValueError, match="within 0..1 MPa"):
        rig.set_pressures(-0.01, 0.05)
    with pytest.raises(ValueError, match="'joint' or 'stretch'"):
        rig.set_experiment("bench")
    rig.set_experiment("stretch")
    with pytest.raises(ValueError, match="payload mass must be >= 0 kg"):
        rig.hang_payload(-1.0)
    with pytest.raises(ValueError, match="beyond the actuator's range"):
        rig.hang_payload(50.0)
    assert rig.true_state()["payload_kg"] == 0.0  # the refused payload left nothing behind
    rig.hang_payload(0.2)
    rig.remove_payload()
    assert rig.true_state()["payload_kg"] == 0.0


def test_drift_moves_the_zeros_slowly_and_only_when_asked():
    still, drifting = RpamRig(seed=4, noise=0.0), RpamRig(seed=4, noise=0.0, drift=1.0)
    for rig in (still, drifting):
        rig.set_pressures(0.06, 0.06)
        rig.advance(20.0)
    first = [r.samples(10, 10.0)[1].astype(float).mean(axis=0) for r in (still, drifting)]
    for rig in (still, drifting):
        rig.advance(900.0)
    later = [r.samples(10, 10.0)[1].astype(float).mean(axis=0) for r in (still, drifting)]
    np.testing.assert_array_equal(first[0], later[0])
    moved = np.abs(later[1] - first[1])
    assert moved.max() >= 1.0 and moved.max() <= 7.0  # a few counts over 15 min
    np.testing.assert_allclose(first[1], first[0], atol=0.6)  # barely any drift in the first 20 s
