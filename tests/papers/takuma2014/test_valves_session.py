"""The session and the board's valves, through the real serial code path on ``sim://``.

A 1.1 board with valves is supplied and held by command and its held chambers are checked for
a leak before the first trial; its chambers are supplied again when a baseline drifts past the
protocol's limit; the session leaves it holding (or venting) however it ends.  A 1.0 board gets
the prompts.  Valves left open are caught at the first load, with and without valve control.
"""

from __future__ import annotations

import io
from pathlib import Path

import numpy as np
import pytest
from rich.console import Console

from labcli.core.device import Device
from labcli.core.engine import RunEngine
from labcli.core.protocol import load_protocol
from labcli.core.simoperator import operator_for
from labcli.core.steps import Hold, HoldReport, Note, Prompt, Valves, WaitSettle
from labcli.core.store import RunFile
from labcli.core.ui import UnattendedUI
from labcli.errors import DeviceError
from labcli.papers.takuma2014.records import load_trials
from labcli.papers.takuma2014.session import CLOSE_TEXT, SUPPLY_TEXT, force_session
from labcli.papers.takuma2014.tables import load_plan

PROTOCOL = load_protocol("takuma2014")
LOADS = [(800, 0), (500, 180), (800, 45), (300, -135), (1000, 0), (500, 135)]  # g, deg


def protocol_with(tmp_path: Path, **acquisition: object):
    lines = "".join(f"{k} = {v!r}\n".replace("'", '"') for k, v in acquisition.items())
    path = tmp_path / f"p{len(list(tmp_path.iterdir()))}.toml"
    path.write_text(PROTOCOL.text.replace("rate_hz = 200.0\n", f"rate_hz = 200.0\n{lines}"))
    return load_protocol(str(path))


class Person(UnattendedUI):
    """Answers as a person who reads the review: Enter (the default), and a fix when it warns."""

    def __init__(self, fix=None) -> None:
        super().__init__(console=Console(file=io.StringIO(), width=300))
        self.fix = fix
        self.reviews: list[tuple[tuple[str, ...], str]] = []

    dev: Device | None = None

    def review(self, row, warnings=(), default="accept"):
        self.reviews.append((tuple(warnings), default))
        if warnings and self.fix is not None:
            self.fix(self.dev)
        return default


def run(tmp_path: Path, url: str, *, protocol=PROTOCOL, loads=LOADS, ui=None, watch=None):
    """(outcome, the steps and their replies, the device still open, the run's path)."""
    plan_csv = tmp_path / f"plan{len(list(tmp_path.iterdir()))}.csv"
    plan_csv.write_text(
        "trial,set,mass_g,direction_deg\n" + "".join(f"{i},fit,{m},{d}\n" for i, (m, d) in enumerate(loads, 1))
    )
    plan, run_path = load_plan(plan_csv), tmp_path / f"run{len(list(tmp_path.iterdir()))}.h5"
    dev = Device.open(url)
    ui = ui or Person()
    ui.dev = dev
    store = RunFile.create(run_path, protocol=protocol, device_info=dev.info, port=url, plan=plan)
    engine = RunEngine(
        dev,
        store,
        protocol,
        ui,
        run_path=str(run_path),
        resume_command="labcli acquire --resume",
        simulated_operator=operator_for(dev),
    )
    seen: list = []
    engine.subscribe(lambda step, reply: seen.append((step, reply)))
    if watch is not None:
        engine.subscribe(watch)
    try:
        outcome = engine.run(force_session(protocol, plan))
    finally:
        store.close()
    return outcome, seen, dev, run_path


def test_a_board_with_valves_is_supplied_held_and_checked_by_command(tmp_path):
    # The kind rig: on the literature's a baseline moves past the 3.1 kPa limit within three trials,
    # and the chambers are supplied again.
    outcome, seen, dev, path = run(tmp_path, "sim://?seed=11&clock=virtual&realism=kind", loads=LOADS[:3])
    try:
        assert outcome.status == "finished" and outcome.stored == 3
        valves = [(s.state, r) for s, r in seen if isinstance(s, Valves)]
        assert [v for v, _ in valves] == ["supply", "hold"]  # no drift past 3.1 kPa in three trials
        assert valves[1][1] == {c: "hold" for c in ("P_L1", "P_R1", "P_L2", "P_R2")}
        assert not any(isinstance(s, Prompt) and s.text in (SUPPLY_TEXT, CLOSE_TEXT) for s, _ in seen)
        (hold,) = [r for s, r in seen if isinstance(s, Hold)]
        assert isinstance(hold, HoldReport) and hold.duration_s == 5.0 and hold.frames == pytest.approx(1000, abs=2)
        leak = hold.slope_per_s[:4] * 60e3  # kPa/min: the simulated rig's leak, about 1 kPa/min
        # The rig's own: each chamber loses its seeded share of its absolute pressure a minute.
        from labcli.papers.takuma2014.sim import nonideal as ni
        from labcli.papers.takuma2014.sim.physics import P_ATM

        given = (hold.mean[:4] * 1e6 + P_ATM) * ni.leak_factors(11, 1.0) * 60 / 1e3
        # What is left of the arm's settling on the closed chambers moves the slope by up to half a
        # kPa/min either way (seen +0.44 with a 5 s settle, -0.29 with the shipped 15 s one).
        assert np.all(np.abs(-leak - given) < 0.5), (leak, given)
        # The board said so on the wire, and holds at the end (the protocol's end_valves).
        events = [(e.kind, tuple(e.fields)) for e in dev.take_events()]
        assert ("VALVE", ("SSSS", "host")) in events and ("VALVE", ("HHHH", "host")) in events
        assert dev.valve_states() == {c: "hold" for c in ("P_L1", "P_R1", "P_L2", "P_R2")}
        assert dev.rig.true_state()["valves"] == "closed"
    finally:
        dev.close()


def test_a_v1_board_gets_the_prompts(tmp_path):
    outcome, seen, dev, _ = run(tmp_path, "sim://?seed=11&clock=virtual&fw=1.0", loads=LOADS[:1])
    dev.close()
    assert outcome.status == "finished"
    assert [r for s, r in seen if isinstance(s, Valves)] == [None]  # asked once, the prompts follow
    texts = [s.text for s, _ in seen if isinstance(s, Prompt)]
    assert texts[:2] == [SUPPLY_TEXT, CLOSE_TEXT]
    assert not any(isinstance(s, Hold) for s, _ in seen)


def test_valves_hand_keeps_the_prompts_on_a_board_with_valves(tmp_path):
    outcome, seen, dev, _ = run(
        tmp_path, "sim://?seed=11&clock=virtual", protocol=protocol_with(tmp_path, valves="hand"), loads=LOADS[:1]
    )
    dev.close()
    assert [r for s, r in seen if isinstance(s, Valves)] == [None]
    assert [s.text for s, _ in seen if isinstance(s, Prompt)][:2] == [SUPPLY_TEXT, CLOSE_TEXT]


def test_a_leak_is_named_before_the_first_trial_and_nothing_is_stored(tmp_path):
    with pytest.raises(DeviceError) as e:
        run(tmp_path, "sim://?seed=11&clock=virtual&leak=30", loads=LOADS[:1])
    text = str(e.value)
    assert text.startswith("The hold check found P_")
    assert "kPa/min with" in text and "a leak; check" in text
    assert "(the protocol allows 5 kPa/min: acquisition.leak_max_kPa_per_min); the 0 completed trials in " in text
    (path,) = tmp_path.glob("run*.h5")
    assert load_trials(path).empty


@pytest.mark.parametrize("fw", ["1.0", "1.1"])
def test_valves_left_open_are_caught_at_the_first_load_and_redone(tmp_path, fw):
    url = f"sim://?seed=11&clock=virtual&fw={fw}&valves=open"

    def close_them(dev):
        dev.rig.valves_open = False  # the experimenter closes them (or frees the stuck valve)
        if fw == "1.1":
            dev.rig.set_valves(("hold",) * 4)
        else:
            dev.rig.close_valves()

    person = Person(fix=close_them)
    outcome, seen, dev, path = run(tmp_path, url, loads=LOADS[:2], ui=person)
    dev.close()
    assert outcome.status == "finished" and outcome.stored == 2
    first, *rest = person.reviews
    (warning,) = first[0]
    assert first[1] == "redo"
    assert warning.startswith("The pressures did not respond to the load (P_")
    assert "sealed chambers would have followed the load, so a valve is open: close the valves so that the " in warning
    assert all(not w for w, _ in rest)  # the redone trial and the next load: the chambers follow the load
    df = load_trials(path)
    dP = (df[["P_L1", "P_R1", "P_L2", "P_R2"]].to_numpy() - df[["P_L10", "P_R10", "P_L20", "P_R20"]].to_numpy()) * 1e3
    assert np.abs(dP).max(axis=1).min() > 2.0  # kPa: every stored trial has a pressure response


def baseline_drift_kPa(path: Path) -> float:
    """The largest move of any chamber's stored baseline from the first trial's, kPa."""
    P0 = load_trials(path)[["P_L10", "P_R10", "P_L20", "P_R20"]].to_numpy()
    return float(np.abs(P0 - P0[0]).max() * 1e3)


def test_the_chambers_are_supplied_again_when_the_baseline_drifts_past_the_limit(tmp_path):
    # A leak twice the typical over eighteen trials (about four minutes of the rig's time).
    loads = LOADS * 3
    # The kind rig: on the literature's the stored baselines still spread by 4.0 kPa with the supply
    # (moves that a supply does not undo), past the limit asserted below.
    url = "sim://?seed=11&clock=virtual&leak=2&realism=kind"
    outcome, seen, dev, path = run(tmp_path, url, loads=loads)
    dev.close()
    assert outcome.status == "finished" and outcome.stored == 18
    notes = [s.text for s, _ in seen if isinstance(s, Note)]
    assert notes and all("since the chambers were last supplied, past the 3.1 kPa limit" in n for n in notes)
    assert [s.state for s, _ in seen if isinstance(s, Valves)] == ["supply", "hold"] * (len(notes) + 1)
    with_supply = baseline_drift_kPa(path)
    assert with_supply <= PROTOCOL.air.repressurise_kPa
    # The same run with the valves by hand: the chambers are supplied once and drift on.
    outcome, _, dev, path = run(tmp_path, url, loads=loads, protocol=protocol_with(tmp_path, valves="hand"))
    dev.close()
    by_hand = baseline_drift_kPa(path)
    assert by_hand > 3 * PROTOCOL.air.repressurise_kPa, (with_supply, by_hand)


@pytest.mark.parametrize("end", ["hold", "vent"])
def test_an_interrupted_session_leaves_the_board_as_the_protocol_says_never_supplying(tmp_path, end):
    def interrupt(step, reply):
        if isinstance(step, Valves) and step.state == "supply":
            raise KeyboardInterrupt  # Ctrl-C while the chambers are being supplied

    outcome, seen, dev, _ = run(
        tmp_path, "sim://?seed=11&clock=virtual", protocol=protocol_with(tmp_path, end_valves=end), watch=interrupt
    )
    try:
        assert outcome.status == "interrupted"
        assert dev.valve_states() == {c: end for c in ("P_L1", "P_R1", "P_L2", "P_R2")}
    finally:
        dev.close()


def test_friction_relief_pulses_the_supply_before_every_baseline(tmp_path):
    protocol = protocol_with(tmp_path, friction_relief_s=0.5)
    assert protocol.air.friction_relief_s == 0.5 and PROTOCOL.air.friction_relief_s == 0.0  # off unless asked
    outcome, seen, dev, path = run(tmp_path, "sim://?seed=11&clock=virtual", protocol=protocol, loads=LOADS[:2])
    dev.close()
    assert outcome.status == "finished" and outcome.stored == 2
    # The setup's supply and hold, then a pulse before each trial's baseline (none redone here).
    assert [s.state for s, _ in seen if isinstance(s, Valves)] == ["supply", "hold"] * 3
    assert [s.duration_s for s, _ in seen if isinstance(s, Hold)] == [5.0, 0.5, 0.5]
    df = load_trials(path)
    dP = (df[["P_L1", "P_R1", "P_L2", "P_R2"]].to_numpy() - df[["P_L10", "P_R10", "P_L20", "P_R20"]].to_numpy()) * 1e3
    assert np.abs(dP).max(axis=1).min() > 2.0  # held after each pulse: the loads still move the pressures


def test_the_hold_checks_leak_is_taken_out_of_every_trials_wait(tmp_path):
    # Seed 3's leakiest chamber loses about 3.6 kPa/min: counted as a tail that never decays, it
    # kept most windows from settling until the timeout.  The waits now take the leak out.
    # The kind rig, whose hold check measures the leak at 3.1 kPa/min (2.9 on the literature's).
    outcome, seen, dev, path = run(tmp_path, "sim://?seed=3&clock=virtual&realism=kind", loads=LOADS[:3])
    dev.close()
    assert outcome.status == "finished" and outcome.stored == 3
    (hold,) = [r for s, r in seen if isinstance(s, Hold)]
    assert -hold.slope_per_s[:4].min() * 60e3 > 2.5  # kPa/min: a leak the waits must not count
    waits = [(s, r) for s, r in seen if isinstance(s, WaitSettle) and s.label in ("baseline", "load")]
    assert sum(s.label == "load" for s, _ in waits) == 3  # (a drifted baseline is retaken after a supply)
    for step, report in waits:
        np.testing.assert_array_equal(step.drift_per_s[:4], hold.slope_per_s[:4])
        assert step.drift_per_s[4:] == (0.0,) * (len(step.drift_per_s) - 4)
        assert report.settled and report.settle_time_s < 15.0, report
        assert report.criterion.endswith(", less the leaks (up to 3.1 kPa/min)")
    # By hand the valves are never checked, so no leak is known: the waits are as before.
    hand = protocol_with(tmp_path, valves="hand")
    _, seen, dev, _ = run(tmp_path, "sim://?seed=3&clock=virtual&realism=kind", loads=LOADS[:3], protocol=hand)
    dev.close()
    assert all(s.drift_per_s == () for s, _ in seen if isinstance(s, WaitSettle))


def pulses(*sides: str) -> list[tuple[str, tuple[str, ...]]]:
    """The relief's valve steps before each trial, venting each side in turn, then supply and hold."""
    return [v for side in sides for v in (("vent", (f"P_{side}1", f"P_{side}2")), ("supply", ()), ("hold", ()))]


def test_friction_relief_vents_one_side_then_supplies_before_every_baseline(tmp_path):
    protocol = protocol_with(tmp_path, friction_relief_s=2.0, friction_relief_vent_s=1.5)
    names = ("P_L1", "P_R1", "P_L2", "P_R2")
    # By default the side each load pulls the arm towards; L where no side is known.
    assert protocol.air.friction_relief_vent == "load"
    assert protocol.air.relief_vented(names, "R") == ("P_R1", "P_R2")
    assert protocol.air.relief_vented(names) == ("P_L1", "P_L2")
    assert protocol_with(tmp_path, friction_relief_vent="L").air.relief_vented(names, "R") == ("P_L1", "P_L2")
    outcome, seen, dev, path = run(
        tmp_path, "sim://?seed=11&clock=virtual&realism=literature", protocol=protocol, loads=LOADS[:2]
    )
    dev.close()
    assert outcome.status == "finished" and outcome.stored == 2
    valves = [(s.state, s.channels) for s, _ in seen if isinstance(s, Valves)]
    # 800 g at 0 deg pulls the upright arm towards the R actuators, 500 g at 180 deg towards the L ones.
    assert valves == [("supply", ()), ("hold", ())] + pulses("R", "L")
    # The board vented the R chambers only: its reply lists the L ones still holding.
    vented = [r for s, r in seen if isinstance(s, Valves) and s.state == "vent"]
    assert vented[0]["P_R1"] == "vent" and vented[0]["P_L1"] == "hold" and vented[0]["P_L2"] == "hold"
    assert [s.duration_s for s, _ in seen if isinstance(s, Hold)] == [5.0, 1.5, 2.0, 1.5, 2.0]
    df = load_trials(path)
    dP = (df[["P_L1", "P_R1", "P_L2", "P_R2"]].to_numpy() - df[["P_L10", "P_R10", "P_L20", "P_R20"]].to_numpy()) * 1e3
    assert np.abs(dP).max(axis=1).min() > 2.0  # held after each pulse: the loads still move the pressures


def test_each_load_is_captured_n_times_each_capture_after_the_relief(tmp_path):
    from labcli.core.steps import BeginTrial

    protocol = protocol_with(tmp_path, captures_per_load=3)
    # No relief given: the one the multi-capture benchmark was chosen with (a 3 s pulse after a 2 s vent).
    assert (protocol.air.friction_relief_s, protocol.air.friction_relief_vent_s) == (3.0, 2.0)
    assert PROTOCOL.air.captures_per_load == 1 and PROTOCOL.air.friction_relief_s == 0.0
    outcome, seen, dev, path = run(
        tmp_path, "sim://?seed=11&clock=virtual&realism=literature", protocol=protocol, loads=LOADS[:2]
    )
    dev.close()
    assert outcome.status == "finished" and outcome.stored == 6
    begun = [s for s, _ in seen if isinstance(s, BeginTrial)]
    assert [b.trial for b in begun] == [1, 2, 3, 4, 5, 6] and [b.total for b in begun] == [6] * 6
    assert begun[4].label == "Trial 2/2 (fit), capture 2/3"
    hung = [s.action.mass_kg for s, _ in seen if isinstance(s, Prompt) and "hang" in s.text]
    assert hung == pytest.approx([0.8] * 3 + [0.5] * 3)
    # Every capture, the first of a load too, comes after the vent (the side the load pulls towards)
    # and the supply pulse.
    assert [(s.state, s.channels) for s, _ in seen if isinstance(s, Valves)] == [
        ("supply", ()),
        ("hold", ()),
    ] + pulses(*"RRRLLL")
    assert [s.duration_s for s, _ in seen if isinstance(s, Hold)] == [5.0] + [2.0, 3.0] * 6
    df = load_trials(path)
    assert df["trial"].tolist() == [1, 2, 3, 4, 5, 6]
    assert df["mass_g"].tolist() == pytest.approx([800] * 3 + [500] * 3)
    # Fresh readings each capture: no two captures of a load hold the same pressures.
    assert df[["P_L1", "P_R1", "P_L2", "P_R2"]].round(9).drop_duplicates().shape[0] == 6


def test_captures_per_load_is_checked_and_a_relief_given_is_kept(tmp_path):
    from labcli.errors import ConfigError

    for bad in (0, 11, 2.5):
        with pytest.raises(ConfigError, match="captures_per_load"):
            protocol_with(tmp_path, captures_per_load=bad)
    kept = protocol_with(tmp_path, captures_per_load=2, friction_relief_s=0.0)
    assert (kept.air.captures_per_load, kept.air.friction_relief_s, kept.air.friction_relief_vent_s) == (2, 0.0, 0.0)
    own = protocol_with(tmp_path, captures_per_load=2, friction_relief_s=1.0, friction_relief_vent_s=0.5)
    assert (own.air.friction_relief_s, own.air.friction_relief_vent_s) == (1.0, 0.5)
    # Captures follow a plan numbered from 1; typed loads are captured once.
    from labcli.core.paper import AcquireOptions
    from labcli.papers.takuma2014.acquisition import acquisition

    with pytest.raises(ConfigError, match="loads typed at the rig are captured once"):
        acquisition(kept, AcquireOptions(str(tmp_path / "r.h5"), no_plan=True))
    plan = tmp_path / "zero.csv"
    plan.write_text("trial,set,mass_g,direction_deg\n0,fit,500,0\n1,fit,800,0\n")
    with pytest.raises(ConfigError, match="numbered from 1.*has trial 0"):
        acquisition(kept, AcquireOptions(str(tmp_path / "r.h5"), plan=plan))
    assert len(acquisition(PROTOCOL, AcquireOptions(str(tmp_path / "r.h5"), plan=plan)).plan) == 2
