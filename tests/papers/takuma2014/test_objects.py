"""The simulated objects' deformations on the paper-scale rig, against the physics and closed forms.

Each object is pushed its demo distance along x into the tip of the design rig (0.30 MPa, valves
closed): at the static equilibrium the object's spring force over its deformation is its
stiffness (Eq. 38, exactly: the model's contact force is radial), and arm and object deform as
two springs in series, ``d k_tip / (k_tip + k_o)`` with ``k_tip`` from the joints' stiffness
matrix and the Jacobian.  The documented deformations (``sim/objects.py``) must be those.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from labcli.papers.takuma2014.sim import physics as ph
from labcli.papers.takuma2014.sim.objects import DEFORMATION_M, DEMO_OBJECTS


def cross(a: np.ndarray, b: np.ndarray) -> float:
    """The z component of a x b for vectors in the plane."""
    return float(a[0] * b[1] - a[1] * b[0])


def design_rig() -> tuple[ph.RigParams, ph.Chambers, np.ndarray]:
    p = ph.nominal_params()
    e0 = ph.solve_equilibrium(p, ph.Chambers.open(p.supply_pa))
    return p, ph.Chambers.closed_at(e0.lengths_m, e0.pressures_MPa * 1e6, p), e0.theta_rad


def pushed(obj, phi_rad: float = 0.0, mu: float = 0.0) -> tuple[float, np.ndarray, np.ndarray, ph.Push]:
    """Deformation (m), force on the tip (N), contact minus the object's centre (m), the load."""
    p, closed, rest = design_rig()
    touch = tuple(float(v) for v in ph.contact_point(rest, p.geometry))
    load = ph.Push(obj.radius_m, obj.distance_m, phi_rad, obj.stiffness_N_per_m, touch, friction_mu=mu)
    eq = ph.solve_equilibrium(p, closed, load, theta0=rest)
    v = ph.contact_point(eq.theta_rad, p.geometry) - load.center(p.geometry)
    return obj.radius_m - float(np.linalg.norm(v)), np.asarray(eq.force_N), v, load


def tip_stiffness_x() -> float:
    """1 / the tip's compliance along x, J K^-1 J^T, at the upright rest (N/m)."""
    p, closed, rest = design_rig()
    K = ph.stiffness_matrix(rest, p, closed, ph.NoLoad())
    J = ph.jacobian(rest, p.geometry)
    return 1.0 / float((J @ np.linalg.solve(K, J.T))[0, 0])


def test_the_upright_tip_yields_about_600_N_per_m_along_x():
    assert tip_stiffness_x() == pytest.approx(604, rel=0.005)


@pytest.mark.parametrize("obj", DEMO_OBJECTS, ids=lambda o: o.name)
def test_each_objects_deformation_is_the_documented_one_and_the_physics(obj):
    dx, F, v, _ = pushed(obj)
    # Eq. 38 on the exact equilibrium: the radial spring's force over the deformation is k_o.
    assert float(np.linalg.norm(F)) / dx == pytest.approx(obj.stiffness_N_per_m, rel=1e-9)
    # ... and the force points from the object's centre to the contact (radial).
    assert cross(v, F) == pytest.approx(0.0, abs=1e-12)
    # Two springs in series, linearised at the rest: within 1 % (the arm's path bends a little).
    k_tip = tip_stiffness_x()
    assert dx == pytest.approx(obj.distance_m * k_tip / (k_tip + obj.stiffness_N_per_m), rel=0.01)
    assert dx == pytest.approx(DEFORMATION_M[obj.name], rel=0.005)


def test_the_steel_can_deforms_1_4_mm_not_the_thin_rigs_0_45():
    steel = next(o for o in DEMO_OBJECTS if o.name == "can-steel-1")
    dx, F, _, _ = pushed(steel)
    assert 1.3e-3 < dx < 1.5e-3 and 10.5 < float(np.linalg.norm(F)) < 12.0
    # The stiffer the object, the less it deforms for the same push (springs in series).
    per_metre = [DEFORMATION_M[o.name] / o.distance_m for o in DEMO_OBJECTS]
    assert per_metre == sorted(per_metre, reverse=True)


def test_contact_friction_tilts_the_force_off_the_radius_by_atan_mu_once_the_tip_slides():
    pet = DEMO_OBJECTS[0]
    mu = 0.3
    dx, F, v, _ = pushed(pet, math.radians(30), mu)
    # Sliding: |F| = N sqrt(1 + mu^2) with N = k_o dx, tilted by atan(mu) from the radius, so
    # Eq. 38 read with |F| overstates k_o by sqrt(1 + mu^2) (4.4 %).
    tilt = math.atan2(cross(v, F), float(v @ F))
    assert abs(tilt) == pytest.approx(math.atan(mu), rel=1e-3)
    assert float(np.linalg.norm(F)) / dx == pytest.approx(pet.stiffness_N_per_m * math.sqrt(1 + mu * mu), rel=1e-3)
    # Pushed along x into the upright tip, the tip barely slips: the force stays within 1 deg of radial.
    dx0, F0, v0, _ = pushed(pet, 0.0, mu)
    assert abs(math.atan2(cross(v0, F0), float(v0 @ F0))) < math.radians(1.0)
    # Mirror pushes drag the tip the mirror way.
    _, Fm, vm, _ = pushed(pet, math.radians(-30), mu)
    assert math.atan2(cross(vm, Fm), float(vm @ Fm)) == pytest.approx(-tilt, rel=1e-3)


def test_the_pulley_holds_back_its_share_of_the_pull():
    w = ph.Weight(0.5, math.radians(30), loss=0.02)
    assert w.force(np.zeros(2), ph.Geometry()) == pytest.approx(
        0.98 * 0.5 * ph.G * np.array([math.cos(math.radians(30)), math.sin(math.radians(30))]), rel=1e-12
    )
    p, closed, rest = design_rig()
    lossy = ph.solve_equilibrium(p, closed, w, theta0=rest)
    lighter = ph.solve_equilibrium(p, closed, ph.Weight(0.49, math.radians(30)), theta0=rest)
    assert lossy.theta_rad == pytest.approx(lighter.theta_rad, abs=1e-12)
