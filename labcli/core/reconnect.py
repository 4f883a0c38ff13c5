"""A lost rig, attended: ask for it until it is back, or until the experimenter stops.

When the rig stops sending (unplugged, powered off, a board that restarted), an attended
session does not end: the engine (:mod:`labcli.core.engine`) says what was lost, closes the
port, and asks the experimenter to reconnect the rig; Enter opens the same port again.  A
rig that still does not answer is said so and asked for again; a quit stops waiting, and the
run ends with the command that resumes it.
"""

from __future__ import annotations

import contextlib
from collections.abc import Callable
from typing import Any

from ..errors import DeviceError
from .simoperator import Connection
from .steps import Prompt
from .ui import QuitRequested


def wait_for_rig(
    ui: Any, device: Any, port: str, what: str, during: str, reopen: Callable[[], Connection]
) -> Connection | None:
    """Ask for the lost rig until it opens again (its connection) or the experimenter stops (None).

    ``what``: what the rig did ("stopped sending data"); ``during``: when, and what happens
    once it is back ("during trial 3, which was not stored; it will be redone ...").
    """
    ui.warn(f"The rig on {port} {what} {during}.")
    with contextlib.suppress(Exception):
        device.close()
    while True:
        try:
            ui.prompt(Prompt(f"Rig lost on {port}; reconnect it and press Enter to retry"))
        except QuitRequested:
            return None
        try:
            return reopen()
        except DeviceError as err:
            ui.warn(str(err))
