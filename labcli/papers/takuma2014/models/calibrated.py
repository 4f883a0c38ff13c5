"""What a model file says about the data it was fitted on, beyond its coefficients.

* ``calibrated_range``: the span of the fit trials' inputs and answers (baseline pressures P0
  and pressure drops P0 - P in MPa per actuator, rest posture, deflections in deg, forces in N),
  so that an estimate from inputs outside them can be flagged ``out-of-range``
  (:mod:`..sensing`);
* ``baseline``: how the fit trials' P0 was taken (:mod:`.leak`): ``p0_leak_corrected`` and the
  median baseline-to-capture ``gap_s`` (null when the trials carried no window times);
* ``captures_per_load``: how many captures each fit row averaged (``acquisition.captures_per_load``),
  written only when more than one, so that a model of one capture a load is written as before.
  The standard errors of a model fitted on averaged rows are an averaged row's
  (:mod:`..captures`), too narrow for one capture: the commands applying it say so.

All are optional: a model file written before them reads as "no range known", "P0 as
measured, gap unknown" and "one capture a load".
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np

from ....errors import ModelError
from ..tables import BASELINE as BASELINE_COLUMNS
from ..tables import LOADED as LOADED_COLUMNS
from ..tables import REST

ANGLE_COLUMNS = ("theta1_deg", "theta2_deg")
FORCE_COLUMNS = ("Fx_N", "Fy_N")
RANGE_KEYS = {"P0_MPa": 4, "dP_MPa": 4, "rest_deg": 2, "theta_deg": 2, "F_N": 2}


def calibrated_range(
    table: Any, rows: np.ndarray, taken: Mapping[str, np.ndarray] | None = None
) -> dict[str, list[list[float]]]:
    """[min, max] per component of each of :data:`RANGE_KEYS` over the ``rows`` (a mask) of a trial table.

    A key's span is over the rows where all its components are finite.  Worked one column at a
    time: numpy's reductions along a 4-wide axis of an (n, 4) stack took a second at 10^6 trials.
    ``taken``: columns the caller has already taken over ``rows`` as floats (the posture fit's
    pressures and forces), used as they are: picking them out again was 40 ms at 10^6 trials.
    """
    taken = {} if taken is None else taken

    def cols(names: tuple[str, ...]) -> list[np.ndarray] | None:
        if not all(c in table.columns for c in names):
            return None
        return [taken[c] if c in taken else np.asarray(table[c], dtype=float)[rows] for c in names]

    P0, P = cols(BASELINE_COLUMNS), cols(LOADED_COLUMNS)
    parts = {
        "P0_MPa": P0,
        "dP_MPa": None if P0 is None or P is None else [a - b for a, b in zip(P0, P, strict=True)],
        "rest_deg": cols(REST),
        "theta_deg": cols(ANGLE_COLUMNS),
        "F_N": cols(FORCE_COLUMNS),
    }
    out = {}
    for key, x in parts.items():
        if x is None:
            continue
        ok = np.logical_and.reduce([np.isfinite(c) for c in x])
        if ok.all():
            out[key] = [[float(c.min()), float(c.max())] for c in x]
        elif ok.any():
            out[key] = [[float(c[ok].min()), float(c[ok].max())] for c in x]
    return out


def check_range(value: Any, name: str) -> dict[str, list[list[float]]]:
    """A model file's ``calibrated_range``, checked (ModelError naming the key)."""
    if value is None:
        return {}
    bad = not isinstance(value, Mapping) or not set(value) <= set(RANGE_KEYS)
    for key, n in RANGE_KEYS.items():
        if bad or key not in value:
            continue
        try:
            a = np.asarray(value[key], dtype=float)
        except (TypeError, ValueError):
            bad = True
            continue
        bad = a.shape != (n, 2) or not np.all(np.isfinite(a)) or bool(np.any(a[:, 0] > a[:, 1]))
    if bad:
        raise ModelError(
            f"{name[:1].upper()}{name[1:]}: key 'calibrated_range' must map "
            f"{', '.join(RANGE_KEYS)} to [min, max] pairs of finite numbers; refit with `labcli fit`."
        )
    return {k: [[float(lo), float(hi)] for lo, hi in v] for k, v in value.items()}


def check_baseline(value: Any, name: str) -> tuple[bool, float | None]:
    """A model file's ``baseline`` (``p0_leak_corrected``, ``gap_s``), checked; absent: (False, None)."""
    if value is None:
        return False, None
    corrected = value.get("p0_leak_corrected", False) if isinstance(value, Mapping) else None
    gap = value.get("gap_s") if isinstance(value, Mapping) else None
    gap_ok = gap is None or (
        isinstance(gap, (int, float)) and not isinstance(gap, bool) and math.isfinite(gap) and gap >= 0
    )
    if not isinstance(corrected, bool) or not gap_ok or not set(value) <= {"p0_leak_corrected", "gap_s"}:
        raise ModelError(
            f"{name[:1].upper()}{name[1:]}: key 'baseline' must hold p0_leak_corrected (true or false) and "
            "gap_s (seconds, or null); refit with `labcli fit`."
        )
    return corrected, None if gap is None else float(gap)


def baseline_dict(corrected: bool, gap_s: float | None) -> dict[str, Any]:
    return {"p0_leak_corrected": bool(corrected), "gap_s": gap_s}


def check_captures(value: Any, name: str) -> int:
    """A model file's ``captures_per_load``, checked; absent: 1."""
    if value is None:
        return 1
    if not isinstance(value, int) or isinstance(value, bool) or not 1 <= value <= 100:
        raise ModelError(
            f"{name[:1].upper()}{name[1:]}: key 'captures_per_load' must be a whole number of captures, "
            "1 to 100; refit with `labcli fit`."
        )
    return value


def captures_dict(captures: int) -> dict[str, int]:
    """The model file's ``captures_per_load`` entry: none for one capture a load (files as before)."""
    return {"captures_per_load": int(captures)} if captures > 1 else {}
