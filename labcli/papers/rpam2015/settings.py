"""What an rPAM protocol says, typed: ``Protocol.settings`` of a protocol of kind ``rpam``.

:func:`labcli.papers.rpam2015.protocol.build` makes an :class:`RpamSettings` of the checked
tables of a protocol file; SI inside (m, m^2, MPa, rad, kg), except the angle bounds and
margins the paper prints in degrees.  Nothing here imports the model: the simulated stand
reads the same settings.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

from .actuator import Actuator
from .joint import JointGeometry

if TYPE_CHECKING:  # numpy-backed: only for the annotations
    from ...core.calibration import Calibration
    from ...core.channels import DeviceSpec


@dataclass(frozen=True)
class Bounds:
    """g2-g7 of Section IV, SI except the angle bounds (degrees, as printed)."""

    L1_m: tuple[float, float]
    L2_m: tuple[float, float]
    L3_m: tuple[float, float]
    actuator_length_m: tuple[float, float]
    alpha_deg: tuple[float, float]


@dataclass(frozen=True)
class OptimizeSettings:
    """Pressures of the optimisation, the holding constraints and the differential-evolution settings.

    ``min_stiffness_Nm_per_rad`` is None for a protocol that predates it (the optimiser asks
    for it); ``min_toggle_margin_deg`` and it must be positive to optimise.
    """

    Pa_MPa: float
    Pb_MPa: float
    seed: int
    popsize: int = 20
    maxiter: int = 300
    tol: float = 1e-6
    mutation: tuple[float, float] = (0.5, 1.0)
    recombination: float = 0.7
    active_tolerance: float = 0.005
    stretch_correction: bool = True
    min_toggle_margin_deg: float = 1.0
    min_stiffness_Nm_per_rad: float | None = 0.07
    paper_links_m: tuple[float, float, float] | None = None
    paper_alpha_deg: float | None = None

    @property
    def k_min(self) -> float:
        """The least joint stiffness a design must have (N m/rad); 0 when the protocol gives none."""
        return self.min_stiffness_Nm_per_rad or 0.0


@dataclass(frozen=True)
class StretchTestGrid:
    """The stretch test's grid (Fig. 5): payloads (kg) x pressures (MPa gauge), each ascending as written."""

    payloads_kg: tuple[float, ...]
    pressures_MPa: tuple[float, ...]


@dataclass(frozen=True)
class JointMapGrid:
    """The joint map's grid (Fig. 8): pressures Pa x Pb (MPa gauge)."""

    Pa_MPa: tuple[float, ...]
    Pb_MPa: tuple[float, ...]


@dataclass(frozen=True)
class Sensors:
    """The stand's DAQ (the ``[sensors]`` table): its device, the calibration of its channels
    (the core's channel map) and the settling limit of its length channel (m)."""

    device: DeviceSpec
    calibration: Calibration
    length_spread_m: float


@dataclass(frozen=True)
class RpamSettings:
    """An rPAM protocol, typed: the joint, the actuator, and what each command needs.

    ``bounds`` and ``optimize`` (``labcli optimize``), ``stretch_test`` and ``joint_map``
    (``labcli acquire --experiment``) and ``sensors`` (``labcli acquire``) are None where the
    protocol leaves their tables out; the command that needs one says so.
    """

    geometry: JointGeometry
    actuator: Actuator
    bounds: Bounds | None = None
    optimize: OptimizeSettings | None = None
    stretch_test: StretchTestGrid | None = None
    joint_map: JointMapGrid | None = None
    sensors: Sensors | None = None
