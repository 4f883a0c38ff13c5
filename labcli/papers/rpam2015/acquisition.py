"""How an rPAM run is acquired: the grid of the chosen experiment, point by point."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from ...core.paper import AcquireOptions, Session
from ...errors import ConfigError
from .session import rpam_session


@dataclass
class PointAcquisition:
    """The stretch test or the joint map of an rPAM protocol (from ``acquisition_protocol``)."""

    protocol: Any
    kind: str
    plan: Any = None

    def session(self, completed: Sequence[int]) -> Session:
        return rpam_session(self.protocol, completed=completed)

    def already_done(self, run: Any, path: str) -> str | None:
        points = self.protocol.settings.points
        if points and {p.point for p in points} <= set(run.records.ids()):
            return (
                f"All {len(points)} points of the {self.protocol.settings.title} are already stored "
                f"in {path}; nothing to resume."
            )
        return None


def acquisition(protocol: Any, options: AcquireOptions) -> PointAcquisition:
    """Plan a run of an rPAM protocol's chosen experiment."""
    if options.resume is None and (options.plan is not None or options.no_plan):
        raise ConfigError(
            "--plan and --no-plan apply to force protocols; an rPAM experiment runs the "
            "grid of its protocol's [experiments] table."
        )
    return PointAcquisition(protocol, protocol.kind)
