"""Physics of the simulated test bed: geometry, actuator, chambers and statics."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from labcli.papers.takuma2014.sim import physics as ph

GEOM = ph.Geometry()
RNG = np.random.default_rng(12)
THETAS = RNG.uniform(-0.4, 0.4, size=(8, 2))


def _fd(f, theta, h=1e-6):
    """Central differences of f (returns (..., k)) over the two angles -> (k, 2)."""
    cols = []
    for k in range(2):
        d = np.zeros(2)
        d[k] = h
        cols.append((f(theta + d) - f(theta - d)) / (2 * h))
    return np.stack(cols, axis=-1)


def _settled(params):
    """Baseline with valves open, then the same posture with the valves closed."""
    e0 = ph.solve_equilibrium(params, ph.Chambers.open(params.supply_pa))
    closed = ph.Chambers.closed_at(e0.lengths_m, e0.pressures_MPa * 1e6, params)
    return e0, closed


# ---------------------------------------------------------------- geometry


def test_paths_at_rest_are_h1_and_h1_plus_h2():
    s = ph.path_lengths(np.zeros(2), GEOM)
    assert s == pytest.approx([0.355, 0.355, 0.485, 0.485], abs=1e-15)


@pytest.mark.parametrize("theta", THETAS)
def test_paths_match_points_in_the_plane(theta):
    # Independent construction from anchor, guide and attachment points.
    t1, t2 = theta

    def rot(a, v):
        return np.array([np.cos(a) * v[0] - np.sin(a) * v[1], np.sin(a) * v[0] + np.cos(a) * v[1]])

    g = GEOM
    joint2 = rot(t1, (0, g.h2))
    want = []
    for j, r in ((1, g.r1), (2, g.r2)):
        for side in (-1, 1):
            base = np.array([side * r, -g.h1])
            on1 = rot(t1, (side * r, 0))
            if j == 1:
                want.append(np.linalg.norm(on1 - base))
            else:
                on2 = joint2 + rot(t1 + t2, (side * r, 0))
                want.append(np.linalg.norm(on1 - base) + np.linalg.norm(on2 - on1))
    got = ph.path_lengths(theta, g)
    assert got[[0, 1, 2, 3]] == pytest.approx([want[0], want[1], want[2], want[3]], rel=1e-13)


@pytest.mark.parametrize("theta", THETAS)
def test_path_gradients_are_exact(theta):
    fd = _fd(lambda t: ph.path_lengths(t, GEOM), theta)
    assert ph.path_gradients(theta, GEOM) == pytest.approx(fd, abs=1e-9)


@pytest.mark.parametrize("theta", THETAS)
def test_jacobian_is_dC_dtheta(theta):
    fd = _fd(lambda t: ph.contact_point(t, GEOM), theta)
    J = ph.jacobian(theta, GEOM)
    assert J == pytest.approx(fd, abs=1e-9)
    # det J = h2 h3 sin(theta2): singular with a straight upper joint (docs/errata.md).
    assert np.linalg.det(J) == pytest.approx(GEOM.h2 * GEOM.h3 * np.sin(theta[1]), abs=1e-14)


def test_exact_eq8_difference_of_squares():
    # Eqs. 2 - 3 give s_R1^2 - s_L1^2 = 4 h1 r1 sin(theta1) with no approximation.
    for t in THETAS:
        s = ph.path_lengths(t, GEOM)
        assert s[1] ** 2 - s[0] ** 2 == pytest.approx(4 * GEOM.h1 * GEOM.r1 * np.sin(t[0]), rel=1e-12)


def test_vectorised_over_postures():
    s = ph.path_lengths(THETAS, GEOM)
    assert s.shape == (8, 4)
    assert s[3] == pytest.approx(ph.path_lengths(THETAS[3], GEOM))
    assert ph.path_gradients(THETAS, GEOM).shape == (8, 4, 2)
    assert ph.jacobian(THETAS, GEOM).shape == (8, 2, 2)


# ---------------------------------------------------------------- actuator


def test_tension_is_minus_p_dV_dL():
    b, n, L, P = 0.29, 10.0, 0.22, 3e5
    h = 1e-7
    dV = (ph.mckibben_volume(L + h, b, n) - ph.mckibben_volume(L - h, b, n)) / (2 * h)
    assert ph.mckibben_tension(L, P, b, n, 0.0, 0.0) == pytest.approx(-P * dV, rel=1e-7)
    # Volume of a cylinder whose circumference is set by the braid.
    D = np.sqrt(b * b - L * L) / (n * np.pi)
    assert ph.mckibben_volume(L, b, n) == pytest.approx(np.pi * D * D / 4 * L, rel=1e-12)


def test_pressurised_actuator_contracts_and_stretching_raises_tension():
    p = ph.nominal_params()
    b, n, kr, Lr = p.b[0], p.n[0], p.k_rubber[0], p.L_rubber[0]
    from scipy.optimize import brentq

    def free(P):
        return brentq(lambda L: ph.mckibben_tension(L, P, b, n, kr, Lr), b / np.sqrt(3) * 0.9, b * 0.999)

    assert free(3e5) < free(1e5) < free(0.0) == pytest.approx(Lr)
    L = np.linspace(0.2, 0.24, 9)
    T = ph.mckibben_tension(L, 3e5, b, n, kr, Lr)
    assert np.all(np.diff(T) > 0)
    # At the braid's neutral angle (54.7 deg) pressure makes no tension.
    L_neutral = b / np.sqrt(3)
    assert np.degrees(ph.braid_angle(L_neutral, b)) == pytest.approx(54.7356, abs=1e-3)
    assert ph.mckibben_tension(L_neutral, 3e5, b, n, 0.0, 0.0) == pytest.approx(0.0, abs=1e-9)


# ---------------------------------------------------------------- statics


def test_zero_load_is_straight_at_supply_pressure():
    p = ph.nominal_params()
    e0, closed = _settled(p)
    assert e0.theta_rad == pytest.approx([0, 0], abs=1e-12)
    assert e0.pressures_MPa == pytest.approx([0.3] * 4, abs=1e-12)
    e = ph.solve_equilibrium(p, closed)
    assert e.theta_rad == pytest.approx([0, 0], abs=1e-12)
    assert e.pressures_MPa == pytest.approx([0.3] * 4, abs=1e-12)
    assert np.all(e0.tensions_N > 5)  # pretension keeps every tendon taut


def test_varied_rig_baseline_is_near_but_not_at_zero_and_closing_keeps_it():
    p = ph.varied_params(7)
    e0, closed = _settled(p)
    assert 1e-4 < np.abs(e0.theta_rad).max() < np.radians(3)
    e = ph.solve_equilibrium(p, closed, theta0=[0.1, -0.1])
    assert e.theta_rad == pytest.approx(e0.theta_rad, abs=1e-10)
    assert e.pressures_MPa == pytest.approx(e0.pressures_MPa, abs=1e-12)
    # The posture, not the tension, absorbs the differences: with no load each
    # antagonistic pair settles at (nearly) equal tensions.
    assert e0.tensions_N[0] == pytest.approx(e0.tensions_N[1], rel=1e-3)
    assert e0.tensions_N[2] == pytest.approx(e0.tensions_N[3], rel=1e-3)
    assert np.ptp(e0.lengths_m[:2] - p.L_mount[:2]) > 1e-5


@pytest.mark.parametrize("mass,deg", [(0.05, 0), (0.2, 30), (0.5, 120), (1.0, 180), (1.0, -90), (0.7, -20)])
def test_equilibrium_residual_and_energy_minimum(mass, deg):
    p = ph.varied_params(3)
    e0, closed = _settled(p)
    load = ph.Weight(mass, np.radians(deg))
    e = ph.solve_equilibrium(p, closed, load, theta0=e0.theta_rad)
    assert e.residual_Nm < 1e-9
    assert e.stable

    # Independent check: the total potential energy is stationary and minimal there.
    def energy(theta):
        L = ph.actuator_lengths(theta, p)
        V = ph.mckibben_volume(L, p.b, p.n)
        # Closed chamber: -int P_gauge dV = -N ln(V + Vd) + P_atm V; rubber: spring energy.
        U = -closed.amount * np.log(V + p.V_dead) + ph.P_ATM * V + 0.5 * p.k_rubber * (L - p.L_rubber) ** 2
        return U.sum() - load.force(theta, p.geometry) @ ph.contact_point(theta, p.geometry)

    grad = _fd(lambda t: np.atleast_1d(energy(t)), e.theta_rad, h=1e-5)[0]
    assert np.abs(grad).max() < 1e-7
    for d in ([1e-3, 0], [0, 1e-3], [1e-3, -1e-3]):
        assert energy(e.theta_rad + d) > energy(e.theta_rad)


@pytest.mark.parametrize("mass,deg", [(0.1, 0), (0.5, 30), (1.0, 60), (0.3, -45)])
def test_mirror_loads_give_mirror_postures_and_swapped_pressures(mass, deg):
    p = ph.nominal_params()
    _, closed = _settled(p)
    a = ph.solve_equilibrium(p, closed, ph.Weight(mass, np.radians(deg)))
    b = ph.solve_equilibrium(p, closed, ph.Weight(mass, np.radians(180 - deg)))
    assert abs(a.theta_rad[0]) > 1e-3
    assert b.theta_rad == pytest.approx(-a.theta_rad, abs=1e-11)
    assert b.pressures_MPa == pytest.approx(a.pressures_MPa[[1, 0, 3, 2]], abs=1e-12)


@pytest.mark.parametrize("deg", [0, 45, 135, 180, -60])
def test_pressure_changes_follow_boyle_for_the_braid_geometry(deg):
    p = ph.varied_params(11)
    e0, closed = _settled(p)
    e = ph.solve_equilibrium(p, closed, ph.Weight(0.6, np.radians(deg)), theta0=e0.theta_rad)
    dL = e.lengths_m - e0.lengths_m
    dV = ph.mckibben_volume(e.lengths_m, p.b, p.n) - ph.mckibben_volume(e0.lengths_m, p.b, p.n)
    dP = e.pressures_MPa - e0.pressures_MPa
    assert np.all(np.degrees(ph.braid_angle(e0.lengths_m, p.b)) < 54.7)
    assert np.all(np.sign(dV) == -np.sign(dL))  # stretched -> smaller volume
    assert np.all(np.sign(dP) == np.sign(dL))  # -> higher pressure
    # Boyle on absolute pressure holds exactly.
    amount = (e.pressures_MPa * 1e6 + ph.P_ATM) * (ph.mckibben_volume(e.lengths_m, p.b, p.n) + p.V_dead)
    assert amount == pytest.approx(closed.amount, rel=1e-13)


def test_braid_beyond_neutral_angle_reverses_the_pressure_change():
    # Above 54.7 deg a stretched chamber grows, so its pressure falls.
    p = ph.nominal_params()
    L = p.L_mount[0]
    b_wide = L / np.cos(np.radians(60))
    assert ph.mckibben_dvolume(L, b_wide, p.n[0]) > 0
    closed = ph.Chambers.closed_at(np.full(4, L), np.full(4, 3e5), replace(p, b=np.full(4, b_wide)))
    q = replace(p, b=np.full(4, b_wide))
    assert closed.gauge(np.full(4, L + 0.002), q)[0] < 3e5 < closed.gauge(np.full(4, L - 0.002), q)[0]


@pytest.mark.parametrize("mass,deg", [(0.05, 0), (0.1, 30), (0.2, 150), (0.2, -60)])
def test_small_loads_agree_with_linearised_eqs_9_13_29(mass, deg):
    # Readings: Eq. 8 writes the left change as a shortening, so in extensions
    # e = s(theta) - s(0) Eq. 9 reads sin(theta1) = (e_R1 - e_L1) / (2 r1) and
    # Eq. 13 reads theta2 = -(e_R1 - e_L1) / (2 r1) + (e_R2 - e_L2) / (2 r2);
    # Eq. 29 is Boyle linearised on ABSOLUTE pressure, with the dead volume:
    # e = beta (P0/P - 1), beta = (V + V_dead) / V'(L).
    # Tolerance: 1 % of the largest angle for the angles, 5 % for extensions.
    p = ph.nominal_params()
    g = p.geometry
    e0, closed = _settled(p)
    e = ph.solve_equilibrium(p, closed, ph.Weight(mass, np.radians(deg)))
    P0 = e0.pressures_MPa * 1e6 + ph.P_ATM
    P = e.pressures_MPa * 1e6 + ph.P_ATM
    ext = ph.boyle_beta(e0.lengths_m, p) * (P0 / P - 1)
    true_ext = e.lengths_m - e0.lengths_m
    assert ext == pytest.approx(true_ext, abs=0.05 * np.abs(true_ext).max())
    t1 = np.arcsin((ext[1] - ext[0]) / (2 * g.r1))
    t2 = -(ext[1] - ext[0]) / (2 * g.r1) + (ext[3] - ext[2]) / (2 * g.r2)
    scale = np.abs(e.theta_rad).max()
    assert scale > np.radians(0.1)
    assert [t1, t2] == pytest.approx(e.theta_rad, abs=0.01 * scale)


def test_tuning_lands_in_the_papers_ranges():
    # Paper scale: 50-1000 g at the tip deflect the joints by about 0.1 deg up to a few
    # degrees; ~0.1 rad at joint 1 changes outside pressures by several percent (gauge),
    # as the paper's sin(theta1) = 0.136 u_L1 - 1.587 u_R1 implies.
    p = ph.nominal_params()
    e0, closed = _settled(p)
    heavy = ph.solve_equilibrium(p, closed, ph.Weight(1.0, 0.0))
    light = ph.solve_equilibrium(p, closed, ph.Weight(0.05, np.radians(45)))
    assert 1.5 < abs(np.degrees(heavy.theta_rad[0])) < 4
    assert 0.05 < abs(np.degrees(light.theta_rad[0])) < 0.3
    mid = ph.solve_equilibrium(p, closed, ph.Weight(0.75, np.pi))
    per_tenth_rad = (mid.pressures_MPa / e0.pressures_MPa - 1) * 0.1 / mid.theta_rad[0]
    assert 0.03 < per_tenth_rad[1] < 0.10  # R1 stretched: pressure up
    assert -0.10 < per_tenth_rad[0] < -0.03
    assert np.all(heavy.pressures_MPa < 1.0)  # inside the sensor span


def test_thin_design_keeps_the_earlier_tuning():
    p = ph.nominal_params(design="thin")
    e0, closed = _settled(p)
    heavy = ph.solve_equilibrium(p, closed, ph.Weight(1.0, 0.0))
    assert 10 < abs(np.degrees(heavy.theta_rad[0])) < 16
    K = ph.stiffness_matrix(e0.theta_rad, p, closed, ph.NoLoad())
    assert K == pytest.approx(np.array([[7.42, 1.79], [1.79, 1.79]]), abs=0.006)


def test_unequal_inside_supply_bends_the_upper_joint():
    # The bent-rest protocol: L2 at 0.40 MPa, R2 at 0.20 MPa pulls link 2 to the left.
    p = ph.nominal_params(supply_MPa=(0.30, 0.30, 0.40, 0.20))
    e = ph.solve_equilibrium(p, ph.Chambers.open(p.supply_pa))
    assert 10 < np.degrees(e.theta_rad[1]) < 20
    assert abs(np.degrees(e.theta_rad[0])) < 1
    assert e.stable and e.residual_Nm < 1e-9


def test_push_force_points_from_object_centre_to_tip_with_eq_39_centre():
    p = ph.nominal_params()
    g = p.geometry
    _, closed = _settled(p)
    push = ph.Push(radius_m=0.04, distance_m=0.006, phi_rad=np.radians(10), stiffness_N_per_m=800.0)
    O2 = push.center(g)
    assert O2 == pytest.approx([0.04 - 0.006 * np.cos(np.radians(10)), g.h2 + g.h3 - 0.006 * np.sin(np.radians(10))])
    e = ph.solve_equilibrium(p, closed, push)
    assert e.residual_Nm < 1e-9
    C = ph.contact_point(e.theta_rad, g)
    v = C - O2
    depth = 0.04 - np.linalg.norm(v)
    assert 0 < depth < 0.006  # the arm yields part of the push
    assert e.force_N == pytest.approx(800.0 * depth * v / np.linalg.norm(v), rel=1e-12)
    # Eqs. 38 and 42 recover the object's stiffness from the true force and O2.
    assert np.linalg.norm(e.force_N) / (0.04 - np.linalg.norm(C - O2)) == pytest.approx(800.0)
    # A stiffer object deflects the arm more for the same push.
    hard = ph.solve_equilibrium(p, closed, replace(push, stiffness_N_per_m=4000.0))
    assert abs(hard.theta_rad[0]) > abs(e.theta_rad[0])
    assert ph.Push(0.04, 0.0, 0.0, 800.0).force(np.zeros(2), g) == pytest.approx([0, 0])


def test_no_equilibrium_is_reported_not_invented():
    p = ph.nominal_params()
    _, closed = _settled(p)
    with pytest.raises(ValueError, match="no static equilibrium"):
        ph.solve_equilibrium(p, closed, ph.Weight(600.0, 0.0))


def test_documented_tuning_table_matches_the_model():
    # The table in the module docstring is what the model computes.
    doc = ph.__doc__
    block = doc[doc.index("mass  dir") :].split("\n\n")[0].splitlines()[1:]
    assert len(block) >= 5
    p = ph.nominal_params()
    e0, closed = _settled(p)
    for row in block:
        f = row.replace("g", " ").split()
        mass, deg, want = float(f[0]) / 1e3, float(f[1]), np.array(f[2:], dtype=float)
        e = ph.solve_equilibrium(p, closed, ph.Weight(mass, np.radians(deg)))
        got = np.concatenate([np.degrees(e.theta_rad), (e.pressures_MPa / e0.pressures_MPa - 1) * 100])
        assert got == pytest.approx(want, abs=0.006), row
    K = ph.stiffness_matrix(e0.theta_rad, p, closed, ph.NoLoad())
    assert K == pytest.approx(np.array([[32.86, 3.94], [3.94, 3.94]]), abs=0.006)
