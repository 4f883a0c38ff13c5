"""The rig's air under the board's valves: supply, hold, the hold check and re-pressurising.

A wire-protocol 1.1 board drives each chamber's valve (``VALVE ... SUPPLY|HOLD|VENT``), so a
session need not *ask* for air and trust that it came: it supplies and holds by command and
reads what the chambers do (:class:`AirSettings` holds the protocol's limits):

* **the hold check** (:func:`hold_problem`): with every valve holding, each chamber's pressure is
  fitted against time over ``hold_check_s``, once the arm has settled on the closed chambers
  (what is left of that settling adds up to half a kPa/min to the leak on the simulated rig,
  whose chambers lose 0.2-2.6 kPa/min on seeds 1-30); a chamber that loses more than
  ``leak_max_kPa_per_min`` leaks (a tube, a fitting, a valve's seat), one that gains as much is
  fed through a valve that should be closed.  Either is named before the first trial.  The slope's
  standard error is far below the limit: 0.15 kPa of noise over 5 s at 200 Hz fits a slope to
  about 0.1 kPa/min.
* **the steady leak**: the slopes the hold check measured are each held chamber's leak; the
  trials' waits take them out of the settling rule's tail (``AirDrift.leak_per_s``,
  :mod:`labcli.core.settle`), so that a chamber losing a few kPa/min steadily is not read as a
  load still settling (seed 3 of the simulated rig, 3.6 kPa/min, had most of its windows accepted
  at the timeout before).
* **re-pressurising** (:class:`AirDrift`): the chambers leak (about 1 kPa/min on the reference
  rig), and a run of 108 trials holds its air for half an hour or more, so the operating point
  drifts under the fitted model.  Each trial's baseline is compared with the first baseline after
  the last supply; once any chamber has drifted by more than ``repressurise_kPa`` the session
  supplies and holds again and retakes the baseline.  The default limit is
  :data:`REPRESSURISE_FLOORS` pressure floors (the settling criterion's pressure spread, at least
  one count): ten times what the protocol calls still, 3.1 kPa on the paper's protocol.
* **friction relief** (``friction_relief_s``, off by default): a supply pulse of that length, then
  hold, before each trial's baseline.  It sets every baseline's pressures back to the regulator's,
  but the sleeves' friction holds the arm where the last load left it (the pulse barely moves the
  arm), so the baseline's friction still follows the history.  On held-out seeds of the kind
  simulated rig it lowers every RMSE of the re-pressurising run by 6-17 %
  (tests/benchmarks/bench_air.py, docs/air.md).  With ``friction_relief_vent_s`` the pulse starts
  with one side's actuators (``friction_relief_vent``: L1 and L2, or R1 and R2) vented for that
  long: the other side swings the arm over, and supplied again it comes back to its rest from that
  side, so the baseline's friction no longer follows the last load (venting all four would not do
  it: on the straight arm the vented posture is close to the rest, and the side it comes back from
  still follows the history).  By default (``"load"``) the side vented is the one each load pulls
  the arm towards (the session finds it from the rig's statics), so that every load pulls the arm
  away from its baseline's lean and moves it at once; venting one side for every trial, the loads
  that pull towards the lean must first overcome two friction bands, which on the literature's rig
  hold a light load entirely, and the load check cannot tell such a trial from one never hung
  (docs/load-check.md).  The posture form's relieved friction terms
  (``PostureModel(friction="relieved")``) fit what is left, and since the baselines now repeat,
  each trial's P0 is the mean of the last few (docs/rig-realism.md).
  Both stay off by default until judged on a real rig.
* **captures per load** (``captures_per_load``, 1 by default): each plan load taken that many
  times in a row, each capture preceded by the relief, so that the pressure sensors read afresh;
  the run stores every capture and the analyses average a load's captures into one row (the
  repeatability's variance over N; tests/benchmarks/multi_capture.py).  A protocol that asks for
  more than one capture and gives no ``friction_relief_s`` gets the relief that benchmark was
  chosen with on seeds 1-10 (:data:`CAPTURE_RELIEF`: a 3 s supply pulse after a 2 s vent).
* **the valves at the end** (``end_valves``): ``hold`` (the default) or ``vent``, set when the
  session ends, however it ends (finished, quit, Ctrl-C, an error); the board is never left
  supplying.  A board that loses its host keeps its pressure limit (``PMAX``) on its own.

``valves = "hand"`` in ``[acquisition]`` keeps the prompts of a 1.0 board ("supply compressed
air", "close the valves") on a board that could drive its valves.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

VALVE_MODES = ("auto", "hand")
END_STATES = ("hold", "vent")
RELIEF_SIDES = ("L", "R")  # the side of each pair the relief vents
# acquisition.friction_relief_vent: "load" (the side each load pulls the arm towards, found by the
# session from the rig's statics; L where it finds none) or one side for every trial.
RELIEF_VENTS = ("load", *RELIEF_SIDES)
DEFAULT_LEAK_MAX_KPA_PER_MIN = 5.0  # five times the reference rig's leak of about 1 kPa/min
DEFAULT_HOLD_CHECK_S = 5.0
REPRESSURISE_FLOORS = 10.0
MAX_CAPTURES = 10  # captures of one load: 10 relieved captures already take ten trials' time
CAPTURE_RELIEF = (3.0, 2.0)  # (supply pulse s, vent s) before each capture unless the protocol gives its own
COUNT_MPA = 5.0 / 16380  # one count of the reference calibration, the floor's floor when none is known

# The [acquisition] keys of this module (labcli.core.protocol's key-spec language).
ACQUISITION_KEYS: dict[str, dict[str, Any]] = {
    "valves": {
        "type": "str",
        "check": ["one-of", list(VALVE_MODES)],
        "optional": True,
        "help": "auto: a board with valves supplies and holds by command; hand: the prompts ask for it",
    },
    "end_valves": {
        "type": "str",
        "check": ["one-of", list(END_STATES)],
        "optional": True,
        "help": "the valves when the session ends, by command: hold or vent",
    },
    "leak_max_kPa_per_min": {
        "type": "number",
        "unit": "kPa/min",
        "check": "positive",
        "optional": True,
        "help": "the largest pressure change of a holding chamber the hold check lets pass",
    },
    "hold_check_s": {
        "type": "number",
        "unit": "s",
        "check": "positive",
        "max": 600,
        "optional": True,
        "help": "how long the hold check watches the held chambers",
    },
    "friction_relief_s": {
        "type": "number",
        "unit": "s",
        "check": "nonnegative",
        "max": 10,
        "optional": True,
        "help": "a supply pulse this long before each baseline, to shake the sleeves' friction loose (0: none)",
    },
    "friction_relief_vent_s": {
        "type": "number",
        "unit": "s",
        "check": "nonnegative",
        "max": 10,
        "optional": True,
        "help": "vent one side's chambers (friction_relief_vent) this long before the relief's supply "
        "pulse, so that every baseline is approached from that side (0: supply pulse only; needs "
        "friction_relief_s)",
    },
    "friction_relief_vent": {
        "type": "str",
        "check": ["one-of", list(RELIEF_VENTS)],
        "optional": True,
        "help": "the actuators vented by the relief: load (the side each load pulls the arm towards, so "
        "that the load pulls it away from where its baseline leans; the default), L (L1 and L2; the R "
        "actuators swing the arm to their side) or R",
    },
    "captures_per_load": {
        "type": "int",
        "check": "positive",
        "max": MAX_CAPTURES,
        "optional": True,
        "help": "take each plan load this many times in a row, each capture after the friction relief "
        "(a 3 s supply pulse after a 2 s vent unless friction_relief_s is given); fit, validate and "
        "predict average a load's captures into one row",
    },
    "repressurise_kPa": {
        "type": "number",
        "unit": "kPa",
        "check": "positive",
        "optional": True,
        "help": "a baseline's drift since the last supply that has the chambers supplied again",
    },
}


@dataclass(frozen=True)
class AirSettings:
    """The protocol's air settings (``[acquisition]``), defaults filled in."""

    valves: str = "auto"
    end_valves: str = "hold"
    leak_max_kPa_per_min: float = DEFAULT_LEAK_MAX_KPA_PER_MIN
    hold_check_s: float = DEFAULT_HOLD_CHECK_S
    repressurise_kPa: float = REPRESSURISE_FLOORS * COUNT_MPA * 1e3
    repressurise_default: bool = True  # the limit came from the sensor noise, not the protocol
    friction_relief_s: float = 0.0
    friction_relief_vent_s: float = 0.0
    friction_relief_vent: str = "load"
    captures_per_load: int = 1

    def relief_side(self, pulled: str | None = None) -> str:
        """The side the relief vents, L or R: with ``friction_relief_vent = "load"`` the side is
        ``pulled``, the side the trial's load pulls the arm towards (L where none is known)."""
        side = self.friction_relief_vent
        if side not in RELIEF_SIDES:
            side = pulled if pulled in RELIEF_SIDES else "L"
        return side

    def relief_vented(self, names: Sequence[str], pulled: str | None = None) -> tuple[str, ...]:
        """The pressure channels the relief vents: one side's actuator of each pair (``P_L1``,
        ``P_L2`` for L), the side :meth:`relief_side`."""
        side = self.relief_side(pulled)
        return tuple(n for n in names if n.upper().startswith(f"P_{side}"))

    @classmethod
    def of(cls, acquisition: dict[str, Any], pressure_floor_MPa: float | None) -> AirSettings:
        """From a checked ``[acquisition]`` table and the protocol's pressure floor (its settle spread)."""
        floor = max(pressure_floor_MPa or 0.0, COUNT_MPA)
        given = acquisition.get("repressurise_kPa")
        captures = int(acquisition.get("captures_per_load", 1))
        pulse, vent = CAPTURE_RELIEF if captures > 1 and "friction_relief_s" not in acquisition else (0.0, 0.0)
        return cls(
            valves=acquisition.get("valves", "auto"),
            end_valves=acquisition.get("end_valves", "hold"),
            leak_max_kPa_per_min=float(acquisition.get("leak_max_kPa_per_min", DEFAULT_LEAK_MAX_KPA_PER_MIN)),
            hold_check_s=float(acquisition.get("hold_check_s", DEFAULT_HOLD_CHECK_S)),
            repressurise_kPa=float(given) if given is not None else REPRESSURISE_FLOORS * floor * 1e3,
            repressurise_default=given is None,
            friction_relief_s=float(acquisition.get("friction_relief_s", pulse)),
            friction_relief_vent_s=float(acquisition.get("friction_relief_vent_s", vent)),
            friction_relief_vent=acquisition.get("friction_relief_vent", "load"),
            captures_per_load=captures,
        )


def record_ids(loads: Any, captures: int) -> np.ndarray:
    """Every capture's record id of the plan trials ``loads``, in order: (load - 1) N + capture, so a
    plan's captures are ids in the plan's order and one capture a load keeps the plan's ids."""
    base = (np.asarray(loads, dtype=np.int64) - 1) * captures
    return (base[:, None] + np.arange(1, captures + 1)[None, :]).ravel()


def load_ids(ids: Any, captures: int) -> np.ndarray:
    """The plan trial of each record id (:func:`record_ids` undone)."""
    return (np.asarray(ids, dtype=np.int64) - 1) // captures + 1


def hold_problem(names: Sequence[str], rate_MPa_per_s: Sequence[float], settings: AirSettings) -> str | None:
    """What the hold check found (a chamber losing or gaining air with its valve holding), or None."""
    rate = np.asarray(rate_MPa_per_s, dtype=float) * 60e3  # kPa/min
    limit = settings.leak_max_kPa_per_min
    losing = [(n, r) for n, r in zip(names, rate, strict=True) if r < -limit]
    gaining = [(n, r) for n, r in zip(names, rate, strict=True) if r > limit]
    if not losing and not gaining:
        return None
    found = []
    if losing:
        listed = ", ".join(f"{n} loses {-r:.1f} kPa/min" for n, r in losing)
        found.append(
            f"{listed} with {'its valve' if len(losing) == 1 else 'their valves'} holding: a leak; check "
            + (
                "that actuator's tube, fittings and valve seat"
                if len(losing) == 1
                else "those actuators' tubes, fittings and valve seats"
            )
        )
    if gaining:
        listed = ", ".join(f"{n} gains {r:.1f} kPa/min" for n, r in gaining)
        found.append(
            f"{listed} with {'its valve' if len(gaining) == 1 else 'their valves'} holding: a supply valve that "
            "does not close (stuck open, or driven by the wrong pin)"
        )
    return (
        "The hold check found " + "; ".join(found) + f" (the protocol allows {limit:g} kPa/min: "
        "acquisition.leak_max_kPa_per_min)"
    )


class AirDrift:
    """How far the held chambers have drifted since the first baseline after the last supply."""

    def __init__(
        self,
        names: Sequence[str],
        cols: Sequence[int],
        settings: AirSettings,
        rate_per_s: Sequence[float] | None = None,
    ) -> None:
        self.names = tuple(names)
        self.cols = list(cols)
        self.settings = settings
        # Every channel's steady drift (SI per s): the hold check's slope on the chambers, zero elsewhere.
        self.leak_per_s: tuple[float, ...] = ()
        if rate_per_s is not None:
            rate = np.asarray(rate_per_s, dtype=float)
            leak = np.zeros(len(rate))
            leak[self.cols] = np.where(np.isfinite(rate[self.cols]), rate[self.cols], 0.0)
            self.leak_per_s = tuple(float(x) for x in leak)
        self._reference: np.ndarray | None = None
        self.largest_kPa = 0.0  # the largest drift any baseline showed (before a re-supply)
        self.supplies = 0  # re-pressurisations so far

    def supplied(self) -> None:
        """The chambers were supplied again: the next baseline is the new reference."""
        self._reference = None
        self.supplies += 1

    def check(self, baseline: Any) -> str | None:
        """The sentence when ``baseline`` drifted past the limit (then supply again), else None."""
        p = np.asarray(baseline.mean(), dtype=float)[self.cols]
        if self._reference is None:
            self._reference = p
            return None
        drift = (p - self._reference) * 1e3
        j = int(np.argmax(np.abs(drift)))
        self.largest_kPa = max(self.largest_kPa, float(abs(drift[j])))
        if not abs(drift[j]) > self.settings.repressurise_kPa:
            return None
        whence = "from the sensor noise" if self.settings.repressurise_default else "acquisition.repressurise_kPa"
        return (
            f"{self.names[j]} has drifted {drift[j]:+.2f} kPa since the chambers were last supplied, past the "
            f"{self.settings.repressurise_kPa:.3g} kPa limit ({whence}): supplying and holding again"
        )


def slope_per_s(t_s: np.ndarray, values: np.ndarray) -> np.ndarray:
    """Least-squares slope of each column of ``values`` (n, k) against ``t_s`` (n,); nan if n < 2."""
    t = np.asarray(t_s, dtype=float)
    if len(t) < 2 or not math.isfinite(float(np.ptp(t))) or np.ptp(t) == 0:
        return np.full(np.shape(values)[1], np.nan)
    tc = t - t.mean()
    v = np.asarray(values, dtype=float)
    return (tc @ (v - v.mean(axis=0))) / float(tc @ tc)


class SlopeSums:
    """Running sums for each channel's least-squares slope against time, frame block by block
    (a hold check of any length takes the same memory)."""

    def __init__(self, channels: int) -> None:
        self.n = 0
        self._t0: float | None = None
        self._st = 0.0
        self._stt = 0.0
        self._sx = np.zeros(channels)
        self._stx = np.zeros(channels)

    def add(self, t_s: np.ndarray, values: np.ndarray) -> None:
        """Frames at times ``t_s`` (n,), values (n, channels)."""
        if not len(t_s):
            return
        if self._t0 is None:
            self._t0 = float(t_s[0])
        t = t_s - self._t0  # times from the first frame: the sums keep their digits
        self.n += len(t)
        self._st += float(t.sum())
        self._stt += float(t @ t)
        self._sx += values.sum(axis=0)
        self._stx += t @ values

    def result(self) -> tuple[np.ndarray, np.ndarray]:
        """(slope per s, mean) per channel; the slope is nan with fewer than two distinct times."""
        if self.n == 0:
            nan = np.full(len(self._sx), np.nan)
            return nan, nan
        mean_t = self._st / self.n
        stt = self._stt - self.n * mean_t**2
        mean = self._sx / self.n
        if not stt > 0:
            return np.full(len(mean), np.nan), mean
        return (self._stx - self.n * mean_t * mean) / stt, mean
