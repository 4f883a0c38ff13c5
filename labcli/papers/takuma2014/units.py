"""Tables whose values contradict their units: refused, or warned, in one sentence naming the column.

A trial or push table states its units in its column names (``docs/table-formats.md``): pressures
in MPa gauge, angles in degrees, forces in newtons.  Every cell can be in range and the table still
be in the wrong unit; a fit on it runs and reports nonsense ("theta1 RMSE 0.00176 deg").  What
the values themselves give away:

* **Forces against the load that made them.**  A row with ``mass_g`` and ``direction_deg`` says
  what ``Fx_N, Fy_N`` must be: ``m g (cos d, sin d)`` (Section 3.2's pulley).  When most such rows
  instead match one known slip, the table is refused naming it: the load in gram-force (``|F|``
  equal to ``mass_g``) or kilogram-force, Fx and Fy swapped, or a sign flipped on one or both.
  Rows that match nothing (a measured force, a pulley's friction) are only warned about when more
  than :data:`FORCE_TOLERANCE` off on most of them.
* **Deflections in radians.**  The plan's loads (a few newtons) move the arm by degrees; a table
  whose ``theta1_deg, theta2_deg`` never reach :data:`RADIAN_LIKE_DEG` while its forces reach
  :data:`RADIAN_LOAD_N` holds radians (a degree is 0.017 rad).  Warned: a very stiff rig could
  do it.
* **Absolute pressures.**  Gauge pressures read 0 at the atmosphere; absolute ones never fall
  below it.  Every baseline pressure within :data:`ATMOSPHERE_BAND_MPA` of the atmosphere's
  0.101 MPa is a rig at rest read in absolute pressure (or one pressurised to just that, which
  the warning names).

:func:`unit_findings` returns the findings as data; :func:`check_units` raises the refusals as
one :class:`~labcli.core.tables.TableError` and warns the rest (:class:`~labcli.errors.LabcliWarning`).
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass
from typing import Any

import numpy as np

from ...core.arrays import stack_columns
from ...core.bounds import fmt_number
from ...core.tables import table_error
from ...errors import LabcliWarning

G = 9.80665  # m/s^2, standard gravity: the weight of the plan's masses
ATMOSPHERE_MPA = 0.101325
ATMOSPHERE_BAND_MPA = 0.015  # a rig at rest read absolute: every baseline within this of 1 atm
RADIAN_LIKE_DEG = 0.2  # no deflection reaches this (deg) ...
RADIAN_LOAD_N = 2.0  # ... while the loads reach this (N): radians in a degree column
FORCE_TOLERANCE = 0.10  # relative; plus FORCE_FLOOR_N: a row "matches" a reading within it
FORCE_FLOOR_N = 0.02
MISTAKE_SHARE = 0.5  # a slip explains at least this share of the checkable rows (and 3 of them)
MISTAKE_MIN_ROWS = 3

_FORCES = ("Fx_N", "Fy_N")
_BASELINE = ("P_L10", "P_R10", "P_L20", "P_R20")
_DEFLECTIONS = ("theta1_deg", "theta2_deg")


@dataclass(frozen=True)
class Finding:
    """One contradiction: the columns it concerns, whether it refuses the table, the sentence."""

    columns: tuple[str, ...]
    refuse: bool
    sentence: str


# The slips a force column is known to suffer, as maps from the load's m g (cos d, sin d) in N to
# what the column would then hold.  Checked in this order after "as stated".
_SLIPS: tuple[tuple[str, Any], ...] = (
    ("they hold the load in gram-force (|F| equals mass_g); the columns are in newtons", lambda e: e * 1000.0 / G),
    ("they hold the load in kilogram-force; the columns are in newtons", lambda e: e / G),
    ("Fx and Fy are swapped", lambda e: e[:, ::-1]),
    ("both signs are flipped (the force the arm exerts, not the load on it)", lambda e: -e),
    ("Fx's sign is flipped", lambda e: e * np.array([-1.0, 1.0])),
    ("Fy's sign is flipped", lambda e: e * np.array([1.0, -1.0])),
)


def _matches(f: np.ndarray, e: np.ndarray) -> np.ndarray:
    tol = FORCE_TOLERANCE * np.linalg.norm(e, axis=1) + FORCE_FLOOR_N
    return np.linalg.norm(f - e, axis=1) <= tol


def _column(table: Any, name: str) -> np.ndarray | None:
    if name not in getattr(table, "columns", ()):
        return None
    return np.asarray(table[name], dtype=float)


def force_findings(table: Any) -> list[Finding]:
    """Fx_N, Fy_N against mass_g and direction_deg, row by row (rows with both, and a mass > 0)."""
    found = [_column(table, c) for c in ("mass_g", "direction_deg", *_FORCES)]
    cols = [c for c in found if c is not None]
    if len(cols) < len(found):
        return []
    mass_g, direction, fx, fy = cols
    use = np.isfinite(mass_g) & np.isfinite(direction) & np.isfinite(fx) & np.isfinite(fy) & (mass_g > 0)
    n = int(use.sum())
    if n == 0:
        return []
    d = np.radians(direction[use])
    e = (mass_g[use] / 1000.0 * G)[:, None] * stack_columns([np.cos(d), np.sin(d)])
    f = stack_columns([fx[use], fy[use]])
    ok = _matches(f, e)
    need = max(MISTAKE_MIN_ROWS, math.ceil(MISTAKE_SHARE * n)) if n >= MISTAKE_MIN_ROWS else n
    for what, slip in _SLIPS:
        hits = int((_matches(f, slip(e)) & ~ok).sum())
        if hits >= need:
            return [
                Finding(
                    _FORCES,
                    True,
                    f"Fx_N and Fy_N contradict mass_g and direction_deg on {hits} of {n} rows: {what}; "
                    "a pulley load of m grams at direction d pulls m/1000 * 9.80665 * (cos d, sin d) N.",
                )
            ]
    off = n - int(ok.sum())
    if off > n / 2:
        first = int(np.flatnonzero(use)[np.flatnonzero(~ok)[0]]) + 2  # as a spreadsheet numbers rows
        return [
            Finding(
                _FORCES,
                False,
                f"Fx_N and Fy_N differ from the pulley load m g (cos d, sin d) of mass_g and direction_deg "
                f"by more than {fmt_number(100 * FORCE_TOLERANCE)} % on {off} of {n} rows (the first at row "
                f"{first}); check the force columns' unit (N) and sign.",
            )
        ]
    return []


def radian_findings(table: Any) -> list[Finding]:
    """theta1_deg, theta2_deg that never reach RADIAN_LIKE_DEG under loads of RADIAN_LOAD_N and more."""
    found = [_column(table, c) for c in (*_DEFLECTIONS, *_FORCES)]
    cols = [c for c in found if c is not None]
    if len(cols) < len(found):
        return []
    load = np.hypot(cols[2], cols[3])
    # Column by column: the trials under a large load whose two deflections are both known.
    sel = np.isfinite(load) & (load >= RADIAN_LOAD_N) & np.isfinite(cols[0]) & np.isfinite(cols[1])
    if np.count_nonzero(sel) < MISTAKE_MIN_ROWS:
        return []
    largest = max(float(np.max(np.abs(cols[0][sel]))), float(np.max(np.abs(cols[1][sel]))))
    if largest >= RADIAN_LIKE_DEG:
        return []
    return [
        Finding(
            _DEFLECTIONS,
            False,
            f"theta1_deg and theta2_deg look like radians: no deflection reaches "
            f"{fmt_number(RADIAN_LIKE_DEG)} deg (largest {largest:.3g}) while the loads "
            f"reach {float(np.nanmax(load)):.3g} N; the columns hold degrees (1 rad = 57.3 deg).",
        )
    ]


def pressure_findings(table: Any) -> list[Finding]:
    """Every baseline pressure within ATMOSPHERE_BAND_MPA of the atmosphere: absolute, not gauge."""
    found = [_column(table, c) for c in _BASELINE]
    cols = [c for c in found if c is not None]
    if len(cols) < len(found):
        return []
    # Column by column over the trials whose four baselines are known: none outside the band.
    known = np.logical_and.reduce([np.isfinite(c) for c in cols])
    if not known.any() or any(np.any(known & (np.abs(c - ATMOSPHERE_MPA) > ATMOSPHERE_BAND_MPA)) for c in cols):
        return []
    return [
        Finding(
            _BASELINE,
            False,
            f"P_L10, P_R10, P_L20 and P_R20 look like absolute pressures: every baseline is within "
            f"{fmt_number(ATMOSPHERE_BAND_MPA * 1e3)} kPa of the atmosphere's 0.101 MPa; the pressure columns "
            "hold gauge pressures (0 at the atmosphere), so subtract 0.101 MPa unless the rig really ran at that.",
        )
    ]


def unit_findings(table: Any) -> list[Finding]:
    """Every contradiction between a trial or push table's values and its units."""
    return [*force_findings(table), *radian_findings(table), *pressure_findings(table)]


def check_units(table: Any, label: str) -> Any:
    """Refuse ``table`` (one TableError naming ``label``) or warn, per :func:`unit_findings`; returns it."""
    findings = unit_findings(table)
    refusals = [f"{label}: {f.sentence}" for f in findings if f.refuse]
    if refusals:
        raise table_error(label, refusals)
    for f in findings:
        warnings.warn(LabcliWarning(f"{label}: {f.sentence}"), stacklevel=3)
    return table
