"""The McKibben rig's records: a force/angle trial (Section 3.2) and an object push (Section 4)."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class TrialRecords:
    """Force/angle trials of a ``force`` run: loaded pressures, deflections, the pulley load."""

    kind: str = "force"
    collection: str = "trials"
    id_column: str = "trial"
    noun: str = "trial"
    plural: str = "trials"
    qualifier: str = ""
    splits: bool = True


@dataclass(frozen=True)
class PushRecords:
    """Object pushes of a ``push`` run: pressures before and with the object pushed in."""

    kind: str = "push"
    collection: str = "pushes"
    id_column: str = "push"
    noun: str = "push"
    plural: str = "pushes"
    qualifier: str = ""
    splits: bool = False


RECORD_TYPES = {"force": TrialRecords(), "push": PushRecords()}
