"""The run-time estimator on scripted sessions of the simulated rig (a short tests/benchmarks/sensing_online.py).

* on the ideal rig, a step load: the settled estimate is the model's own answer to the true
  pressures (the closed form the estimator must converge to);
* on the kind rig (realism=kind: friction at 0.5 %, leak, heat, backlash, link weight), a few loads: every one
  found, settled and released, no false event, settled errors as the offline protocol's on the
  same loads, intervals that hold the truth.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from labcli.core.protocol import load_protocol
from labcli.papers.takuma2014.sensing import TakumaSensing
from labcli.papers.takuma2014.sim import scenario as sc
from labcli.papers.takuma2014.sim.script import ScriptError, parse_script
from labcli.papers.takuma2014.sim.scripted import ScriptedRig
from labcli.sensing import LOAD, RELEASE, SETTLED, Estimate, Event
from labcli.sensing.scoring import score

QUANTITIES = ("theta1", "theta2", "Fx", "Fy")
# The kind rig: on the literature's rig (seed 3) a load's release is not found within half a second
# (the sleeves' friction leaves the arm short of its baseline) and pet-1 reads 249 N/m of its 420.
KIND = {"realism": "kind"}


@pytest.fixture(scope="module")
def protocol():
    return load_protocol("takuma2014")


@pytest.fixture(scope="module")
def model(protocol):
    """The model `labcli fit` would write for the kind rig of seed 3 (the shipped plan, 108 trials)."""
    return sc.calibrate(protocol, 3, KIND)


def script(loads, idle_s=60.0, hold_s=14.0, first_s=30.0):
    rows, t = [], first_s
    for mass_g, direction in loads:
        rows.append({"at_s": t, "hold_s": hold_s, "mass_g": mass_g, "direction_deg": direction})
        t += hold_s + 16.0
    idle = [{"from_s": t, "to_s": t + idle_s}]
    return parse_script({"air": {"supply_s": 0.0, "close_s": 6.0}, "load": rows, "idle": idle})


def test_on_the_ideal_rig_a_step_load_settles_on_the_models_answer_to_the_true_pressures(protocol):
    ideal = {"ideal": True}
    model = sc.calibrate(protocol, 4, ideal)
    sens = TakumaSensing(model)
    # 80 s of rest before the load: the baseline's slope is learnt well (it is extrapolated under the load).
    s = sc.run_session(model, protocol, script([(700.0, -30.0)], 1.0, 30.0, 90.0), 4, rig_options=ideal)
    ests = [i for i in s.items if isinstance(i, Estimate)]
    assert [e.kind for e in s.items if isinstance(e, Event)] == [LOAD, SETTLED, RELEASE]
    # The true pressures before and under the load (the rig's own, isothermal once settled).
    cal = protocol.calibration
    pc = [cal.index(n) for n in ("P_L1", "P_R1", "P_L2", "P_R2")]
    ac = [cal.index(n) for n in ("POT1", "POT2")]
    before = (s.t_s > 85.0) & (s.t_s <= 90.0)
    under = (s.t_s > 115.0) & (s.t_s <= 120.0)
    exact = sens.predict(
        s.si[before][:, pc].mean(axis=0)[None],
        s.si[under][:, pc].mean(axis=0)[None],
        s.si[before][:, ac].mean(axis=0)[None],
    )
    late = [e for e in ests if 115.0 < e.t_device_s <= 120.0]
    for j, q in enumerate(QUANTITIES):
        got = np.mean([e.values[q] for e in late])
        se = np.mean([e.se[q] for e in late])
        assert abs(got - exact.values[0, j]) < 0.5 * se, q
    truth = s.changes[0]
    assert math.hypot(*(late[-1].values[q] for q in ("Fx", "Fy"))) == pytest.approx(
        math.hypot(*truth["force_N"]), rel=0.05
    )


def test_on_the_kind_rig_loads_are_found_settled_and_released_as_the_offline_protocol_measures_them(protocol, model):
    seed = 3
    loads = [(800.0, -60.0), (400.0, 150.0), (1000.0, 30.0), (300.0, -120.0)]  # 3-10 N, away from the arm
    sess = sc.run_session(model, protocol, script(loads), seed, rig_options=KIND)
    changes = sc.true_changes(sess)
    result = score(sess.items, sess.truth_t, sess.truth, changes, QUANTITIES, idle=[(150.0, 210.0)])
    assert all(c.detected_s is not None and c.detected_s - c.on_s < 0.5 for c in result.changes)
    assert all(c.released_s is not None and c.released_s - c.off_s < 0.5 for c in result.changes)
    assert result.false_events == 0
    # The offline protocol's settling rule without the shipped hold of 12 s (a floor of five thermal
    # time constants): the scripted loads are held 14 s, as a person at the rig might.
    from dataclasses import replace

    quick = replace(protocol, settling=replace(protocol.settling, hold_s=2.0))
    offline = sc.offline_twin(TakumaSensing(model), quick, sess)
    for j, q in enumerate(QUANTITIES[:3]):  # Fy: unobservable on the upright arm, offline as online
        use = [(c, o) for c, o in zip(result.changes, offline, strict=True) if o and c.settled_sq is not None]
        online = math.sqrt(np.mean([c.settled_sq[j] for c, _ in use]))
        off = math.sqrt(np.mean([(o["values"][j] - o["truth"][j]) ** 2 for _, o in use]))
        slack = math.radians(0.05) if q.startswith("theta") else 0.05
        assert online <= 1.5 * off + slack, (q, online, off)
    # The intervals hold the truth about as often as the model's own hold the offline protocol's
    # (on the kind rig its angle errors run above their standard errors: tests/benchmarks/sensing_online.py).
    for q, least in (("theta1", 0.8), ("theta2", 0.8), ("Fx", 0.9)):
        assert least <= result.coverage[q] <= 1.0, (q, result.coverage[q])


def test_pushes_give_their_objects_stiffness_and_category_as_each_settles(protocol, model):
    from labcli.papers.takuma2014.pushes import PlannedPush, PushClassifier
    from labcli.papers.takuma2014.sim.objects import DEMO_OBJECTS

    objects = {o.name: o for o in DEMO_OBJECTS}
    # Soft and medium: the steel can deforms by 1.4 mm, where this arm's angle errors set its stiffness.
    plan = [("pet-1", 0.0), ("can-al-1", 15.0), ("pet-1", -15.0)]
    rows, t = [], 30.0
    for name, phi in plan:
        o = objects[name]
        rows.append(
            {"at_s": t, "hold_s": 15.0, "object": name, "radius_mm": o.radius_m * 1e3,
             "distance_mm": o.distance_m * 1e3, "phi_deg": phi, "stiffness_N_per_m": o.stiffness_N_per_m}
        )  # fmt: skip
        t += 35.0
    hook = PushClassifier.from_protocol(
        load_protocol("takuma2014-stiffness"),
        model,
        [PlannedPush(n, objects[n].radius_m, objects[n].distance_m, math.radians(phi)) for n, phi in plan],
    )
    push_script = parse_script({"air": {"supply_s": 0.0, "close_s": 6.0}, "push": rows})
    s = sc.run_session(model, protocol, push_script, 3, on_settled=hook, rig_options=KIND)
    pushes = [e for e in s.items if isinstance(e, Event) and e.kind == "push"]
    assert [p.data["object"] for p in pushes] == [n for n, _ in plan]  # one result per push, in order
    for p, (name, _) in zip(pushes, plan, strict=True):
        o = objects[name]
        assert p.data["category"] == o.category
        assert p.data["k_N_per_m"] == pytest.approx(o.stiffness_N_per_m, rel=0.35)
        assert p.t_device_s < rows[pushes.index(p)]["at_s"] + 15.0  # while the object is still pushed
    assert pushes[-1].data["object_category"] == "soft" and "object_k_median_N_per_m" in pushes[-1].as_json()


def test_with_the_friction_terms_the_live_estimates_are_what_predict_gives_the_same_loads(protocol):
    """A model fitted with the sleeves' friction terms on the literature's rig (15 s waits, as
    `labcli acquire` takes them) reads each load's motion into its baseline from the load before.
    Live, the estimator keeps that history; offline, the twin gives each load's windows to the
    model with the history ``labcli predict`` reads from a run's rows.  On the loads the estimator
    takes from a baseline of their own, the settled live estimates are the offline ones to a
    quarter of their standard errors (Fx: 0.06 N RMS of 0.52 N on this seed; 0.70 N with the
    history dropped)."""
    from dataclasses import replace

    opts = {"realism": "literature"}
    model = sc.calibrate(protocol, 3, opts, settle_s=15.0, friction=True)
    sens = TakumaSensing(model)
    assert sens.uses_history
    loads = [(800.0, -60.0), (400.0, 150.0), (1000.0, 30.0), (300.0, -120.0), (600.0, 100.0), (900.0, -150.0)]
    loads += [(700.0, 60.0), (500.0, -30.0)]
    sess = sc.run_session(model, protocol, script(loads, idle_s=20.0), 3, rig_options=opts)
    quick = replace(protocol, settling=replace(protocol.settling, hold_s=2.0))
    twin = sc.offline_twin(sens, quick, sess)
    blind = TakumaSensing(model)
    blind.uses_history = False  # the same windows, the history dropped
    twin_blind = sc.offline_twin(blind, quick, sess)
    ests = [i for i in sess.items if isinstance(i, Estimate) and i.state == "loaded"]
    released = [e.t_device_s for e in sess.items if isinstance(e, Event) and e.kind == RELEASE]
    live, off, off_blind, se = [], [], [], []
    for k, (c, o, ob) in enumerate(zip(sess.changes, twin, twin_blind, strict=True)):
        late = [e for e in ests if c["on_s"] < e.t_device_s <= c["off_s"]][-20:]
        # The first load has no history to read; a load the estimator took as one on top of the
        # last (its release not seen: on this rig a small load's may not show) has no baseline of its own.
        fresh = k > 0 and any(sess.changes[k - 1]["on_s"] < r < c["on_s"] for r in released)
        if o is None or len(late) < 10 or not fresh:
            continue
        live.append([np.mean([e.values[q] for e in late]) for q in QUANTITIES[:3]])
        se.append([np.mean([e.se[q] for e in late]) for q in QUANTITIES[:3]])
        off.append(o["values"][:3])
        off_blind.append(ob["values"][:3])
    live, off, off_blind, se = map(np.array, (live, off, off_blind, se))
    assert len(live) >= 3
    rms, sd = np.sqrt(np.mean((live - off) ** 2, axis=0)), np.mean(se, axis=0)
    rms_blind = np.sqrt(np.mean((live - off_blind) ** 2, axis=0))
    assert np.all(rms <= 0.25 * sd), (rms, sd)
    assert rms[2] <= 0.15, rms  # N
    assert rms_blind[2] > 4 * rms[2] and rms_blind[2] > 0.4, (rms_blind, rms)


def test_a_second_weight_on_the_same_hanger_hangs_their_sum_and_comes_off_on_its_own():
    # 200 g from 20 s to 50 s and 150 g on the same hanger from 30 s to 40 s: from 30 s the rig holds
    # 350 g (the force of one 350 g weight), from 40 s 200 g again; the truth keeps each weight's times.
    air = {"supply_s": 0.0, "close_s": 6.0}
    rows = [
        {"at_s": 20.0, "hold_s": 30.0, "mass_g": 200.0, "direction_deg": 10.0},
        {"at_s": 30.0, "hold_s": 10.0, "mass_g": 150.0, "direction_deg": 10.0},
    ]
    stacked = ScriptedRig(sc.build(1, KIND), parse_script({"air": air, "load": rows}))
    single = {
        m: ScriptedRig(sc.build(1, KIND), parse_script({"air": air, "load": [dict(rows[0], mass_g=m)]}))
        for m in (200.0, 350.0)
    }
    force = {}
    for t in (29.0, 39.0, 49.0):
        for name, rig in [("stacked", stacked)] + [(m, r) for m, r in single.items()]:
            rig.advance_to(t)
            force[name, t] = rig.truth_at(np.array([math.inf]))["force_N"][0]
    np.testing.assert_allclose(force["stacked", 29.0], force[200.0, 29.0], rtol=1e-9)
    np.testing.assert_allclose(force["stacked", 39.0], force[350.0, 39.0], rtol=1e-9)
    assert np.linalg.norm(force["stacked", 39.0]) > 1.5 * np.linalg.norm(force["stacked", 29.0])
    stacked.advance_to(60.0)
    assert [(c["on_s"], c["off_s"]) for c in stacked.changes] == [(20.0, 50.0), (30.0, 40.0)]


def test_weights_that_pull_different_ways_cannot_share_the_hanger():
    rows = [
        {"at_s": 20.0, "hold_s": 30.0, "mass_g": 200.0, "direction_deg": 10.0},
        {"at_s": 30.0, "hold_s": 10.0, "mass_g": 150.0, "direction_deg": 40.0},
    ]
    with pytest.raises(
        ScriptError,
        match=r"^The sim script s: the load at 30 s begins before the load at 20 s ends \(50 s\), and pulls another way \(stacked weights share one hanger\)\.$",
    ):
        parse_script({"load": rows}, "s")
