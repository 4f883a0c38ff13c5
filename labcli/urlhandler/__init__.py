"""pyserial URL handlers of the toolkit (``sim://``).

pyserial finds a handler for ``scheme://`` by importing
``<package>.protocol_<scheme>`` for each package in
``serial.protocol_handler_packages``; :func:`register` adds this one.
"""

from __future__ import annotations

PACKAGE = "labcli.urlhandler"


def register() -> None:
    """Make ``serial.serial_for_url`` understand ``sim://`` (idempotent)."""
    import serial

    if PACKAGE not in serial.protocol_handler_packages:
        serial.protocol_handler_packages.append(PACKAGE)
