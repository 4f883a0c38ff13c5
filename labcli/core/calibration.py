"""Raw ADC counts to SI and back, per channel, as a protocol file declares it.

Every channel is linear in its counts::

    value[unit] = gain * (counts - zero_counts)

with ``unit`` as written in the protocol file (``MPa``, ``kPa``, ``deg`` ...).
Loading converts gain and range to the library's internal units: MPa (gauge)
for pressures, because the paper's coefficients are fitted in MPa, rad for
angles and m for lengths (the rPAM rig's draw-wire sensor).  Degrees and
millimetres appear only when a number is shown to a person
(:meth:`Calibration.to_display`, :func:`format_value`).

The reference rig (``docs/wire-protocol.md``) reads, for a 12-bit ADC at 5.0 V::

    P[MPa]     = (counts * 5.0 / 4095 - 1.0) / 4.0   -> gain 5/16380 MPa, zero 819
    angle[deg] = (counts - 2048) * 340 / 4095        -> gain 340/4095 deg, zero 2048

Writing the offset as the count that reads zero keeps the documented zero
points exact: 819 counts is exactly 0 MPa and 2048 counts exactly 0 rad.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

# Internal (SI) unit per quantity and the unit people read.
SI_UNITS: dict[str, str] = {"pressure": "MPa", "angle": "rad", "length": "m"}
DISPLAY_UNITS: dict[str, str] = {"pressure": "MPa", "angle": "deg", "length": "mm"}

# Factor from a unit a protocol file may use to the internal unit of its quantity.
UNIT_FACTORS: dict[str, dict[str, float]] = {
    "pressure": {"MPa": 1.0, "kPa": 1e-3, "Pa": 1e-6, "bar": 0.1, "psi": 0.006894757293168361},
    "angle": {"rad": 1.0, "deg": math.pi / 180.0},
    "length": {"m": 1.0, "mm": 1e-3},
}

# Internal -> display factor per quantity (MPa stays MPa, rad becomes deg, m becomes mm).
_DISPLAY_FACTORS: dict[str, float] = {"pressure": 1.0, "angle": 180.0 / math.pi, "length": 1e3}


@dataclass(frozen=True)
class Channel:
    """One calibrated channel; ``gain``, ``range`` in internal units (MPa or rad)."""

    name: str
    quantity: str  # "pressure" | "angle" | "length"
    gain: float  # internal unit per count
    zero_counts: float  # the count that reads zero
    range: tuple[float, float]  # plausible / sensor span, internal unit
    unit_in_file: str = ""  # unit the protocol file used (for messages)
    actuator: str | None = None  # "L1" | "R1" | "L2" | "R2" for pressure channels
    joint: int | None = None  # 1 (bottom) | 2 (upper) for angle channels

    @property
    def unit(self) -> str:
        return SI_UNITS[self.quantity]

    @property
    def display_unit(self) -> str:
        return DISPLAY_UNITS[self.quantity]


@dataclass(frozen=True, eq=False)
class Calibration:
    """Linear counts <-> SI for an ordered set of channels (the order of data lines)."""

    channels: tuple[Channel, ...]
    adc_range: tuple[float, float] = (0.0, 4095.0)
    _gain: np.ndarray = field(init=False, repr=False)
    _zero: np.ndarray = field(init=False, repr=False)
    _disp: np.ndarray = field(init=False, repr=False)

    def __post_init__(self) -> None:
        # Frozen dataclass: the cached vectors are set once, here.
        object.__setattr__(self, "_gain", np.array([c.gain for c in self.channels], dtype=float))
        object.__setattr__(self, "_zero", np.array([c.zero_counts for c in self.channels], dtype=float))
        object.__setattr__(self, "_disp", np.array([_DISPLAY_FACTORS[c.quantity] for c in self.channels], dtype=float))

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, Calibration):
            return NotImplemented
        return self.channels == other.channels and tuple(self.adc_range) == tuple(other.adc_range)

    __hash__ = None  # type: ignore[assignment]

    # -- description -----------------------------------------------------
    @property
    def names(self) -> tuple[str, ...]:
        return tuple(c.name for c in self.channels)

    @property
    def quantities(self) -> tuple[str, ...]:
        return tuple(c.quantity for c in self.channels)

    @property
    def units(self) -> tuple[str, ...]:
        """Internal unit per channel: ``MPa`` or ``rad``."""
        return tuple(c.unit for c in self.channels)

    @property
    def display_units(self) -> tuple[str, ...]:
        """Unit per channel as shown to people: ``MPa`` or ``deg``."""
        return tuple(c.display_unit for c in self.channels)

    @property
    def ranges(self) -> tuple[tuple[float, float], ...]:
        """Sensor span (pressures) or plausible range (angles), internal units."""
        return tuple(c.range for c in self.channels)

    @property
    def gains(self) -> np.ndarray:
        return self._gain.copy()

    @property
    def zero_counts(self) -> np.ndarray:
        return self._zero.copy()

    def index(self, name: str) -> int:
        """Column of channel ``name`` in a (n, k) array; KeyError if absent."""
        for i, c in enumerate(self.channels):
            if c.name == name:
                return i
        raise KeyError(name)

    def pressure_index(self) -> dict[str, int]:
        """Actuator (``L1``...) -> column of its pressure channel."""
        return {c.actuator: i for i, c in enumerate(self.channels) if c.quantity == "pressure" and c.actuator}

    def angle_index(self) -> dict[int, int]:
        """Joint (1, 2) -> column of its angle channel."""
        return {c.joint: i for i, c in enumerate(self.channels) if c.quantity == "angle" and c.joint}

    # -- conversion ------------------------------------------------------
    def _check_width(self, a: np.ndarray, what: str) -> None:
        if a.ndim == 0 or a.shape[-1] != len(self.channels):
            raise ValueError(
                f"{what} must have {len(self.channels)} values per row ({', '.join(self.names)}), got shape {a.shape}"
            )

    def to_si(self, counts: np.ndarray | Sequence) -> np.ndarray:
        """Counts (n, k) or (k,) -> MPa / rad, same shape, float64."""
        a = np.asarray(counts, dtype=float)
        self._check_width(a, "counts")
        return (a - self._zero) * self._gain

    def to_counts(self, si: np.ndarray | Sequence, *, integer: bool = False) -> np.ndarray:
        """MPa / rad -> counts; ``integer=True`` rounds and clips to the ADC range as an ADC would."""
        a = np.asarray(si, dtype=float)
        self._check_width(a, "values")
        c = a / self._gain + self._zero
        if integer:
            return np.clip(np.rint(c), self.adc_range[0], self.adc_range[1]).astype(np.int64)
        return c

    def to_display(self, si: np.ndarray | Sequence) -> np.ndarray:
        """MPa / rad -> MPa / deg (for printing)."""
        a = np.asarray(si, dtype=float)
        self._check_width(a, "values")
        return a * self._disp

    def from_display(self, shown: np.ndarray | Sequence) -> np.ndarray:
        """MPa / deg (as typed) -> MPa / rad."""
        a = np.asarray(shown, dtype=float)
        self._check_width(a, "values")
        return a / self._disp

    def in_range(self, si: np.ndarray | Sequence) -> np.ndarray:
        """Boolean mask, True where a value lies in its channel's range."""
        a = np.asarray(si, dtype=float)
        self._check_width(a, "values")
        lo = np.array([c.range[0] for c in self.channels])
        hi = np.array([c.range[1] for c in self.channels])
        return (a >= lo) & (a <= hi)


def to_display(value_si: float | np.ndarray, quantity: str) -> float | np.ndarray:
    """Internal unit -> display unit for ``quantity`` (``pressure``: MPa, ``angle``: deg)."""
    return value_si * _DISPLAY_FACTORS[quantity]


def from_display(value: float | np.ndarray, quantity: str) -> float | np.ndarray:
    """Display unit (MPa or deg) -> internal unit (MPa or rad)."""
    return value / _DISPLAY_FACTORS[quantity]


def format_value(value_si: float, quantity: str, digits: int | None = None) -> str:
    """A reading with its unit, e.g. ``0.3052 MPa`` or ``-12.35 deg``."""
    if digits is None:
        # Four decimals of MPa is 0.1 kPa, finer than one count (0.31 kPa);
        # two of deg is finer than one potentiometer count (0.083 deg), two of mm
        # finer than one count of the rPAM rig's draw-wire sensor (0.073 mm).
        digits = 4 if quantity == "pressure" else 2
    return f"{to_display(value_si, quantity):.{digits}f} {DISPLAY_UNITS[quantity]}"
