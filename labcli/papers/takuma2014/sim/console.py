"""The McKibben rig's operator actions on the console of ``labcli sim --pty``
(:mod:`labcli.core.sim.console`).  Units are the ones people type: grams,
degrees, millimetres and MPa gauge.

=====================================  =============================================
``supply [P | P_L1 P_R1 P_L2 P_R2]``   open the valves at the regulator (MPa gauge;
                                       default: the rig's supply)
``hold`` (or ``close``)                close the valves (each chamber keeps its air)
``vent``                               open the valves to the atmosphere
``hang MASS_G DIR_DEG``                hang a weight over the pulley along DIR_DEG
``remove``                             take the weight off
``push OBJECT D_MM PHI_DEG``           push a demo object (pet-1, can-al-1, ...)
                                       D_MM into the tip along PHI_DEG
``release``                            withdraw the object
``state``                              the truth: angles, pressures, force, valves
=====================================  =============================================
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from ....core.sim.console import ConsoleCommand, ConsoleError, numbers
from .objects import DEMO_OBJECTS


def _fmt(values, digits: int) -> str:
    return ",".join(f"{v:.{digits}f}" for v in np.asarray(values, dtype=float))


def describe_state(st: dict[str, Any]) -> str:
    """The rig's truth on one line (deg, MPa gauge, N)."""
    load = st["load"]
    if load["kind"] == "weight":
        what = f"weight {load['mass_kg'] * 1e3:g} g at {math.degrees(load['direction_rad']):g} deg"
    elif load["kind"] == "push":
        what = f"push {load['distance_m'] * 1e3:g} mm at {math.degrees(load['phi_rad']):g} deg"
    else:
        what = "none"
    return (
        f"state t={st['time_s']:.3f} s valves={st['valves']} load={what}"
        f" theta_deg={_fmt(np.degrees(st['theta_rad']), 3)}"
        f" rest_deg={_fmt(np.degrees(st['rest_theta_rad']), 3)}"
        f" P_MPa={_fmt(st['pressures_MPa'], 4)} F_N={_fmt(st['force_N'], 3)}"
    )


def _supply(rig: Any, args: list[str]) -> str:
    usage = "supply [MPA | MPA MPA MPA MPA]"
    if len(args) not in (0, 1, 4):
        raise ConsoleError(f"usage: {usage}")
    p = numbers(args, ("pressure",) * len(args), usage)
    rig.supply_air(None if not p else (p[0] if len(p) == 1 else p))
    shown = rig.true_state()["supply_MPa"] if not p else np.broadcast_to(p, (4,))
    return f"ok supply {_fmt(shown, 3)} MPa (t={rig.time_s:.3f} s)"


def _plain(name: str, action: str):
    def act(rig: Any, args: list[str]) -> str:
        numbers(args, (), name)
        getattr(rig, action)()
        return f"ok {name} (t={rig.time_s:.3f} s)"

    return act


def _hang(rig: Any, args: list[str]) -> str:
    grams, deg = numbers(args, ("mass", "direction"), "hang GRAMS DEG")
    if grams < 0:
        raise ConsoleError(f"mass must be >= 0 g, got {grams:g}")
    rig.hang_weight(grams / 1e3, math.radians(deg))
    return f"ok hang {grams:g} g at {deg:g} deg (t={rig.time_s:.3f} s)"


def _push(rig: Any, args: list[str]) -> str:
    if len(args) != 3:
        raise ConsoleError("usage: push OBJECT MM DEG")
    names = {o.name: o for o in DEMO_OBJECTS}
    if args[0] not in names:
        raise ConsoleError(f"unknown object '{args[0]}'; known: {', '.join(names)}")
    obj = names[args[0]]
    mm, deg = numbers(args[1:], ("distance", "direction"), "push OBJECT MM DEG")
    rig.push_object(obj.radius_m, mm / 1e3, math.radians(deg), obj.stiffness_N_per_m)
    return f"ok push {obj.name} {mm:g} mm at {deg:g} deg (t={rig.time_s:.3f} s)"


def _state(rig: Any, args: list[str]) -> str:
    numbers(args, (), "state")
    return describe_state(rig.true_state())


COMMANDS = {
    "supply": ConsoleCommand("supply [MPA | MPA MPA MPA MPA]", _supply),
    "hold": ConsoleCommand("hold", _plain("hold", "close_valves")),
    "close": ConsoleCommand("close", _plain("close", "close_valves")),
    "vent": ConsoleCommand("vent", _plain("vent", "vent")),
    "hang": ConsoleCommand("hang GRAMS DEG", _hang),
    "remove": ConsoleCommand("remove", _plain("remove", "remove_weight")),
    "push": ConsoleCommand("push OBJECT MM DEG (" + ", ".join(o.name for o in DEMO_OBJECTS) + ")", _push),
    "release": ConsoleCommand("release", _plain("release", "release_object")),
    "state": ConsoleCommand("state", _state),
}
