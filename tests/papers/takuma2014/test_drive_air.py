"""The direct drive of the simulated rig re-pressurises as the acquisition session does (sim/drive.py)."""

from __future__ import annotations

import numpy as np
import pandas as pd

from labcli.core.protocol import load_protocol
from labcli.papers.takuma2014.sim.drive import simulate_pushes, simulate_weight_trials
from labcli.papers.takuma2014.sim.nonideal import NonIdeal
from labcli.papers.takuma2014.sim.objects import DEMO_OBJECTS
from labcli.papers.takuma2014.sim.rig import SimRig

PROTOCOL = load_protocol("takuma2014")
P0 = ["P_L10", "P_R10", "P_L20", "P_R20"]
LIMIT_KPA = 3.1


class Supplies:
    """The rig, counting the air supplies."""

    def __init__(self, rig):
        self._rig, self.supplies = rig, 0

    def __getattr__(self, name):
        return getattr(self._rig, name)

    def supply_air(self):
        self.supplies += 1
        self._rig.supply_air()


def leaky_rig(seed: int = 4) -> Supplies:
    # Three times the leak: a chamber loses a 3.1 kPa limit in a minute or two of 15 s waits.
    return Supplies(SimRig(seed=seed, nonideal=NonIdeal(realism="kind", leak=3.0)))


def plan(n: int) -> pd.DataFrame:
    return pd.DataFrame(
        {"trial": range(1, n + 1), "set": "fit", "mass_g": 200.0, "direction_deg": [0.0, 90.0] * (n // 2)}
    )


def drift_kPa(table: pd.DataFrame) -> float:
    p0 = table[P0].to_numpy()
    return float(np.max(np.abs(p0 - p0[0])) * 1e3)


def test_weight_trials_resupply_once_a_baseline_drifted_past_the_limit():
    held, fed = leaky_rig(), leaky_rig()
    kw = {"calibration": PROTOCOL.calibration, "settle_s": 15.0}
    shut = simulate_weight_trials(held, plan(24), **kw)
    resupplied = simulate_weight_trials(fed, plan(24), repressurise_kPa=LIMIT_KPA, **kw)
    assert held.supplies == 1  # the run's first supply only: the valves held throughout
    assert drift_kPa(shut) > 3 * LIMIT_KPA  # without it the operating point walks away
    assert fed.supplies >= 3
    # Every recorded baseline is within the limit of the first after a supply; the regulators
    # bring every supply back to the same pressures, so within about twice it of the run's first.
    assert drift_kPa(resupplied) < 2 * LIMIT_KPA
    assert len(resupplied) == 24 and list(resupplied["trial"]) == list(range(1, 25))


def test_pushes_resupply_too_and_no_limit_holds_the_valves():
    kw = {"calibration": PROTOCOL.calibration, "settle_s": 15.0, "pushes_per_object": 4}
    objects = DEMO_OBJECTS[-2:]
    held, fed = leaky_rig(5), leaky_rig(5)
    shut = simulate_pushes(held, objects, repressurise_kPa=0.0, **kw)
    resupplied = simulate_pushes(fed, objects, repressurise_kPa=LIMIT_KPA, **kw)
    assert held.supplies == 1 and fed.supplies > 1
    assert drift_kPa(resupplied) < 2 * LIMIT_KPA < drift_kPa(shut)
    assert list(resupplied["push"]) == list(range(1, 9))
