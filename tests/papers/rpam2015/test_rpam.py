"""The rPAM actuator and joint model: geometry, moment arms, forces, torque balance."""

from __future__ import annotations

import copy
import math
from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from labcli.core.protocol import check_document
from labcli.errors import ConfigError, ModelError
from labcli.papers.rpam2015.models import rpam
from labcli.papers.rpam2015.protocol import apply_overrides, checked_actuator, load_rpam

PROTOCOL = load_rpam("rpam2015")
PATH, RAW = PROTOCOL.path, PROTOCOL.document
ACT = PROTOCOL.settings.actuator
PAPER = rpam.JointGeometry(0.03, 0.1048, 0.06)
KPA = 1e-3  # MPa per kPa

links = st.floats(0.01, 0.2)
angles = st.floats(-math.pi / 2, math.pi / 2)


# --------------------------------------------------------------------------- geometry


@given(angles, links, links, links)
def test_eq4_lengths_are_distances_between_table1_points(alpha, L1, L2, L3):
    g = rpam.JointGeometry(L1, L2, L3)
    p = rpam.mount_points(alpha, g)
    La, Lb = rpam.actuator_lengths(alpha, g)
    assert La == pytest.approx(np.linalg.norm(p["a"] - p["a_low"]), rel=1e-9, abs=1e-12)
    assert Lb == pytest.approx(np.linalg.norm(p["b"] - p["b_low"]), rel=1e-9, abs=1e-12)
    # Table I's a, b sit L3 either side of m, and |O a| = L23 as Eq. 5 needs.
    assert np.linalg.norm(p["a"] - p["m"]) == pytest.approx(L3)
    assert np.linalg.norm(p["a"]) == pytest.approx(math.hypot(L2, L3))


@given(links, links, links, st.floats(0.0, 0.999))
def test_heron_equals_exact_distance_on_the_valid_branch(L1, L2, L3, frac):
    g = rpam.JointGeometry(L1, L2, L3)
    t = float(rpam.toggle_angle(g))
    for alpha in (frac * t, -frac * t):
        ha, hb = rpam.moment_arms_heron(alpha, g)
        ma, mb = rpam.moment_arms(alpha, g)
        assert ma > 0 and mb > 0
        assert ha == pytest.approx(ma, rel=1e-6, abs=1e-9)
        assert hb == pytest.approx(mb, rel=1e-6, abs=1e-9)


def test_moment_arm_of_b_changes_sign_at_the_toggle_while_heron_does_not():
    t = float(rpam.toggle_angle(PAPER))
    assert math.degrees(t) == pytest.approx(math.degrees(math.atan(0.1048 / 0.06)))
    assert math.degrees(t) == pytest.approx(60.208, abs=1e-3)
    _, mb_at = rpam.moment_arms(t, PAPER)
    assert abs(mb_at) < 1e-15
    beyond = t + math.radians(5)
    _, mb = rpam.moment_arms(beyond, PAPER)
    _, hb = rpam.moment_arms_heron(beyond, PAPER)
    assert mb < 0 < hb
    assert hb == pytest.approx(-mb, rel=1e-6)
    # Closed form of the signed arm: L1 b_y / L_b.
    b_y = 0.1048 * math.cos(beyond) - 0.06 * math.sin(beyond)
    assert mb == pytest.approx(0.03 * b_y / float(rpam.actuator_lengths(beyond, PAPER)[1]))


# --------------------------------------------------------------------------- forces


def test_helical_term_vanishes_at_the_magic_angle():
    b, n = 1.0, 5.0
    L = b / math.sqrt(3)  # thread at acos(1/sqrt 3) = 54.7356 deg from the axis
    assert math.degrees(math.acos(L / b)) == pytest.approx(54.7356, abs=1e-4)
    assert rpam.helical_tension(0.2, L, n, b) == pytest.approx(0.0, abs=1e-9)
    # Shorter than that (threads nearer hoops) it pushes; longer, it pulls like a McKibben.
    assert rpam.helical_tension(0.2, 0.9 * L, n, b) < 0 < rpam.helical_tension(0.2, 1.1 * L, n, b)


def test_hoop_threads_give_the_end_cap_force_on_the_whole_cage():
    r, L, P = 0.01, 0.08, 0.1  # m, m, MPa
    for n in (1e3, 1e4, 1e5):
        b = math.hypot(2 * math.pi * r * n, L)
        cage = -rpam.helical_tension(P, L, n, b)
        # Exact: P (pi r^2 - L^2 / (2 pi n^2)) for this cage, -> P pi r^2 as n -> inf.
        assert cage == pytest.approx(P * 1e6 * (math.pi * r**2 - L**2 / (2 * math.pi * n**2)), rel=1e-12)
    assert cage == pytest.approx(0.1e6 * math.pi * 1e-4, rel=1e-9)  # 31.4159 N
    assert cage == pytest.approx(31.4159, abs=1e-3)
    # A wall of section A0 inside the cage takes nothing off the gas's share: its volume is
    # fixed, so the gas volume changes as the cage's (no P A0 / lambda term).
    act = rpam.Actuator(
        L0_m=L,
        A0_m2=5e-5,
        n_turns=1e5,
        thread_length_m=math.hypot(2 * math.pi * r * 1e5, L),
        ogden_mu_MPa=(0.1,),
        ogden_alpha=(2.0,),
    )
    for lam in (1.0, 1.5, 2.0):
        assert rpam.constraint_force(P, lam * L, act) == pytest.approx(
            rpam.helical_tension(P, lam * L, act.n_turns, act.thread_length_m), rel=1e-12
        )


def test_helical_term_is_minus_p_dv_dl_and_scales_as_an_area():
    b, n, P = 1.1, 14.0, 0.096

    def volume(L):
        return L * (b**2 - L**2) / (4 * math.pi * n**2)

    for L in (0.07, 0.1, 0.14, 0.5):
        h = 1e-6
        dVdL = (volume(L + h) - volume(L - h)) / (2 * h)
        assert rpam.helical_tension(P, L, n, b) == pytest.approx(-P * 1e6 * dVdL, rel=1e-7)
        # All lengths times k: an area times a pressure, so the force goes as k^2.
        k = 3.0
        assert rpam.helical_tension(P, k * L, n, k * b) == pytest.approx(k**2 * rpam.helical_tension(P, L, n, b))
    assert rpam.helical_tension(0.0, 0.1, n, b) == 0.0


def test_shipped_actuator_extends_under_pressure():
    # Threads 86.4 deg from the axis at rest: the cage pushes at every stretch of g5/g6.
    assert math.degrees(ACT.rest_helix_angle_rad) == pytest.approx(86.36, abs=0.01)
    assert ACT.rest_radius_m == pytest.approx(0.0125, rel=1e-4)
    L = np.linspace(0.07, 0.14, 8)
    assert np.all(rpam.helical_tension(0.096, L, ACT.n_turns, ACT.thread_length_m) < 0)
    free = rpam.loaded_length(np.array([0.0, 0.041, 0.096, 0.138]), 0.0, ACT)
    assert free[0] == pytest.approx(ACT.L0_m, rel=1e-9)
    assert np.all(np.diff(free) > 0)
    assert rpam.push_force(0.096, free[2], ACT) == pytest.approx(0.0, abs=1e-9)
    # A payload stretches it further (stretch test, Fig. 5).
    assert rpam.loaded_length(0.096, 1.0, ACT) > free[2]


def test_ogden_force_vanishes_unstretched_with_slope_three_mu_a0():
    assert rpam.material_force(1.0, ACT) == pytest.approx(0.0, abs=1e-12)
    h = 1e-6
    slope = (rpam.material_force(1 + h, ACT) - rpam.material_force(1 - h, ACT)) / (2 * h)
    mu0 = sum(ACT.ogden_mu_MPa) * 1e6
    assert slope == pytest.approx(3 * mu0 * ACT.A0_m2, rel=1e-6)  # E = 3 mu, incompressible


def test_shipped_ogden_constants_follow_the_cited_dragon_skin_10_fit_in_every_mode():
    # Uniaxial, planar and equibiaxial nominal stress (MPa) of the cited Yeoh fit against
    # Eq. 3's Ogden form with the shipped constants, over stretch 1.05-3.
    lam = np.linspace(1.05, 3.0, 40)
    mu, al = np.array(ACT.ogden_mu_MPa), np.array(ACT.ogden_alpha)
    assert np.all(mu > 0)  # every term's energy convex: stable in every mode
    modes = {  # I1, d I1 / d lambda / 2, lateral exponent factor k in lambda^(-k alpha - 1)
        "uniaxial": (lam**2 + 2 / lam, lam - lam**-2, 0.5),
        "planar": (lam**2 + 1 + lam**-2, lam - lam**-3, 1.0),
        "equibiaxial": (2 * lam**2 + lam**-4, lam - lam**-5, 2.0),
    }
    for name, (I1, half_dI1, k) in modes.items():
        x = I1 - 3
        yeoh = 2 * half_dI1 * (0.036 + 2 * 2.5e-4 * x + 3 * 2.3e-5 * x**2)
        ogden = sum(2 * m / a * (lam ** (a - 1) - lam ** (-k * a - 1)) for m, a in zip(mu, al, strict=False))
        assert np.max(np.abs(ogden / yeoh - 1)) < 0.08, name
    nominal = rpam.material_force(lam, ACT) / ACT.A0_m2 / 1e6
    assert nominal == pytest.approx(
        sum(2 * m / a * (lam ** (a - 1) - lam ** (-a / 2 - 1)) for m, a in zip(mu, al, strict=False))
    )
    at_100 = float(rpam.material_force(2.0, ACT)) / ACT.A0_m2 / 1e6
    assert at_100 == pytest.approx(22 * 0.00689476, rel=0.2)  # datasheet 100% modulus, 22 psi


def test_stretch_correction_is_clamped_and_fits_back():
    lo, hi = ACT.stretch_lambda_range
    assert rpam.stretch_force(hi + 1.0, ACT) == pytest.approx(rpam.stretch_force(hi, ACT))
    assert rpam.stretch_force(1.0, ACT) == pytest.approx(0.0, abs=1e-12)
    assert rpam.stretch_force(2.0, ACT) == pytest.approx(12.0)  # 10 (lam-1)^2 + 2 (lam-1)^3
    lam = np.linspace(1.0, 2.2, 12)
    coef = (1.0, -2.0, 3.0, 0.5)
    force = np.polynomial.polynomial.polyval(lam, coef)
    assert rpam.fit_stretch_correction(lam, force) == pytest.approx(coef, abs=1e-8)
    with pytest.raises(ModelError) as e:
        rpam.fit_stretch_correction([1.0, 1.1, 1.1, 1.2], [0, 1, 1, 2])
    assert str(e.value) == (
        "The stretch correction is a cubic and needs at least 4 distinct stretches; the stretch test gave 3."
    )


# --------------------------------------------------------------------------- balance


@pytest.mark.parametrize("p_kpa", [0.0, 41.0, 96.0, 138.0])
def test_equal_pressures_on_the_symmetric_joint_give_zero_angle(p_kpa):
    P = p_kpa * KPA
    eq = rpam.solve_equilibrium(P, P, PAPER, ACT)
    assert float(eq.alpha_rad) == 0.0
    assert rpam.equilibrium_angle(P, P, PAPER, ACT) == 0.0
    # The centre is stable: a small turn either way meets a restoring torque.
    h = 1e-3
    assert rpam.joint_torque(h, P, P, PAPER, ACT) < 0 < rpam.joint_torque(-h, P, P, PAPER, ACT)


def test_angle_grows_monotonically_with_pressure_difference_and_stays_below_toggle():
    Pa = np.linspace(41, 138, 98) * KPA
    eq = rpam.solve_equilibrium(Pa, 41 * KPA, PAPER, ACT)
    ok = eq.status == rpam.OK
    assert ok[:40].all()  # up to about 80 kPa the joint balances
    alpha = eq.alpha_rad[ok]
    assert np.all(np.diff(alpha) > 0)
    assert np.all(alpha < eq.toggle_rad[ok])
    # Once it runs onto the toggle, more pressure keeps it there.
    first_bad = np.argmin(ok) if not ok.all() else len(ok)
    assert not ok[first_bad:].any()


def test_swapping_the_pressures_mirrors_the_angle():
    Pa = np.array([41, 60, 80, 96]) * KPA
    fwd = rpam.solve_equilibrium(Pa, 41 * KPA, PAPER, ACT).alpha_rad
    back = rpam.solve_equilibrium(41 * KPA, Pa, PAPER, ACT).alpha_rad
    np.testing.assert_allclose(back, -fwd, atol=1e-12)


def test_solved_angle_satisfies_eq6_with_heron_arms_and_brent_agrees():
    alpha = rpam.equilibrium_angle(0.08, 0.06, PAPER, ACT)
    La, Lb = rpam.actuator_lengths(alpha, PAPER)
    ha, hb = rpam.moment_arms_heron(alpha, PAPER)
    Fa = rpam.push_force(0.08, La, ACT)
    Fb = rpam.push_force(0.06, Lb, ACT)
    assert Fa * ha == pytest.approx(Fb * hb, rel=1e-9)
    grid = rpam.joint_map([0.08], [0.06], PAPER, ACT)
    assert float(grid.alpha_rad[0, 0]) == pytest.approx(alpha, abs=1e-12)
    # Stable: torque drives the joint back from either side, and the stiffness says so.
    h = 1e-4
    assert (
        rpam.joint_torque(alpha - h, 0.08, 0.06, PAPER, ACT) > 0 > rpam.joint_torque(alpha + h, 0.08, 0.06, PAPER, ACT)
    )
    K = float(rpam.joint_stiffness(alpha, 0.08, 0.06, PAPER, ACT))
    assert K > 0
    assert float(rpam.joint_torque(alpha + h, 0.08, 0.06, PAPER, ACT)) == pytest.approx(-K * h, rel=1e-3)


@settings(max_examples=60, deadline=None)
@given(st.floats(0.03, 0.06), st.floats(0.07, 0.14), st.floats(0.03, 0.06), st.floats(0, 190), st.floats(0, 190))
def test_solver_never_returns_an_angle_on_the_spurious_branch(L1, L2, L3, pa, pb):
    g = rpam.JointGeometry(L1, L2, L3)
    eq = rpam.solve_equilibrium(pa * KPA, pb * KPA, g, ACT)
    t = float(rpam.toggle_angle(g))
    if eq.status == rpam.OK:
        a = float(eq.alpha_rad)
        assert abs(a) < t
        ma, mb = rpam.moment_arms(a, g)
        assert ma > 0 and mb > 0
        assert abs(float(rpam.joint_torque(a, pa * KPA, pb * KPA, g, ACT))) < 1e-9
    else:
        assert eq.status == rpam.TOGGLE and np.isnan(eq.alpha_rad)


def test_joint_map_matches_the_scalar_solver_and_marks_toggles():
    Pa = np.linspace(41, 138, 6) * KPA
    Pb = np.linspace(41, 138, 5) * KPA
    m = rpam.joint_map(Pa, Pb, PAPER, ACT)
    assert m.alpha_rad.shape == (6, 5)
    for i, pa in enumerate(Pa):
        for j, pb in enumerate(Pb):
            if m.status[i, j] == rpam.OK:
                assert m.alpha_rad[i, j] == pytest.approx(rpam.equilibrium_angle(pa, pb, PAPER, ACT), abs=1e-10)
    assert (m.status == rpam.TOGGLE).any() and (m.status == rpam.OK).any()


def test_no_equilibrium_is_a_clear_error():
    with pytest.raises(ModelError) as e:
        rpam.equilibrium_angle(0.138, 0.0, PAPER, ACT)
    assert str(e.value) == (
        "The joint has no equilibrium below its toggle angle 60.2 deg at Pa = 138 kPa, "
        "Pb = 0 kPa: it runs onto the toggle (check the pressures and links)."
    )


# --------------------------------------------------------------------------- protocol file


def test_shipped_protocol_holds_the_papers_numbers():
    s = PROTOCOL.settings
    g = s.geometry
    assert (g.L1_m, g.L2_m, g.L3_m) == (0.03, 0.1048, 0.06)
    assert s.bounds.L2_m == (0.07, 0.14) and s.bounds.actuator_length_m == (0.07, 0.14)
    assert (s.optimize.Pa_MPa, s.optimize.Pb_MPa) == (0.096, 0.041)
    assert RAW["pressure"]["joint_map_kPa"] == [41.0, 138.0]
    assert s.stretch_test.payloads_kg[-1] == pytest.approx(1.3)
    # The thread cage and the pitch agree: 5 mm over 70 mm.
    assert ACT.L0_m / ACT.n_turns == pytest.approx(0.005)


def test_overrides_set_values_and_reject_unknown_keys():
    out = apply_overrides(RAW, ["actuator.L0_m=0.08", "ogden.alpha=[1.5, 5, -2]"])
    assert out["actuator"]["L0_m"] == 0.08 and RAW["actuator"]["L0_m"] == 0.07
    assert out["ogden"]["alpha"] == [1.5, 5, -2]
    assert check_document(out).settings.actuator.ogden_alpha == (1.5, 5.0, -2.0)
    with pytest.raises(ConfigError) as e:
        apply_overrides(RAW, ["actuator.L0=0.08"])
    assert str(e.value) == (
        "Unknown protocol key 'actuator.L0' in --set; keys under actuator: "
        "A0_m2, L0_m, force_reading, n_turns, prestretch, thread_length_m."
    )
    with pytest.raises(ConfigError) as e:
        apply_overrides(RAW, ["ogden.alpha=[1, 2]"])
    assert str(e.value) == "--set ogden.alpha=[1, 2]: expected a list of 3 values like the protocol's [1.3, 5.0, -2.0]."
    with pytest.raises(ConfigError) as e:
        apply_overrides(RAW, ["joint"])
    assert str(e.value) == "--set needs key=value (for example actuator.L0_m=0.08), got 'joint'."
    with pytest.raises(ConfigError) as e:
        apply_overrides(RAW, ["joint.bounds=1"])
    assert str(e.value).startswith("Protocol key 'joint.bounds' is a table; --set one of its keys: L1_m")


def actuator_of(assignment: str) -> Any:
    """The actuator of the shipped protocol with one value changed, as the model takes it."""
    return checked_actuator(check_document(apply_overrides(RAW, [assignment]), source="p.toml").settings, "p.toml")


def test_bad_protocol_values_are_one_sentence(tmp_path):
    # A uniaxial-only fit can have a negative modulus; in Eq. 3's convention that is unstable.
    with pytest.raises(ConfigError) as e:
        actuator_of("ogden.mu_MPa=[0.1004, 0.00281, -0.03314]")
    assert str(e.value) == (
        "p.toml: the Ogden constants need mu_i > 0 and alpha_i != 0 for every term (Eq. 3's "
        "convention; a negative mu_i makes the wall unstable outside uniaxial tension)."
    )
    with pytest.raises(ConfigError) as e:
        actuator_of("actuator.A0_m2=5e-4")
    assert str(e.value) == (
        "p.toml: key 'actuator.A0_m2' must be less than the cage's section at rest, "
        "pi r^2 = 0.0004909 m^2 (r from actuator.n_turns and thread_length_m): the wall lies "
        "inside the thread cage."
    )
    with pytest.raises(ConfigError) as e:
        actuator_of("actuator.thread_length_m=0.05")
    assert "must exceed actuator.L0_m" in str(e.value)
    # Types and signs are the loader's: the same sentences as every protocol's.
    with pytest.raises(ConfigError) as e:
        actuator_of("actuator.L0_m=-0.07")
    assert str(e.value) == "p.toml: key 'actuator.L0_m' must be greater than 0, not -0.07."
    odd = copy.deepcopy(RAW)
    odd["ogden"]["alpha"] = [1.3, 5.0, True]
    with pytest.raises(ConfigError) as e:
        check_document(odd, source="p.toml")
    assert str(e.value) == (
        "p.toml: key 'ogden.alpha' must be a list of numbers (Eq. 3's exponents), not the list [1.3, 5.0, true]."
    )
    f = tmp_path / "other.toml"
    f.write_text('kind = "force"\n')
    with pytest.raises(ConfigError) as e:
        load_rpam(f)
    assert str(e.value) == f"Protocol file {f} has kind = 'force'; the rPAM model needs kind = \"rpam\"."
    with pytest.raises(ConfigError) as e:
        load_rpam("takuma2014")
    assert str(e.value) == "Protocol takuma2014 has kind = 'force'; the rPAM model needs kind = \"rpam\"."
    f.write_text("kind = [\n")
    with pytest.raises(ConfigError) as e:
        load_rpam(f)
    assert str(e.value) == f"{f}: TOML syntax error at line 2 (end of file): invalid value."


def test_stretch_test_round_trip_recovers_the_correction():
    # Lengths the model predicts for the stretch-test grid, fed back as measurements,
    # give back the stretch force and a cubic fit returns the shipped coefficients.
    grid = PROTOCOL.settings.stretch_test
    masses, pressures = np.array(grid.payloads_kg), np.array(grid.pressures_MPa)
    assert masses.tolist() == pytest.approx([0, 0.1, 0.2, 0.3, 1.0, 1.3])
    assert pressures[0] == 0.0 and pressures[-1] == pytest.approx(0.190) and len(pressures) == 20
    M, P = np.meshgrid(masses, pressures)
    L = rpam.loaded_length(P, M, ACT)
    ok = np.isfinite(L) & (L / ACT.L0_m <= ACT.stretch_lambda_range[1])
    resid = rpam.stretch_residual(P[ok], L[ok], M[ok], ACT)
    np.testing.assert_allclose(resid, rpam.stretch_force(L[ok] / ACT.L0_m, ACT), atol=1e-8)
    coef = rpam.fit_stretch_correction(L[ok] / ACT.L0_m, resid)
    assert coef == pytest.approx(ACT.stretch_coefficients_N, abs=1e-5)


def test_joint_map_plan_spans_the_papers_pressures():
    grid = PROTOCOL.settings.joint_map
    Pa, Pb = np.array(grid.Pa_MPa), np.array(grid.Pb_MPa)
    assert Pa[0] == pytest.approx(0.041) and Pa[-1] == pytest.approx(0.138) and len(Pa) == 11
    # np.linspace's spacing, to the last bit (the set values the rig is driven to).
    np.testing.assert_array_equal(Pa, np.linspace(41.0, 138.0, 11) * 1e-3)
    np.testing.assert_array_equal(Pa, Pb)
    bad = apply_overrides(RAW, ["experiments.joint_map.Pa_count=0"])
    with pytest.raises(ConfigError) as e:
        check_document(bad, source="p.toml")
    assert str(e.value) == "p.toml: key 'experiments.joint_map.Pa_count' must be at least 1, not 0."
    bad = apply_overrides(RAW, ["experiments.joint_map.Pb_stop_kPa=40.0"])
    with pytest.raises(ConfigError) as e:
        check_document(bad, source="p.toml")
    assert (
        str(e.value)
        == "p.toml: key 'experiments.joint_map.Pb_stop_kPa' must be at least Pb_start_kPa (41.0), not 40.0."
    )


def test_fast_arms_in_the_torque_match_the_cross_products():
    alpha = np.linspace(-1.2, 1.2, 25)
    La, Lb = rpam.actuator_lengths(alpha, PAPER)
    fast = rpam._moment_arms_closed(alpha, PAPER, La, Lb)
    exact = rpam.moment_arms(alpha, PAPER)
    np.testing.assert_allclose(fast, exact, rtol=1e-12, atol=1e-15)
