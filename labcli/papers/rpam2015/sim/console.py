"""The rPAM rig's operator actions on the console of ``labcli sim --pty --mode rpam``
(:mod:`labcli.core.sim.console`).  Units are the ones the rPAM paper and the acquisition's
prompts use: kPa gauge, grams, degrees, millimetres.

=====================================  =============================================
``pressures KPA_A KPA_B``              set the two regulators (kPa gauge); the
                                       pressures and the joint follow with the lag
``vent``                               vent both actuators (0 kPa)
``mount joint|stretch``                re-rig the stand: both actuators on the joint,
                                       or actuator a hanging on the stretch stand
                                       (vented, without payload)
``hang GRAMS``                         hang a payload from actuator a (stretch stand)
``remove``                             take the payload off
``state``                              the truth: angle, pressures, length, stretch
=====================================  =============================================

The joint's angle is not set directly: it settles where the two actuators' torques balance
(Eq. 6), so ``pressures`` is how the operator moves it, as at the real joint.
"""

from __future__ import annotations

import math
from typing import Any

from ....core.sim.console import ConsoleCommand, ConsoleError, numbers
from .options import EXPERIMENTS


def describe_state(st: dict[str, Any]) -> str:
    """The rig's truth on one line (kPa gauge, deg, mm, g)."""
    pa, pb = (float(v) * 1e3 for v in st["pressures_MPa"])
    return (
        f"state t={st['time_s']:.3f} s experiment={st['experiment']} status={st['status']}"
        f" P_kPa={pa:.2f},{pb:.2f} alpha_deg={math.degrees(st['alpha_rad']):.3f}"
        f" L_mm={st['length_m'] * 1e3:.3f} lambda={st['lambda']:.4f} payload_g={st['payload_kg'] * 1e3:g}"
    )


def _pressures(rig: Any, args: list[str]) -> str:
    pa, pb = numbers(args, ("P_A", "P_B"), "pressures KPA_A KPA_B")
    rig.set_pressures(pa / 1e3, pb / 1e3)
    return f"ok pressures {pa:g},{pb:g} kPa (t={rig.time_s:.3f} s)"


def _vent(rig: Any, args: list[str]) -> str:
    numbers(args, (), "vent")
    rig.vent()
    return f"ok vent (t={rig.time_s:.3f} s)"


def _mount(rig: Any, args: list[str]) -> str:
    usage = "mount " + "|".join(EXPERIMENTS)
    if len(args) != 1:
        raise ConsoleError(f"usage: {usage}")
    if args[0] not in EXPERIMENTS:
        raise ConsoleError(f"unknown configuration '{args[0]}'; usage: {usage}")
    rig.set_experiment(args[0])
    return f"ok mount {args[0]} (t={rig.time_s:.3f} s)"


def _hang(rig: Any, args: list[str]) -> str:
    (grams,) = numbers(args, ("mass",), "hang GRAMS")
    if grams < 0:
        raise ConsoleError(f"mass must be >= 0 g, got {grams:g}")
    if rig.experiment != "stretch":
        raise ConsoleError("payloads hang from the stretch stand; type 'mount stretch' first")
    rig.hang_payload(grams / 1e3)
    return f"ok hang {grams:g} g (t={rig.time_s:.3f} s)"


def _remove(rig: Any, args: list[str]) -> str:
    numbers(args, (), "remove")
    rig.remove_payload()
    return f"ok remove (t={rig.time_s:.3f} s)"


def _state(rig: Any, args: list[str]) -> str:
    numbers(args, (), "state")
    return describe_state(rig.true_state())


COMMANDS = {
    "pressures": ConsoleCommand("pressures KPA_A KPA_B", _pressures),
    "vent": ConsoleCommand("vent", _vent),
    "mount": ConsoleCommand("mount " + "|".join(EXPERIMENTS), _mount),
    "hang": ConsoleCommand("hang GRAMS", _hang),
    "remove": ConsoleCommand("remove", _remove),
    "state": ConsoleCommand("state", _state),
}
