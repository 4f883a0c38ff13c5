"""The rPAM joint's links as plain data (Fig. 4, Table I of the rPAM joint paper).

The pivot O sits on the bottom plate; the lower swivel mounts at ``(-L1, 0)`` (actuator a)
and ``(+L1, 0)`` (actuator b); the upper plate, at height ``L2``, carries the upper mounts
``L3`` either side of its middle.  The model (:mod:`labcli.papers.rpam2015.models.rpam`) and
the simulated stand read the same links; the optimiser searches over them.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    import numpy as np


@dataclass(frozen=True)
class JointGeometry:
    """Link lengths of the 1-DoF joint (Fig. 4), metres.

    The model solves whole populations of designs at once: the fields are then arrays that
    broadcast together.
    """

    L1_m: float | np.ndarray
    L2_m: float | np.ndarray
    L3_m: float | np.ndarray

    def to_dict(self) -> dict[str, float | np.ndarray]:
        return asdict(self)
