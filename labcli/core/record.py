"""The record a session commits and a run file gives back: typed, whatever the paper.

A record is the paper's values (a trial's pressures and force, a push's object, an rPAM
point's stretch: its record type's business, :class:`labcli.core.paper.RecordType`) plus
what every record carries, typed here:

============  ==================================================================
``started``   when the record began (ISO 8601); the engine sets it
``ended``     when it was stored (ISO 8601); the run file sets it to now
``accepted``  how it was accepted: ``auto``, ``timeout``, ``operator``, ``imported``
``flags``     what was noticed about it, one sentence each
``settle``    how each window reached equilibrium (:class:`Settle`), by window
``raw``       its windows of frames (:class:`~labcli.core.window.Window`), by window
``extra``     an imported table's columns labcli does not know
``order``     where it was recorded (read back only)
============  ==================================================================

Windows are named ``baseline`` and ``load``.  A paper types its own records by deriving
from :class:`Record` (``class TrialRecord(Record): trial: int; P_MPa: np.ndarray; ...``),
so the session that builds one and the run file that takes it agree on every key.
"""

from __future__ import annotations

from typing import Any, Literal, TypedDict

from .window import Window

WindowName = Literal["baseline", "load"]
ACCEPTED = ("auto", "timeout", "operator", "imported")


class Settle(TypedDict, total=False):
    """How a window's equilibrium was reached (:meth:`labcli.core.steps.SettleReport.as_dict`)."""

    settled: bool  # False: timed out and accepted
    settle_time_s: float  # device time from the start of the wait to equilibrium
    waited_s: float  # device time spent waiting in all
    pressure_spread_MPa: float
    angle_spread_rad: float
    criterion: str
    accepted: str  # overrides the auto/timeout reading of ``settled`` (e.g. "operator")


class Record(TypedDict, total=False):
    """What every record may carry beside its paper's values (see the module docstring)."""

    started: str
    ended: str
    accepted: str
    flags: list[str]
    settle: dict[str, Settle]
    raw: dict[str, Window]
    extra: dict[str, Any]


class StoredRecord(Record, total=False):
    """A record as a run file gives it back (``run.records.read``): every key of :class:`Record`
    present, and ``order``; the paper's values beside them."""

    order: int
