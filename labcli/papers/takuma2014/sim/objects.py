"""Objects for the simulated stiffness experiment (Takuma et al. 2014, Section 4, Figure 9).

The paper pushes six cylinders of three materials: three PET bottles, two
aluminium cans and one steel can.  It prints neither their sizes nor their
stiffnesses, so the catalogue below takes radii from common real objects and
lateral stiffnesses from what such objects have when a rounded tip presses
the middle of their side; every stiffness is an assumption, stated per object.

Why these push distances.  The arm is soft against these objects: on the paper-scale rig
(:mod:`labcli.papers.takuma2014.sim.physics`, design values, 0.30 MPa, valves closed) its tip
yields 604 N/m along x when upright (518 N/m resting bent on the bent protocol's supply).  Arm
and object act as springs in series, so an object of stiffness k_o pushed by d along x deforms by
``d k_tip / (k_tip + k_o)`` and the tip feels ``k_o`` times that (Eq. 38).  Solved exactly on the
design rig (:data:`DEFORMATION_M`, ``tests/papers/takuma2014/test_objects.py`` holds the physics
to it and to the closed form):

=============  ============  =======  ============  ==========  ===============
object         k_o (N/m)     d (mm)   deformation   force (N)   tip deflection
=============  ============  =======  ============  ==========  ===============
pet-1          420           10       5.90 mm       2.48        4.1 mm
pet-2          520           10       5.38 mm       2.79        4.6 mm
pet-3          610           10       4.98 mm       3.04        5.0 mm
can-al-1       1800          15       3.78 mm       6.80        11.2 mm
can-al-2       2400          15       3.02 mm       7.26        12.0 mm
can-steel-1    8000          20       1.41 mm       11.30       18.6 mm
=============  ============  =======  ============  ==========  ===============

A stiffer object deforms less at the same push, so the stiffer ones get longer pushes (10, 15,
20 mm for PET, aluminium, steel; 20 mm is the top of the protocol's range,
``[push] distance_max_m``).  The steel can's 1.41 mm is what the pressure-only angles must
resolve: the tip sits 0.195 m from the bottom joint, so an error of 0.1 deg in the angles
misplaces the contact by about 0.34 mm, a quarter of the deformation, while the bottles'
5-6 mm hardly notice it.  Much stiffer than 1e4 N/m the deformation at 20 mm shrinks towards
the angles' error and this arm stops telling objects apart.  (Before the paper-scale retune the
thin-muscle rig's tip yielded 186 N/m and the steel can deformed 0.45 mm.)

Plain data: :data:`DEMO_OBJECTS` lists :class:`SimObject` rows,
:data:`DEMO_PHI_DEG` the push directions cycled through for each object;
:func:`demo_plan` turns them into the acquisition session's schedule, and
:func:`labcli.papers.takuma2014.sim.drive.simulate_pushes` pushes them on a rig directly.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from ..push_session import PlannedObject
from ..session import ObjectSpec, PushSpec

CATEGORY_OF_MATERIAL = {"PET": "soft", "aluminium": "medium", "steel": "hard"}


@dataclass(frozen=True)
class SimObject:
    """One cylinder: name, material, the category it belongs to, radius (m),
    lateral stiffness (N/m), the push distance used for it (m) and where the
    numbers come from."""

    name: str
    material: str
    radius_m: float
    stiffness_N_per_m: float
    distance_m: float
    source: str

    @property
    def category(self) -> str:
        return CATEGORY_OF_MATERIAL[self.material]


DEMO_OBJECTS: tuple[SimObject, ...] = (
    SimObject(
        "pet-1",
        "PET",
        0.033,
        420.0,
        0.010,
        "500 ml water bottle, 66 mm across; assumed 0.3-0.6 N/mm, the range of an empty capped "
        "thin-wall (0.3 mm) PET bottle pressed at mid-height",
    ),
    SimObject(
        "pet-2",
        "PET",
        0.0325,
        520.0,
        0.010,
        "500 ml soft-drink bottle, 65 mm across, slightly thicker wall; assumed, as pet-1",
    ),
    SimObject(
        "pet-3",
        "PET",
        0.035,
        610.0,
        0.010,
        "600 ml bottle with ribs, 70 mm across; assumed, ribs stiffen it towards the top of the PET range",
    ),
    SimObject(
        "can-al-1",
        "aluminium",
        0.033,
        1800.0,
        0.015,
        "350 ml aluminium drink can, 66 mm across, 0.1 mm wall; assumed 1.5-3 N/mm for an empty "
        "opened can pressed between its rims",
    ),
    SimObject(
        "can-al-2",
        "aluminium",
        0.033,
        2400.0,
        0.015,
        "250 ml slim aluminium can, 66 mm body; assumed, the shorter body is stiffer between the rims",
    ),
    SimObject(
        "can-steel-1",
        "steel",
        0.037,
        8000.0,
        0.020,
        "tinplate food can (74 mm across, 0.2 mm beaded wall); assumed 8 N/mm, near the upper end of "
        "what this arm resolves (a real steel can may be stiffer still)",
    ),
)

# Deformation (m) of each object pushed its distance along x into the tip of the design rig
# (0.30 MPa, valves closed, upright): the table above.
DEFORMATION_M: dict[str, float] = {
    "pet-1": 5.90e-3,
    "pet-2": 5.38e-3,
    "pet-3": 4.98e-3,
    "can-al-1": 3.78e-3,
    "can-al-2": 3.02e-3,
    "can-steel-1": 1.41e-3,
}

# Push directions (deg) cycled through an object's pushes: the paper's arbitrary
# directions, kept inside +-30 deg where the pushed object still meets the tip
# squarely (phi must stay well below acos(d / 2R) = 72 deg for R = 33 mm, d = 20 mm).
DEMO_PHI_DEG: tuple[float, ...] = (0.0, 15.0, -15.0, 30.0, -30.0, 7.5, -7.5, 22.5, -22.5, 0.0)


def demo_plan(
    objects: Sequence[SimObject] = DEMO_OBJECTS,
    pushes_per_object: int = 10,
    *,
    phi_known: bool = True,
    labelled: bool = False,
) -> list[Any]:
    """The demo's push schedule as :class:`labcli.papers.takuma2014.session.PlannedObject` rows.

    ``phi_known=False`` leaves the direction out of the table (it is then
    solved); ``labelled`` writes each object's category (reference objects).
    """
    plan = []
    for obj in objects:
        pushes = tuple(
            PushSpec(obj.distance_m, math.radians(DEMO_PHI_DEG[k % len(DEMO_PHI_DEG)]) if phi_known else None)
            for k in range(pushes_per_object)
        )
        spec = ObjectSpec(obj.name, obj.radius_m, obj.category if labelled else "", obj.stiffness_N_per_m)
        plan.append(PlannedObject(spec, pushes))
    return plan
