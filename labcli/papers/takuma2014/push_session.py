"""The stiffness experiment of Section 4 as a session of plain steps: objects pushed into the tip.

Per object the experimenter says once what belongs to the object: its name, radius R,
category, and the push distance d and direction phi its pushes use; each push then asks
only for Enter, which does the push as announced, or for a new distance and direction
typed instead ("12 30": 12 mm along 30 deg), which the push then uses::

    Push 3/10 of pet-1: push pet-1 by 10 mm along 0 deg, then press Enter (or type another
    distance in mm and direction in deg, e.g. 12 30) (q to quit):

So a push takes three answers (the push, the release, the review), and an object of ten
pushes 35.  A push plan (:mod:`labcli.papers.takuma2014.push_plan`) fixes every push in
advance, as the trial plan does for the force trials; so do the simulated objects of an
unattended run.
"""

from __future__ import annotations

import re
from collections.abc import Generator, Iterable, Sequence
from dataclasses import dataclass, replace
from functools import partial
from typing import Any

from ...core.air import AirDrift
from ...core.guard import Guard
from ...core.steps import Ask, BeginTrial, Field, Finish, Prompt, SettleReport, Step, Window
from .records import PushRecord
from .session import (
    ChannelMap,
    Checked,
    ObjectSpec,
    PushObject,
    PushSpec,
    ReleaseObject,
    _pressurise,
    _trial,
    fmt_deg,
    parse_direction_deg,
    parse_length_mm,
    session_guard,
)


@dataclass(frozen=True)
class PlannedObject:
    """An object to push, with its pushes when they are known in advance (a plan, simulated runs)."""

    spec: ObjectSpec
    pushes: tuple[PushSpec, ...] = ()


# --------------------------------------------------------------------------- text


def push_prompt(label: str, name: str, distance_m: float, phi_rad: float | None) -> str:
    along = "along an unknown direction" if phi_rad is None else f"along {fmt_deg(phi_rad)}"
    return f"{label}: push {name} by {distance_m * 1e3:.4g} mm {along}, then press Enter"


CHANGE_OFFER = " (or type another distance in mm and direction in deg, e.g. 12 30)"


def release_prompt(label: str, name: str) -> str:
    return f"{label}: move {name} back until it just touches the contact point, then press Enter"


# --------------------------------------------------------------------------- typed input


def parse_stiffness(text: str) -> float:
    """Parse a typed stiffness in N/m ("800", "800 N/m")."""
    try:
        value = float(text.strip().removesuffix("N/m").strip())
    except ValueError:
        raise ValueError(f"'{text.strip()}' is not a stiffness: type newtons per metre, e.g. 800.") from None
    if not 0 < value < float("inf"):
        raise ValueError(f"The stiffness must be more than 0 N/m, got {value:g} N/m.")
    return value


def parse_push_change(text: str, keep_phi: float | None, distance_range_m: tuple[float, float]) -> PushSpec:
    """A push typed instead of Enter: ``D`` (mm, the direction kept) or ``D PHI`` (deg, ``?`` unknown)."""
    lo, hi = (v * 1e3 for v in distance_range_m)
    m = re.fullmatch(r"\s*(\S+?)\s*(?:mm)?(?:\s+(\S+?)\s*(?:deg)?)?\s*", text)
    if not m:
        raise ValueError(
            f"'{text.strip()}' is not a push: type the distance in mm and the direction in deg, "
            "e.g. 12 30, or press Enter."
        )
    distance = parse_length_mm(m.group(1), "push distance", lo, hi)
    phi = keep_phi if m.group(2) is None else parse_direction_deg(m.group(2), allow_unknown=True)
    return PushSpec(distance, phi)


def ask_object(index: int, distance_range_m: tuple[float, float], last: PushSpec | None) -> Ask:
    """The next object: name (Enter ends the run), radius, category, and its pushes' distance and
    direction (Enter keeps the last object's)."""
    lo, hi = (v * 1e3 for v in distance_range_m)
    d_keep = "" if last is None else f"; Enter keeps {last.distance_m * 1e3:.4g}"
    phi_keep = "unknown" if last is None or last.phi_rad is None else fmt_deg(last.phi_rad)
    return Ask(
        (
            Field(
                "name",
                f"Object {index}: name (e.g. pet-1; Enter when all objects are done, q to quit):",
                stop_if_empty=True,
            ),
            Field(
                "radius_m",
                lambda a: f"{a['name']}: radius R in mm:",
                partial(parse_length_mm, what="radius", lo_mm=0.0, hi_mm=500.0),
            ),
            Field("category", lambda a: f"{a['name']}: category (soft, medium, hard, a name, or Enter if unknown):"),
            Field(
                "distance_m",
                lambda a: f"{a['name']}: push distance d in mm for its pushes, {lo:g} to {hi:g}{d_keep}:",
                partial(parse_length_mm, what="push distance", lo_mm=lo, hi_mm=hi),
                **({} if last is None else {"default": last.distance_m}),  # type: ignore[arg-type]
            ),
            Field(
                "phi_rad",
                lambda a: (
                    f"{a['name']}: push direction phi in deg for its pushes (? if unknown; Enter keeps {phi_keep}):"
                ),
                partial(parse_direction_deg, allow_unknown=True),
                default=None if last is None else last.phi_rad,
            ),
            Field(
                "stiffness_N_per_m",
                lambda a: f"{a['name']}: stiffness of the simulated object in N/m:",
                parse_stiffness,
                simulated_only=True,
            ),
        )
    )


# --------------------------------------------------------------------------- records


def push_record(
    push: int,
    obj: ObjectSpec,
    spec: PushSpec,
    baseline: Window,
    loaded: Window,
    settle_baseline: SettleReport,
    settle_load: SettleReport,
    cmap: ChannelMap,
) -> PushRecord:
    """One push of the stiffness experiment (Section 4), SI, with both raw windows."""
    b = baseline.mean()
    m = loaded.mean()
    record: PushRecord = {
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
        "raw": {"baseline": baseline, "load": loaded},
    }
    if obj.stiffness_N_per_m is not None:
        record["true_stiffness_N_per_m"] = float(obj.stiffness_N_per_m)
    return record


# --------------------------------------------------------------------------- session


@dataclass
class _Pushing:
    """What every push of a session shares: windows, channels, distance limits, the checks."""

    capture_s: float
    cmap: ChannelMap
    d_range: tuple[float, float]
    guard: Guard
    air: AirDrift | None = None  # a board that drives its valves: re-pressurise on drift


def _push(
    ctx: _Pushing, push_id: int, label: str, obj: ObjectSpec, spec: PushSpec, changeable: bool
) -> Generator[Step, Any, bool]:
    """One push until stored (True) or skipped (False); a changeable push's prompt takes a new
    distance and direction typed instead of Enter, and the push starts again with them."""
    while True:
        act = PushObject(obj.radius_m, spec.distance_m, spec.phi_rad, obj.stiffness_N_per_m)
        text = push_prompt(label, obj.name, spec.distance_m, spec.phi_rad)
        change = None
        if changeable:
            change = Field(
                "push",
                "",
                partial(parse_push_change, keep_phi=spec.phi_rad, distance_range_m=ctx.d_range),
                again=f"{text} (or type another distance in mm and direction in deg) (q to quit):",
            )
            text += CHANGE_OFFER
        release = Prompt(release_prompt(label, obj.name), ReleaseObject())
        result = yield from _trial(
            ctx.capture_s,
            Prompt(text, act, change),
            release,
            lambda base, loaded, wait_b, wait_l, s=spec: push_record(
                push_id, obj, s, base, loaded, wait_b, wait_l, ctx.cmap
            ),
            Checked(
                ctx.guard,
                (spec.distance_m,),
                (obj.name, spec.phi_rad),
                release,
                f"{obj.name} may still press on the tip",
            ),
            ctx.air,
        )
        if isinstance(result, bool):
            return result
        spec = result


def push_session(
    protocol: Any,
    objects: Sequence[PlannedObject] | None = None,
    *,
    completed: Iterable[int] = (),
    ids: Sequence[int] | None = None,
) -> Generator[Step, Any, None]:
    """The stiffness experiment of Section 4: per object, ``pushes_per_object`` pushes.

    With ``objects`` (each with its pushes: a plan, or the simulated objects) the schedule
    is fixed and its pushes get the ``ids`` (a plan's; default 1, 2, ... through the
    schedule), so a resumed run skips the ones already stored; without, the experimenter
    names each object and its pushes' distance and direction once, and confirms each push
    with Enter.
    """
    push = protocol.settings.push
    per_object = push.pushes_per_object if push is not None else 10
    ctx = _Pushing(
        float(protocol.settling.capture_s),
        ChannelMap.from_channels(protocol.channels),
        (push.distance_min_m, push.distance_max_m) if push is not None else (0.002, 0.020),
        session_guard(protocol),
    )
    done = set(int(t) for t in completed)
    fixed = list(objects or [])
    total = sum(len(o.pushes) for o in fixed) if fixed else 0

    air = yield from _pressurise(protocol)
    ctx = replace(ctx, air=air)

    skipped: list[int] = []
    next_id = 1
    index = 0
    last: PushSpec | None = None
    while not fixed or index < len(fixed):
        if fixed:
            planned = fixed[index]
        else:
            answer = yield ask_object(index + 1, ctx.d_range, last)
            if answer is None:
                break
            last = PushSpec(answer["distance_m"], answer["phi_rad"])
            planned = PlannedObject(
                ObjectSpec(answer["name"], answer["radius_m"], answer["category"], answer.get("stiffness_N_per_m")),
                (last,) * per_object,
            )
            next_id = max(done, default=0) + 1
        index += 1
        obj = planned.spec
        n = len(planned.pushes)
        for k in range(1, n + 1):
            push_id = ids[next_id - 1] if fixed and ids is not None else next_id
            next_id += 1
            if push_id in done:
                continue
            label = f"Push {k}/{n} of {obj.name}"
            yield BeginTrial(push_id, "", len(done) + 1, total or per_object * index, label)
            stored = yield from _push(ctx, push_id, label, obj, planned.pushes[k - 1], changeable=not fixed)
            (done.add if stored else skipped.append)(push_id)
    yield Finish(None, tuple(skipped))
