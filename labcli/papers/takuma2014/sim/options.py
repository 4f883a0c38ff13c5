"""The McKibben rig's own options, declared as data (``sim://?leak=2``, ``labcli sim --leak 2``), and the
rig they build.

Each non-ideality (:mod:`.nonideal`) has a scale (1 = its level, 0 = off);
``realism`` picks the levels and default scales (``literature``, the default, or ``kind``, the rig as it was
before the literature's levels, byte for byte with ``flow=lag``); ``ideal`` turns every effect off, and a scale
given beside it still applies (``ideal=1&leak=1`` is the ideal rig with a leak).  ``supply`` is the regulator
pressure, MPa gauge, one value or four (L1, R1, L2, R2); ``design`` the actuators
(``paper``, the paper-scale default, or ``thin``, the earlier soft tuning); ``valves=open`` leaves the valves open to
the regulator whatever closes them (an operator who forgot, a valve stuck open); ``valve_c`` and
``valve_b`` the valves' orifice (ISO 6358 sonic conductance in dm^3/(s bar) and critical pressure
ratio, :mod:`labcli.core.sim.orifice`), which set how long a supply or a vent takes; ``flow=lag``
the earlier rig's first-order lag instead of the orifice (``design=thin&ideal=1&flow=lag`` and
``realism=kind&flow=lag`` reproduce the runs recorded before the orifice frame for frame).  ``script`` is a
file of loads and pushes the rig acts out on its own clock, the truth kept beside the stream
(:mod:`.script`).  An option left out (None) is the rig's own default.

This module imports nothing heavy: the paper's declaration reads :class:`McKibbenRigOptions`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields
from typing import TYPE_CHECKING, Any

from ....core.options import choice, number, switch, text

if TYPE_CHECKING:
    from .rig import SimRig
    from .scripted import ScriptedRig

SCALES = ("friction", "leak", "thermal", "backlash", "links", "contact", "pulley", "potscale", "potlin", "repeat")
REALISM_NAMES = ("literature", "kind")  # nonideal.REALISMS (a test holds them equal)
DESIGN_NAMES = ("paper", "thin")  # the keys of physics.DESIGNS (a test holds them equal)
SUPPLY_FORM = "one or four pressures in MPa within 0..1, comma-separated"


def parse_supply(text: str) -> tuple[float, ...]:
    """``"0.3"`` or ``"0.3,0.3,0.4,0.2"`` (MPa gauge) as four pressures; ValueError otherwise."""
    values = tuple(float(v) for v in text.split(","))
    if len(values) not in (1, 4) or not all(math.isfinite(v) and 0 <= v <= 1 for v in values):
        raise ValueError
    return values if len(values) == 4 else values * 4


def parse_script(text: str) -> Any:
    """A sim script file's path, read and checked (:mod:`.script`; ValueError when it cannot be)."""
    from .script import load_script

    return load_script(text)


def _scale(what: str) -> Any:
    return number(help=what, minimum=0)


@dataclass(frozen=True)
class McKibbenRigOptions:
    """The McKibben rig's own options (``sim://?mode=mckibben``, the default rig)."""

    ideal: bool = switch(help="Turn every non-ideality off (friction, leak, heat, play, link weight, sensor errors).")
    friction: float | None = _scale("Scale of sleeve friction and hysteresis (1 = typical, 0 = off).")
    leak: float | None = _scale("Scale of the closed chambers' leak (1 = about 1 kPa/min).")
    thermal: float | None = _scale("Scale of the air's heating by a fast load (1 = adiabatic, relaxing over 3 s).")
    backlash: float | None = _scale("Scale of the potentiometers' backlash (1 = 0.2 deg).")
    links: float | None = _scale("Scale of the links' own weight (1 = 80 g and 30 g).")
    contact: float | None = _scale(
        "Scale of the friction where the tip presses a pushed object (1 = a coefficient of 0.3)."
    )
    pulley: float | None = _scale("Scale of the weight pulley's friction (1 = 2 % of the pull).")
    potscale: float | None = _scale("Scale of the potentiometers' gain error (1 = 1 % rms).")
    potlin: float | None = _scale("Scale of the potentiometers' non-linearity (1 = 0.5 % of the span at most).")
    repeat: float | None = _scale(
        "Scale of the pressure sensors' non-repeatability (1 = 0.2 % of full scale as three sd)."
    )
    supply: tuple[float, ...] | None = text(
        help="Regulator pressure, gauge: one value or four (L1,R1,L2,R2).",
        parse=parse_supply,
        what=SUPPLY_FORM,
        form="MPA[,MPA,MPA,MPA]",
        units="MPa",
        default_text="0.3",
    )
    design: str | None = choice(
        DESIGN_NAMES, help="Actuators: paper-scale, or the earlier thin-muscle tuning.", default_text="paper"
    )
    realism: str | None = choice(
        REALISM_NAMES,
        help="Levels of the non-idealities: the literature's (the default), or kind, the kinder rig of earlier runs.",
        default_text="literature",
    )
    valves: str | None = choice(
        ("ok", "open"),
        help="open: the valves stay open to the regulator whatever closes them (a valve stuck open).",
        default_text="ok",
    )
    valve_c: float | None = number(
        help="Sonic conductance of each chamber's valve with its tubing (ISO 6358), for supply and vent.",
        units="dm3/(s bar)",
        minimum=0,
        above=True,
        maximum=10,
        default_text="0.1",
    )
    valve_b: float | None = number(
        help="Critical pressure ratio of each chamber's valve (ISO 6358): the flow is choked below it.",
        minimum=0,
        above=True,
        maximum=0.95,
        default_text="0.3",
    )
    flow: str | None = choice(
        ("orifice", "lag"),
        help="lag: open chambers follow the regulator with the arm's first-order lag, as the rig did "
        "before its valves had orifices (reproduces runs recorded then).",
        default_text="orifice",
    )
    script: Any = text(
        help="A file of loads and pushes the rig acts out on its own clock, the truth kept beside the stream.",
        parse=parse_script,
        what="a sim script file that reads and checks (see the sensing page of the docs)",
        form="FILE",
    )


def build_rig(
    *, seed: int = 0, noise: float = 1.0, drift: float | None = None, tau_s: float = 0.7, options: McKibbenRigOptions
) -> SimRig | ScriptedRig:
    """The McKibben rig with these options (None: the rig's default).

    ``drift`` None takes the realism's default (``ideal`` turns it off with the rest)."""
    from dataclasses import replace

    from . import physics
    from .nonideal import REALISM_DEFAULT, NonIdeal
    from .rig import SimRig

    level = options.realism or REALISM_DEFAULT
    base = NonIdeal.ideal(level) if options.ideal else NonIdeal(realism=level)
    scales = {f.name: getattr(options, f.name) for f in fields(options) if f.name in SCALES}
    nonideal = replace(base, **{k: v for k, v in scales.items() if v is not None})
    supply = physics.SUPPLY_MPA if options.supply is None else options.supply
    design = options.design or "paper"
    valve = None
    if options.valve_c is not None or options.valve_b is not None:
        from ....core.sim.orifice import DM3_PER_S_BAR, Orifice
        from .rig import VALVE_B, VALVE_C_DM3_PER_S_BAR

        c = VALVE_C_DM3_PER_S_BAR if options.valve_c is None else options.valve_c
        valve = Orifice(c * DM3_PER_S_BAR, VALVE_B if options.valve_b is None else options.valve_b)
    rig = SimRig(
        seed=seed,
        noise=noise,
        drift=drift,
        tau_s=tau_s,
        supply_MPa=supply,
        nonideal=nonideal,
        design=design,
        valves_open=options.valves == "open",
        valve=valve,
        flow=options.flow or "orifice",
    )
    if options.script is None:
        return rig
    from .scripted import ScriptedRig

    return ScriptedRig(rig, options.script)
