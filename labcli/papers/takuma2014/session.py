"""The paper's two experiments as sessions of plain steps (:mod:`labcli.core.steps`).

* :func:`force_session`: the force/angle calibration of Section 3.2, one trial per plan row
  (or per load the experimenter types): baseline, hang the weight, equilibrium, capture,
  remove the weight, review, commit.
* :func:`push_session`: the stiffness experiment of Section 4, ``pushes_per_object``
  pushes per object: the object's name, radius, default push distance and direction are
  asked once, and each push asks only for Enter (or a new distance and direction).

Both check the readings as they go (:mod:`labcli.core.guard`): the air supply before the
first trial; after each load, that the readings moved as the run's earlier trials say the
load should (a weight never hung, an object never pushed: the review warns and offers redo
as the default); and before each baseline, that the last load was taken off.

The actions below are what the experimenter does at the McKibben rig; each carries
``act_on(rig)``, which the simulated rig performs in unattended runs.  The records are
plain dicts (SI) that :mod:`labcli.papers.takuma2014.records` stores.
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable, Generator, Iterable, Sequence
from dataclasses import dataclass, replace
from functools import partial
from typing import Any

import numpy as np

from ...core.air import AirDrift, hold_problem
from ...core.guard import Guard, Watch, supply_problem
from ...core.steps import (
    Ask,
    Baseline,
    BeginTrial,
    Capture,
    Commit,
    Field,
    Finish,
    Hold,
    Note,
    Problem,
    Prompt,
    Review,
    SettleReport,
    SetupCheck,
    Step,
    Valves,
    WaitSettle,
    Window,
)
from ...core.words import count
from .captures import load_ids, record_ids
from .records import TrialRecord

G = 9.80665  # standard gravity, m/s^2 (docs/table-formats.md)

PRESSURE_NAMES = ("P_L1", "P_R1", "P_L2", "P_R2")
POT_NAMES = ("POT1", "POT2")


# --------------------------------------------------------------------------- actions
# What the experimenter does at the rig.  The simulated rig can do each one
# itself (unattended mode); on a real rig they are only words in a prompt.


@dataclass(frozen=True)
class SupplyAir:
    def act_on(self, rig: Any) -> None:
        rig.supply_air()


@dataclass(frozen=True)
class CloseValves:
    def act_on(self, rig: Any) -> None:
        rig.close_valves()


@dataclass(frozen=True)
class HangWeight:
    mass_kg: float
    direction_rad: float

    def act_on(self, rig: Any) -> None:
        rig.hang_weight(self.mass_kg, self.direction_rad)


@dataclass(frozen=True)
class RemoveWeight:
    def act_on(self, rig: Any) -> None:
        rig.remove_weight()


@dataclass(frozen=True)
class PushObject:
    radius_m: float
    distance_m: float
    phi_rad: float | None  # None: the direction is not known to the experimenter
    stiffness_N_per_m: float | None = None  # simulated objects only

    def act_on(self, rig: Any) -> None:
        # A direction unknown to the experimenter is still some direction for the
        # simulated rig: it pushes along the normal (phi = 0) then.
        phi = 0.0 if self.phi_rad is None else self.phi_rad
        if self.stiffness_N_per_m is None:
            raise ValueError(
                "the object's stiffness is not given (a push plan's stiffness_N_per_m), and the simulated rig needs it"
            )
        rig.push_object(self.radius_m, self.distance_m, phi, self.stiffness_N_per_m)


@dataclass(frozen=True)
class ReleaseObject:
    def act_on(self, rig: Any) -> None:
        rig.release_object()


Action = SupplyAir | CloseValves | HangWeight | RemoveWeight | PushObject | ReleaseObject


# --------------------------------------------------------------------------- replies


@dataclass(frozen=True)
class Load:
    mass_kg: float
    direction_rad: float


@dataclass(frozen=True)
class ObjectSpec:
    name: str
    radius_m: float
    category: str = ""
    stiffness_N_per_m: float | None = None  # simulated objects only


@dataclass(frozen=True)
class PushSpec:
    distance_m: float
    phi_rad: float | None


# --------------------------------------------------------------------------- plan rows


@dataclass(frozen=True)
class PlannedTrial:
    trial: int
    set: str
    mass_kg: float
    direction_rad: float
    plan_row: dict | None = None  # the plan's values as written (g, deg), kept with the trial
    capture: tuple[int, int] = (1, 1)  # (this capture, captures of its load)

    @property
    def load(self) -> int:
        """The plan trial this capture is of (its own id when a load is captured once)."""
        return capture_load(self.trial, self.capture[1])


def capture_id(load: int, capture: int, captures: int) -> int:
    """The record id of capture ``capture`` (1..``captures``) of plan trial ``load``: (load - 1) N + capture,
    so that a plan's captures are ids in the plan's order and one capture a load keeps the plan's ids."""
    return int(record_ids([load], captures)[capture - 1])


def capture_load(rid: int, captures: int) -> int:
    """The plan trial a record id is a capture of (:func:`capture_id` undone)."""
    return int(load_ids([rid], captures)[0])


def planned_trials(plan: Any, captures: int = 1) -> list[PlannedTrial]:
    """Plan rows (a DataFrame or dicts with trial, set, mass_g, direction_deg) in SI, each row
    ``captures`` times in a row (ids by :func:`capture_id`)."""
    if plan is None:
        return []
    rows = _plan_rows(plan)
    if captures == 1:
        return rows
    return [
        replace(r, trial=capture_id(r.trial, c, captures), capture=(c, captures))
        for r in rows
        for c in range(1, captures + 1)
    ]


def _plan_rows(plan: Any) -> list[PlannedTrial]:
    if hasattr(plan, "to_dict"):
        rows: Iterable[dict] = plan.to_dict("records")
    else:
        rows = plan
    out = []
    for r in rows:
        out.append(
            PlannedTrial(
                trial=int(r["trial"]),
                set=str(r.get("set", "") or ""),
                mass_kg=float(r["mass_g"]) * 1e-3,
                direction_rad=math.radians(float(r["direction_deg"])),
                plan_row={
                    "set": str(r.get("set", "") or ""),
                    "mass_g": float(r["mass_g"]),
                    "direction_deg": float(r["direction_deg"]),
                },
            )
        )
    return out


# --------------------------------------------------------------------------- text


def fmt_g(mass_kg: float) -> str:
    return f"{mass_kg * 1e3:.4g} g"


def fmt_deg(angle_rad: float) -> str:
    return f"{math.degrees(angle_rad):.4g} deg"


def trial_label(trial: int, total: int, set_: str) -> str:
    return f"Trial {trial}/{total}" + (f" ({set_})" if set_ else "")


def planned_label(planned: PlannedTrial, loads: int) -> str:
    """``Trial 12/108 (fit)``, and ``, capture 2/3`` when each load is captured more than once."""
    c, n = planned.capture
    return trial_label(planned.load, loads, planned.set) + (f", capture {c}/{n}" if n > 1 else "")


def load_prompt(label: str, mass_kg: float, direction_rad: float) -> str:
    return f"{label}: hang {fmt_g(mass_kg)}, pulley direction {fmt_deg(direction_rad)}, then press Enter"


SUPPLY_TEXT = "Supply compressed air to the four actuators, then press Enter"
CLOSE_TEXT = "Close the valves so that the actuators are sealed, then press Enter"


def remove_prompt(label: str) -> str:
    return f"{label}: remove the weight, then press Enter"


# --------------------------------------------------------------------------- typed input


def parse_mass_g(text: str, lo_g: float = 1.0, hi_g: float = 2000.0) -> float:
    """Parse a typed mass ("200", "200 g", "0.2 kg") into kg; ValueError with a sentence if bad."""
    m = re.fullmatch(r"\s*([-+]?[0-9]*\.?[0-9]+(?:[eE][-+]?[0-9]+)?)\s*(g|kg)?\s*", text)
    if not m:
        raise ValueError(f"'{text.strip()}' is not a mass: type a number of grams, e.g. 200 g.")
    value = float(m.group(1)) * (1000.0 if m.group(2) == "kg" else 1.0)
    if not 0 < value or not lo_g <= value <= hi_g:
        raise ValueError(f"The mass must be from {lo_g:g} g to {hi_g:g} g, got {value:g} g.")
    return value * 1e-3


def wrap_direction_deg(value: float, lo_deg: float = -180.0, hi_deg: float = 180.0) -> float | None:
    """``value`` (deg) turned by whole turns into [lo_deg, hi_deg]: 270 is -90; None when no turn fits.

    A direction is an angle on a circle (docs/table-formats.md): any number names one, and
    the one typed is kept when it is in range already; otherwise the turn nearest to it.
    """
    if not math.isfinite(value):
        return None
    for turns in sorted(range(-(int(abs(value)) // 360) - 2, int(abs(value)) // 360 + 3), key=abs):
        turned = value + 360.0 * turns
        if lo_deg <= turned <= hi_deg:
            return turned
    return None


def parse_direction_deg(
    text: str, lo_deg: float = -180.0, hi_deg: float = 180.0, *, allow_unknown: bool = False
) -> float | None:
    """Parse a typed direction in degrees into rad; "?" or nothing is unknown when allowed.

    Directions wrap: 270 is -90 (:func:`wrap_direction_deg`); one that no whole turn brings
    into [lo_deg, hi_deg] is refused with the range.
    """
    t = text.strip()
    if allow_unknown and t.lower() in ("?", "unknown", ""):
        return None
    m = re.fullmatch(r"([-+]?[0-9]*\.?[0-9]+(?:[eE][-+]?[0-9]+)?)\s*(deg)?", t)
    if not m:
        raise ValueError(f"'{t}' is not a direction: type degrees counter-clockwise from +x, e.g. 45 deg.")
    value = float(m.group(1))
    wrapped = wrap_direction_deg(value, lo_deg, hi_deg)
    if wrapped is None:
        raise ValueError(
            f"The direction must be from {lo_deg:g} deg to {hi_deg:g} deg (or a whole turn from there), "
            f"got {value:g} deg."
        )
    return math.radians(wrapped)


def parse_load_change(
    text: str, keep_direction_rad: float, mass_range_g: tuple[float, float], direction_range_deg: tuple[float, float]
) -> Load:
    """A load typed instead of Enter: ``MASS`` (g, the direction kept) or ``MASS DIRECTION``
    (g and deg, e.g. ``300 90`` or ``300 g 90 deg``)."""
    m = re.fullmatch(r"\s*(\S+?)\s*(g|kg)?(?:[\s,]+(\S+?)\s*(deg)?)?\s*", text)
    if not m:
        raise ValueError(
            f"'{text.strip()}' is not a load: type the mass in g and the direction in deg, e.g. 300 90, or press Enter."
        )
    mass = parse_mass_g(m.group(1) + (m.group(2) or ""), *mass_range_g)
    if m.group(3) is None:
        return Load(mass, keep_direction_rad)
    direction = parse_direction_deg(m.group(3), *direction_range_deg)
    assert direction is not None  # "unknown" is not allowed for a pulley
    return Load(mass, direction)


def parse_length_mm(text: str, what: str, lo_mm: float = 0.0, hi_mm: float = 500.0) -> float:
    """Parse a typed length in millimetres into metres."""
    m = re.fullmatch(r"\s*([-+]?[0-9]*\.?[0-9]+(?:[eE][-+]?[0-9]+)?)\s*(mm)?\s*", text)
    if not m:
        raise ValueError(f"'{text.strip()}' is not a {what}: type millimetres, e.g. 10 mm.")
    value = float(m.group(1))
    if not (value > 0 and lo_mm <= value <= hi_mm):
        raise ValueError(f"The {what} must be from {lo_mm:g} mm to {hi_mm:g} mm, got {value:g} mm.")
    return value * 1e-3


# --------------------------------------------------------------------------- records


@dataclass(frozen=True)
class ChannelMap:
    """Where the four pressures and two potentiometers sit among the device channels."""

    pressure: tuple[int, ...]
    pot: tuple[int, ...]

    @classmethod
    def from_channels(cls, channels: Sequence[str]) -> ChannelMap:
        names = list(channels)
        missing = [n for n in PRESSURE_NAMES + POT_NAMES if n not in names]
        if missing:
            raise ValueError(
                "the protocol's channels lack "
                + ", ".join(missing)
                + " (need "
                + ",".join(PRESSURE_NAMES + POT_NAMES)
                + ")"
            )
        return cls(tuple(names.index(n) for n in PRESSURE_NAMES), tuple(names.index(n) for n in POT_NAMES))


def force_record(
    trial: int,
    set_: str,
    mass_kg: float,
    direction_rad: float,
    baseline: Window,
    loaded: Window,
    settle_baseline: SettleReport,
    settle_load: SettleReport,
    cmap: ChannelMap,
    plan_row: dict | None = None,
) -> TrialRecord:
    """One force/angle trial, SI, with both raw windows (what the store writes)."""
    b = baseline.mean()
    m = loaded.mean()
    p0 = b[list(cmap.pressure)]
    p = m[list(cmap.pressure)]
    pot0 = b[list(cmap.pot)]
    theta = m[list(cmap.pot)] - pot0
    weight = mass_kg * G
    record: TrialRecord = {
        "trial": int(trial),
        "set": set_,
        "P0_MPa": p0,
        "P_MPa": p,
        "pot0_rad": pot0,
        "theta_rad": theta,
        "force_N": np.array([weight * math.cos(direction_rad), weight * math.sin(direction_rad)]),
        "mass_kg": float(mass_kg),
        "direction_rad": float(direction_rad),
        "settle": {"baseline": settle_baseline.as_dict(), "load": settle_load.as_dict()},
        "raw": {"baseline": baseline, "load": loaded},
    }
    if plan_row:
        record["plan"] = dict(plan_row)
    return record


def summary_row(record: dict) -> dict[str, str]:
    """The trial's row as people read it: degrees, grams, the unit of every column in its name."""
    p0 = record["P0_MPa"]
    p = record["P_MPa"]
    row = {"push": str(record["push"])} if "push" in record else {"trial": str(record["trial"])}
    if record.get("set"):
        row["set"] = record["set"]
    if "object" in record:
        row["object"] = record["object"]
        row["d (mm)"] = f"{record['d_m'] * 1e3:.4g}"
        phi = record.get("phi_rad")
        row["phi (deg)"] = "unknown" if phi is None or not np.isfinite(phi) else f"{math.degrees(phi):.4g}"
    for name, a, c in zip(PRESSURE_NAMES, p0, p, strict=False):
        row[f"{name} (MPa)"] = f"{a:.4f}->{c:.4f}"
    if "theta_rad" in record:
        row["theta1 (deg)"] = f"{math.degrees(record['theta_rad'][0]):+.3f}"
        row["theta2 (deg)"] = f"{math.degrees(record['theta_rad'][1]):+.3f}"
    if "force_N" in record:
        row["Fx (N)"] = f"{record['force_N'][0]:+.3f}"
        row["Fy (N)"] = f"{record['force_N'][1]:+.3f}"
    load = record["settle"]["load"]
    row["settled (s)"] = f"{load['settle_time_s']:.2f}" + ("" if load["settled"] else " timed out")
    return row


def capture_row(record: dict, planned: PlannedTrial) -> dict[str, str]:
    """:func:`summary_row` of a force trial, which names a capture of a load taken several times by its
    plan trial and the capture (``trial 2  capture 1/3``), as the prompts do, not by its record id."""
    row = summary_row(record)
    c, n = planned.capture
    if n == 1:
        return row
    return {"trial": str(planned.load), "capture": f"{c}/{n}", **{k: v for k, v in row.items() if k != "trial"}}


STILL_HANGING = "the last weight may still hang on the pulley"  # what the load check suspects of a baseline


# --------------------------------------------------------------------------- questions


def ask_load(
    trial: int,
    total: int,
    mass_range_g: tuple[float, float] = (1.0, 2000.0),
    direction_range_deg: tuple[float, float] = (-180.0, 180.0),
) -> Ask:
    """No plan: the mass (g) and pulley direction (deg) of the next trial; Enter ends the run."""
    head = f"Trial {trial}/{total}"
    lo, hi = mass_range_g
    dlo, dhi = direction_range_deg
    return Ask(
        (
            Field(
                "mass_kg",
                f"{head}: mass to hang in g, {lo:g} to {hi:g} (Enter when the run is complete, q to quit):",
                partial(parse_mass_g, lo_g=lo, hi_g=hi),
                again=f"{head}: mass to hang in g:",
                stop_if_empty=True,
            ),
            Field(
                "direction_rad",
                f"{head}: pulley direction in deg, counter-clockwise from +x ({dlo:g} to {dhi:g}, whole turns wrap):",
                partial(parse_direction_deg, lo_deg=dlo, hi_deg=dhi),
            ),
        )
    )


LOAD_CHANGE_OFFER = " (or type another mass in g and direction in deg, e.g. 300 90)"


def confirm_end(stored: int) -> Ask:
    """After an empty answer to the mass: end the run only on y (Enter goes on with the next load)."""
    return Ask(
        (
            Field(
                "end",
                f"End the run here with {count(stored, 'trial')} stored? y ends it, Enter goes on:",
                parse_yes,
                default=False,
            ),
        )
    )


def parse_yes(text: str) -> bool:
    """y/yes is True, n/no False; anything else is asked again."""
    t = text.strip().lower()
    if t in ("y", "yes"):
        return True
    if t in ("n", "no"):
        return False
    raise ValueError(f"Type y to end the run or press Enter to go on, not '{text.strip()}'.")


# --------------------------------------------------------------------------- sessions


FIX_AIR_TEXT = "Fix what the check found, then press Enter: the board supplies the air again"


def _pressurise(protocol: Any) -> Generator[Step, Any, AirDrift | None]:
    """Setup check, air supply (held until the pressures settle, then checked), valves closed.

    A board that drives its valves (the ``Valves`` step's reply) supplies and holds by command,
    and the held chambers are watched for ``hold_check_s`` (:func:`labcli.core.air.hold_problem`)
    before the first trial; the drift tracker it returns has the trials re-pressurise.  Otherwise
    the prompts ask the experimenter, and None is returned.
    """
    capture_s = float(protocol.settling.capture_s)
    cols = [i for i, u in enumerate(protocol.calibration.units) if u == "MPa"]
    names = [protocol.channels[i] for i in cols]
    yield SetupCheck()
    if (yield Valves("supply")) is not None:
        return (yield from _pressurise_by_command(protocol, capture_s, cols, names))
    problem = None
    while True:
        supply = Prompt(SUPPLY_TEXT, SupplyAir())
        yield supply if problem is None else Problem(problem, supply)
        if (yield WaitSettle("air supply")) == "redo":
            problem = None
            continue
        readings = yield Baseline(capture_s)
        problem = supply_problem(names, readings.mean()[cols], protocol.supply_min_MPa)
        if problem is None:
            break
    yield Prompt(CLOSE_TEXT, CloseValves())
    return None


def _pressurise_by_command(
    protocol: Any, capture_s: float, cols: list[int], names: list[str]
) -> Generator[Step, Any, AirDrift]:
    """Supplied by command (the Valves step already sent): settle, check the supply, hold, the hold check."""
    air = protocol.air
    while True:
        if (yield WaitSettle("air supply")) == "redo":
            continue
        readings = yield Baseline(capture_s)
        problem = supply_problem(names, readings.mean()[cols], protocol.supply_min_MPa)
        yield Valves("hold")
        if problem is None:
            # The arm and the air come to rest on the closed chambers first: then what is left is the leak.
            yield WaitSettle("hold")
            hold = yield Hold(air.hold_check_s)
            problem = hold_problem(names, hold.slope_per_s[cols], air)
        if problem is None:
            return AirDrift(names, cols, air, hold.slope_per_s)
        yield Problem(problem, Prompt(FIX_AIR_TEXT))
        yield Valves("supply")


def _relieve(air: AirDrift, checked: Checked | None) -> Generator[Step, Any, str]:
    """Friction relief: a supply pulse of ``friction_relief_s``, then hold (a fresh supply each trial),
    after one side's chambers are vented for ``friction_relief_vent_s`` where the protocol asks for it
    (the arm swings to the other side, and comes back to the baseline from there): by default the
    side the trial's load pulls the arm towards, so that the load pulls it away from its lean.
    Returns the side vented ("" for none), which the trial's record keeps (``relief_vent``)."""
    guard = checked.guard if checked is not None else None
    vented = ""
    if air.settings.friction_relief_vent_s > 0:
        pulled = getattr(getattr(guard, "prior", None), "pulled_side", None)
        vented = air.settings.relief_side(pulled(checked.load) if pulled is not None and checked is not None else None)
        yield Valves("vent", air.settings.relief_vented(air.names, vented))
        yield Hold(air.settings.friction_relief_vent_s)
    yield Valves("supply")
    yield Hold(air.settings.friction_relief_s)
    yield Valves("hold")
    air.supplied()
    if guard is not None:
        guard.resupplied()
    return vented


def _resupply(air: AirDrift, why: str, guard: Guard | None) -> Generator[Step, Any, None]:
    """The chambers drifted: supply by command until the pressures settle, then hold again."""
    yield Note(f"{why[:1].upper()}{why[1:]}.")
    yield Valves("supply")
    yield WaitSettle("air supply")
    yield Valves("hold")
    air.supplied()
    if guard is not None:
        guard.resupplied()


def session_guard(protocol: Any) -> Guard:
    """The checks of one session, with the sleeves' friction as the bound of what an unloaded
    baseline may keep (:mod:`labcli.papers.takuma2014.friction`), and what a load must do before
    the run's trials say (:mod:`.guard_prior`): the rig's statics where the protocol gives its
    geometry (a load they say friction may hold is judged by nothing else), the protocol's paper
    coefficients otherwise."""
    from .friction import baseline_hold
    from .guard_prior import ModelPrior, PhysicsPrior

    prior = PhysicsPrior.of(protocol) or ModelPrior.of(protocol)
    return Guard(protocol, hold_prior=baseline_hold(Watch.of(protocol).units), prior=prior)


@dataclass(frozen=True)
class Checked:
    """What the checks of one trial need: the guard, the trial's load vector and its model's key,
    and the prompt that takes a forgotten load off (``"remove the weight"``)."""

    guard: Guard
    load: tuple[float, ...]
    key: Any
    undo: Prompt
    forgotten: str  # "a weight may still hang on the pulley"


def _trial(
    capture_s: float,
    load: Prompt,
    unload: Prompt,
    record_of: Any,
    checked: Checked | None = None,
    air: AirDrift | None = None,
    row_of: Callable[[dict], dict[str, str]] = summary_row,
) -> Generator[Step, Any, Any]:
    """One trial or push until accepted (True) or skipped (False).

    Baseline at equilibrium, the load, equilibrium, capture, the unload, then the review;
    a redo (of a wait or of the review) starts again from the baseline.
    ``record_of(baseline, loaded, settle_baseline, settle_load)`` makes the record, ``row_of`` its review row.
    With ``checked``, a baseline that still carries the last load asks for it to be taken
    off, and a load the readings did not follow makes redo the review's default.  A load
    prompt answered with new values (its ``change``) returns them: nothing was loaded, and
    the caller starts the trial again with them.  With ``air`` (a board that drives its valves),
    a baseline that drifted past the protocol's limit since the last supply has the chambers
    supplied and held again, and the baseline retaken.
    """
    vented = ""  # the side the relief vented before this baseline, kept with the record
    while True:
        if air is not None and air.settings.friction_relief_s > 0:
            vented = yield from _relieve(air, checked)
        leak = air.leak_per_s if air is not None else ()
        wait_b = yield WaitSettle("baseline", leak)
        if wait_b == "redo":
            continue
        base = yield Baseline(capture_s)
        if checked is not None:
            left = checked.guard.after_baseline(base)
            if left is not None:
                lead = (
                    "The arm is not where it rests unloaded"
                    if left.startswith(("the first baseline since", "the baseline after that trial"))
                    else "The readings have not returned since the last load"
                )
                yield Problem(f"{lead}: {left}; {checked.forgotten}.", checked.undo)
                continue
        if air is not None:
            drifted = air.check(base)
            if drifted is not None:
                yield from _resupply(air, drifted, checked.guard if checked is not None else None)
                continue
        typed = yield load
        if typed is not None:
            return typed
        wait_l = yield WaitSettle("load", leak)
        if wait_l == "redo":
            yield unload
            continue
        loaded = yield Capture(capture_s)
        weak = checked.guard.after_load(checked.load, base, loaded, checked.key) if checked else None
        yield unload
        record: Any = {**record_of(base, loaded, wait_b, wait_l), **({"relief_vent": vented} if vented else {})}
        fix = (
            ""
            if checked is not None and checked.guard.unsealed
            else ": check that the load was applied as the prompt said"
        )
        warnings: tuple[str, ...] = (
            (f"{weak[:1].upper()}{weak[1:]}{fix}, then redo the trial (Enter), or accept it as it is (a).",)
            if weak
            else ()
        )
        decision = yield Review(row_of(record), warnings, "redo" if weak else "accept")
        if weak and checked is not None and checked.guard.unsealed:
            # The valves are closed from now on: the baselines before say nothing of the leak.
            checked.guard.resupplied()
        if decision == "redo":
            continue
        if decision == "skip":
            return False
        if weak:
            record = {**record, "accepted": "operator", "flags": [warnings[0]]}
        elif checked is not None:
            checked.guard.learn(checked.load, base, loaded, checked.key)
        yield Commit(record)
        return True


def _load_limits(protocol: Any) -> tuple[tuple[float, float], tuple[float, float]]:
    """Typed-load limits from the protocol's [force] section (defaults: 1-2000 g, +-180 deg)."""
    lim = protocol.settings.force_limits
    if lim is None:
        return (1.0, 2000.0), (-180.0, 180.0)
    return (lim.mass_min_g, lim.mass_max_g), (lim.direction_min_deg, lim.direction_max_deg)


def force_vector(mass_kg: float, direction_rad: float) -> tuple[float, float]:
    """(Fx, Fy) in N of a pulley weight: m g along its direction."""
    return (mass_kg * G * math.cos(direction_rad), mass_kg * G * math.sin(direction_rad))


def _resumed_guard(protocol: Any, history: Iterable[Any], baselines: Sequence[Sequence[float]]) -> Any:
    """The load check, taught what the trials already stored did and where their baselines lie."""
    guard = session_guard(protocol)
    history = tuple(history)
    for force, change in history:
        guard.model().add(force, change)
    learn = getattr(guard.prior, "learn_change", None)
    if learn is not None and len(baselines) == len(history):  # the stored trials' rows, in order
        for (force, change), base in zip(history, baselines, strict=True):
            learn(force, base, change)
    if len(baselines):
        guard.resumed(baselines)
    return guard


def _planned_total(protocol: Any, target: int | None) -> int:
    """The trials announced when there is no plan: ``target``, else the protocol's fit + validation."""
    trials = protocol.settings.trials
    return target or (int(trials.fit) + int(trials.validation) if trials is not None else 0)


def _hang_prompt(label: str, planned: Any, limits: Any, *, typed_by_hand: bool) -> Prompt:
    """The prompt to hang the trial's weight; a load typed by hand (no plan) can be typed again
    there (after a redo, say) instead of Enter."""
    hang = Prompt(
        load_prompt(label, planned.mass_kg, planned.direction_rad),
        HangWeight(planned.mass_kg, planned.direction_rad),
    )
    if not typed_by_hand:
        return hang
    return Prompt(
        hang.text + LOAD_CHANGE_OFFER,
        hang.action,
        Field(
            "load",
            "",
            partial(
                parse_load_change,
                keep_direction_rad=planned.direction_rad,
                mass_range_g=limits[0],
                direction_range_deg=limits[1],
            ),
            again=f"{hang.text}{LOAD_CHANGE_OFFER} (q to quit):",
        ),
    )


def force_session(
    protocol: Any,
    plan: Any = None,
    *,
    completed: Iterable[int] = (),
    target: int | None = None,
    history: Iterable[tuple[Sequence[float], Sequence[float]]] = (),
    baselines: Sequence[Sequence[float]] = (),
) -> Generator[Step, Any, None]:
    """Section 3.2's calibration: a trial per plan row, or ``captures_per_load`` records in a row (:func:`capture_id`).

    ``plan``: the plan table (None: the experimenter types each load, captured once);
    ``completed``: trial ids already stored (resume skips them);
    ``target``: the number of trials announced when there is no plan
    (default: the protocol's fit + validation counts);
    ``history``: (force N, change of the watched channels SI) of trials already stored,
    from which the load check learns what a load does on this rig;
    ``baselines``: the watched channels' baselines (SI) of those trials, against which the first
    new baseline is checked for a weight still hanging.
    """
    capture_s = float(protocol.settling.capture_s)
    cmap = ChannelMap.from_channels(protocol.channels)
    guard = _resumed_guard(protocol, history, baselines)
    done, captures = set(int(t) for t in completed), protocol.air.captures_per_load if plan is not None else 1
    rows = planned_trials(plan, captures)
    remaining = [r for r in rows if r.trial not in done]
    total = len(rows) // captures or _planned_total(protocol, target)

    air = yield from _pressurise(protocol)

    skipped: list[int] = []
    limits = _load_limits(protocol)
    typed: Load | None = None  # a load typed at the hang prompt instead of Enter (no plan)
    while not rows or remaining:
        if rows:
            planned = remaining.pop(0)
            label = planned_label(planned, total)
        else:
            # Ids stay dense: a skipped trial's id is used by the next load.
            next_id = max(done, default=0) + 1
            shown_total = max(total, len(done) + 1)
            if typed is None:
                load = yield ask_load(next_id, shown_total, *limits)
                if load is None:
                    # An Enter alone may be a slip: the run ends only when the experimenter says so.
                    if (yield confirm_end(len(done)))["end"]:
                        break
                    continue
                typed = Load(load["mass_kg"], load["direction_rad"])
            planned = PlannedTrial(next_id, "", typed.mass_kg, typed.direction_rad)
            typed = None
            label = trial_label(next_id, shown_total, "")
        # The label counts trials (loads); the bar counts every capture of them.
        yield BeginTrial(
            planned.trial, planned.set, len(done) + 1, total * captures, label, "captures" if captures > 1 else ""
        )
        remove = Prompt(remove_prompt(label), RemoveWeight())
        hang = _hang_prompt(label, planned, limits, typed_by_hand=not rows)
        stored = yield from _trial(
            capture_s,
            hang,
            remove,
            lambda base, loaded, wait_b, wait_l, p=planned: force_record(
                p.trial, p.set, p.mass_kg, p.direction_rad, base, loaded, wait_b, wait_l, cmap, p.plan_row
            ),
            Checked(guard, force_vector(planned.mass_kg, planned.direction_rad), None, remove, STILL_HANGING),
            air,
            partial(capture_row, planned=planned),
        )
        if isinstance(stored, Load):  # a new load typed instead of hanging this one: the trial again with it
            typed = stored
            continue
        (done.add if stored else skipped.append)(planned.trial)

    split = None
    if rows:
        split = {r.trial: r.set for r in rows if r.trial in done and r.set}
    yield Finish(split, tuple(skipped))
