"""A scripted session on the simulated McKibben rig: loads and pushes at known times.

``sim://?script=FILE`` (or :class:`ScriptedRig` in a program) acts out a small TOML file on
the rig's own clock (device time, seconds from power-up) and keeps the ground truth beside
the stream: every frame's true joint deflection and tip force, and one row per load.

::

    # The air: the regulators open at supply_s, the valves close at close_s.
    [air]
    supply_s = 0.0
    close_s = 6.0

    # A pulley weight: hung at at_s, taken off hold_s later.
    [[load]]
    at_s = 20.0
    hold_s = 15.0
    mass_g = 300.0
    direction_deg = 45.0        # counter-clockwise from +x, as a plan's

    # Section 4's cylinder, pushed distance_mm along phi_deg and withdrawn hold_s later.
    [[push]]
    at_s = 60.0
    hold_s = 10.0
    object = "can-al-1"         # optional: a name for the reports
    radius_mm = 33.0
    distance_mm = 15.0
    phi_deg = 0.0
    stiffness_N_per_m = 2000.0

    # A stretch left alone on purpose (checked: no load or push may fall in it).
    [[idle]]
    from_s = 100.0
    to_s = 700.0

A load may begin while another hangs when it pulls the same way: a second weight put on the
same hanger (the rig then holds their sum, and each comes off at its own time, the last put on
first or not).  Pushes overlap nothing, and nothing starts before the valves close.  The truth
(:meth:`ScriptedRig.truth`): per frame the device time, the true deflection from the rest
posture the arm last rested at (rad) and the force on the tip (N); per load the times it
came on and off, its force (a weight stacked on another: the hanger's) and the deflection it settles to.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ....core.protocol import tomllib

KEYS = {
    "load": {"at_s", "hold_s", "mass_g", "direction_deg"},
    "push": {"at_s", "hold_s", "object", "radius_mm", "distance_mm", "phi_deg", "stiffness_N_per_m"},
    "idle": {"from_s", "to_s"},
    "air": {"supply_s", "close_s"},
}
LIMITS = {  # key: (lowest, highest), SI-free as typed
    "at_s": (0.0, 1e7),
    "hold_s": (0.0, 1e6),
    "mass_g": (0.0, 2000.0),
    "direction_deg": (-360.0, 360.0),
    "radius_mm": (1.0, 500.0),
    "distance_mm": (0.0, 100.0),
    "phi_deg": (-180.0, 180.0),
    "stiffness_N_per_m": (1.0, 1e7),
    "from_s": (0.0, 1e7),
    "to_s": (0.0, 1e7),
    "supply_s": (0.0, 1e7),
    "close_s": (0.0, 1e7),
}


class ScriptError(ValueError):
    """A sim script that cannot be acted out; ``str()`` is one sentence naming the file and entry."""


@dataclass(frozen=True)
class Change:
    """One scripted load or push: what, when it comes on and off, and its numbers (SI)."""

    kind: str  # "load" | "push"
    on_s: float
    off_s: float
    mass_kg: float = math.nan
    direction_rad: float = math.nan
    radius_m: float = math.nan
    distance_m: float = math.nan
    phi_rad: float = math.nan
    stiffness_N_per_m: float = math.nan
    name: str = ""


@dataclass(frozen=True)
class Script:
    """A checked script: the air times, the changes in time order, the idle stretches."""

    supply_s: float
    close_s: float
    changes: tuple[Change, ...]
    idle: tuple[tuple[float, float], ...]
    source: str = ""

    @property
    def end_s(self) -> float:
        """The last scripted time (a change's end or an idle stretch's)."""
        return max([self.close_s] + [c.off_s for c in self.changes] + [b for _, b in self.idle])


def load_script(path: str | Path) -> Script:
    """Read and check a script file (ScriptError with one sentence)."""
    from ....core.files import read_input

    p = Path(path)
    try:
        text = read_input(p, "a sim script", label=f"The sim script {p}", error=ScriptError).decode("utf-8")
    except (OSError, UnicodeDecodeError) as e:
        raise ScriptError(f"The sim script {p} cannot be read ({getattr(e, 'strerror', None) or e}).") from None
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as e:
        raise ScriptError(f"The sim script {p} is not valid TOML ({e}).") from None
    return parse_script(data, str(p))


def _number(value: Any, key: str, where: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise ScriptError(f"{where}: {key} must be a number, got {value!r}.")
    lo, hi = LIMITS[key]
    if not lo <= value <= hi:
        raise ScriptError(f"{where}: {key} must be within {lo:g}..{hi:g}, got {value:g}.")
    return float(value)


def _entry(kind: str, item: Any, i: int, source: str) -> dict[str, Any]:
    where = f"The sim script {source}, {kind} {i}" if i else f"The sim script {source}, [{kind}]"
    if not isinstance(item, Mapping):
        raise ScriptError(f"{where} must be a table of keys.")
    unknown = sorted(set(item) - KEYS[kind])
    if unknown:
        raise ScriptError(f"{where}: unknown key {unknown[0]!r}; a {kind} takes {', '.join(sorted(KEYS[kind]))}.")
    needed = KEYS[kind] - {"object"} - ({"supply_s", "close_s"} if kind == "air" else set())
    missing = sorted(needed - set(item))
    if missing:
        raise ScriptError(f"{where} lacks {missing[0]}.")
    out: dict[str, Any] = {k: _number(v, k, where) for k, v in item.items() if k != "object"}
    if "object" in item:
        if not isinstance(item["object"], str):
            raise ScriptError(f"{where}: object must be a name in quotes.")
        out["object"] = item["object"]
    return out


def parse_script(data: Mapping[str, Any], source: str = "script") -> Script:
    """A script from its parsed TOML (ScriptError naming ``source`` and the entry)."""
    unknown = sorted(set(data) - set(KEYS))
    if unknown:
        raise ScriptError(
            f"The sim script {source} has an unknown table {unknown[0]!r}; it takes air, load, push, idle."
        )
    air = _entry("air", data.get("air", {}), 0, source)
    supply = air.get("supply_s", 0.0)
    close = air.get("close_s", supply + 6.0)
    if close < supply:
        raise ScriptError(f"The sim script {source}: the valves close at {close:g} s, before the air is supplied.")
    changes = []
    for kind in ("load", "push"):
        for i, item in enumerate(_list(data, kind, source), start=1):
            e = _entry(kind, item, i, source)
            on, off = e["at_s"], e["at_s"] + e["hold_s"]
            if kind == "load":
                changes.append(Change("load", on, off, e["mass_g"] * 1e-3, math.radians(e["direction_deg"])))
            else:
                changes.append(
                    Change(
                        "push",
                        on,
                        off,
                        radius_m=e["radius_mm"] * 1e-3,
                        distance_m=e["distance_mm"] * 1e-3,
                        phi_rad=math.radians(e["phi_deg"]),
                        stiffness_N_per_m=e["stiffness_N_per_m"],
                        name=e.get("object", f"object-{i}"),
                    )
                )
    changes.sort(key=lambda c: c.on_s)
    idle = tuple((e["from_s"], e["to_s"]) for e in (_entry("idle", d, i, source) for i, d in _idle(data, source)))
    _check_times(changes, idle, close, source)
    return Script(supply, close, tuple(changes), idle, source)


def _list(data: Mapping[str, Any], kind: str, source: str) -> list[Any]:
    items = data.get(kind, [])
    if not isinstance(items, list):
        raise ScriptError(f"The sim script {source}: write each {kind} as [[{kind}]].")
    return items


def _idle(data: Mapping[str, Any], source: str) -> list[tuple[int, Any]]:
    return list(enumerate(_list(data, "idle", source), start=1))


def _stacked(a: Change, b: Change) -> bool:
    """May ``b`` hang while ``a`` does: two weights on one hanger (module docstring)?"""
    return a.kind == b.kind == "load" and math.isclose(a.direction_rad, b.direction_rad, abs_tol=1e-9)


def _check_times(changes: list[Change], idle: tuple[tuple[float, float], ...], close: float, source: str) -> None:
    for i, b in enumerate(changes):
        for a in changes[:i]:
            if b.on_s >= a.off_s or _stacked(a, b):
                continue
            raise ScriptError(
                f"The sim script {source}: the {b.kind} at {b.on_s:g} s begins before the {a.kind} "
                f"at {a.on_s:g} s ends ({a.off_s:g} s)"
                + (", and pulls another way (stacked weights share one hanger)." if a.kind == b.kind == "load" else ".")
            )
    if changes and changes[0].on_s < close:
        raise ScriptError(
            f"The sim script {source}: the {changes[0].kind} at {changes[0].on_s:g} s comes before "
            f"the valves close ({close:g} s)."
        )
    for lo, hi in idle:
        if hi < lo:
            raise ScriptError(f"The sim script {source}: the idle stretch {lo:g}-{hi:g} s ends before it begins.")
        for c in changes:
            if c.on_s < hi and c.off_s > lo:
                raise ScriptError(
                    f"The sim script {source}: the {c.kind} at {c.on_s:g} s falls in the idle stretch {lo:g}-{hi:g} s."
                )
