"""The acquisition protocol as plain steps (labcli.papers.takuma2014.session), recorded without a rig."""

from __future__ import annotations

import math

import numpy as np
import pytest

from labcli.core.protocol import load_protocol
from labcli.core.steps import (
    Ask,
    Baseline,
    BeginTrial,
    Capture,
    Commit,
    Finish,
    Prompt,
    Review,
    SettleReport,
    SetupCheck,
    Valves,
    WaitSettle,
    Window,
)
from labcli.papers.takuma2014.protocol import load_plan
from labcli.papers.takuma2014.push_session import PlannedObject, parse_push_change, push_session
from labcli.papers.takuma2014.session import (
    CloseValves,
    G,
    HangWeight,
    Load,
    ObjectSpec,
    PushObject,
    PushSpec,
    ReleaseObject,
    RemoveWeight,
    SupplyAir,
    force_session,
    parse_direction_deg,
    parse_length_mm,
    parse_mass_g,
)

PROTOCOL = load_protocol("takuma2014")
STIFFNESS = load_protocol("takuma2014-stiffness")
P_BASE = np.array([0.30, 0.31, 0.29, 0.32])  # MPa
POT_BASE = np.radians([1.0, -2.0])


PLAN = load_plan(PROTOCOL)


def plan():
    return PLAN


def window(p_mpa, pot_rad, n=20, t0=0.0):
    si = np.tile(np.concatenate([p_mpa, pot_rad]), (n, 1))
    counts = PROTOCOL.calibration.to_counts(si)
    t_s = t0 + np.arange(n) / 200.0
    return Window.of(np.arange(n, dtype=np.int64), counts, si, t_us=(t_s * 1e6).astype(np.int64), t_s=t_s)


SETTLED = SettleReport(True, 3.1, 3.1, 0.0004, 0.0002, "rule")


def drive(session, review=lambda step, n: "accept", loads=None, objects=None, changes=None):
    """Run a session as the engine would, with made-up readings; return the steps.

    ``changes`` maps a push prompt's label ("Push 2/10 of pet-1") to what the experimenter
    types at it instead of Enter (once)."""
    changes = dict(changes or {})
    steps = []
    reply = None
    current = None
    reviews: dict[int, int] = {}
    loaded_p = None
    while True:
        try:
            step = session.send(reply)
        except StopIteration:
            return steps
        steps.append(step)
        reply = None
        if isinstance(step, BeginTrial):
            current = step.trial
        elif isinstance(step, WaitSettle):
            reply = SETTLED
        elif isinstance(step, Baseline):
            reply = window(P_BASE, POT_BASE)
        elif isinstance(step, Prompt) and isinstance(step.action, (HangWeight, PushObject)):
            label = step.text.split(":")[0]
            if step.change is not None and label in changes:
                reply = step.change.parse(changes.pop(label))
                continue
            # A load raises the left pressures and bends the joints (made-up, but trial-specific).
            loaded_p = P_BASE + 0.001 * current * np.array([1, -1, 1, -1])
        elif isinstance(step, Capture):
            reply = window(loaded_p, POT_BASE + np.radians([0.01 * current, -0.02 * current]))
        elif isinstance(step, Review):
            reviews[current] = reviews.get(current, 0) + 1
            reply = review(step, reviews[current])
        elif isinstance(step, Ask):
            reply = answer(step, loads, objects)


def answer(step, loads, objects):
    """The experimenter's typed answers to an Ask, as the UI returns them (SI)."""
    asked = step.fields[0].key
    if asked == "end":  # an empty mass confirmed: the run ends
        return {"end": True}
    if asked == "mass_kg":
        load = loads.pop(0) if loads else None
        return None if load is None else {"mass_kg": load.mass_kg, "direction_rad": load.direction_rad}
    assert asked == "name"
    obj = objects.pop(0) if objects else None
    if obj is None:
        return None
    spec, push = obj
    return {
        "name": spec.name,
        "radius_m": spec.radius_m,
        "category": spec.category,
        "distance_m": push.distance_m,
        "phi_rad": push.phi_rad,
    }


def of(steps, kind):
    return [s for s in steps if isinstance(s, kind)]


def asks(steps, key):
    """The questions whose first field is ``key`` (mass_kg: a load, name: an object)."""
    return [s for s in of(steps, Ask) if s.fields[0].key == key]


def test_the_shipped_plan_as_steps():
    steps = drive(force_session(PROTOCOL, plan()))
    assert isinstance(steps[0], SetupCheck)
    # The board is asked to supply first; answered None (no valve control), the prompts ask for it.
    assert steps[1] == Valves("supply")
    assert steps[2] == Prompt("Supply compressed air to the four actuators, then press Enter", SupplyAir())
    # The valves close only once the supplied pressures have settled and been read (the supply check).
    assert steps[3] == WaitSettle("air supply")
    assert steps[4] == Baseline(1.0)
    assert steps[5] == Prompt("Close the valves so that the actuators are sealed, then press Enter", CloseValves())
    assert len(of(steps, Valves)) == 1  # never asked again: the prompts have the valves
    commits = of(steps, Commit)
    assert [c.record["trial"] for c in commits] == list(range(1, 109))
    assert len(of(steps, BeginTrial)) == 108
    prompts = [s.text for s in of(steps, Prompt)]
    # Trial 12 of the shipped plan: 200 g at -120 deg (protocols/takuma2014-plan.csv, row 12).
    assert "Trial 12/108 (fit): hang 200 g, pulley direction -120 deg, then press Enter" in prompts
    assert "Trial 12/108 (fit): remove the weight, then press Enter" in prompts
    assert prompts[-1] == "Trial 108/108 (validation): remove the weight, then press Enter"
    # Every trial runs the same sequence, in this order.
    first = steps.index(of(steps, BeginTrial)[11])
    kinds = [type(s).__name__ for s in steps[first : first + 10]]
    assert kinds == [
        "BeginTrial",
        "WaitSettle",
        "Baseline",
        "Prompt",
        "WaitSettle",
        "Capture",
        "Prompt",
        "Review",
        "Commit",
        "BeginTrial",
    ]
    hang = steps[first + 3].action
    assert steps[first + 6].action == RemoveWeight()
    assert hang == HangWeight(pytest.approx(0.2), pytest.approx(math.radians(-120)))
    finish = steps[-1]
    assert isinstance(finish, Finish) and finish.skipped == ()
    assert sorted(t for t, s in finish.split.items() if s == "fit") == list(range(1, 91))
    assert sorted(t for t, s in finish.split.items() if s == "validation") == list(range(91, 109))


def test_trial_record_holds_the_load_the_baseline_and_the_deflection():
    steps = drive(force_session(PROTOCOL, plan()))
    rec = of(steps, Commit)[11].record
    assert rec["trial"] == 12 and rec["set"] == "fit"
    w = 0.2 * G
    assert rec["force_N"] == pytest.approx([w * math.cos(math.radians(-120)), w * math.sin(math.radians(-120))])
    assert rec["force_N"][0] == pytest.approx(-0.980665)
    assert rec["P0_MPa"] == pytest.approx(P_BASE)
    assert rec["P_MPa"] == pytest.approx(P_BASE + 0.012 * np.array([1, -1, 1, -1]))
    # Deflection is the potentiometer now minus the trial's own baseline, not the absolute angle.
    assert rec["theta_rad"] == pytest.approx(np.radians([0.12, -0.24]))
    assert rec["pot0_rad"] == pytest.approx(POT_BASE)
    assert rec["plan"] == {"set": "fit", "mass_g": 200.0, "direction_deg": -120.0}
    assert set(rec["raw"]) == {"baseline", "load"}
    assert rec["raw"]["load"].counts.shape == (20, 6)
    assert rec["settle"]["load"]["settle_time_s"] == 3.1


def test_resume_starts_at_the_first_trial_not_complete():
    done = list(range(1, 12)) + [15]
    steps = drive(force_session(PROTOCOL, plan(), completed=done))
    begins = of(steps, BeginTrial)
    assert begins[0].trial == 12 and begins[0].index == 13 and begins[0].label == "Trial 12/108 (fit)"
    assert 15 not in [b.trial for b in begins]
    assert len(of(steps, Commit)) == 108 - 12
    # The split at the end covers the stored trials as well as the new ones.
    assert len(steps[-1].split) == 108


def test_redo_repeats_the_trial_and_skip_leaves_it_out():
    def review(step, n):
        if step.row["trial"] == "3" and n == 1:
            return "redo"
        if step.row["trial"] == "5":
            return "skip"
        return "accept"

    steps = drive(force_session(PROTOCOL, plan()), review=review)
    ids = [c.record["trial"] for c in of(steps, Commit)]
    assert ids.count(3) == 1 and 5 not in ids and len(ids) == 107
    hangs_3 = [s for s in of(steps, Prompt) if s.text.startswith("Trial 3/108 (fit): hang")]
    assert len(hangs_3) == 2
    assert steps[-1].skipped == (5,)
    assert 5 not in steps[-1].split


def test_without_a_plan_the_experimenter_types_each_load():
    loads = [Load(0.15, math.radians(30)), Load(0.5, math.radians(-45))]
    steps = drive(force_session(PROTOCOL, None), loads=loads)
    loads_asked = asks(steps, "mass_kg")
    assert [a.fields[0].prompt.split(":")[0] for a in loads_asked] == ["Trial 1/108", "Trial 2/108", "Trial 3/108"]
    # The protocol's limits for typed loads, in the prompts and in the parsers.
    mass, direction = loads_asked[0].fields
    assert "1 to 2000 (Enter when the run is complete" in mass.prompt and mass.stop_if_empty
    assert "(-180 to 180, whole turns wrap)" in direction.prompt
    with pytest.raises(ValueError, match="from 1 g to 2000 g"):
        mass.parse("2500")
    assert direction.parse("-45") == pytest.approx(math.radians(-45))
    prompts = [s.text for s in of(steps, Prompt)]
    offer = " (or type another mass in g and direction in deg, e.g. 300 90)"
    assert "Trial 1/108: hang 150 g, pulley direction 30 deg, then press Enter" + offer in prompts
    assert "Trial 2/108: hang 500 g, pulley direction -45 deg, then press Enter" + offer in prompts
    # The empty third answer is confirmed before the run ends.
    assert asks(steps, "end")[0].fields[0].prompt == "End the run here with 2 trials stored? y ends it, Enter goes on:"
    recs = [c.record for c in of(steps, Commit)]
    assert [r["trial"] for r in recs] == [1, 2] and recs[0]["set"] == ""
    assert recs[1]["force_N"] == pytest.approx([0.5 * G / math.sqrt(2), -0.5 * G / math.sqrt(2)])
    assert steps[-1].split is None


def test_typed_values_are_checked_with_units_in_the_message():
    assert parse_mass_g("200") == pytest.approx(0.2)
    assert parse_mass_g("200 g") == pytest.approx(0.2)
    assert parse_mass_g("0.25 kg") == pytest.approx(0.25)
    with pytest.raises(ValueError, match=r"^The mass must be from 1 g to 2000 g, got -5 g\.$"):
        parse_mass_g("-5")
    with pytest.raises(ValueError, match=r"^'heavy' is not a mass: type a number of grams, e\.g\. 200 g\.$"):
        parse_mass_g("heavy")
    assert parse_direction_deg("45 deg") == pytest.approx(math.pi / 4)
    assert parse_direction_deg("270") == pytest.approx(-math.pi / 2)  # directions wrap
    with pytest.raises(
        ValueError, match=r"^'up' is not a direction: type degrees counter-clockwise from \+x, e\.g\. 45 deg\.$"
    ):
        parse_direction_deg("up")
    assert parse_direction_deg("?", allow_unknown=True) is None
    assert parse_length_mm("10", "push distance", 2, 20) == pytest.approx(0.010)
    with pytest.raises(ValueError, match=r"^The push distance must be from 2 mm to 20 mm, got 25 mm\.$"):
        parse_length_mm("25 mm", "push distance", 2, 20)


def test_push_session_asks_per_object_what_is_per_object_and_per_push_only_a_change():
    objects = [(ObjectSpec("pet-1", 0.033, "soft"), PushSpec(0.010, math.radians(30)))]
    steps = drive(push_session(STIFFNESS), objects=objects, changes={"Push 2/10 of pet-1": "5 ?"})
    prompts = [s.text for s in of(steps, Prompt)]
    offer = " (or type another distance in mm and direction in deg, e.g. 12 30)"
    assert "Push 1/10 of pet-1: push pet-1 by 10 mm along 30 deg, then press Enter" + offer in prompts
    # Typed at push 2 instead of Enter: that push is announced again with the new values ...
    assert prompts.count("Push 2/10 of pet-1: push pet-1 by 10 mm along 30 deg, then press Enter" + offer) == 1
    assert "Push 2/10 of pet-1: push pet-1 by 5 mm along an unknown direction, then press Enter" + offer in prompts
    # ... and the next push keeps the object's own.
    assert "Push 3/10 of pet-1: push pet-1 by 10 mm along 30 deg, then press Enter" + offer in prompts
    assert "Push 10/10 of pet-1: move pet-1 back until it just touches the contact point, then press Enter" in prompts
    obj_asked = asks(steps, "name")
    assert len(obj_asked) == 2  # the second answer (none) ends the session
    assert [f.key for f in obj_asked[0].fields] == [
        "name",
        "radius_m",
        "category",
        "distance_m",
        "phi_rad",
        "stiffness_N_per_m",
    ]
    d_field = obj_asked[0].fields[3]
    assert d_field.prompt({"name": "pet-1"}) == "pet-1: push distance d in mm for its pushes, 2 to 20:"
    assert not d_field.has_default  # the first object has no distance to keep
    # The next object offers this one's distance and direction as the defaults.
    second = obj_asked[1].fields
    assert second[3].default == pytest.approx(0.010) and second[4].default == pytest.approx(math.radians(30))
    assert second[4].prompt({"name": "can"}).endswith("(? if unknown; Enter keeps 30 deg):")
    recs = [c.record for c in of(steps, Commit)]
    assert [r["push"] for r in recs] == list(range(1, 11))
    assert recs[0]["R_m"] == 0.033 and recs[0]["category"] == "soft"
    assert recs[0]["phi_rad"] == pytest.approx(math.radians(30)) and math.isnan(recs[1]["phi_rad"])
    assert recs[1]["d_m"] == pytest.approx(0.005) and recs[2]["d_m"] == pytest.approx(0.010)
    assert "true_stiffness_N_per_m" not in recs[0]


def test_a_typed_push_change_is_checked():
    assert parse_push_change("12", math.radians(30), (0.002, 0.02)) == PushSpec(
        pytest.approx(0.012), pytest.approx(math.radians(30))
    )
    assert parse_push_change("12 mm -45 deg", None, (0.002, 0.02)) == PushSpec(
        pytest.approx(0.012), pytest.approx(math.radians(-45))
    )
    assert parse_push_change("8 ?", 0.5, (0.002, 0.02)) == PushSpec(pytest.approx(0.008), None)
    with pytest.raises(ValueError, match=r"^The push distance must be from 2 mm to 20 mm, got 25 mm\.$"):
        parse_push_change("25 0", None, (0.002, 0.02))
    with pytest.raises(ValueError, match=r"^'1 2 3' is not a push: type the distance in mm and the direction"):
        parse_push_change("1 2 3", None, (0.002, 0.02))


def test_push_session_with_a_fixed_schedule_resumes_by_push_id():
    objs = [
        PlannedObject(ObjectSpec("pet-1", 0.033, "soft", 300.0), tuple(PushSpec(0.01, 0.0) for _ in range(10))),
        PlannedObject(ObjectSpec("can-steel-1", 0.033, "hard", 5000.0), tuple(PushSpec(0.004, 0.1) for _ in range(10))),
    ]
    steps = drive(push_session(STIFFNESS, objs, completed=range(1, 14)))
    recs = [c.record for c in of(steps, Commit)]
    assert [r["push"] for r in recs] == list(range(14, 21))
    assert all(r["object"] == "can-steel-1" and r["true_stiffness_N_per_m"] == 5000.0 for r in recs)
    acts = [s.action for s in of(steps, Prompt)]
    assert PushObject(0.033, 0.004, 0.1, 5000.0) in acts and ReleaseObject() in acts
    assert of(steps, BeginTrial)[0].label == "Push 4/10 of can-steel-1"


def test_n_captures_of_each_load_as_steps_and_a_resume_takes_only_the_captures_missing():
    """No rig: the session's steps alone.  Three captures a load, each its own trial (id (load - 1) 3 +
    capture) hung, captured and committed; a session resumed with captures 1, 2 and 4 stored takes 3, 5, 6."""
    from labcli.core.protocol import with_captures

    three = with_captures(PROTOCOL, 3)
    two_loads = PLAN.iloc[:2]
    steps = drive(force_session(three, two_loads))
    begun = of(steps, BeginTrial)
    assert [b.trial for b in begun] == [1, 2, 3, 4, 5, 6]
    assert [b.label for b in begun[:4]] == [
        "Trial 1/2 (fit), capture 1/3",
        "Trial 1/2 (fit), capture 2/3",
        "Trial 1/2 (fit), capture 3/3",
        "Trial 2/2 (fit), capture 1/3",
    ]
    hung = [s.action.mass_kg for s in of(steps, Prompt) if isinstance(s.action, HangWeight)]
    masses = two_loads["mass_g"].to_numpy() * 1e-3
    assert hung == pytest.approx(np.repeat(masses, 3))
    commits = [s.record for s in of(steps, Commit)]
    assert [r["trial"] for r in commits] == [1, 2, 3, 4, 5, 6]
    assert [r["mass_kg"] for r in commits] == pytest.approx(np.repeat(masses, 3))
    assert of(steps, Finish)[0].split == {t: "fit" for t in range(1, 7)}
    # The progress bar counts captures, as its total does, beside a label counting trials (loads).
    from labcli.core.ui import progress_text

    shown = progress_text(begun[4], 4, 60.0, None)
    assert shown.startswith("Trial 2/2 (fit), capture 2/3  [################--------] 4/6 captures done (4 stored ")
    # Each capture's review row names its plan trial and capture as the prompts do, not its record id.
    rows = [(r.row["trial"], r.row["capture"], r.row["set"]) for r in of(steps, Review)]
    assert rows == [(str(t), f"{c}/3", "fit") for t in (1, 2) for c in (1, 2, 3)]
    assert list(of(steps, Review)[0].row)[:3] == ["trial", "capture", "set"]
    resumed = drive(force_session(three, two_loads, completed=[1, 2, 4]))
    assert [r.record["trial"] for r in of(resumed, Commit)] == [3, 5, 6]
    assert [b.label for b in of(resumed, BeginTrial)] == [
        "Trial 1/2 (fit), capture 3/3",
        "Trial 2/2 (fit), capture 2/3",
        "Trial 2/2 (fit), capture 3/3",
    ]
    # One capture a load: the plan's own ids and labels, as before.
    once = drive(force_session(PROTOCOL, two_loads))
    assert [(b.trial, b.label, b.total) for b in of(once, BeginTrial)] == [
        (1, "Trial 1/2 (fit)", 2),
        (2, "Trial 2/2 (fit)", 2),
    ]
    assert [r.row["trial"] for r in of(once, Review)] == ["1", "2"] and "capture" not in of(once, Review)[0].row
    assert " [------------------------] 0/2 done (0 stored " in progress_text(of(once, BeginTrial)[0], 0, 0.0, None)
