"""The benchmark's scoring (labcli/sensing/scoring.py) on hand-made estimates with known answers.

A quantity an estimate flags ``unobservable`` is not reported: its value, however wrong, must
count neither in the settled RMSE nor in the coverage (Fy on the straight arm, where a force
along the arm makes no torque).
"""

from __future__ import annotations

import math

import numpy as np

from labcli.sensing import Estimate, Event
from labcli.sensing.scoring import Change, pooled, score

Q = ("Fx", "Fy")


def est(t: float, fx: float, fy: float, flags: tuple[str, ...] = ()) -> Estimate:
    return Estimate(
        int(t * 10), t, "loaded", {"Fx": fx, "Fy": fy}, {"Fx": 0.1, "Fy": 0.1}, {"Fx": "N", "Fy": "N"}, flags
    )


def session(fy_flags: tuple[str, ...]) -> list[Estimate | Event]:
    items: list[Estimate | Event] = [Event("load", 1.0, 1.1, 11), Event("settled", 2.0, 2.0, 20)]
    # Settled from 2 s on: Fx off by 0.1 N then 0.3 N; Fy off by 5 N (a straight arm's guess).
    items += [est(2.0, 1.1, 5.0, fy_flags), est(3.0, 1.3, 5.0, fy_flags)]
    items += [Event("release", 4.0, 4.1, 41), est(4.5, 0.0, 0.0)]
    return items


def truth() -> tuple[np.ndarray, np.ndarray]:
    t = np.arange(0.0, 5.0, 0.1)
    on = (t >= 1.0) & (t < 4.0)
    return t, np.column_stack([np.where(on, 1.0, 0.0), np.zeros_like(t)])


def test_an_unobservable_quantity_counts_in_neither_rmse_nor_coverage() -> None:
    t, x = truth()
    s = score(session(("unobservable:Fy",)), t, x, [Change(1.0, 4.0, 1.0)], Q)
    assert math.isclose(s.settled_rmse["Fx"], math.sqrt((0.1**2 + 0.3**2) / 2), rel_tol=1e-9)
    assert math.isnan(s.settled_rmse["Fy"]) and math.isnan(s.changes[0].settled_sq[1])
    assert s.coverage_n == {"Fx": 3, "Fy": 1}  # the unflagged estimate after the release only
    assert s.coverage["Fy"] == 1.0 and math.isclose(s.coverage["Fx"], 2 / 3)
    p = pooled([s], Q)
    assert math.isnan(p["settled_rmse"]["Fy"]) and math.isclose(p["settled_rmse"]["Fx"], s.settled_rmse["Fx"])


def test_the_same_error_reported_counts_in_both() -> None:
    t, x = truth()
    s = score(session(()), t, x, [Change(1.0, 4.0, 1.0)], Q)
    assert math.isclose(s.settled_rmse["Fy"], 5.0)
    assert s.coverage_n["Fy"] == 3 and math.isclose(s.coverage["Fy"], 1 / 3)
