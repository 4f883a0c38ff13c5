"""The simulated rig's valves: supply and vent through an orifice take time, reach the regulator's
pressure or the atmosphere's, conserve the air, respect the board's limit; the console moves them."""

from __future__ import annotations

import math

import numpy as np
import pytest

from labcli.core.board import limit_counts
from labcli.core.device import Device
from labcli.core.sim import orifice as o
from labcli.core.sim.console import execute
from labcli.errors import DeviceNotFound
from labcli.papers.takuma2014.sim import physics as ph
from labcli.papers.takuma2014.sim.nonideal import NonIdeal
from labcli.papers.takuma2014.sim.rig import SimRig

SUPPLY = 0.30e6


def ideal_rig(**kw) -> SimRig:
    return SimRig(seed=2, nonideal=NonIdeal.ideal(), **kw)


def pressures_over(rig: SimRig, seconds: float, rate_hz: float = 1000.0) -> tuple[np.ndarray, np.ndarray]:
    """True gauge pressures (Pa, (n, 4)) at ``rate_hz`` over the next ``seconds``, and their times from now."""
    t0 = rig.time_s
    t = t0 + np.arange(1, int(round(seconds * rate_hz)) + 1) / rate_hz
    _, p = rig._state_at(t)
    rig.advance(seconds)
    return t - t0, p


def fill_time(x0: float, b: float, k: np.ndarray) -> np.ndarray:
    """Closed form: from ``x0 = P / P_s`` below ``b``, choked to ``b``, then the subsonic quarter sine."""
    return ((b - x0) + (1 - b) * math.pi / 2) / k


def test_a_supply_from_vented_takes_the_time_the_orifice_closed_form_gives_and_ends_at_the_regulator():
    rig = ideal_rig()
    k = rig.valve.rate(rig.chamber_volumes())
    rig.supply_air()
    t, p = pressures_over(rig, 1.0)
    full = fill_time(ph.P_ATM / (SUPPLY + ph.P_ATM), rig.valve.b, k)
    for i in range(4):
        reached = t[np.argmax(p[:, i] >= SUPPLY)]
        assert reached == pytest.approx(full[i], abs=1.5e-3)  # one frame
    # Realistic for these muscles: the outside chambers (44 mL) in half a second, the inside (20 mL) in 0.2 s.
    assert 0.4 < full[:2].min() and full[:2].max() < 0.6 and 0.15 < full[2:].min() and full[2:].max() < 0.3
    # Choked at first: the pressure rises at k P_s until it is b P_s (absolute).
    early = t < 0.005
    np.testing.assert_allclose(p[early], (k * (SUPPLY + ph.P_ATM))[None, :] * t[early, None], rtol=1e-9)
    assert np.all(p[-1] == SUPPLY)  # steady state: the regulator's pressure, exactly
    assert np.all(np.diff(p, axis=0) >= 0)  # never past it


def test_a_vent_reaches_the_atmosphere_in_the_closed_form_time_and_stays_there():
    rig = ideal_rig()
    rig.supply_air()
    rig.advance(3.0)
    k = rig.valve.rate(rig.chamber_volumes())
    rig.vent()
    t, p = pressures_over(rig, 1.5)
    b, p0 = rig.valve.b, SUPPLY + ph.P_ATM
    # 0.4 MPa absolute is above P_atm / b (0.34 MPa): choked at first, an exponential decay.
    early = t < 0.01
    np.testing.assert_allclose(p[early] + ph.P_ATM, p0 * np.exp(-k[None, :] * t[early, None]), rtol=1e-9)
    t_end = (np.log(p0 * b / ph.P_ATM) + float(o.empty_tau(1.0, b))) / k
    for i in range(4):
        assert t[np.argmax(p[:, i] <= 0.0)] == pytest.approx(t_end[i], abs=1.5e-3)
    assert np.all(p[-1] == 0.0) and rig.true_state()["pressures_MPa"].tolist() == [0.0] * 4


def test_the_air_a_supplied_chamber_gains_is_what_its_orifice_let_through():
    """Mass conservation in the rig: one chamber supplied while the others hold."""
    rig = ideal_rig()
    rig.supply_air(0.15)
    rig.advance(3.0)
    rig.close_valves()
    rig.advance(3.0)
    held_before = rig.true_state()["pressures_MPa"][1:]
    volume = rig.chamber_volumes()[0]  # the volume the rig took for the flow: where the valve acted
    rig.set_valves(["supply", "hold", "hold", "hold"])
    t, p = pressures_over(rig, 0.8, rate_hz=20_000)
    q = rig.valve.mass_flow(SUPPLY + ph.P_ATM, p[:, 0] + ph.P_ATM)
    added = np.sum(0.5 * (q[1:] + q[:-1]) * np.diff(t))
    p_start = 0.15e6
    gained = (p[-1, 0] - p_start) * volume / (o.R_AIR * o.T0)
    assert gained == pytest.approx(added + q[0] * t[0], rel=1e-4)
    assert p[-1, 0] == SUPPLY
    # The held chambers kept their air: only the arm's small motion moves their pressures (Boyle).
    assert np.abs(rig.true_state()["pressures_MPa"][1:] - held_before).max() < 0.01


def test_a_chamber_held_part_way_keeps_the_air_it_had():
    rig = ideal_rig()
    rig.supply_air()
    rig.advance(0.1)
    part = rig.true_state()["pressures_MPa"]
    assert np.all(part > 0.02) and np.all(part < 0.29)  # filling, not filled
    rig.close_valves()
    rig.advance(3.0)
    after = rig.true_state()["pressures_MPa"]
    assert after == pytest.approx(part, abs=0.02)  # the arm settles on what was let in
    assert np.all(after < 0.29)


def test_a_faster_valve_is_a_rig_option():
    slow = Device.open("sim://?seed=2&ideal=1")
    fast = Device.open("sim://?seed=2&ideal=1&valve_c=0.4&valve_b=0.4")
    try:
        assert fast.rig.valve == o.Orifice(0.4e-8, 0.4)
        k_slow = slow.rig.valve.rate(slow.rig.chamber_volumes())
        k_fast = fast.rig.valve.rate(fast.rig.chamber_volumes())
        np.testing.assert_allclose(k_fast / k_slow, 4.0, rtol=1e-9)
    finally:
        slow.close()
        fast.close()
    with pytest.raises(
        DeviceNotFound, match="option 'valve_b' in sim:// URL must be a number within 0..0.95 above 0, got '1'"
    ):
        Device.open("sim://?valve_b=1")


def test_the_board_limit_holds_while_the_regulator_is_above_it():
    """The regulator at 0.5 MPa, the board's limit at 0.35 MPa: every chamber is vented by the
    board as it crosses, and none gets further past than its orifice fills it in one check."""
    gain, zero = 5 / 16380, 819.0
    with Device.open("sim://?seed=1&ideal=1&supply=0.5") as dev:
        limit = limit_counts(0.35, [gain] * 4, [zero] * 4)[0]
        dev.set_pressure_limit(limit)
        dev.set_rate(200)
        dev.start()
        dev.set_valves("supply")
        frames = []
        while sum(map(len, frames)) < 800:
            frames.append(dev.read(1.0))
        dev.stop()
        rig = dev.rig
        events = dev.take_events()
    pmax = [e for e in events if e.kind == "PMAX"]
    assert sorted(e.fields[0] for e in pmax) == ["P_L1", "P_L2", "P_R1", "P_R2"]
    source = 0.5e6 + ph.P_ATM
    x = (0.35e6 + ph.P_ATM) / source
    rise = rig.valve.rate(rig.chamber_volumes()) * source * o.flow_factor(x, rig.valve.b) * 0.02 * 1.1 / 1e6 / gain
    values = np.concatenate([f.values for f in frames])
    over = values[:, :4].max(axis=0) - limit
    assert np.all(over < rise + 3) and over.max() > 10  # past it, by no more than one check's fill
    assert rig.valve_states == ("vent",) * 4
    assert np.abs(rig.true_state()["pressures_MPa"]).max() == 0.0  # vented down to the atmosphere


def test_the_console_supplies_holds_and_vents_by_hand_and_the_air_takes_time():
    rig = ideal_rig()
    assert execute(rig, "supply").startswith("ok supply 0.300,0.300,0.300,0.300 MPa")
    assert execute(rig, "wait 0.1").startswith("ok wait 0.1 s")
    part = rig.true_state()["pressures_MPa"]
    assert np.all(part > 0.02) and np.all(part < 0.29)
    assert execute(rig, "hold").startswith("ok hold")
    assert rig.valve_states == ("hold",) * 4
    assert execute(rig, "wait 2").startswith("ok wait 2 s")
    assert rig.true_state()["pressures_MPa"] == pytest.approx(part, abs=0.02)
    assert execute(rig, "supply").startswith("ok supply")
    execute(rig, "wait 1")
    assert rig.true_state()["pressures_MPa"].tolist() == [0.3] * 4
    assert execute(rig, "vent").startswith("ok vent")
    execute(rig, "wait 0.1")
    assert np.all(rig.true_state()["pressures_MPa"] > 0.01)  # still emptying
    execute(rig, "wait 2")
    assert rig.true_state()["pressures_MPa"].tolist() == [0.0] * 4
    assert execute(rig, "close").startswith("ok close")  # the older word still works
