"""The two readings of the rPAM's force (derived, paper): numerical derivatives, closed forms,
and how each is chosen and recorded."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from labcli.errors import ModelError
from labcli.papers.rpam2015.actuator import FORCE_READINGS, Actuator
from labcli.papers.rpam2015.models import rpam
from labcli.papers.rpam2015.models import rpam_force as rf
from labcli.papers.rpam2015.protocol import actuator_of, load_rpam, with_overrides

DERIVED = actuator_of("rpam2015")
PAPER = DERIVED.with_force_reading("paper")
MPA = 1e6


def uniaxial(lam: np.ndarray, act: Actuator) -> np.ndarray:
    """Eq. 3 written out again, term by term."""
    return sum(
        2 * m * MPA * act.A0_m2 / a * (lam ** (a - 1) - lam ** (-a / 2 - 1))
        for m, a in zip(act.ogden_mu_MPa, act.ogden_alpha, strict=True)
    )


def test_the_shipped_protocol_reads_the_force_as_derived_and_both_readings_are_named():
    assert FORCE_READINGS == ("derived", "paper")
    assert DERIVED.force_reading == "derived" and PAPER.force_reading == "paper"
    assert DERIVED.with_force_reading(None) is DERIVED
    with pytest.raises(ModelError, match="read as derived or paper, not 'printed'"):
        DERIVED.with_force_reading("printed")


@pytest.mark.parametrize("P", [0.0, 0.041, 0.096, 0.19])
@pytest.mark.parametrize("lam", [0.8, 1.0, 1.4, 1.9, 2.5])
def test_the_paper_reading_is_the_derivative_of_its_potential(P, lam):
    L, h = lam * PAPER.L0_m, 1e-6
    up, down = (float(rf.potential_energy(P, L + d, PAPER)) for d in (h, -h))
    assert float(rf.internal_force(P, L, PAPER)) == pytest.approx((up - down) / (2 * h), rel=1e-7, abs=1e-7)


def test_the_paper_reading_is_the_lumen_free_body_term_by_term():
    lam = np.linspace(0.9, 2.4, 12)
    L = lam * PAPER.L0_m
    b, n = PAPER.thread_length_m, PAPER.n_turns
    for P in (0.041, 0.096, 0.138):
        gas, wall = rf.force_parts(P, L, PAPER)
        # Thread pull with the full hoop load, minus the gas on the lumen's section pi r_c^2 - A0/lambda.
        r_c2 = (b**2 - L**2) / (4 * math.pi**2 * n**2)
        lumen = math.pi * r_c2 - PAPER.A0_m2 / lam
        np.testing.assert_allclose(gas, P * MPA * (L**2 / (2 * math.pi * n**2) - lumen), rtol=1e-12)
        np.testing.assert_allclose(wall, uniaxial(lam, PAPER), rtol=1e-12)
        # Against the derived reading's gas term it is exactly the P A0 / lambda the paper keeps.
        np.testing.assert_allclose(gas - rf.force_parts(P, L, DERIVED)[0], P * MPA * PAPER.A0_m2 / lam, rtol=1e-9)


def test_both_readings_agree_on_a_vented_stretched_actuator_and_differ_under_pressure():
    lam = np.linspace(1.05, 2.5, 10)
    L = lam * DERIVED.L0_m
    np.testing.assert_allclose(rf.internal_force(0.0, L, PAPER), uniaxial(lam, PAPER), rtol=1e-12)
    np.testing.assert_allclose(rf.internal_force(0.0, L, DERIVED), rf.internal_force(0.0, L, PAPER), rtol=1e-9)
    # At rest and vented both carry nothing.
    for act in (DERIVED, PAPER):
        assert float(rf.internal_force(0.0, act.L0_m, act)) == pytest.approx(0.0, abs=1e-9)
    # Pressurised, the paper's reading pushes less: the lumen is narrower than the cage.
    diff = rf.internal_force(0.096, L, PAPER) - rf.internal_force(0.096, L, DERIVED)
    assert np.all(diff > 0)


def test_small_strain_stiffness_is_uniaxial_in_the_paper_reading():
    # dF/dlambda at rest, vented: 3 mu A0 (Eq. 3's uniaxial wall); the derived reading's
    # cage-held wall is stiffer under pressure (4 mu A0 in the hoop limit, tested elsewhere).
    h = 1e-6
    slope = float(
        rf.internal_force(0.0, (1 + h) * PAPER.L0_m, PAPER) - rf.internal_force(0.0, (1 - h) * PAPER.L0_m, PAPER)
    )
    assert slope / (2 * h) == pytest.approx(3 * sum(PAPER.ogden_mu_MPa) * MPA * PAPER.A0_m2, rel=1e-6)


def test_hoop_threads_make_the_paper_gas_term_the_end_cap_force_on_the_lumen():
    # n -> inf at a fixed cage radius: the thread's axial pull vanishes and what is left is the
    # gas pushing the end cap over the lumen, -P (pi r^2 - A0 / lambda).
    r, L0 = 0.0125, 0.07
    act = replace(PAPER, n_turns=1e5, thread_length_m=math.hypot(2 * math.pi * r * 1e5, L0))
    for lam in (1.2, 1.8):
        gas, _ = rf.force_parts(0.1, lam * L0, act)
        assert float(gas) == pytest.approx(-0.1 * MPA * (math.pi * r**2 - act.A0_m2 / lam), rel=1e-6)


def test_the_printed_sign_would_make_the_wall_pull_the_lumen_shut():
    # Eq. 2 as printed subtracts P A0 / lambda: at 96 kPa and the optimum's L_a that is 2 x 10.4 N
    # less push than the paper reading, more than a third of the cage term.
    L, P = 0.1336, 0.096
    paper_gas = float(rf.force_parts(P, L, PAPER)[0])
    printed = paper_gas - 2 * P * MPA * PAPER.A0_m2 / (L / PAPER.L0_m)
    assert printed - float(rf.force_parts(P, L, DERIVED)[0]) == pytest.approx(-10.4, abs=0.05)


def test_the_reading_travels_with_the_actuator_record_and_old_records_read_as_derived():
    d = PAPER.to_dict()
    assert d["force_reading"] == "paper"
    assert Actuator.from_dict(d) == PAPER
    del d["force_reading"]
    assert Actuator.from_dict(d).force_reading == "derived"
    d["force_reading"] = "printed"
    with pytest.raises(ModelError, match="key 'actuator.force_reading' must be one of derived, paper"):
        Actuator.from_dict(d)


def test_a_protocol_chooses_its_reading_and_one_without_the_key_is_derived():
    base = load_rpam("rpam2015")
    assert with_overrides(base, ['actuator.force_reading="paper"'], "p").settings.actuator.force_reading == "paper"
    doc = dict(base.document)
    doc["actuator"] = {k: v for k, v in doc["actuator"].items() if k != "force_reading"}
    from labcli.core.protocol import check_document

    assert check_document(doc, source="old").settings.actuator.force_reading == "derived"
    from labcli.errors import ConfigError

    with pytest.raises(ConfigError, match="force_reading"):
        with_overrides(base, ['actuator.force_reading="printed"'], "p")


def test_the_joint_balances_under_either_reading_at_the_papers_design():
    geom = rpam.JointGeometry(0.03, 0.1048, 0.06)
    a_derived = rpam.solve_equilibrium(0.096, 0.041, geom, DERIVED).alpha_deg
    a_paper = rpam.solve_equilibrium(0.096, 0.041, geom, PAPER).alpha_deg
    # The derived reading runs onto the toggle (60.2 deg); the paper's balances short of it.
    assert np.isnan(a_derived)
    assert 50.0 < float(a_paper) < 58.0
