"""The literature's rig and the kind one: levels, switches, and each added effect against its model.

``realism`` picks the levels (sim/nonideal.py); the kind rig must stay the earlier default frame
for frame, so that figures measured on it can be remade.  The effects the literature's levels
added (contact and pulley friction, potentiometer scale and linearity, pressure repeatability,
drift on by default) are each checked against their own model here.
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np
import pytest
import serial

from labcli.core.sim import register
from labcli.core.sim.sensors import GainLinearity, Linear, repeat_error
from labcli.papers.takuma2014.sim import nonideal as ni
from labcli.papers.takuma2014.sim import options
from labcli.papers.takuma2014.sim.nonideal import NonIdeal
from labcli.papers.takuma2014.sim.rig import SimRig, angle_to_counts

sys.path.insert(0, str(Path(__file__).resolve().parent))
from test_nonideal import session_digest  # noqa: E402

register()


@pytest.mark.parametrize(
    "url,digest",
    [
        # Recorded from the default rig before the literature's levels existed (then simply
        # sim://?seed=1 and sim://?seed=3&supply=0.15,0.15,0.45,0.15), behind the board of the
        # time: wire protocol 1.0 (a 1.1 board samples in shorter blocks while supplying), and the
        # valves of the time: a first-order lag, not an orifice (flow=lag).
        (
            "sim://?seed=1&realism=kind&fw=1.0&flow=lag",
            "fe3ec5152fff499ae039be9460b63b75a60989a85b86fc51612e76484c1b69a3",
        ),
        (
            "sim://?seed=3&supply=0.15,0.15,0.45,0.15&realism=kind&fw=1.0&flow=lag",
            "e8ce0ac744e0de7bf5f92ea0a329b36b7ddf19c6d51842cc0a7d2d0b0a9d8f29",
        ),
        (
            "sim://?seed=2&drift=1&noise=3&realism=kind&fw=1.0&flow=lag",
            "75f5697c4ee58c240cc066ad835a5f387a93ebb43f4a3f4ab01d39c14b983e9e",
        ),
    ],
)
def test_the_kind_rig_reproduces_the_earlier_default_byte_for_byte(url, digest):
    assert session_digest(url) == digest


def test_the_two_realisms_levels_and_how_a_scale_applies_to_them():
    assert options.REALISM_NAMES == ni.REALISMS
    lit = NonIdeal(realism="literature").magnitudes()
    assert lit["friction_fraction"] == 0.02 and lit["contact_mu"] == 0.3 and lit["pulley_loss"] == 0.02
    assert lit["pot_scale_sd"] == 0.01 and lit["pot_linearity"] == 0.005 and lit["drift"] == 1.0
    assert lit["pressure_repeat_sd_MPa"] == pytest.approx(0.002 / 6)
    kind = NonIdeal(realism="kind").magnitudes()
    assert kind["friction_fraction"] == 0.005 and kind["drift"] == 0.0
    assert kind["contact_mu"] == kind["pulley_loss"] == kind["pot_scale_sd"] == kind["pot_linearity"] == 0.0
    assert kind["pressure_repeat_sd_MPa"] == 0.0
    # A scale multiplies its realism's level; an effect the kind rig lacks is switched on at the literature's.
    twice = serial.serial_for_url("sim://?seed=2&realism=kind&friction=2&contact=1").rig
    assert twice.nonideal.magnitudes()["friction_fraction"] == 0.01
    assert twice.nonideal.magnitudes()["contact_mu"] == 0.3
    assert serial.serial_for_url("sim://?seed=2&realism=literature&friction=2").rig._friction == 0.04
    # ideal=1 turns everything off, drift included; drift= given in the URL wins over the realism's.
    assert serial.serial_for_url("sim://?realism=literature&ideal=1").rig.drift == 0.0
    assert serial.serial_for_url("sim://?realism=literature&drift=0.5").rig.drift == 0.5
    assert SimRig(seed=1, nonideal=NonIdeal(realism="literature")).drift == 1.0
    with pytest.raises(ValueError, match="^the realism must be one of literature, kind, got 'harsh'$"):
        NonIdeal(realism="harsh")
    with pytest.raises(ValueError, match="^the pulley scale must be a number >= 0, got -1"):
        NonIdeal(pulley=-1)


def test_a_bad_realism_in_the_url_shows_the_accepted_form():
    from labcli.core.sim.url import accepted_form

    with pytest.raises(ValueError) as e:
        serial.serial_for_url("sim://?realism=harsh")
    assert str(e.value) == (
        f"option 'realism' in sim:// URL must be one of literature, kind, got 'harsh'; expected {accepted_form()}"
    )
    assert "[&realism=literature|kind]" in accepted_form()


def settled(nonideal: NonIdeal, seed: int = 4, **kw) -> SimRig:
    rig = SimRig(seed=seed, noise=0, nonideal=nonideal, **kw)
    rig.supply_air()
    rig.advance(10)
    rig.close_valves()
    rig.advance(10)
    return rig


def only(**scales: float) -> NonIdeal:
    return NonIdeal(**{**NonIdeal.ideal().as_dict(), **scales}, realism="literature")


def test_the_pulley_and_the_contact_reach_the_rigs_loads():
    rig = settled(only(pulley=1.0, contact=1.0))
    rig.hang_weight(0.8, math.radians(-60))
    rig.advance(10)
    st = rig.true_state()
    pull = 0.8 * 9.80665 * (1 - ni.PULLEY_LOSS)
    assert st["force_N"] == pytest.approx(pull * np.array([math.cos(-math.pi / 3), math.sin(-math.pi / 3)]))
    assert st["load"]["pulley_loss"] == ni.PULLEY_LOSS
    rig.remove_weight()
    rig.advance(10)
    rig.push_object(0.033, 0.010, math.radians(30), 420.0)
    rig.advance(10)
    st = rig.true_state()
    v = np.asarray(st["contact_m"]) - np.asarray(st["load"]["center_m"])
    f = st["force_N"]
    tilt = math.atan2(v[0] * f[1] - v[1] * f[0], float(v @ f))
    assert st["load"]["contact_mu"] == ni.CONTACT_MU
    assert abs(tilt) == pytest.approx(math.atan(ni.CONTACT_MU), rel=0.02)  # sliding at an oblique push


def test_a_potentiometers_scale_and_linearity_errors_are_what_they_say():
    span = math.radians(340)
    nominal = Linear(math.radians(340) / 4095, 2048.0)
    a = np.linspace(-1.0, 1.0, 7)
    scaled = GainLinearity.seeded(np.random.default_rng(1), nominal, span, 0.01, 0.0)
    assert scaled.reading(a) == pytest.approx(a * (1 + scaled.scale_error), rel=1e-12)
    assert scaled(a) == pytest.approx(nominal(a * (1 + scaled.scale_error)), rel=1e-12)
    bent = GainLinearity.seeded(np.random.default_rng(1), nominal, span, 0.0, 0.005)
    grid = np.linspace(-span / 2, span / 2, 4001)
    dev = bent.reading(grid) - grid
    # Independent linearity: the largest departure is the stated share of the span, zero at the ends.
    assert np.abs(dev).max() == pytest.approx(0.005 * span, rel=1e-4)
    assert dev[[0, -1]] == pytest.approx([0.0, 0.0], abs=1e-12)
    # At the middle of the span the bow is flat and the S tilts: slope 1 - 2 pi linearity c2.
    assert bent.slope(np.array(0.0)) == pytest.approx(1 - 2 * math.pi * 0.005 * bent.coeffs[1], rel=1e-6)
    # Over seeds the scale errors spread as configured.
    s = [GainLinearity.seeded(np.random.default_rng(k), nominal, span, 0.01, 0.0).scale_error for k in range(800)]
    assert np.std(s) == pytest.approx(0.01, rel=0.1)


def test_the_rigs_potentiometer_counts_carry_the_scale_and_linearity_errors():
    rig = settled(only(potscale=1.0, potlin=1.0), seed=9)
    rig.hang_weight(1.0, 0.0)
    rig.advance(10)
    st = rig.true_state()
    _, counts = rig.samples(1, 200)
    shaft = st["pot_shaft_rad"] + rig.pot_offset_rad
    assert counts[0, 4:] == pytest.approx(np.rint(angle_to_counts(rig.pot_reading(shaft))))
    pots = [c.transfer for c in rig.sensors.channels[4:]]
    assert all(isinstance(t, GainLinearity) and t.linearity == ni.POT_LINEARITY for t in pots)
    assert not np.allclose(rig.pot_reading(shaft), shaft)
    # A small deflection reads its slope there: 1 + the scale error + the non-linearity's local slope.
    assert st["pot_slope"] == pytest.approx([t.slope(a) for t, a in zip(pots, shaft, strict=True)])
    assert np.all(np.abs(st["pot_slope"] - 1) < 0.1)
    exact = SimRig(seed=9, variation=False, nonideal=only(potscale=1.0, potlin=1.0))
    assert [c.transfer for c in exact.sensors.channels[4:]] == [angle_to_counts, angle_to_counts]


def test_a_held_pressure_reads_back_elsewhere_after_each_change_by_the_repeatability():
    sd = ni.PRESSURE_REPEAT_SD_MPA
    rig = settled(only(repeat=1.0), seed=11)
    cal = (5 / 16380, 819.0)
    readings, within = [], []
    for _ in range(120):
        rig.hang_weight(0.2, 0.0)
        rig.advance(8)
        rig.remove_weight()
        rig.advance(8)
        _, counts = SimRig.samples(rig, 200, 200)
        p = (counts[:, :4] - cal[1]) * cal[0]
        readings.append(p.mean(axis=0))
        within.append(p.std(axis=0))
    readings = np.array(readings) - rig.true_state()["pressures_MPa"]
    # Each unloaded reading is off by a fresh error: the spread of the window means is the
    # repeatability (the posture comes back exactly without friction; 12-bit counts blur it by
    # 0.09 kPa rms), while a window itself holds still (noise off).
    assert np.std(readings, axis=0) == pytest.approx([math.hypot(sd, 0.305e-3 / math.sqrt(12))] * 4, rel=0.2)
    assert np.array(within).max() < 0.31e-3
    # After a change the error settles with the posture's lag, from the old value to the new.
    before = rig.true_state()["repeat_MPa"]
    rig.hang_weight(0.2, 0.0)
    assert rig.true_state()["repeat_MPa"] == pytest.approx(before)
    rig.advance(30)
    assert not np.allclose(rig.true_state()["repeat_MPa"], before)
    assert np.array_equal(repeat_error(np.random.default_rng(0), 0.0, 4), np.zeros(4))
