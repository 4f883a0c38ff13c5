"""An acquisition protocol as a sequence of plain steps.

A *session* is a generator of step objects; it knows nothing of serial ports,
HDF5 files or terminals.  The run engine (:mod:`labcli.core.engine`) executes each
step and sends its result back into the generator, much as a bluesky plan
yields messages to its run engine::

    gen = force_session(protocol, plan)
    reply = None
    while True:
        step = gen.send(reply)          # SetupCheck(), Prompt(...), WaitSettle(...), ...
        reply = execute(step)           # what the step returns is listed on each class

Because steps are plain data, a test can drive a session with made-up replies
and check every prompt and every record without a rig.

Replies the engine sends back:

=================  ==========================================================
step               reply
=================  ==========================================================
``SetupCheck``     ``None``
``Prompt``         ``None`` (a quit ends the session inside the engine)
``AskLoad``        :class:`Load`, or ``None`` when the experimenter is done
``AskObject``      :class:`ObjectSpec`, or ``None`` when there are no more
``AskPush``        :class:`PushSpec`
``BeginTrial``     ``None``
``WaitSettle``     :class:`SettleReport`, or ``"redo"``
``Baseline``       :class:`Window`
``Capture``        :class:`Window`
``Review``         ``"accept"``, ``"redo"`` or ``"skip"`` (quit ends the session)
``Commit``         ``None``
``Finish``         ``None``
=================  ==========================================================
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from typing import Any, Generator, Iterable, Sequence

import numpy as np

G = 9.80665  # standard gravity, m/s^2 (table-formats.md)

PRESSURE_NAMES = ("P_L1", "P_R1", "P_L2", "P_R2")
POT_NAMES = ("POT1", "POT2")


# --------------------------------------------------------------------------- actions
# What the experimenter does at the rig.  The simulated rig can do each one
# itself (unattended mode); on a real rig they are only words in a prompt.


@dataclass(frozen=True)
class SupplyAir:
    pass


@dataclass(frozen=True)
class CloseValves:
    pass


@dataclass(frozen=True)
class HangWeight:
    mass_kg: float
    direction_rad: float


@dataclass(frozen=True)
class RemoveWeight:
    pass


@dataclass(frozen=True)
class PushObject:
    radius_m: float
    distance_m: float
    phi_rad: float | None  # None: the direction is not known to the experimenter
    stiffness_N_per_m: float | None = None  # simulated objects only


@dataclass(frozen=True)
class ReleaseObject:
    pass


Action = SupplyAir | CloseValves | HangWeight | RemoveWeight | PushObject | ReleaseObject


# --------------------------------------------------------------------------- steps


@dataclass(frozen=True)
class SetupCheck:
    """Handshake done; check channels against the protocol and live readings in range."""


@dataclass(frozen=True)
class Prompt:
    """Tell the experimenter what to do and wait for Enter."""

    text: str
    action: Action | None = None


@dataclass(frozen=True)
class AskLoad:
    """No plan: ask for the mass (g) and pulley direction (deg) of the next trial."""

    trial: int
    index: int
    total: int
    mass_range_g: tuple[float, float] = (1.0, 2000.0)
    direction_range_deg: tuple[float, float] = (-180.0, 180.0)


@dataclass(frozen=True)
class AskObject:
    """Push experiment: ask for the next object's name, radius and category."""

    index: int


@dataclass(frozen=True)
class AskPush:
    """Push experiment: ask for push distance (mm) and direction (deg or unknown)."""

    object: str
    index: int
    total: int
    distance_range_m: tuple[float, float] = (0.002, 0.020)


@dataclass(frozen=True)
class BeginTrial:
    """A trial (or push) starts: for the progress display and the engine's bookkeeping."""

    trial: int
    set: str
    index: int  # 1-based position in this session's schedule
    total: int
    label: str  # "Trial 12/108 (fit)"


@dataclass(frozen=True)
class WaitSettle:
    """Read until the joint is at equilibrium (``labcli.core.settle``)."""

    label: str  # "baseline" or "load"


@dataclass(frozen=True)
class Baseline:
    """Record the unloaded readings over ``capture_s`` seconds of device time."""

    capture_s: float


@dataclass(frozen=True)
class Capture:
    """Record the loaded readings over ``capture_s`` seconds of device time."""

    capture_s: float


@dataclass(frozen=True)
class Review:
    """Show the trial's summary row; the experimenter accepts, redoes, skips or quits."""

    row: dict


@dataclass(frozen=True)
class Commit:
    """Store one finished trial (or push) whole."""

    record: dict


@dataclass(frozen=True)
class Finish:
    """End of the schedule; ``split`` maps trial ids to "fit"/"validation" (None: no split)."""

    split: dict | None
    skipped: tuple[int, ...] = ()


Step = (
    SetupCheck | Prompt | AskLoad | AskObject | AskPush | BeginTrial | WaitSettle | Baseline
    | Capture | Review | Commit | Finish
)


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


@dataclass
class Window:
    """Raw samples of one capture window, as received, plus their SI values."""

    seq: np.ndarray  # (n,) int64
    t_us: np.ndarray  # (n,) int64, device clock as sent (wraps at 2**32)
    counts: np.ndarray  # (n, k) float64, values as sent
    si: np.ndarray  # (n, k) float64, MPa / rad per the protocol's calibration
    t_s: np.ndarray  # (n,) float64, unwrapped device time

    def __len__(self) -> int:
        return len(self.seq)

    def mean(self) -> np.ndarray:
        return self.si.mean(axis=0)

    def as_dict(self) -> dict[str, np.ndarray]:
        return {"seq": self.seq, "t_us": self.t_us, "counts": self.counts, "si": self.si, "t_s": self.t_s}


@dataclass(frozen=True)
class SettleReport:
    settled: bool  # False: timed out and accepted by the experimenter
    settle_time_s: float  # device time from the start of the wait to equilibrium
    waited_s: float  # device time spent waiting in all
    pressure_spread_MPa: float
    angle_spread_rad: float
    criterion: str

    def as_dict(self) -> dict[str, Any]:
        return {
            "settled": self.settled,
            "settle_time_s": self.settle_time_s,
            "waited_s": self.waited_s,
            "pressure_spread_MPa": self.pressure_spread_MPa,
            "angle_spread_rad": self.angle_spread_rad,
            "criterion": self.criterion,
        }


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


# --------------------------------------------------------------------------- sessions


def _pressurise() -> Generator[Step, Any, None]:
    """Setup check, air supply (held until the pressures settle), valves closed."""
    yield SetupCheck()
    while True:
        yield Prompt(SUPPLY_TEXT, SupplyAir())
        if (yield WaitSettle("air supply")) != "redo":
            break
    yield Prompt(CLOSE_TEXT, CloseValves())


def _load_limits(protocol: Any) -> tuple[tuple[float, float], tuple[float, float]]:
    """Typed-load limits from the protocol's [force] section (defaults: 1-2000 g, +-180 deg)."""
    force = getattr(protocol, "force_limits", None) or {}
    get = force.get if isinstance(force, dict) else lambda k, d: getattr(force, k, d)
    return (
        (float(get("mass_min_g", 1.0)), float(get("mass_max_g", 2000.0))),
        (float(get("direction_min_deg", -180.0)), float(get("direction_max_deg", 180.0))),
    )


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
    settling = protocol.settling
    capture_s = float(settling.capture_s)
    cmap = ChannelMap.from_channels(protocol.channels)
    done = set(int(t) for t in completed)
    rows = planned_trials(plan)
    if rows:
        total = len(rows)
        remaining = [r for r in rows if r.trial not in done]
    else:
        trials = getattr(protocol, "trials", None)
        total = target or (int(trials.fit) + int(trials.validation) if trials is not None else 0)
        remaining = []

    yield from _pressurise()

    skipped: list[int] = []
    position = 0
    while True:
        if rows:
            if position >= len(remaining):
                break
            planned = remaining[position]
            position += 1
            label = trial_label(planned.trial, total, planned.set)
        else:
            # Ids stay dense: a skipped trial's id is used by the next load.
            next_id = max(done, default=0) + 1
            shown_total = max(total, len(done) + 1)
            load = yield AskLoad(next_id, len(done) + 1, shown_total, *_load_limits(protocol))
            if load is None:
                break
            planned = PlannedTrial(next_id, "", load.mass_kg, load.direction_rad)
            label = trial_label(next_id, shown_total, "")
        yield BeginTrial(planned.trial, planned.set, len(done) + 1, total, label)
        while True:  # until accepted or skipped
            wait_b = yield WaitSettle("baseline")
            if wait_b == "redo":
                continue
            base = yield Baseline(capture_s)
            yield Prompt(load_prompt(label, planned.mass_kg, planned.direction_rad),
                         HangWeight(planned.mass_kg, planned.direction_rad))
            wait_l = yield WaitSettle("load")
            if wait_l == "redo":
                yield Prompt(remove_prompt(label), RemoveWeight())
                continue
            loaded = yield Capture(capture_s)
            yield Prompt(remove_prompt(label), RemoveWeight())
            record = force_record(planned.trial, planned.set, planned.mass_kg, planned.direction_rad,
                                  base, loaded, wait_b, wait_l, cmap, planned.plan_row)
            decision = yield Review(summary_row(record))
            if decision == "redo":
                continue
            if decision == "skip":
                skipped.append(planned.trial)
                break
            yield Commit(record)
            done.add(planned.trial)
            break

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
    settling = protocol.settling
    capture_s = float(settling.capture_s)
    cmap = ChannelMap.from_channels(protocol.channels)
    push_cfg = getattr(protocol, "push", None) or {}
    get = push_cfg.get if isinstance(push_cfg, dict) else lambda k, d: getattr(push_cfg, k, d)
    per_object = int(get("pushes_per_object", 10))
    d_range = (float(get("distance_min_m", 0.002)), float(get("distance_max_m", 0.020)))
    done = set(int(t) for t in completed)
    fixed = list(objects or [])
    total = sum(len(o.pushes) for o in fixed) if fixed else 0

    yield from _pressurise()

    skipped: list[int] = []
    next_id = 1
    index = 0
    while True:
        if fixed:
            if index >= len(fixed):
                break
            planned = fixed[index]
        else:
            spec = yield AskObject(index + 1)
            if spec is None:
                break
            planned = PlannedObject(spec)
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
            spec_k = planned.pushes[k - 1] if fixed else (yield AskPush(obj.name, k, n, d_range))
            while True:
                wait_b = yield WaitSettle("baseline")
                if wait_b == "redo":
                    continue
                base = yield Baseline(capture_s)
                yield Prompt(push_prompt(label, obj.name, spec_k.distance_m, spec_k.phi_rad),
                             PushObject(obj.radius_m, spec_k.distance_m, spec_k.phi_rad, obj.stiffness_N_per_m))
                wait_l = yield WaitSettle("load")
                if wait_l == "redo":
                    yield Prompt(release_prompt(label, obj.name), ReleaseObject())
                    continue
                loaded = yield Capture(capture_s)
                yield Prompt(release_prompt(label, obj.name), ReleaseObject())
                record = push_record(push_id, obj, spec_k, base, loaded, wait_b, wait_l, cmap)
                decision = yield Review(summary_row(record))
                if decision == "redo":
                    continue
                if decision == "skip":
                    skipped.append(push_id)
                    break
                yield Commit(record)
                done.add(push_id)
                break
    yield Finish(None, tuple(skipped))
