"""Drive the simulated rig through the paper's experiments directly (no wire protocol).

For tests and accuracy scripts that need many trials fast: the rig's operator
hooks are called the way the acquisition session calls them (air supplied and
valves closed once, then per trial or push: settle, baseline window, load,
settle, loaded window, unload), and each window is the mean of sampled, noisy
ADC counts calibrated by the protocol, as a recorded run has it.  The result
is the CSV exchange table of ``docs/table-formats.md``.  ``labcli acquire`` on a
``sim://`` port is the full path through the serial protocol.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from typing import Any

import numpy as np

from .objects import DEMO_OBJECTS, DEMO_PHI_DEG, SimObject
from .physics import G


def _window(rig: Any, calibration: Any, n: int, rate_hz: float) -> np.ndarray:
    _, counts = rig.samples(n, rate_hz)
    return np.asarray(calibration.to_si(counts), dtype=float).mean(axis=0)


def _pressurise(rig: Any, settle_s: float) -> None:
    rig.release_object()
    rig.remove_weight()
    rig.supply_air()
    rig.advance(settle_s)
    rig.close_valves()


class _Air:
    """Re-pressurising as the acquisition session does it, by its own rule
    (:class:`labcli.core.air.AirDrift`): each baseline's pressures against the first baseline since
    the last supply; once a chamber has drifted past ``limit_kPa`` the chambers are supplied for
    ``settle_s``, held, and the baseline is taken again.  ``limit_kPa`` <= 0: never (the valves
    held for the whole run, as before)."""

    def __init__(self, rig: Any, p_idx: list[int], limit_kPa: float, settle_s: float) -> None:
        from ....core.air import AirDrift, AirSettings

        self.rig, self.settle_s = rig, settle_s
        names = [str(c) for c in rig.channels]
        settings = AirSettings(repressurise_kPa=float(limit_kPa), repressurise_default=False)
        self.drift = AirDrift(names, p_idx, settings) if limit_kPa > 0 else None

    def baseline(self, window: Any) -> np.ndarray:
        """Settle, then the baseline window (supplying again first when the chambers drifted)."""
        while True:
            self.rig.advance(self.settle_s)
            base = window()
            if self.drift is None or self.drift.check(_Means(base)) is None:
                return base
            self.rig.supply_air()
            self.rig.advance(self.settle_s)
            self.rig.close_valves()
            self.drift.supplied()


class _Means:
    """A window's channel means where :meth:`AirDrift.check` takes a window (its ``mean()``)."""

    def __init__(self, means: np.ndarray) -> None:
        self.means = means

    def mean(self) -> np.ndarray:
        return self.means


def _indices(rig: Any) -> tuple[list[int], list[int]]:
    names = list(rig.channels)
    return [names.index(c) for c in ("P_L1", "P_R1", "P_L2", "P_R2")], [names.index(c) for c in ("POT1", "POT2")]


def simulate_weight_trials(
    rig: Any,
    plan: Any,
    *,
    calibration: Any,
    rate_hz: float = 200.0,
    capture_s: float = 1.0,
    settle_s: float = 6.0,
    relief_s: float = 0.0,
    relief_vent_s: float = 0.0,
    relief_vent: str = "L",
    repressurise_kPa: float = 0.0,
) -> Any:
    """Hang each plan row's weight (``trial, set, mass_g, direction_deg``) and return the trial table.

    ``relief_s`` > 0: the protocol's friction relief (``acquisition.friction_relief_s``), the
    chambers supplied for that long and held again before each baseline, as the session does it;
    ``relief_vent_s`` > 0: first the ``relief_vent`` side's actuators (L or R) vented for that
    long, the others held (``acquisition.friction_relief_vent_s``, ``friction_relief_vent`` of a
    run that vents one side; the session's default, per load, is not simulated here).
    ``repressurise_kPa`` > 0: the chambers supplied again once a baseline drifted that far since the
    last supply (``acquisition.repressurise_kPa``, as ``labcli acquire`` on a board that drives its
    valves does it); 0 holds them for the whole run.
    """
    import pandas as pd

    if relief_vent_s > 0 and relief_vent not in ("L", "R"):
        # The session's per-load side ("load") needs the guard's statics, which this driver has not:
        # matched as a prefix it would vent nothing and say nothing.
        raise ValueError(f"relief_vent must be 'L' or 'R' here, not {relief_vent!r}")
    p_idx, a_idx = _indices(rig)
    n = max(1, int(round(capture_s * rate_hz)))
    _pressurise(rig, settle_s)
    air = _Air(rig, p_idx, repressurise_kPa, settle_s)
    rows = []
    for r in plan.itertuples():
        if relief_vent_s > 0:
            rig.set_valves(tuple("vent" if c.startswith(f"P_{relief_vent}") else "hold" for c in rig.valve_channels))
            rig.advance(relief_vent_s)
        if relief_s > 0:
            rig.supply_air()
            rig.advance(relief_s)
            rig.close_valves()
        base = air.baseline(lambda: _window(rig, calibration, n, rate_hz))
        m, direction = float(r.mass_g) / 1000.0, math.radians(float(r.direction_deg))
        rig.hang_weight(m, direction)
        rig.advance(settle_s)
        loaded = _window(rig, calibration, n, rate_hz)
        rig.remove_weight()
        dth = np.degrees(loaded[a_idx] - base[a_idx])
        rows.append(
            {
                "trial": int(r.trial),
                "set": str(r.set),
                **dict(zip(("P_L10", "P_R10", "P_L20", "P_R20"), base[p_idx], strict=False)),
                **dict(zip(("P_L1", "P_R1", "P_L2", "P_R2"), loaded[p_idx], strict=False)),
                "theta1_deg": dth[0],
                "theta2_deg": dth[1],
                "Fx_N": m * G * math.cos(direction),
                "Fy_N": m * G * math.sin(direction),
                "mass_g": float(r.mass_g),
                "direction_deg": float(r.direction_deg),
            }
        )
    return pd.DataFrame(rows)


def simulate_pushes(
    rig: Any,
    objects: Iterable[SimObject] = DEMO_OBJECTS,
    *,
    calibration: Any,
    pushes_per_object: int = 10,
    phi_deg: Sequence[float] = DEMO_PHI_DEG,
    phi_known: bool = True,
    labelled: bool = False,
    rate_hz: float = 200.0,
    capture_s: float = 1.0,
    settle_s: float = 6.0,
    first_push: int = 1,
    repressurise_kPa: float = 0.0,
) -> Any:
    """Push each object on the simulated rig and return the push table (DataFrame).

    The rig is pressurised and its valves closed once, as at the real rig;
    every push then averages a ``capture_s`` window of sampled, noisy ADC
    counts (calibrated by ``calibration.to_si``) before and after the push,
    ``settle_s`` after each change (the lag's time constant is about 0.7 s).
    Extra columns: ``true_stiffness_N_per_m``, ``theta1_deg, theta2_deg``
    (potentiometer deflections) and ``true_phi_deg`` (the direction used even
    when the table leaves ``phi_deg`` empty).  ``repressurise_kPa``: as for
    :func:`simulate_weight_trials`.
    """
    import pandas as pd

    p_idx, a_idx = _indices(rig)
    n = max(1, int(round(capture_s * rate_hz)))

    def window() -> np.ndarray:
        return _window(rig, calibration, n, rate_hz)

    _pressurise(rig, settle_s)
    air = _Air(rig, p_idx, repressurise_kPa, settle_s)
    rows = []
    push = first_push
    for obj in objects:
        for k in range(pushes_per_object):
            phi = float(phi_deg[k % len(phi_deg)])
            base = air.baseline(window)
            rig.push_object(obj.radius_m, obj.distance_m, math.radians(phi), obj.stiffness_N_per_m)
            rig.advance(settle_s)
            loaded = window()
            rig.release_object()
            dth = np.degrees(loaded[a_idx] - base[a_idx])
            rows.append(
                {
                    "push": push,
                    "object": obj.name,
                    "R_m": obj.radius_m,
                    "d_m": obj.distance_m,
                    "phi_deg": phi if phi_known else math.nan,
                    **dict(zip(("P_L10", "P_R10", "P_L20", "P_R20"), base[p_idx], strict=False)),
                    **dict(zip(("P_L1", "P_R1", "P_L2", "P_R2"), loaded[p_idx], strict=False)),
                    "category": obj.category if labelled else "",
                    "true_stiffness_N_per_m": obj.stiffness_N_per_m,
                    "theta1_deg": dth[0],
                    "theta2_deg": dth[1],
                    "true_phi_deg": phi,
                }
            )
            push += 1
    return pd.DataFrame(rows)
