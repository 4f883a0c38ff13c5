"""The simulated rig's plumbing: a rig model behind the rig wire protocol.

A simulated rig is any object with ``channels``, ``device``, ``firmware``,
``samples(n, rate_hz)``, ``advance``, ``advance_to`` and ``time_s`` (the McKibben rig of
:mod:`labcli.papers.takuma2014.sim.rig` is one); the firmware (:mod:`.firmware`),
the fault injector (:mod:`.faults`), the pty server (:mod:`.pty`) and the ``sim://`` URL
handler (:mod:`.protocol_sim`, its grammar in :mod:`.url`) need nothing else.  The compiled
firmware on simavr (:mod:`.hil`; as ``sim://?firmware=ELF`` :mod:`.hil_port`, on a pty
:mod:`.hil_pty`) needs a rig with the firmware's six channels.  The rigs themselves belong to the
papers: ``mode=NAME`` picks one through the registry (:func:`make_rig`).

This package is also the toolkit's pyserial URL-handler package: pyserial finds a
handler for ``scheme://`` by importing ``<package>.protocol_<scheme>`` for each
package in ``serial.protocol_handler_packages``, and :func:`register` adds this one.
"""

from __future__ import annotations

from typing import Any

from .. import registry
from ..options import Typed, bind

PACKAGE = "labcli.core.sim"


def register() -> None:
    """Make ``serial.serial_for_url`` understand ``sim://`` (idempotent)."""
    import serial

    if PACKAGE not in serial.protocol_handler_packages:
        serial.protocol_handler_packages.append(PACKAGE)


def modes() -> list[str]:
    """The ``mode=`` values of the installed papers' rigs, in name order."""
    return registry.sim_modes()


def default_mode() -> str:
    """The rig ``sim://`` gives without ``mode=``."""
    return registry.default_sim_mode()


def make_rig(
    mode: str | None = None,
    *,
    seed: int = 0,
    noise: float = 1.0,
    drift: float | None = None,
    tau_s: float = 0.7,
    **options: Any,
) -> Any:
    """Build the simulated rig named ``mode`` (None: the default rig); ``options`` are the rig's
    own (declared by its paper's ``sim_options``; parsed values); ``drift`` None is the rig's own
    default.  ValueError for an unknown mode or an option the rig does not declare."""
    return registry.make_rig(
        mode or registry.default_sim_mode(), seed=seed, noise=noise, drift=drift, tau_s=tau_s, **options
    )


def rig_values(mode: str | None, typed: Typed) -> tuple[str, dict[str, Any]]:
    """The rig ``mode`` names (None: the default) and the options typed for it (name -> value).

    An option its rig does not declare is refused in one sentence (a ConfigError):
    "--friction is an option of the mckibben rig; --mode rpam serves the rpam rig."
    """
    mode = mode or registry.default_sim_mode()
    owner = registry.sim_owner(mode)

    def owners(name: str) -> list[str]:
        return [f"the {m} rig" for m in registry.modes_taking(name)]

    bind(owner.sim_options, typed, owners=owners, subject=f"--mode {mode} serves the {mode} rig")
    return mode, dict(typed.values)
