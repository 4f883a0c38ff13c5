"""The rPAM's force derived from its potential: energy consistency and closed-form limits."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from labcli.papers.rpam2015.models import rpam
from labcli.papers.rpam2015.models import rpam_force as rf
from labcli.papers.rpam2015.protocol import load_rpam

PROTOCOL = load_rpam("rpam2015")
PATH, RAW = PROTOCOL.path, PROTOCOL.document
ACT = PROTOCOL.settings.actuator
MPA = 1e6


def numerical_push(P: float, L: float, act: rpam.Actuator, h: float = 1e-6) -> float:
    """Minus the central difference of the potential U - P V_g (N)."""
    up, down = (float(rf.potential_energy(P, L + d, act)) for d in (h, -h))
    return -(up - down) / (2 * h)


@pytest.mark.parametrize("P", [0.0, 0.003, 0.008, 0.041, 0.096, 0.19])
@pytest.mark.parametrize("lam", [0.8, 1.3, 1.6, 1.9, 2.5])
def test_push_is_minus_the_derivative_of_the_potential(P, lam):
    L = lam * ACT.L0_m
    push = float(rpam.push_force(P, L, ACT, stretch=False))
    assert push == pytest.approx(numerical_push(P, L, ACT), rel=1e-7, abs=1e-7)


def test_both_branches_are_exercised_and_meet_at_the_liftoff_pressure():
    L = 1.6 * ACT.L0_m
    P_lift = float(rf.liftoff_pressure(L, ACT))
    assert 0.004 < P_lift < 0.0102  # a few kPa: the gas soon holds the wall on the cage
    below, above = P_lift * (1 - 1e-6), P_lift * (1 + 1e-6)
    assert not rf.wall_state(below, L, ACT)[1] and rf.wall_state(above, L, ACT)[1]
    # Continuous across it: the slack tube has just grown to the cage.
    ro2, _ = rf.wall_state(below, L, ACT)
    assert float(ro2) == pytest.approx(float(rf.cage_radius_sq(L, ACT)), rel=1e-5)
    F = [float(rf.internal_force(p, L, ACT)) for p in (below, above)]
    assert F[0] == pytest.approx(F[1], abs=1e-4)
    # The shipped actuator's lift-off pressure stays below the joint map's 41 kPa everywhere.
    lam = np.linspace(1.0, 3.0, 41)
    assert np.max(rf.liftoff_pressure(lam * ACT.L0_m, ACT)) < 0.0102
    # Shortened, the wall bulges into the cage even when vented.
    assert rf.wall_state(0.0, 0.9 * ACT.L0_m, ACT)[1]


def test_vented_and_stretched_it_is_eq3_exactly():
    lam = np.linspace(1.01, 3.0, 30)
    gas, wall = rf.force_parts(0.0, lam * ACT.L0_m, ACT)
    np.testing.assert_array_equal(gas, 0.0)
    np.testing.assert_allclose(wall, rpam.material_force(lam, ACT), rtol=1e-12)
    np.testing.assert_allclose(rpam.wall_force(0.0, lam * ACT.L0_m, ACT), rpam.material_force(lam, ACT), rtol=1e-12)


def test_on_the_cage_the_gas_term_is_eq2_rederived_without_a_wall_term():
    L = np.linspace(0.07, 0.14, 8)
    for P in (0.041, 0.096, 0.138):
        np.testing.assert_allclose(
            rpam.constraint_force(P, L, ACT),
            P * MPA * (3 * L**2 - ACT.thread_length_m**2) / (4 * math.pi * ACT.n_turns**2),
            rtol=1e-13,
        )
        # ... and the wall's part does not depend on the pressure while the cage holds it.
        np.testing.assert_allclose(rpam.wall_force(P, L, ACT), rpam.wall_force(0.041, L, ACT), rtol=1e-12)
    assert float(rpam.wall_force(0.096, ACT.L0_m, ACT)) == pytest.approx(0.0, abs=1e-9)


def test_hoop_threads_and_a_thin_wall_give_planar_ogden_extension():
    # n -> inf: the cage radius no longer changes with L, the hoop stretch is 1 at the outer
    # surface; a thin wall is then in planar extension: A0 sum 2 mu/alpha (l^(a-1) - l^(-a-1)).
    r, L0, A0 = 0.0125, 0.07, 1e-9  # a vanishingly thin wall (13 nm)
    act = replace(ACT, L0_m=L0, A0_m2=A0, n_turns=1e5, thread_length_m=math.hypot(2 * math.pi * r * 1e5, L0))
    lam = np.array([1.2, 1.6, 2.0, 2.5])
    planar = sum(
        2 * m * MPA * A0 / a * (lam ** (a - 1) - lam ** (-a - 1))
        for m, a in zip(act.ogden_mu_MPa, act.ogden_alpha, strict=False)
    )
    np.testing.assert_allclose(rpam.wall_force(0.1, lam * L0, act), planar, rtol=1e-5)
    # Stiffer than Eq. 3's uniaxial wall: 4 mu A0 against 3 mu A0 per unit stretch at rest.
    h = 1e-5
    slope = float(rpam.wall_force(0.1, (1 + h) * L0, act) - rpam.wall_force(0.1, (1 - h) * L0, act)) / (2 * h)
    assert slope == pytest.approx(4 * sum(act.ogden_mu_MPa) * MPA * A0, rel=1e-4)
    # The gas pushes on the whole cage section.
    assert float(rpam.constraint_force(0.1, 1.5 * L0, act)) == pytest.approx(-0.1 * MPA * math.pi * r**2, rel=1e-6)


def test_thick_neo_hookean_wall_on_the_cage_matches_its_closed_form_energy():
    # One Ogden term with alpha = 2 is neo-Hookean, W = mu/2 (I1 - 3); integrated over the
    # thick wall with r^2 = r_o^2 - (R_o^2 - R^2)/lambda it has the closed form
    # U = mu/2 L0 [A0 (lam^2 + 2/lam - 3) + pi A ln(R_o^2 r_i^2 / (R_i^2 r_o^2))], A = r_o^2 - R_o^2/lam.
    mu = 0.07
    act = replace(ACT, ogden_mu_MPa=(mu,), ogden_alpha=(2.0,))
    Ri2, Ro2 = rf.wall_radii_sq(act)
    for lam in (0.9, 1.3, 2.0, 2.6):
        L = lam * act.L0_m
        P = 0.1  # well above lift-off: on the cage
        ro2 = float(rf.cage_radius_sq(L, act))
        ri2 = ro2 - act.A0_m2 / (math.pi * lam)
        A = ro2 - Ro2 / lam
        U = (
            mu
            * MPA
            / 2
            * act.L0_m
            * (act.A0_m2 * (lam**2 + 2 / lam - 3) + math.pi * A * math.log(Ro2 * ri2 / (Ri2 * ro2)))
        )
        gas_volume = math.pi * ro2 * L - act.A0_m2 * act.L0_m
        assert float(rf.potential_energy(P, L, act)) + P * MPA * gas_volume == pytest.approx(U, rel=1e-7)


def test_the_old_wall_term_is_the_difference_the_review_measured():
    # At L_a = 0.1336 m and 96 kPa the printed-Eq.-2 reading added +P A0 / lambda = 10.4 N
    # against a cage force of -45.2 N; the derived force has the cage term alone.
    L, P = 0.1336, 0.096
    cage = float(rpam.constraint_force(P, L, ACT))
    assert cage == pytest.approx(-45.2, abs=0.05)
    assert P * MPA * ACT.A0_m2 / (L / ACT.L0_m) == pytest.approx(10.4, abs=0.05)


def test_a_closed_lumen_is_nan_not_a_number_pretending():
    # Squashed to a quarter of its length the thick wall would more than fill the cage.
    assert np.isnan(rpam.external_force(0.05, 0.25 * ACT.L0_m, ACT))
