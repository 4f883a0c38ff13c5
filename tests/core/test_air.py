"""The rig's air under the board's valves (labcli.core.air) and the seal check (labcli.core.guard).

Known answers: the hold check's leak and gain limits, the re-pressurising limit's default from
the protocol's pressure floor, a baseline drift tracked from the first baseline after a supply;
and the seal check on windows of a rig whose pressures follow the joints (sealed) or stay put
(valves open, supply off).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from labcli.core.air import AirDrift, AirSettings, hold_problem, slope_per_s
from labcli.core.guard import Guard, Watch, unsealed_response
from labcli.core.protocol import load_protocol
from labcli.core.steps import Window
from labcli.errors import ConfigError

PROTOCOL = load_protocol("takuma2014")
WATCH = Watch.of(PROTOCOL)
NAMES = ("P_L1", "P_R1", "P_L2", "P_R2")
P0 = np.array([0.2986, 0.2990, 0.3010, 0.3020, 0.0, 0.0])


def window(values, n=200, noise=0.0, seed=0):
    rng = np.random.default_rng(seed)
    si = np.tile(np.asarray(values, dtype=float), (n, 1)) + rng.normal(0.0, noise, (n, len(values)))
    t = np.arange(n) / 200.0
    return Window.of(np.arange(n), si.copy(), si, t_us=(t * 1e6).astype(np.int64), t_s=t)


def test_the_protocols_air_settings_and_their_defaults():
    air = PROTOCOL.air
    assert (air.valves, air.end_valves) == ("auto", "hold")
    assert air.leak_max_kPa_per_min == 5.0 and air.hold_check_s == 5.0
    # Ten pressure floors: the settling criterion's 0.31 kPa spread.
    assert air.repressurise_kPa == pytest.approx(3.1) and air.repressurise_default
    # A protocol without a spread as large as a count still gets a count's worth.
    assert AirSettings.of({}, 1e-6).repressurise_kPa == pytest.approx(10 * 5 / 16380 * 1e3)
    given = AirSettings.of({"repressurise_kPa": 2.0, "valves": "hand", "end_valves": "vent"}, 0.00031)
    assert (given.repressurise_kPa, given.repressurise_default, given.valves, given.end_valves) == (
        2.0,
        False,
        "hand",
        "vent",
    )


@pytest.mark.parametrize(
    "line, message",
    [
        ('valves = "sometimes"', "key 'acquisition.valves' must be one of auto, hand, not 'sometimes'."),
        ('end_valves = "supply"', "key 'acquisition.end_valves' must be one of hold, vent, not 'supply'."),
        ("leak_max_kPa_per_min = -1", "key 'acquisition.leak_max_kPa_per_min' must be greater than 0, not -1.0."),
        ("hold_check_s = 1000", "key 'acquisition.hold_check_s' must be at most 600 s, not 1000.0."),
        ("friction_relief_s = -0.5", "key 'acquisition.friction_relief_s' must be at least 0, not -0.5."),
        (
            'friction_relief_vent = "both"',
            "key 'acquisition.friction_relief_vent' must be one of load, L, R, not 'both'.",
        ),
        (
            "friction_relief_vent_s = 2.0",
            "key 'acquisition.friction_relief_vent_s' needs acquisition.friction_relief_s above 0: "
            "the supply pulse that fills the vented chambers again.",
        ),
    ],
)
def test_bad_air_settings_are_refused_in_one_sentence(tmp_path, line, message):
    text = PROTOCOL.text.replace("rate_hz = 200.0\n", f"rate_hz = 200.0\n{line}\n")
    path = tmp_path / "p.toml"
    path.write_text(text)
    with pytest.raises(ConfigError) as e:
        load_protocol(str(path))
    assert str(e.value) == f"{path}: {message}"


def test_the_hold_check_names_a_leak_and_a_valve_that_feeds_a_held_chamber():
    air = PROTOCOL.air
    per_min = 1.0 / 60e3  # 1 kPa/min in MPa/s
    assert hold_problem(NAMES, [-1 * per_min, -4.9 * per_min, 0.0, 4.9 * per_min], air) is None
    leak = hold_problem(NAMES, [-1 * per_min, -12.34 * per_min, 0.0, 0.0], air)
    assert leak == (
        "The hold check found P_R1 loses 12.3 kPa/min with its valve holding: a leak; check that actuator's "
        "tube, fittings and valve seat (the protocol allows 5 kPa/min: acquisition.leak_max_kPa_per_min)"
    )
    both = hold_problem(NAMES, [-6 * per_min, -7 * per_min, 8 * per_min, 0.0], air)
    assert "P_L1 loses 6.0 kPa/min, P_R1 loses 7.0 kPa/min with their valves holding" in both
    assert "P_L2 gains 8.0 kPa/min with its valve holding: a supply valve that does not close" in both


def test_the_slope_is_the_least_squares_one():
    t = np.linspace(0.0, 5.0, 1001)
    v = np.column_stack([0.3 - 2e-5 * t, 0.1 + 0.0 * t])
    assert slope_per_s(t, v) == pytest.approx([-2e-5, 0.0], abs=1e-15)
    assert np.isnan(slope_per_s(t[:1], v[:1])).all()


def test_the_drift_is_measured_from_the_first_baseline_after_a_supply():
    drift = AirDrift(NAMES, [0, 1, 2, 3], PROTOCOL.air)
    assert drift.check(window(P0)) is None  # the reference
    assert drift.check(window(P0 - [0.003, 0.001, 0.0, 0.0, 0.0, 0.0])) is None  # 3.0 kPa: within 3.1
    found = drift.check(window(P0 - [0.001, 0.0, 0.0032, 0.0, 0.0, 0.0]))
    assert found == (
        "P_L2 has drifted -3.20 kPa since the chambers were last supplied, past the 3.1 kPa limit "
        "(from the sensor noise): supplying and holding again"
    )
    assert drift.largest_kPa == pytest.approx(3.2)
    drift.supplied()
    assert drift.supplies == 1
    assert drift.check(window(P0 + [0.01, 0, 0, 0, 0, 0])) is None  # the new reference
    assert drift.check(window(P0 + [0.012, 0, 0, 0, 0, 0])) is None


# Per degree of joint deflection, sealed chambers of the simulated rig move by about 2.6 kPa
# (800 g at 0 deg: P_L1 +4.8 kPa, P_L2 +9.4 kPa for theta1 -1.8 deg, theta2 -5.5 deg).
SEALED = np.array([4.76e-3, -4.99e-3, 9.40e-3, -9.18e-3, math.radians(-1.84), math.radians(-5.47)])
OPEN = np.array([0.0, 0.0, 0.0, 0.0, math.radians(-2.2), math.radians(-6.2)])


def test_a_sealed_rig_passes_the_seal_check_at_any_load_that_moves_it():
    for scale in (0.1, 0.5, 1.0, 2.0):
        assert unsealed_response(WATCH, window(P0, noise=1e-4), window(P0 + scale * SEALED, noise=1e-4, seed=1)) is None


def test_valves_left_open_are_named_from_the_first_trial():
    text = unsealed_response(WATCH, window(P0, noise=1e-4), window(P0 + OPEN, noise=1e-4, seed=1), 0.1)
    assert text is not None
    assert text.startswith("the pressures did not respond to the load (P_")
    assert "while POT2 moved -6.20 deg); sealed chambers would have followed the load, so a valve is open" in text
    # The guard says it before it knows anything of the rig (no earlier trial).
    guard = Guard(PROTOCOL)
    assert guard.after_load((7.8, 0.0), window(P0), window(P0 + OPEN)) == unsealed_response(
        WATCH, window(P0), window(P0 + OPEN), PROTOCOL.supply_min_MPa
    )
    assert guard.unsealed


def test_a_supply_that_is_off_is_told_from_open_valves():
    vented = np.array([0.002, 0.001, 0.0, 0.003, 0.0, 0.0])
    text = unsealed_response(WATCH, window(vented), window(vented + OPEN), 0.1)
    assert text.endswith("the chambers are at the atmosphere's pressure: supply air, then close the valves")


def test_a_load_that_hardly_moves_the_joints_is_not_judged():
    # 0.4 deg: under five angle floors (0.1 deg each), whatever the pressures did.
    small = np.array([0.0, 0.0, 0.0, 0.0, math.radians(0.4), 0.0])
    assert unsealed_response(WATCH, window(P0), window(P0 + small), 0.1) is None


def test_the_running_sums_give_the_slope_of_the_whole_window():
    from labcli.core.air import SlopeSums

    rng = np.random.default_rng(3)
    t = 1e4 + np.arange(2000) / 200.0  # a clock far from zero: the sums keep their digits
    v = np.column_stack([0.3 - 2e-5 * (t - t[0]), 0.2 + 1e-6 * (t - t[0])]) + rng.normal(0, 1e-4, (2000, 2))
    sums = SlopeSums(2)
    for a in range(0, 2000, 137):
        sums.add(t[a : a + 137], v[a : a + 137])
    slope, mean = sums.result()
    assert slope == pytest.approx(slope_per_s(t, v), rel=1e-9)
    assert mean == pytest.approx(v.mean(axis=0), rel=1e-12)
    assert sums.n == 2000
    assert np.isnan(SlopeSums(2).result()[0]).all()


def test_the_hold_checks_slopes_are_the_waits_steady_leak():
    air = AirSettings()
    slopes = np.array([-1e-5, -6e-5, np.nan, 2e-6, 0.01, -0.02])  # four chambers, then two angles
    drift = AirDrift(NAMES, [0, 1, 2, 3], air, slopes)
    # The chambers' own slopes (a chamber the check could not fit counts none); the angles none.
    assert drift.leak_per_s == (-1e-5, -6e-5, 0.0, 2e-6, 0.0, 0.0)
    assert AirDrift(NAMES, [0, 1, 2, 3], air).leak_per_s == ()
