"""What a number in an exchange table may be: each quantity's unit and physical range, in one place.

A table column (:class:`labcli.core.tables.TableSpec`) names its kind, e.g. ``"angle"`` or
``"force-or-empty"``; the kind's :class:`Quantity` says the unit a cell is written in and
the range a value must fall in, so that a typo, a unit slip (millimetres typed as metres) or
a damaged file is refused by row and column instead of reaching a fit as ``1e308``.

The ranges are bench-top physics, wide enough for any rig the toolkit drives and narrow
enough to catch what no such rig can produce:

* joint angles within a half turn either way (a potentiometer covers 340 deg);
* directions any angle, within two turns either way; a direction is wrapped into
  (-180, 180] deg on reading (270 and -90 are the same direction, -180 reads 180), values
  already in that range are kept as typed;
* forces at the tip within 1 kN (about 100 kg): far beyond what a pneumatic arm of this
  size can exert or bear (a McKibben muscle at the 1 MPa sensor limit pulls a few hundred
  N at most, and the arm's levers reduce it at the tip);
* loads up to 100 kg, lengths up to 1 m (object radii, push distances and actuator lengths
  are centimetres);
* gauge pressures of a rig that reads below zero (rPAM), above perfect vacuum
  (-0.101325 MPa) and up to 1 MPa; the McKibben sensors' span is the protocol's
  (:data:`PRESSURE_SPAN_MPA` by default);
* stretch ratios up to 10 (silicone tears well before).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

ATMOSPHERE_MPA = 0.101325
PRESSURE_SPAN_MPA = (0.0, 1.0)  # what a "pressure" cell may hold unless a table says otherwise: gauge, MPa


@dataclass(frozen=True)
class Quantity:
    """A kind of number in a table: its unit, its range and, for directions, wrapping."""

    unit: str  # as cells are written and messages show it ("deg", "N", "g", "m", "MPa", "kPa"; "" for ratios)
    what: str  # the range in words: "a joint angle"
    lo: float
    hi: float
    sign: str = ""  # "positive" (> 0) or "nonnegative" (>= 0): checked first, in the words of the tables
    wrap: bool = False  # a direction: wrapped into (-180, 180] deg once in range

    def problem(self, v: float) -> str | None:
        """Why ``v`` (finite) cannot be this quantity, or None."""
        if self.sign == "positive" and not v > 0:
            return f"{fmt_number(v)} must be greater than 0"
        if self.sign == "nonnegative" and not v >= 0:
            return f"{fmt_number(v)} must be 0 or more"
        if not self.lo <= v <= self.hi:
            unit = f" {self.unit}" if self.unit else ""
            return (
                f"{fmt_number(v)}{unit} is outside the range of {self.what}, "
                f"{fmt_number(self.lo)} to {fmt_number(self.hi)}{unit}"
            )
        return None


QUANTITIES: dict[str, Quantity] = {
    "angle": Quantity("deg", "a joint angle", -180.0, 180.0),
    "direction": Quantity("deg", "a direction", -720.0, 720.0, wrap=True),
    "tip-force": Quantity("N", "a force at the tip", -1000.0, 1000.0),
    "mass": Quantity("g", "a load", 0.0, 100_000.0, sign="positive"),
    "payload": Quantity("g", "a load", 0.0, 100_000.0, sign="nonnegative"),
    "length": Quantity("m", "a length on the bench", 0.0, 1.0, sign="positive"),
    "distance": Quantity("m", "a length on the bench", 0.0, 1.0, sign="nonnegative"),
    "gauge": Quantity("MPa", "a gauge pressure", -ATMOSPHERE_MPA, 1.0),
    "gauge-kPa": Quantity("kPa", "a gauge pressure", -ATMOSPHERE_MPA * 1e3, 1000.0),
    "stretch": Quantity("", "a stretch ratio", 0.0, 10.0, sign="positive"),
}


def wrap_degrees(v: float) -> float:
    """A direction in (-180, 180] deg: values already there as given, others wrapped into it.

    The wrapped value is ``v - 360 k`` (exact in floating point) kept to 12 significant
    digits, the digits a table keeps of a converted angle, so that a table holding 200
    and its export holding -160 read back the same; -180 and 540 both read 180.
    """
    if -180.0 < v <= 180.0 or not math.isfinite(v):
        return v
    w = v - 360.0 * math.ceil((v - 180.0) / 360.0)
    if w > 180.0:
        w -= 360.0
    elif w <= -180.0:
        w += 360.0
    return float(f"{w:.12g}")


def wrap_degrees_array(v: Any) -> Any:
    """:func:`wrap_degrees` on a numpy array (NaN stays NaN)."""
    import numpy as np

    v = np.asarray(v, dtype=np.float64)
    outside = np.flatnonzero((v <= -180.0) | (v > 180.0))
    if not len(outside):
        return v
    out = v.copy()
    out[outside] = [wrap_degrees(float(x)) for x in v[outside]]
    return out


def fmt_number(v: float) -> str:
    """A number as a message shows it: an integer without a decimal point, else ``repr``."""
    return repr(float(v)) if v != int(v) or abs(v) >= 1e16 else str(int(v))


def number_problem(kind: str, v: float, span: tuple[float, float] = PRESSURE_SPAN_MPA) -> str | None:
    """Why the finite number ``v`` cannot be a cell of ``kind`` (without "-or-empty"), or None."""
    if kind == "pressure":
        lo, hi = span
        if not v > lo:
            return f"{fmt_number(v)} MPa is not a positive gauge pressure"
        if v > hi:
            return f"{fmt_number(v)} MPa is outside the sensor span {fmt_number(lo)} to {fmt_number(hi)} MPa"
    elif kind == "positive" and not v > 0:
        return f"{fmt_number(v)} must be greater than 0"
    elif kind == "nonnegative" and not v >= 0:
        return f"{fmt_number(v)} must be 0 or more"
    elif kind in QUANTITIES:
        return QUANTITIES[kind].problem(v)
    return None


def number_problem_mask(kind: str, v: Any, span: tuple[float, float] = PRESSURE_SPAN_MPA) -> Any:
    """Where :func:`number_problem` finds a problem, for a numpy array of finite numbers."""
    import numpy as np

    if kind == "pressure":
        return ~(v > span[0]) | (v > span[1])
    if kind == "positive":
        return ~(v > 0)
    if kind == "nonnegative":
        return ~(v >= 0)
    q = QUANTITIES.get(kind)
    if q is None:
        return np.zeros(len(v), dtype=bool)
    bad = ~((v >= q.lo) & (v <= q.hi))
    if q.sign == "positive":
        bad |= ~(v > 0)
    elif q.sign == "nonnegative":
        bad |= ~(v >= 0)
    return bad
