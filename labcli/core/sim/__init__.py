"""The simulated rig: a physical model behind the rig wire protocol.

``MODELS`` maps the ``mode`` option of a ``sim://`` URL to a factory
``f(seed, noise, drift, tau_s) -> rig``.  A rig is any object with
``channels``, ``device``, ``firmware``, ``samples(n, rate_hz)``, ``advance``,
``advance_to`` and ``time_s`` (see :mod:`labcli.experiments.takuma2014.sim.rig`); the firmware and the
URL handler need nothing else, so other rig models plug in here.

This package is also the toolkit's pyserial URL-handler package: pyserial finds a
handler for ``scheme://`` by importing ``<package>.protocol_<scheme>`` for each
package in ``serial.protocol_handler_packages``, and :func:`register` adds this one
(:mod:`labcli.core.sim.protocol_sim` serves ``sim://``).
"""

from __future__ import annotations

from typing import Callable

PACKAGE = "labcli.core.sim"


def register() -> None:
    """Make ``serial.serial_for_url`` understand ``sim://`` (idempotent)."""
    import serial

    if PACKAGE not in serial.protocol_handler_packages:
        serial.protocol_handler_packages.append(PACKAGE)


def _mckibben(seed: int, noise: float, drift: float, tau_s: float):
    from ...experiments.takuma2014.sim.rig import SimRig

    return SimRig(seed=seed, noise=noise, drift=drift, tau_s=tau_s)


def _rpam(seed: int, noise: float, drift: float, tau_s: float):
    from ...experiments.rpam2015.sim.rig import RpamRig

    return RpamRig(seed=seed, noise=noise, drift=drift, tau_s=tau_s)


MODELS: dict[str, Callable] = {"mckibben": _mckibben, "rpam": _rpam}


def make_rig(mode: str = "mckibben", *, seed: int = 0, noise: float = 1.0, drift: float = 0.0, tau_s: float = 0.7):
    """Build the simulated rig named ``mode`` (a key of ``MODELS``)."""
    try:
        factory = MODELS[mode]
    except KeyError:
        raise ValueError(f"unknown simulated rig mode {mode!r}; known: {', '.join(MODELS)}") from None
    return factory(seed, noise, drift, tau_s)
