"""Errors that carry one sentence for the person at the rig.

Every error raised on purpose by the library derives from :class:`LabcliError`;
the command line turns it into a one-line message and a non-zero exit, never a
traceback.  The message names what was wrong, where, and what to check.
"""

from __future__ import annotations


class LabcliError(Exception):
    """Base class: ``str(err)`` is a complete sentence for the user."""


class ConfigError(LabcliError):
    """A protocol file, plan, table or option is invalid (names file/row/key)."""


class DeviceError(LabcliError):
    """The rig could not be opened or did not behave as the wire protocol says."""

    reconnects = True  # an attended session may wait for the rig to come back (False: it never left)


class DeviceNotFound(DeviceError):
    """The serial port does not exist or cannot be opened."""


class DeviceTimeout(DeviceError):
    """The device did not answer, or stopped sending data, within the timeout.

    ``what`` says what the rig did, for a sentence of the form "the rig on PORT {what}
    during trial 3" ("stopped sending data", "sends no valid frames (...)").
    """

    def __init__(self, message: str = "", what: str = "stopped sending data") -> None:
        super().__init__(message)
        self.what = what


class DeviceRailed(DeviceTimeout):
    """A capture window's counts sat at an end of the ADC's range on some channel: a sensor at its
    rail, or a link sending counts no ADC gives.  No trial is stored from it, and waiting for the
    rig to come back does not help (it never left)."""

    reconnects = False


class DeviceUnsupported(DeviceError):
    """The board lacks what a command needs (a wire-protocol 1.0 board asked to move its valves)."""


class DeviceDisconnected(DeviceError):
    """The device vanished mid-stream (unplugged, port closed)."""

    what = "was disconnected"


class DeviceClockError(DeviceError):
    """The device's clock (``t_us``) ran backwards, or stood almost still, while it streamed;
    ``what`` as for :class:`DeviceTimeout`."""

    def __init__(self, message: str = "", what: str = "sent timestamps that do not increase") -> None:
        super().__init__(message)
        self.what = what


class StoreError(LabcliError):
    """A run file is missing, of another schema, damaged, or would be overwritten."""


class DiskFull(StoreError):
    """The disk (or the file size limit, ``ulimit -f``) has no room for a write; nothing was changed."""


class OutOfMemory(LabcliError):
    """Memory ran out mid-session (a MemoryError): what was committed is whole, the sentence says how to resume."""


class ModelError(LabcliError):
    """A model cannot be fitted or applied (too few trials, wrong protocol, ...)."""


class LabcliWarning(UserWarning):
    """A sentence for the user that does not stop the command (a damaged record left out, ...).

    The command line prints it as ``Warning: ...`` on stderr; a library user gets it through
    :mod:`warnings` (``warnings.simplefilter("error", LabcliWarning)`` makes it an error).
    """
