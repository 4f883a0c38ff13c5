"""The paper's two experiments as sessions of plain steps (:mod:`labcli.core.steps`).

* :func:`force_session`: the force/angle calibration of Section 3.2, one trial per plan row
  (or per load the experimenter types): baseline, hang the weight, equilibrium, capture,
  remove the weight, review, commit.
* :func:`push_session`: the stiffness experiment of Section 4, ``pushes_per_object``
  pushes per object.

The actions below are what the experimenter does at the McKibben rig; each carries
``act_on(rig)``, which the simulated rig performs in unattended runs.  The records are
plain dicts (SI) that :mod:`labcli.experiments.takuma2014.records` stores.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from functools import partial
from typing import Any, Generator, Iterable, Sequence

import numpy as np

from ...core.steps import (
    Ask,
    Baseline,
    BeginTrial,
    Capture,
    Commit,
    Field,
    Finish,
    Prompt,
    Review,
    SettleReport,
    SetupCheck,
    Step,
    WaitSettle,
    Window,
)

G = 9.80665  # standard gravity, m/s^2 (docs/table-formats.md)

PRESSURE_NAMES = ("P_L1", "P_R1", "P_L2", "P_R2")
POT_NAMES = ("POT1", "POT2")
LOW_SUPPLY_MPA = 0.02  # a supplied actuator below this has no air


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


def planned_trials(plan: Any) -> list[PlannedTrial]:
    """Plan rows (a DataFrame or dicts with trial, set, mass_g, direction_deg) in SI."""
    if plan is None:
        return []
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
                plan_row={"set": str(r.get("set", "") or ""), "mass_g": float(r["mass_g"]),
                          "direction_deg": float(r["direction_deg"])},
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


def parse_direction_deg(
    text: str, lo_deg: float = -180.0, hi_deg: float = 180.0, *, allow_unknown: bool = False
) -> float | None:
    """Parse a typed direction in degrees into rad; "?" or nothing is unknown when allowed."""
    t = text.strip()
    if allow_unknown and t.lower() in ("?", "unknown", ""):
        return None
    m = re.fullmatch(r"([-+]?[0-9]*\.?[0-9]+(?:[eE][-+]?[0-9]+)?)\s*(deg)?", t)
    if not m:
        raise ValueError(f"'{t}' is not a direction: type degrees counter-clockwise from +x, e.g. 45 deg.")
    value = float(m.group(1))
    if not lo_deg <= value <= hi_deg:
        raise ValueError(f"The direction must be from {lo_deg:g} deg to {hi_deg:g} deg, got {value:g} deg.")
    return math.radians(value)


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
    def from_channels(cls, channels: Sequence[str]) -> "ChannelMap":
        names = list(channels)
        missing = [n for n in PRESSURE_NAMES + POT_NAMES if n not in names]
        if missing:
            raise ValueError(
                "the protocol's channels lack " + ", ".join(missing)
                + " (need " + ",".join(PRESSURE_NAMES + POT_NAMES) + ")"
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
) -> dict:
    """One force/angle trial, SI, with both raw windows (what the store writes)."""
    b = baseline.mean()
    m = loaded.mean()
    p0 = b[list(cmap.pressure)]
    p = m[list(cmap.pressure)]
    pot0 = b[list(cmap.pot)]
    theta = m[list(cmap.pot)] - pot0
    weight = mass_kg * G
    return {
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
        "raw": {"baseline": baseline.as_dict(), "load": loaded.as_dict()},
        **({"plan": dict(plan_row)} if plan_row else {}),
    }


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
    for name, a, c in zip(PRESSURE_NAMES, p0, p):
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


# --------------------------------------------------------------------------- questions


def parse_stiffness(text: str) -> float:
    """Parse a typed stiffness in N/m ("800", "800 N/m")."""
    try:
        value = float(text.strip().removesuffix("N/m").strip())
    except ValueError:
        raise ValueError(f"'{text.strip()}' is not a stiffness: type newtons per metre, e.g. 800.") from None
    if not 0 < value < float("inf"):
        raise ValueError(f"The stiffness must be more than 0 N/m, got {value:g} N/m.")
    return value


def ask_load(trial: int, total: int, mass_range_g: tuple[float, float] = (1.0, 2000.0),
             direction_range_deg: tuple[float, float] = (-180.0, 180.0)) -> Ask:
    """No plan: the mass (g) and pulley direction (deg) of the next trial; Enter ends the run."""
    head = f"Trial {trial}/{total}"
    lo, hi = mass_range_g
    dlo, dhi = direction_range_deg
    return Ask((
        Field("mass_kg", f"{head}: mass to hang in g, {lo:g} to {hi:g} (Enter when the run is complete, q to quit):",
              partial(parse_mass_g, lo_g=lo, hi_g=hi), again=f"{head}: mass to hang in g:", stop_if_empty=True),
        Field("direction_rad", f"{head}: pulley direction in deg, counter-clockwise from +x ({dlo:g} to {dhi:g}):",
              partial(parse_direction_deg, lo_deg=dlo, hi_deg=dhi)),
    ))


def ask_object(index: int) -> Ask:
    """Push experiment: the next object's name, radius and category; Enter ends the run."""
    return Ask((
        Field("name", f"Object {index}: name (e.g. pet-1; Enter when all objects are done, q to quit):",
              stop_if_empty=True),
        Field("radius_m", lambda a: f"{a['name']}: radius R in mm:",
              partial(parse_length_mm, what="radius", lo_mm=0.0, hi_mm=500.0)),
        Field("category", lambda a: f"{a['name']}: category (soft, medium, hard, a name, or Enter if unknown):"),
        Field("stiffness_N_per_m", lambda a: f"{a['name']}: stiffness of the simulated object in N/m:",
              parse_stiffness, simulated_only=True),
    ))


def ask_push(name: str, index: int, total: int, distance_range_m: tuple[float, float] = (0.002, 0.020)) -> Ask:
    """Push experiment: push distance (mm) and direction (deg, or unknown)."""
    head = f"Push {index}/{total} of {name}"
    lo, hi = (v * 1e3 for v in distance_range_m)
    return Ask((
        Field("distance_m", f"{head}: push distance d in mm, {lo:g} to {hi:g}:",
              partial(parse_length_mm, what="push distance", lo_mm=lo, hi_mm=hi)),
        Field("phi_rad", f"{head}: push direction phi in deg (? or Enter if unknown):",
              partial(parse_direction_deg, allow_unknown=True)),
    ))


# --------------------------------------------------------------------------- sessions


def _pressurise() -> Generator[Step, Any, None]:
    """Setup check, air supply (held until the pressures settle), valves closed."""
    yield SetupCheck()
    while True:
        yield Prompt(SUPPLY_TEXT, SupplyAir())
        if (yield WaitSettle("air supply", min_pressure_MPa=LOW_SUPPLY_MPA)) != "redo":
            break
    yield Prompt(CLOSE_TEXT, CloseValves())


def _trial(capture_s: float, load: Prompt, unload: Prompt, record_of: Any) -> Generator[Step, Any, bool]:
    """One trial or push until accepted (True) or skipped (False).

    Baseline at equilibrium, the load, equilibrium, capture, the unload, then the review;
    a redo (of a wait or of the review) starts again from the baseline.
    ``record_of(baseline, loaded, settle_baseline, settle_load)`` makes the record.
    """
    while True:
        wait_b = yield WaitSettle("baseline")
        if wait_b == "redo":
            continue
        base = yield Baseline(capture_s)
        yield load
        wait_l = yield WaitSettle("load")
        if wait_l == "redo":
            yield unload
            continue
        loaded = yield Capture(capture_s)
        yield unload
        record = record_of(base, loaded, wait_b, wait_l)
        decision = yield Review(summary_row(record))
        if decision == "redo":
            continue
        if decision == "skip":
            return False
        yield Commit(record)
        return True


def _load_limits(protocol: Any) -> tuple[tuple[float, float], tuple[float, float]]:
    """Typed-load limits from the protocol's [force] section (defaults: 1-2000 g, +-180 deg)."""
    lim = protocol.settings.force_limits
    if lim is None:
        return (1.0, 2000.0), (-180.0, 180.0)
    return (lim.mass_min_g, lim.mass_max_g), (lim.direction_min_deg, lim.direction_max_deg)


def force_session(
    protocol: Any,
    plan: Any = None,
    *,
    completed: Iterable[int] = (),
    target: int | None = None,
) -> Generator[Step, Any, None]:
    """The force/angle calibration session of Section 3.2 (one trial per plan row).

    ``plan``: the plan table (None: the experimenter types each load);
    ``completed``: trial ids already stored (resume skips them);
    ``target``: the number of trials announced when there is no plan
    (default: the protocol's fit + validation counts).
    """
    capture_s = float(protocol.settling.capture_s)
    cmap = ChannelMap.from_channels(protocol.channels)
    done = set(int(t) for t in completed)
    rows = planned_trials(plan)
    remaining = [r for r in rows if r.trial not in done]
    if rows:
        total = len(rows)
    else:
        trials = protocol.settings.trials
        total = target or (int(trials.fit) + int(trials.validation) if trials is not None else 0)

    yield from _pressurise()

    skipped: list[int] = []
    while not rows or remaining:
        if rows:
            planned = remaining.pop(0)
            label = trial_label(planned.trial, total, planned.set)
        else:
            # Ids stay dense: a skipped trial's id is used by the next load.
            next_id = max(done, default=0) + 1
            shown_total = max(total, len(done) + 1)
            load = yield ask_load(next_id, shown_total, *_load_limits(protocol))
            if load is None:
                break
            planned = PlannedTrial(next_id, "", load["mass_kg"], load["direction_rad"])
            label = trial_label(next_id, shown_total, "")
        yield BeginTrial(planned.trial, planned.set, len(done) + 1, total, label)
        stored = yield from _trial(
            capture_s,
            Prompt(load_prompt(label, planned.mass_kg, planned.direction_rad),
                   HangWeight(planned.mass_kg, planned.direction_rad)),
            Prompt(remove_prompt(label), RemoveWeight()),
            lambda base, loaded, wait_b, wait_l, p=planned: force_record(
                p.trial, p.set, p.mass_kg, p.direction_rad, base, loaded, wait_b, wait_l, cmap, p.plan_row),
        )
        (done.add if stored else skipped.append)(planned.trial)

    split = None
    if rows:
        split = {r.trial: r.set for r in rows if r.trial in done and r.set}
    yield Finish(split, tuple(skipped))


# --------------------------------------------------------------------------- push experiment


@dataclass(frozen=True)
class PlannedObject:
    """An object to push, with its pushes when they are known in advance (simulated runs)."""

    spec: ObjectSpec
    pushes: tuple[PushSpec, ...] = ()


def push_prompt(label: str, name: str, distance_m: float, phi_rad: float | None) -> str:
    along = "along an unknown direction" if phi_rad is None else f"along {fmt_deg(phi_rad)}"
    return f"{label}: push {name} by {distance_m * 1e3:.4g} mm {along}, then press Enter"


def release_prompt(label: str, name: str) -> str:
    return f"{label}: move {name} back until it just touches the contact point, then press Enter"


def push_record(
    push: int,
    obj: ObjectSpec,
    spec: PushSpec,
    baseline: Window,
    loaded: Window,
    settle_baseline: SettleReport,
    settle_load: SettleReport,
    cmap: ChannelMap,
) -> dict:
    """One push of the stiffness experiment (Section 4), SI, with both raw windows."""
    b = baseline.mean()
    m = loaded.mean()
    record = {
        "push": int(push),
        "object": obj.name,
        "R_m": float(obj.radius_m),
        "d_m": float(spec.distance_m),
        "phi_rad": float("nan") if spec.phi_rad is None else float(spec.phi_rad),
        "category": obj.category,
        "P0_MPa": b[list(cmap.pressure)],
        "P_MPa": m[list(cmap.pressure)],
        "pot0_rad": b[list(cmap.pot)],
        "theta_rad": m[list(cmap.pot)] - b[list(cmap.pot)],
        "settle": {"baseline": settle_baseline.as_dict(), "load": settle_load.as_dict()},
        "raw": {"baseline": baseline.as_dict(), "load": loaded.as_dict()},
    }
    if obj.stiffness_N_per_m is not None:
        record["true_stiffness_N_per_m"] = float(obj.stiffness_N_per_m)
    return record


def push_session(
    protocol: Any,
    objects: Sequence[PlannedObject] | None = None,
    *,
    completed: Iterable[int] = (),
) -> Generator[Step, Any, None]:
    """The stiffness experiment of Section 4: per object, ``pushes_per_object`` pushes.

    With ``objects`` (each with its pushes) the schedule is fixed and push ids are
    numbered through it, so a resumed run skips the ones already stored; without,
    the experimenter names each object and types each push.
    """
    capture_s = float(protocol.settling.capture_s)
    cmap = ChannelMap.from_channels(protocol.channels)
    push = protocol.settings.push
    per_object = push.pushes_per_object if push is not None else 10
    d_range = (push.distance_min_m, push.distance_max_m) if push is not None else (0.002, 0.020)
    done = set(int(t) for t in completed)
    fixed = list(objects or [])
    total = sum(len(o.pushes) for o in fixed) if fixed else 0

    yield from _pressurise()

    skipped: list[int] = []
    next_id = 1
    index = 0
    while not fixed or index < len(fixed):
        if fixed:
            planned = fixed[index]
        else:
            answer = yield ask_object(index + 1)
            if answer is None:
                break
            planned = PlannedObject(ObjectSpec(answer["name"], answer["radius_m"], answer["category"],
                                               answer.get("stiffness_N_per_m")))
            next_id = max(done, default=0) + 1
        index += 1
        obj = planned.spec
        n = len(planned.pushes) if fixed else per_object
        for k in range(1, n + 1):
            push_id = next_id
            next_id += 1
            if push_id in done:
                continue
            label = f"Push {k}/{n} of {obj.name}"
            yield BeginTrial(push_id, "", len(done) + 1, total or per_object * index, label)
            if fixed:
                spec = planned.pushes[k - 1]
            else:
                typed = yield ask_push(obj.name, k, n, d_range)
                spec = PushSpec(typed["distance_m"], typed["phi_rad"])
            stored = yield from _trial(
                capture_s,
                Prompt(push_prompt(label, obj.name, spec.distance_m, spec.phi_rad),
                       PushObject(obj.radius_m, spec.distance_m, spec.phi_rad, obj.stiffness_N_per_m)),
                Prompt(release_prompt(label, obj.name), ReleaseObject()),
                lambda base, loaded, wait_b, wait_l, pid=push_id, o=obj, s=spec: push_record(
                    pid, o, s, base, loaded, wait_b, wait_l, cmap),
            )
            (done.add if stored else skipped.append)(push_id)
    yield Finish(None, tuple(skipped))
