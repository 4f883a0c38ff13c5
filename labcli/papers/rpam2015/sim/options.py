"""The rPAM rig's own options, declared as data (``sim://?mode=rpam&experiment=stretch``,
``labcli sim --mode rpam --experiment stretch``); the paper's ``make_rig`` builds the rig with them.

``experiment`` is how the stand is rigged at power-up (the console's ``mount`` and an
acquisition's prompts re-rig it): the joint map (actuators a and b on the joint) or the
stretch test (actuator a hanging on the stand).  ``nominal`` gives the rig without its
seeded variation: symmetric actuators with the protocol's stretch correction, no friction,
no potentiometer offset.  ``reading`` builds the stand's actuators on one reading of the force
(``sim://?mode=rpam&reading=paper``), so a joint map measured on it checks a model built on the
other reading against physics it was not built on.  An option left out is the rig's own default.

This module imports nothing heavy: the paper's declaration reads :class:`RpamRigOptions`.
"""

from __future__ import annotations

from dataclasses import dataclass

from ....core.options import choice, switch

EXPERIMENTS = ("joint", "stretch")  # the rig's configurations (rig.EXPERIMENTS; a test holds them equal)
FORCE_READINGS = ("derived", "paper")  # actuator.FORCE_READINGS (a test holds them equal)


@dataclass(frozen=True)
class RpamRigOptions:
    """The rPAM rig's own options (``sim://?mode=rpam``)."""

    experiment: str | None = choice(
        EXPERIMENTS,
        help="How the stand is rigged at power-up: the joint (a and b on the swivel plates) or the "
        "stretch test (actuator a hanging on the stand).",
        default_text="joint",
    )
    nominal: bool = switch(
        help="The nominal rig: symmetric actuators with the protocol's stretch correction, no friction, no offsets."
    )
    reading: str | None = choice(
        FORCE_READINGS,
        help="The reading of the actuator force the stand's actuators follow: derived (the cage-held wall's "
        "energy and the gas's virtual work) or paper (the lumen's free body).",
        default_text="the protocol's actuator.force_reading",
    )
