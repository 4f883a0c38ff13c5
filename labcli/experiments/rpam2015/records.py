"""The rPAM runs' records: one point of the stretch test or of the joint map."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class PointRecords:
    """Points of an rPAM run; ``experiment`` is the run's ("stretch" or "joint")."""

    kind: str
    experiment: str
    title: str
    collection: str = "points"
    id_column: str = "point"
    noun: str = "point"
    plural: str = "points"
    splits: bool = False

    @property
    def qualifier(self) -> str:
        return f" of the {self.title}"


RECORD_TYPES = {
    "rpam-stretch": PointRecords("rpam-stretch", "stretch", "stretch test"),
    "rpam-joint": PointRecords("rpam-joint", "joint", "joint map"),
}
