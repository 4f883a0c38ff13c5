"""The McKibben rig's own ``sim://`` options, and the rig they build.

Each non-ideality (:mod:`.nonideal`) has a scale (1 = its level, 0 = off);
``realism`` picks the levels and default scales (``literature`` or ``kind``, the rig as it was
before the literature's levels, byte for byte); ``ideal=1`` turns every effect off, and a scale
given beside it still applies (``ideal=1&leak=1`` is the ideal rig with a leak).  ``supply`` is the regulator
pressure, MPa gauge, one value or four (L1, R1, L2, R2); ``design`` the actuators
(``paper``, the paper-scale default, or ``thin``, the earlier soft tuning;
``design=thin&ideal=1`` reproduces its frames exactly); ``valves=open`` leaves the valves open to
the regulator whatever closes them (an operator who forgot, a valve stuck open).
``script`` is a file of loads and pushes
the rig acts out on its own clock, the truth kept beside the stream (:mod:`.script`).

This module imports nothing heavy: the experiment's declaration reads :data:`SIM_OPTIONS`.
"""

from __future__ import annotations

import math
from typing import Any

from ....core.paper import SimOption

SCALES = ("friction", "leak", "thermal", "backlash", "links", "contact", "pulley", "potscale", "potlin", "repeat")
REALISM_NAMES = ("literature", "kind")  # nonideal.REALISMS (a test holds them equal)
DESIGN_NAMES = ("paper", "thin")  # the keys of physics.DESIGNS (a test holds them equal)
SUPPLY_FORM = "one or four pressures in MPa within 0..1, comma-separated"


def parse_flag(text: str) -> bool:
    if text not in ("0", "1"):
        raise ValueError
    return text == "1"


def parse_scale(text: str) -> float:
    v = float(text)
    if not (math.isfinite(v) and v >= 0):
        raise ValueError
    return v


def parse_supply(text: str) -> tuple[float, ...]:
    """``"0.3"`` or ``"0.3,0.3,0.4,0.2"`` (MPa gauge) as four pressures; ValueError otherwise."""
    values = tuple(float(v) for v in text.split(","))
    if len(values) not in (1, 4) or not all(math.isfinite(v) and 0 <= v <= 1 for v in values):
        raise ValueError
    return values if len(values) == 4 else values * 4


def parse_realism(text: str) -> str:
    if text not in REALISM_NAMES:
        raise ValueError
    return text


def parse_valves(text: str) -> bool:
    """``open``: the valves stay open to the regulator whatever closes them (True); ``ok``: False."""
    if text not in ("ok", "open"):
        raise ValueError
    return text == "open"


def parse_design(text: str) -> str:
    if text not in DESIGN_NAMES:
        raise ValueError
    return text


def parse_script(text: str) -> Any:
    """A sim script file's path, read and checked (:mod:`.script`; ValueError when it cannot be)."""
    from .script import load_script

    return load_script(text)


SIM_OPTIONS = {
    "ideal": SimOption(parse_flag, "0|1", "0 or 1"),
    **{name: SimOption(parse_scale, "X", "a number >= 0") for name in SCALES},
    "supply": SimOption(parse_supply, "MPA[,MPA,MPA,MPA]", SUPPLY_FORM),
    "design": SimOption(parse_design, "|".join(DESIGN_NAMES), "one of " + ", ".join(DESIGN_NAMES)),
    "realism": SimOption(parse_realism, "|".join(REALISM_NAMES), "one of " + ", ".join(REALISM_NAMES)),
    "valves": SimOption(parse_valves, "ok|open", "ok or open"),
    "script": SimOption(
        parse_script, "FILE", "a sim script file that reads and checks (see the sensing page of the docs)"
    ),
}


def build_rig(
    *,
    seed: int = 0,
    noise: float = 1.0,
    drift: float | None = None,
    tau_s: float = 0.7,
    ideal: bool = False,
    supply: Any = None,
    design: str | None = None,
    realism: str | None = None,
    valves: bool = False,
    script: Any = None,
    **scales: float,
) -> Any:
    """The McKibben rig with these options (parsed values of :data:`SIM_OPTIONS`; None: the default).

    ``drift`` None takes the realism's default (``ideal`` turns it off with the rest)."""
    from dataclasses import replace

    from .nonideal import NonIdeal
    from .rig import SimRig

    unknown = set(scales) - set(SCALES)
    if unknown:
        raise ValueError(f"the McKibben rig has no option {sorted(unknown)[0]!r}")
    from .nonideal import REALISM_DEFAULT

    level = realism or REALISM_DEFAULT
    base = NonIdeal.ideal(level) if ideal else NonIdeal(realism=level)
    extra = {} if supply is None else {"supply_MPa": supply}
    given: dict[str, Any] = {k: v for k, v in scales.items() if v is not None}
    nonideal = replace(base, **given)
    rig = SimRig(
        seed=seed,
        noise=noise,
        drift=drift,
        tau_s=tau_s,
        nonideal=nonideal,
        design=design or "paper",
        valves_open=bool(valves),
        **extra,
    )
    if script is None:
        return rig
    from .scripted import ScriptedRig

    return ScriptedRig(rig, script)
