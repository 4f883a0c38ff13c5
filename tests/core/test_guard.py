"""The checks of the readings at the rig (labcli.core.guard): supply, a load never applied, a load left on.

The load check must never call a loaded trial unloaded, on an ideal rig or on one with friction,
hysteresis, noise and a leak, and must catch a missing load wherever the run's earlier trials
make its effect sure.  Both are measured here on synthetic rigs with a known response and on
the committed sample run of the simulated rig.
"""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
import pytest

from labcli.core.guard import (
    Guard,
    ResponseModel,
    Watch,
    least_expected,
    still_loaded,
    supply_problem,
    weak_response,
)
from labcli.core.protocol import load_protocol
from labcli.core.steps import Window

PROTOCOL = load_protocol("takuma2014")
WATCH = Watch.of(PROTOCOL)
ROOT = Path(__file__).resolve().parents[2]
# Per newton of (Fx, Fy): four pressures (MPa) and two deflections (rad), about the simulated rig's.
M = np.array(
    [[1.0e-3, 0.2e-3], [-1.0e-3, -0.1e-3], [1.2e-3, 0.3e-3], [-1.1e-3, -0.2e-3], [-2.4e-2, 0.1e-2], [0.3e-2, 0.2e-2]]
)
P0 = np.array([0.30, 0.31, 0.29, 0.32, 0.0, 0.0])


def window(values, n=200, noise=None, rng=None):
    si = np.tile(np.asarray(values, dtype=float), (n, 1))
    if noise is not None:
        si = si + rng.normal(0.0, noise, si.shape)
    t = np.arange(n) / 200.0
    return Window.of(np.arange(n), si.copy(), si, t_us=(t * 1e6).astype(np.int64), t_s=t)


def force(mass_g, direction_deg):
    w = mass_g * 1e-3 * 9.80665
    return np.array([w * math.cos(math.radians(direction_deg)), w * math.sin(math.radians(direction_deg))])


def test_floors_are_the_settle_spread_one_count_or_four_standard_errors():
    assert WATCH.names == ("P_L1", "P_R1", "P_L2", "P_R2", "POT1", "POT2")
    quiet = WATCH.floors(window(P0), window(P0))
    assert quiet[:4] == pytest.approx([0.00031] * 4)  # pressure_spread_MPa (one count is 0.000305 MPa)
    assert quiet[4:] == pytest.approx([math.radians(0.1)] * 2)  # angle_spread_deg
    rng = np.random.default_rng(1)
    noisy = WATCH.floors(window(P0, noise=0.01, rng=rng), window(P0, noise=0.01, rng=rng))
    # sd 0.01 over 200 samples in each window: 4 * 0.01 * sqrt(2 / 200) = 0.004 > 0.00031
    assert noisy[:4] == pytest.approx([0.004] * 4, rel=0.15)


def test_the_model_recovers_a_linear_rig_and_waits_for_enough_directions():
    model = ResponseModel()
    for mass, d in ((300, -60), (500, -60), (800, -60)):
        model.add(force(mass, d), M @ force(mass, d))
    assert model.predict(force(200, 30)) is None  # one direction only: Fy's effect is unknown
    model.add(force(400, 30), M @ force(400, 30))
    assert model.predict(force(200, 30)) is None  # two directions, but no scatter measured yet
    model.add(force(600, 150), M @ force(600, 150))
    mean, sd, h = model.predict(force(1000, -30))
    assert mean == pytest.approx(M @ force(1000, -30), rel=1e-9, abs=1e-15)
    assert sd == pytest.approx(np.zeros(6), abs=1e-12) and h > 0


def trained(rng, friction=0.0, n=12):
    """A guard that saw ``n`` accepted trials of a rig whose response varies by ``friction`` (a share)."""
    guard = Guard(PROTOCOL)
    plan = [(m, d) for m in (200, 500, 800, 1000) for d in (-60, 30, 150)]
    for mass, d in plan[:n]:
        F = force(mass, d)
        gain = 1.0 + friction * rng.uniform(-1, 1)
        offset = friction * rng.uniform(-1, 1, 6) * WATCH.floors(window(P0), window(P0))
        guard.learn(F, window(P0), window(P0 + np.r_[gain * (M @ F) + offset]))
    return guard


@pytest.mark.parametrize("friction", [0.0, 0.2])
def test_a_loaded_trial_is_never_called_unloaded_and_a_missing_heavy_load_is_caught(friction):
    rng = np.random.default_rng(7)
    flagged, caught, heavy = 0, 0, 0
    for seed in range(20):
        guard = trained(np.random.default_rng(seed), friction)
        for mass in (50, 100, 200, 400, 600, 800, 1000):
            for d in (-150, -120, -60, -30, 30, 60, 120, 150):
                F = force(mass, d)
                # The trial as it happened: the response within the rig's friction band, noise on top.
                gain = 1.0 + friction * rng.uniform(-1, 1)
                base = window(P0, noise=1e-4, rng=rng)
                loaded = window(P0 + gain * (M @ F), noise=1e-4, rng=rng)
                flagged += weak_response(WATCH, base, loaded, guard.model().predict(F)) is not None
                # The same trial with the weight never hung.
                empty = window(P0, noise=1e-4, rng=rng)
                miss = weak_response(WATCH, base, empty, guard.model().predict(F))
                caught += miss is not None
                heavy += mass >= 600
                if mass <= 50 or (friction and mass <= 100):
                    assert miss is None  # too light to be sure of: no verdict
    assert flagged == 0
    assert caught >= 0.9 * heavy  # the heavy loads (and some lighter ones) of every direction


def test_the_weak_response_sentence_names_the_channel_and_the_numbers():
    guard = trained(np.random.default_rng(0))
    F = force(1000, -60)
    text = weak_response(WATCH, window(P0), window(P0), guard.model().predict(F))
    # POT1 should move by M[4] @ F = -0.1262 rad = -7.23 deg; less 3 floors (0.1 deg each) widened by
    # the leverage h = 0.324 of this load among the 12 training loads: 7.23 - 0.3 * sqrt(1.324) = 6.88 deg.
    assert text == (
        "the readings moved by 0% of what this run's earlier trials say this load surely does "
        "(POT1 +0.00 deg, at least -6.88 deg expected)"
    )


def test_least_expected_drops_what_the_trials_scatter_over():
    prediction = (np.array([0.010, -0.010, 0.001, 0.0, 0.1, 0.001]), np.array([0.001] * 4 + [0.05, 0.01]), 0.0)
    floors = np.array([0.002] * 4 + [0.01] * 2)
    sure = least_expected(prediction, floors)
    # 0.010 - 3 * 0.002 = 0.004; 0.001 MPa is under three floors.
    # 0.1 rad - 3 * 0.05 < 0 for POT1; POT2's 0.001 is under three floors.
    assert sure == pytest.approx([0.004, -0.004, 0.0, 0.0, 0.0, 0.0])


def test_a_weight_left_hanging_is_seen_at_the_next_baseline_but_friction_and_a_leak_are_not():
    F = force(800, -60)
    base, loaded = window(P0), window(P0 + M @ F)
    # Judged on the pressures; the largest change, P_R1 under 800 g at -60 deg:
    # -1.0e-3 * 3.923 N - 0.1e-3 * -6.794 N = -3.244e-3 MPa = -3.24 kPa.
    assert still_loaded(WATCH, base, loaded, window(P0 + M @ F)) == (
        "they are still 100% of the way to the loaded ones (P_R1 -3.24 kPa from the baseline, -3.24 kPa under the load)"
    )
    # Potentiometer play and sleeve friction: the pressures are back, the angles still where the load left them.
    assert still_loaded(WATCH, base, loaded, window(np.r_[P0[:4], (P0 + M @ F)[4:]])) is None
    # Friction leaves the arm a few percent short of its old posture.
    assert still_loaded(WATCH, base, loaded, window(P0 + 0.05 * (M @ F))) is None
    # A leak: every chamber down by 5 kPa, none of the angles moved.
    assert still_loaded(WATCH, base, loaded, window(P0 - np.r_[[0.005] * 4, 0, 0])) is None
    # A light load's response is too small to judge by.
    small = force(50, -60)
    assert still_loaded(WATCH, base, window(P0 + M @ small), window(P0 + M @ small)) is None


def test_the_guard_forgets_a_load_once_a_baseline_shows_it_off():
    guard = Guard(PROTOCOL)
    F = force(800, -60)
    guard.after_load(F, window(P0), window(P0 + M @ F))
    assert guard.after_baseline(window(P0 + M @ F)) is not None
    assert guard.after_baseline(window(P0)) is None
    assert guard.after_baseline(window(P0 + M @ F)) is None  # nothing loaded since


def test_the_removal_check_allows_for_a_leak_that_drifts_every_trial():
    # Chambers at a high supply lose over a trial as much as a load's response moves them (the
    # bent protocol's P_L2 at 0.45 MPa: about -2.5 kPa per trial on the simulated rig); here the
    # two chambers this load loads, 3 kPa each.
    leak = np.r_[0.0, -0.0032, 0.0, -0.0030, 0.0, 0.0]
    F = force(800, -60)
    guard = Guard(PROTOCOL)
    assert guard.after_baseline(window(P0)) is None
    small = force(50, -60)  # too light to judge its removal by: the first trial shows the leak
    guard.after_load(small, window(P0), window(P0 + M @ small))
    assert guard.after_baseline(window(P0 + leak)) is None
    guard.after_load(F, window(P0 + leak), window(P0 + leak + M @ F))
    # Without the allowance the drift alone reads as most of a load still hanging.
    assert still_loaded(WATCH, window(P0 + leak), window(P0 + leak + M @ F), window(P0 + 2 * leak)) is not None
    assert guard.after_baseline(window(P0 + 2 * leak)) is None
    # A weight left hanging is seen through the allowance.
    guard.after_load(F, window(P0 + 2 * leak), window(P0 + 2 * leak + M @ F))
    assert guard.after_baseline(window(P0 + 3 * leak + M @ F)) is not None


def test_supply_problems_say_what_is_wrong():
    names = ["P_L1", "P_R1", "P_L2", "P_R2"]
    assert supply_problem(names, [0.30, 0.31, 0.29, 0.30], 0.1) is None
    assert supply_problem(names, [0.001, 0.0, 0.002, -0.001], 0.1) == (
        "After the air supply P_L1 reads 0.001 MPa, P_R1 reads 0.000 MPa, P_L2 reads 0.002 MPa, P_R2 reads "
        "-0.001 MPa, below the 0.1 MPa the protocol asks for (acquisition.supply_min_MPa): check the compressor, "
        "the regulator and that the valves are open."
    )
    assert supply_problem(names, [0.30, 0.002, 0.29, 0.30], 0.1) == (
        "After the air supply P_R1 reads 0.002 MPa while the others read about 0.30 MPa: check that actuator's "
        "tube, fitting and valve."
    )


def replay(table) -> tuple[int, int, int, int]:
    """Replay a 108-trial run in its recording order, as the session met it: the trials the load
    check flags, the missing loads (a baseline read in place of the loaded window) it would catch,
    those of 600 g or more it would catch, and how many of those there are."""
    guard = Guard(PROTOCOL)
    flagged, caught, caught_heavy, heavy = 0, 0, 0, 0
    for r in table.to_dict("records"):
        base = window([r["P_L10"], r["P_R10"], r["P_L20"], r["P_R20"], 0.0, 0.0])
        loaded = window(
            [r["P_L1"], r["P_R1"], r["P_L2"], r["P_R2"], math.radians(r["theta1_deg"]), math.radians(r["theta2_deg"])]
        )
        F = (r["Fx_N"], r["Fy_N"])
        prediction = guard.model().predict(F)
        flagged += weak_response(WATCH, base, loaded, prediction) is not None
        miss = weak_response(WATCH, base, base, prediction) is not None
        caught += miss
        if r["mass_g"] >= 600:
            heavy += 1
            caught_heavy += miss
        guard.learn(F, base, loaded)
    return flagged, caught, caught_heavy, heavy


def test_on_the_kind_rigs_run_no_trial_is_flagged_and_most_missing_loads_would_be():
    import pandas as pd

    # The kind rig's seed-1 run (realism=kind), kept from before the default rig's move.
    flagged, caught, caught_heavy, heavy = replay(pd.read_csv(ROOT / "tests" / "data" / "kind-rig" / "trials.csv"))
    assert flagged == 0
    assert caught >= 50 and caught_heavy >= 0.8 * heavy


def test_on_the_literature_rigs_sample_run_no_trial_is_flagged_and_most_heavy_missing_loads_would_be():
    """The default rig's sample run: no false alarm, but its pressure repeatability and friction
    hide more of the light loads' response (seed 1: 32 of 108 missing loads caught, 26 of the 36
    heavy ones, against 71 and 33 on the kind rig); the check stays silent rather than guess."""
    from labcli.papers.takuma2014.records import load_trials

    flagged, caught, caught_heavy, heavy = replay(load_trials(ROOT / "sample_runs" / "force.h5"))
    assert flagged == 0
    assert heavy == 36 and caught_heavy >= 24 and caught >= 25


# ---------------------------------------------------------------- friction against a weight left on
#
# A rig with sleeve friction in the guard's terms: two posture coordinates (rad) move the four
# pressures through G (MPa per rad, the size of the simulated rig's closed-chamber response); a
# load moves the frictionless posture by D @ F (rad per N); friction stops the arm at the edge
# of a band of half-width BAND about the frictionless posture, on the side it came from, or
# holds it where it is when the load's own move stays within the band (stiction).
G = np.array([[0.050, 0.010], [-0.050, -0.008], [0.020, 0.060], [-0.018, -0.060]])
D = np.array([[-0.0040, 0.0005], [-0.0100, 0.0020]])
BAND = np.array([0.004, 0.010])


def sleeves(mean):
    """The physical bound of the McKibben plug-in: friction may move a chamber's pressure
    between two baselines by 2 x 5 % of what it holds (labcli.papers.takuma2014.friction)."""
    return np.where(np.arange(6) < 4, 0.1 * np.clip(mean, 0, None), 0.0)


def reading(posture, leak=0.0):
    return window(np.r_[P0[:4] + G @ posture - leak, posture])


class FrictionRig:
    """Unloaded postures within the friction band; a trial's load, loaded and next baseline."""

    def __init__(self, leak_per_trial=0.0):
        self.rest = np.zeros(2)  # where the last unload left the arm
        self.leak, self.n = leak_per_trial, 0

    def trial(self, F):
        free = D @ np.asarray(F)
        loaded = self.rest + free  # the loaded posture (stopping short is within the noise here)
        # Unloaded, the arm moves back towards 0 and stops at the band's edge on the load's side.
        back = np.where(np.abs(loaded) > BAND, np.sign(loaded) * BAND, loaded)
        base = reading(self.rest, self.leak * self.n)
        self.n += 1
        self.rest = back
        return base, reading(loaded, self.leak * (self.n - 0.5))


def run_through(guard, rig, loads):
    for F in loads:
        base, loaded = rig.trial(F)
        assert guard.after_baseline(base) is None
        guard.after_load(F, base, loaded)
        guard.learn(F, base, loaded)
    return base, loaded


LOADS = [force(m, d) for m, d in ((600, -60), (800, 30), (400, 150), (1000, -150), (300, 90), (800, -90)) * 2]


def test_friction_keeping_most_of_a_loads_response_is_not_a_weight_left_on():
    guard, rig = Guard(PROTOCOL, hold_prior=sleeves), FrictionRig(leak_per_trial=0.0004)
    run_through(guard, rig, LOADS)
    # The arm rests at one edge of the band; a load moves it 2.4 band widths the other way, and
    # unloaded it stops at the far edge: 2 of the 2.4 remain, 83 % of the response, which the
    # earlier rule called a weight still hanging.  The run has seen friction move the baselines
    # that far, so the guard does not.
    side = np.array([1.0, 1.0])
    rig.rest = -BAND * side
    F = np.linalg.solve(D, 2.4 * BAND * side)
    base, loaded = rig.trial(F)
    assert guard.after_baseline(base) is None
    guard.after_load(F, base, loaded)
    now = rig.trial(force(800, 150))[0]
    r = WATCH.change(base, loaded)[:4]
    assert (WATCH.change(base, now)[:4] + 0.0004) @ r / (r @ r) > 0.8
    assert guard.after_baseline(now) is None


def test_a_heavy_weight_left_on_is_caught_through_friction_and_the_sentence_says_so():
    guard, rig = Guard(PROTOCOL, hold_prior=sleeves), FrictionRig(leak_per_trial=0.0004)
    run_through(guard, rig, LOADS)
    F = force(1000, -60)
    base, loaded = rig.trial(F)
    assert guard.after_baseline(base) is None
    guard.after_load(F, base, loaded)
    text = guard.after_baseline(window(loaded.si[0] - np.r_[[0.0004] * 4, 0, 0]))  # one trial's leak later
    assert text is not None
    assert re.fullmatch(
        r"they are still \d+% of the way to the loaded ones beyond the \d+% friction can leave "
        r"\(P_\w+ [+-]\d+\.\d\d kPa from the baseline, [+-]\d+\.\d\d kPa under the load\)",
        text,
    ), text
    share, allowed = (int(v) for v in re.findall(r"(\d+)%", text))
    assert share >= 95 and 0 < allowed < 50


def test_until_the_run_has_shown_its_friction_only_the_physical_bound_judges():
    from labcli.core.guard import HOLD_MIN_MOVES

    # The case, at the rig's second load: 65 % of a 2.6 kPa response is still there
    # after the weight came off.  Without a physical bound the earlier rule calls it loaded.
    r = np.r_[0.0, 0.0, -0.00262, 0.00250, 0.0, 0.0]
    base, loaded, now = window(P0), window(P0 + r), window(P0 + 0.65 * r)
    bare = Guard(PROTOCOL)
    bare.after_baseline(base)
    bare.after_load(force(500, 0), base, loaded)
    assert bare.after_baseline(now) is not None

    bounded = Guard(PROTOCOL, hold_prior=sleeves)
    bounded.after_baseline(base)
    bounded.after_load(force(500, 0), base, loaded)
    assert bounded.after_baseline(now) is None
    assert len(bounded.baselines._moves) < HOLD_MIN_MOVES


def test_the_leaks_drift_is_the_median_move_so_friction_does_not_pass_for_a_leak():
    from labcli.core.guard import BaselineHistory

    h = BaselineHistory(WATCH)
    leak = np.r_[-0.0005, -0.0004, -0.0006, -0.0005, 0, 0]
    # Friction alternates the baseline by +-2 kPa on L1 and R1 as the loads change side.
    swing = np.r_[0.002, -0.002, 0.0, 0.0, 0, 0]
    for n in range(9):
        h.add(window(P0 + n * leak + (swing if n % 2 else 0.0)))
    assert h.drift()[2:4] == pytest.approx(leak[2:4], abs=1e-12)  # chambers friction did not swing
    assert h.drift()[:2] == pytest.approx(leak[:2], abs=0.0011)  # the median, not the last move
    assert np.abs(h.drift()[:2] - leak[:2]).max() < 0.5 * 0.002
    # The hold along a direction: 1.5 times the largest projection of a move less the drift;
    # L1's moves less the drift reach the swing of 2 kPa.
    along = h.hold(window(P0))
    offsets = np.array(h._moves) - h.drift()
    w = np.r_[1000.0, 0, 0, 0, 0, 0]  # per MPa, on L1 alone
    assert along(w) == pytest.approx(1.5 * 1000 * np.abs(offsets[:, 0]).max())
    assert 1.5 * 2.0 < along(w) < 1.5 * 2.6
