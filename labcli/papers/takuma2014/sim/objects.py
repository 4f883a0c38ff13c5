"""Objects for the simulated stiffness experiment (Takuma et al. 2014, Section 4, Figure 9).

The paper pushes six cylinders of three materials: three PET bottles, two
aluminium cans and one steel can.  It prints neither their sizes nor their
stiffnesses, so the catalogue below takes radii from common real objects and
lateral stiffnesses from what such objects have when a rounded tip presses
the middle of their side; every stiffness is an assumption, stated per object.

Why these push distances.  The simulated arm is soft: with the valves closed
its tip yields about 186 N/m along x (pushing a rigid object 10 mm moves the
tip 10 mm for 1.86 N; ``tests/cli/test_classify_cli.py`` measures it).  Arm and
object act as springs in series, so an object of stiffness k_o pushed by d
deforms by about ``d k_tip / (k_tip + k_o)``: 2.7 mm for a bottle (500 N/m)
pushed 10 mm, but only 0.45 mm for the steel can (8000 N/m) pushed 20 mm, the
top of the protocol's range (``[push] distance_max_m``).  Stiffer objects
therefore get longer pushes (10, 15, 20 mm for PET, aluminium, steel).  The
pressure-only angles err by about 0.01 deg rms on the simulated rig, some
0.03 mm at the 0.195 m lever, plus a model error of the paper's regression
that grows with the deflection; against the steel can's 0.45 mm this leaves
k_o some 6 % high with 8 % spread per push (``tests/benchmarks/classify_accuracy.py``).
Much stiffer than 1e4 N/m the deformation at 20 mm shrinks towards that error
and this arm stops telling objects apart.

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
