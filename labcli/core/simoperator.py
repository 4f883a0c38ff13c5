"""Who does at a simulated rig what the prompts ask: the engine is told, never guesses.

At a real rig the experimenter does what a prompt says (hang the weight, open the air) and
presses Enter.  Nobody stands at a simulated rig, so something must act for them: a
:class:`SimulatedOperator`, handed to the engine (:class:`labcli.core.engine.RunEngine`) by
whoever opened the rig.  With one, the engine has it do each prompt's action
(:class:`labcli.core.paper.RigAction`) once the prompt is answered, asks the questions only a
simulated rig needs (its objects' true stiffness) and lets ``--unattended`` run; without one
(a real port) a person is at the rig.

:func:`operator_for` gives the operator of a ``sim://`` rig (:attr:`labcli.core.device.Device.rig`);
a test may hand the engine any object with :meth:`SimulatedOperator.act`.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, NamedTuple, Protocol

from ..errors import ConfigError
from .paper import RigAction

if TYPE_CHECKING:
    from .device import RigLink


class SimulatedOperator(Protocol):
    """Acts at a simulated rig for the experimenter nobody needs to be."""

    def act(self, action: RigAction) -> None:
        """Do what a prompt asked; ConfigError with a sentence when the rig cannot."""


class RigOperator:
    """The simulated rig's own operator: each action acted out on ``rig`` (its ``act_on``)."""

    def __init__(self, rig: Any) -> None:
        self.rig = rig

    def act(self, action: RigAction) -> None:
        try:
            action.act_on(self.rig)
        except ValueError as e:
            raise ConfigError(f"The simulated rig cannot do {action}: {str(e).rstrip('.')}.") from None


class Connection(NamedTuple):
    """An open rig: its link (a :class:`labcli.core.device.Device`) and who acts at it when it is simulated."""

    device: RigLink
    operator: SimulatedOperator | None


def operator_for(device: RigLink) -> SimulatedOperator | None:
    """The operator of the simulated rig behind ``device`` (a ``sim://`` port); None at a real port."""
    rig = device.rig
    return None if rig is None else RigOperator(rig)


def connect(device: RigLink) -> Connection:
    """``device`` with the operator of its simulated rig (None at a real port)."""
    return Connection(device, operator_for(device))
