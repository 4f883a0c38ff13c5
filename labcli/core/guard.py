"""Is the rig as the prompts said?  Checks of the readings against what the experimenter was asked to do.

A person at the rig can press Enter without doing what a prompt asked: no air supplied,
a weight never hung, a weight left hanging.  The readings show each of these, and the
session says so before anything wrong is stored:

* **the supply** (:func:`supply_problem`): after "supply compressed air", every pressure
  channel must read at least the protocol's ``acquisition.supply_min_MPa``;
* **the load** (:meth:`Guard.after_load`): the change from the baseline to the loaded
  window is compared with what the run's earlier accepted trials did per unit of load
  (:class:`ResponseModel`, least squares ``change = M @ load``).  Of the prediction only the
  part the run is sure of counts (:func:`least_expected`: less three prediction errors, each
  the trials' scatter about the fit, at least the noise floor, widened by the load's
  leverage).  When that sure part is at least four noise floors and the readings moved by
  less than a quarter of it, the trial is "not loaded": the review warns and offers redo
  as its default;
* **the removal** (:meth:`Guard.after_baseline`): a new baseline must not still sit more
  than half-way along the last load's pressure response (a weight still hanging, an object
  still pressed in), counting from what friction can leave (:func:`still_loaded`), after taking
  off the leak's drift per trial (:class:`BaselineHistory`).  The angles are left out of this
  check: potentiometer play and sleeve friction leave an unloaded arm a few tenths of a degree
  from where it was, which is no sign of a load.

Friction against a weight left on.  With the valves closed the pressures follow the posture
(Boyle's law), so a weight left hanging and friction both show as an arm not back where it
was; what tells them apart is how far.  A weight left on keeps the whole loaded response.
Friction's offset is bounded and depends on the history: the arm stops where the tendons no
longer overcome the sleeves' friction, on the side it came from, so an unloaded baseline lies
within a band about the frictionless rest and two baselines differ by at most the band's
width, whatever the load was.  Along the load's response that width (the *hold*) comes from the
run itself: :data:`HOLD_MARGIN` times the largest projection of a move between accepted baselines
(less the leak's drift), once :data:`HOLD_MIN_MOVES` moves are known; never more than the rig's
physics allows (the paper's ``hold_prior``, per channel: for sleeve friction a share of each
chamber's pressure, labcli.papers.takuma2014.friction), which alone judges until then.  A
baseline is still loaded when it sits beyond the hold plus half of the rest of the response; a
response that does not clear the hold by :data:`RETURN_FLOORS` floors is too small to judge, as
friction could hold the arm there.  Replayed on the simulated rig (the shipped plans' 107
removals per run, seeds 1-10 or 5-10; friction from half the literature's level to four times
it, and the kind rig at up to four times its own): no removal was taken for a weight left on.
Of the weights left on it names 59 % on the kind rig (26 % at four times its friction), on the
literature's 24 % upright and 29 % bent (the heavier loads), 42 % at half its friction, 10 % at
twice it and none at four times, where friction can hold the arm wherever a plan load leaves it.

* **the seal** (:func:`unsealed_response`, needing no earlier trial): a sealed chamber's
  pressure follows its volume (Boyle's law), so a load that moves the joints by at least
  :data:`SEAL_ANGLE_FLOORS` floors while every pressure stays within a tenth of that many floors
  (:data:`SEAL_SHARE`) is a load on chambers that are not sealed: valves left open to the
  regulator, or open to the air with the supply off.  On the simulated rig 800 g moves the sealed
  chambers by 5-9 kPa and the joints by 2-5 deg (about 2 pressure floors per angle floor); left
  open, the pressures move by nothing at all while the joints move a little further.  The review
  names it and offers redo as its default, from the very first trial, with or without valve
  control.

Noise floors.  A change on one channel counts only beyond its floor, the largest of: the
settling criterion's spread for the channel's quantity (how far the protocol lets a still
signal wander), one ADC count, and four standard errors of the difference of the two
window means.  Changes are judged in floor units, so pressures (MPa) and angles (rad) weigh
alike.

Why a real rig does not trip it.  Sleeve friction and hysteresis make a response differ
from the linear prediction by a few percent of the load, noise by a floor; both show in the
trials' scatter about the fit, which widens the prediction error and so shrinks the sure
part, and what is left must still be missed by three quarters.  A loaded trial lands near
1 on that scale, one without its load near 0 (the share counted is the readings' change along
the sure change, so that noise and a leak across it count for nothing).  The run's trials predict
a load from the third trial along a direction already pulled (the loads' main direction alone
while they span no more, :data:`OFF_SPAN`), and every direction once they span it; loads too
light to move the readings clearly (50 g on a stiff rig) are not judged.

Before that, the prior (:class:`ResponsePrior`, the paper's; for the McKibben rig the rig's
statics less what friction can hold, :mod:`labcli.papers.takuma2014.guard_prior`) says what share
of the load the readings account for, and the least share a loaded trial shows: trial 1 with no
weight hung is caught by it.  A prediction of the run's own that is too vague to judge by is
handed to the prior only once the run's trials have refined it (:attr:`ResponsePrior.refined`:
for the McKibben rig, the friction they showed): with the prior's own allowance, on a rig with
more friction than it allows for, that multiplied its false alarms (docs/load-check.md).  A trial warned of leaves the next baseline checked against where the run's unloaded arm rests
(:func:`off_stored_baselines`, the angles), as is the first baseline after a resume, against
the run's stored baselines: a weight still hanging is named.  A chamber leak moves all
pressures one way while a load moves the two actuators of a pair opposite ways, so a leak
projects little onto a load's response in the removal check.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Hashable, Sequence
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np

EXPECT_FLOORS = 4.0  # a prediction this many floors or more is clear enough to judge by
WEAK_FRACTION = 0.25  # a load moved the readings by less than this share of the prediction: not loaded
RETURN_FRACTION = 0.5  # a baseline still this share of the way to the last loaded readings: not unloaded
# A load's pressure response must be this many floors for the removal to be judged: sleeve friction
# and the chambers' leak leave an unloaded baseline a kPa or so off, which half of a smaller
# response would mistake for a weight still hanging.
RETURN_FLOORS = 8.0
DRIFT_MOVES = 8  # the leak's drift per trial: the median of the last this many baseline moves
HOLD_MIN_MOVES = 8  # baseline moves seen before the run's own bound on friction's offsets is used
HOLD_MARGIN = 1.5  # the largest friction offset seen between baselines, times this, bounds the next
# The seal check: the joints moved by this many floors or more (0.5 deg on the paper's protocol) ...
SEAL_ANGLE_FLOORS = 5.0
# ... and the pressures by less than this share of it, in floors: sealed chambers move about 2 pressure
# floors per angle floor on the simulated rig, 20 times this.
SEAL_SHARE = 0.1
SE_FLOORS = 4.0  # standard errors of a difference of means that count as noise
MIN_DOF = 2  # trials beyond the load's dimension before a prediction is made (to measure their scatter)
MIN_SPAN = 0.2  # smallest / largest singular value of the loads: directions at least ~23 deg apart
SURE_SD = 3.0  # prediction errors taken off a prediction before it is relied on
MAX_LEVERAGE = 0.95  # a trial the fit must pass through (leverage ~1) says nothing of the scatter
# The prior (before the run's own trials can predict a load): the readings must account for at least
# this share of the load, as the prior's model reads them; a share it judges only where this share
# of the load is at least PRIOR_NOISE times what one noise floor on every channel makes of it.
PRIOR_SHARE = 0.1
PRIOR_NOISE = 2.0
# The first baseline after a resume (or after a warned trial): an angle this many floors beyond the
# band the run's baselines lie in (HOLD_MARGIN times their spread about their median) is a load still carried.
RESUME_FLOORS = 4.0
MIN_BASELINES = 5  # baselines that show where the run's unloaded arm rests (friction's band among them)
OFF_SPAN = 0.2  # a load more than this share off the explored directions (~12 deg) is not predicted from them


@dataclass(frozen=True)
class Watch:
    """The channels the checks watch (pressures and angles) and the smallest change that counts on each."""

    cols: tuple[int, ...]
    names: tuple[str, ...]
    units: tuple[str, ...]  # "MPa" or "rad"
    limit: np.ndarray  # settle spread limit of each channel's quantity, SI
    count: np.ndarray  # one ADC count, SI

    @classmethod
    def of(cls, protocol: Any) -> Watch:
        cal = protocol.calibration
        settling = protocol.settling
        spread = {"MPa": settling.pressure_spread_MPa, "rad": settling.angle_spread_rad}
        cols = tuple(i for i, u in enumerate(cal.units) if u in spread)
        return cls(
            cols,
            tuple(cal.names[i] for i in cols),
            tuple(cal.units[i] for i in cols),
            np.array([spread[cal.units[i]] for i in cols], dtype=float),
            np.abs(cal.gains[list(cols)]),
        )

    def change(self, before: Any, after: Any) -> np.ndarray:
        """Mean of ``after`` minus mean of ``before`` on the watched channels, SI."""
        c = list(self.cols)
        return after.mean()[c] - before.mean()[c]

    def floors(self, *windows: Any) -> np.ndarray:
        """Per channel: the settle spread, one count, or four standard errors of a difference of means."""
        c = list(self.cols)
        var = sum(w.var(ddof=1)[c] / len(w) if len(w) > 1 else 0.0 for w in windows)
        return np.maximum(np.maximum(self.limit, self.count), SE_FLOORS * np.sqrt(var))

    @property
    def pressures(self) -> np.ndarray:
        """Which watched channels are pressures."""
        return np.array([u == "MPa" for u in self.units], dtype=bool)

    def show(self, j: int, value: float) -> str:
        """One channel's change as people read it: kPa or deg, with its sign."""
        if self.units[j] == "MPa":
            return f"{self.names[j]} {value * 1e3:+.2f} kPa"
        return f"{self.names[j]} {math.degrees(value):+.2f} deg"


class ResponseModel:
    """What accepted trials did per unit of load: ``change = M @ load`` by least squares (no intercept).

    ``load`` is any vector that the rig responds to linearly to first order: the force (Fx, Fy)
    of a pulley weight in N, the push distance of one object in m.  :meth:`predict` says nothing
    until the loads seen span every direction of load space well (:data:`MIN_SPAN`) and leave
    :data:`MIN_DOF` degrees of freedom to measure how far the trials scatter about the fit, in
    every direction (no trial's leverage above :data:`MAX_LEVERAGE`: a direction explored by one
    trial alone is fitted exactly, so its scatter is unknown).
    """

    def __init__(self) -> None:
        self._loads: list[np.ndarray] = []
        self._changes: list[np.ndarray] = []
        self._fit: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray] | None = None
        self._stale = True

    def __len__(self) -> int:
        return len(self._loads)

    def add(self, load: Sequence[float], change: Sequence[float] | np.ndarray) -> None:
        self._loads.append(np.asarray(load, dtype=float))
        self._changes.append(np.asarray(change, dtype=float))
        self._stale = True

    def _solve(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray] | None:
        L = np.array(self._loads)
        if not len(L):
            return None
        _, s, vt = np.linalg.svd(L, full_matrices=False)
        if not s[0] > 0:
            return None
        # The directions of load space the trials explored well: the whole space once the loads
        # span it, else their main direction alone (the shipped plan's first nine trials all pull
        # at -60 deg), so that a load along it is judged from the third trial on.
        k = int(np.sum(s / s[0] >= MIN_SPAN))
        basis = vt[:k].T  # (load dims, k)
        X = L @ basis
        if len(X) < k + MIN_DOF:
            return None
        inv = np.linalg.inv(X.T @ X)
        # A direction only one trial explored is fitted exactly whatever the rig did: no scatter known there.
        if np.einsum("ij,jk,ik->i", X, inv, X).max() > MAX_LEVERAGE:
            return None
        C = np.array(self._changes)
        M, *_ = np.linalg.lstsq(X, C, rcond=None)
        resid = C - X @ M
        sd = np.sqrt((resid**2).sum(axis=0) / (len(X) - k))
        return M.T, sd, inv, basis

    def predict(self, load: Sequence[float]) -> tuple[np.ndarray, np.ndarray, float] | None:
        """The change this load should cause (SI, per watched channel), the trials' scatter about
        the fit (SI, per channel) and the load's leverage; None while unknown, or for a load off
        the directions the trials explored (more than :data:`OFF_SPAN` of it outside them)."""
        if self._stale:
            self._fit, self._stale = self._solve(), False
        if self._fit is None:
            return None
        M, sd, inv, basis = self._fit
        x = np.asarray(load, dtype=float)
        z = basis.T @ x
        if np.linalg.norm(x - basis @ z) > OFF_SPAN * np.linalg.norm(x):
            return None
        return M @ z, sd, float(z @ inv @ z)


def least_expected(prediction: tuple[np.ndarray, np.ndarray, float], floors: np.ndarray) -> np.ndarray:
    """The change a load surely causes: the prediction less :data:`SURE_SD` prediction errors, per channel.

    A prediction error is the trials' scatter about the fit (at least the noise floor) widened
    by the load's leverage: ``max(sd, floor) * sqrt(1 + h)``.  A channel the fit explains
    badly (the upper joint's small, nonlinear response) drops out this way."""
    mean, sd, h = prediction
    err = np.maximum(sd, floors) * math.sqrt(1.0 + h)
    return np.sign(mean) * np.maximum(0.0, np.abs(mean) - SURE_SD * err)


def clear_enough(watch: Watch, baseline: Any, loaded: Any, prediction: tuple[np.ndarray, np.ndarray, float]) -> bool:
    """Whether what the load surely causes (:func:`least_expected`) is clear enough to judge by."""
    f = watch.floors(baseline, loaded)
    return float(np.linalg.norm(least_expected(prediction, f) / f)) >= EXPECT_FLOORS


def weak_response(
    watch: Watch, baseline: Any, loaded: Any, prediction: tuple[np.ndarray, np.ndarray, float] | None
) -> str | None:
    """The sentence when the readings moved by less than a quarter of what the load surely causes."""
    if prediction is None:
        return None
    f = watch.floors(baseline, loaded)
    e = least_expected(prediction, f) / f
    size = float(np.linalg.norm(e))
    if size < EXPECT_FLOORS:
        return None
    seen = watch.change(baseline, loaded)
    # The share of the sure change the readings made along it: noise and the leak across it do not count.
    share = max(0.0, float((seen / f) @ e)) / size**2
    if share >= WEAK_FRACTION:
        return None
    j = int(np.argmax(np.abs(e)))
    return (
        f"the readings moved by {share:.0%} of what this run's earlier trials say this load surely does "
        f"({watch.show(j, seen[j])}, at least {watch.show(j, e[j] * f[j]).split(' ', 1)[1]} expected)"
    )


def unsealed_response(watch: Watch, baseline: Any, loaded: Any, supply_min_MPa: float | None = None) -> str | None:
    """The sentence when a load moved the joints but not the pressures: the chambers are not sealed.

    Judged without any earlier trial (see the module docstring); ``supply_min_MPa`` tells a supply
    that is off (the chambers at the atmosphere's pressure) from valves left open to the regulator.
    """
    p = watch.pressures
    a = np.array([u == "rad" for u in watch.units], dtype=bool)
    if not (p.any() and a.any()):
        return None
    f = watch.floors(baseline, loaded)
    seen = watch.change(baseline, loaded)
    angles = float(np.linalg.norm(seen[a] / f[a]))
    if angles < SEAL_ANGLE_FLOORS or float(np.linalg.norm(seen[p] / f[p])) >= SEAL_SHARE * angles:
        return None
    c = list(watch.cols)
    before, after = baseline.mean()[c], loaded.mean()[c]
    i = int(np.flatnonzero(p)[np.argmax(np.abs(seen[p]))])  # the pressure that moved most, and still did not
    j = int(np.flatnonzero(a)[np.argmax(np.abs(seen[a]))])
    moved = (
        f"{watch.names[i]} {before[i]:.4f} -> {after[i]:.4f} MPa while {watch.names[j]} moved "
        f"{math.degrees(seen[j]):+.2f} deg"
    )
    low = supply_min_MPa is not None and float(np.max(before[p])) < supply_min_MPa
    why = (
        "the chambers are at the atmosphere's pressure: supply air, then close the valves"
        if low
        else "sealed chambers would have followed the load, so a valve is open: close the valves "
        "so that the actuators are sealed"
    )
    return f"the pressures did not respond to the load ({moved}); {why}"


def still_loaded(
    watch: Watch,
    baseline: Any,
    loaded: Any,
    now: Any,
    drift: np.ndarray | None = None,
    hold: Callable[[np.ndarray], float] | None = None,
) -> str | None:
    """The sentence when ``now`` (a new baseline) is still over half-way to ``loaded`` from
    ``baseline``, beyond what friction can leave.

    ``drift`` (SI, per watched channel): the leak's move per trial, taken off ``now``'s move.
    ``hold(w)``: the largest ``|m . w|`` over the moves ``m`` (SI, per watched channel)
    friction can leave between two unloaded baselines.  Along the load's response it allows
    ``hold_r``; the baseline counts as loaded beyond ``hold_r`` plus :data:`RETURN_FRACTION` of
    the rest of the response, and a response less than :data:`RETURN_FLOORS` floors beyond
    ``hold_r`` is not judged (friction could hold the arm there).
    """
    f = np.maximum(watch.floors(baseline, loaded), watch.floors(now))
    r = watch.change(baseline, loaded) / f
    # Judged on the pressures alone when there are any: a potentiometer's play and the sleeves'
    # friction leave an unloaded arm where the load left it, within a few tenths of a degree,
    # while a weight still hanging keeps its whole pressure change.
    use = watch.pressures if watch.pressures.any() else np.ones(len(r), dtype=bool)
    r = np.where(use, r, 0.0)
    size = float(np.linalg.norm(r))
    if size == 0.0:
        return None
    u = r / size
    hold_r = 0.0 if hold is None else float(hold(u / f))
    if size - hold_r < RETURN_FLOORS:
        return None
    q = (watch.change(baseline, now) - (0.0 if drift is None else drift)) / f
    along = float(q @ u)
    if along <= hold_r + RETURN_FRACTION * (size - hold_r):
        return None
    j = int(np.argmax(np.abs(r)))
    moved = watch.change(baseline, now)
    allowed = f" beyond the {hold_r / size:.0%} friction can leave" if hold_r else ""
    return (
        f"they are still {min(along / size, 9.99):.0%} of the way to the loaded ones{allowed} "
        f"({watch.show(j, moved[j])} from the baseline, {watch.show(j, r[j] * f[j]).split(' ', 1)[1]} under the load)"
    )


class ResponsePrior(Protocol):
    """What a load should do before the run's own trials can say: the share of ``load`` that the
    readings account for (1 as expected, 0 nothing), and the share below which the readings are
    surely not loaded, or None where this load cannot be judged (too light for the noise)."""

    def __call__(
        self, load: Sequence[float], baseline: Any, loaded: Any, floors: np.ndarray
    ) -> PriorReading | None: ...

    @property
    def refined(self) -> bool:
        """Whether the run's own trials have refined the prior, so that it may judge a load the
        trials alone predict too vaguely."""
        ...

    def learn(self, load: Sequence[float], baseline: Any, loaded: Any) -> None:
        """A trial accepted without a warning (the prior may refine itself by it, or ignore it)."""


@dataclass(frozen=True)
class PriorReading:
    """What a prior made of one trial: the share of the load its model reads in the readings,
    the share below which the trial is not loaded, and how it says what it read (a sentence part)."""

    share: float
    least: float
    seen: str


def prior_response(watch: Watch, prior: ResponsePrior, load: Sequence[float], baseline: Any, loaded: Any) -> str | None:
    """The sentence when the prior reads less than its least share of the load in the readings."""
    reading = prior(load, baseline, loaded, watch.floors(baseline, loaded))
    if reading is None or reading.share >= reading.least:
        return None
    return (
        f"the readings account for {reading.share:.0%} of this load ({reading.seen}), where the rig's "
        f"physics says at least {reading.least:.0%}"
    )


def off_stored_baselines(
    watch: Watch, stored: np.ndarray, now: Any, which: str = "the first baseline since the run was resumed"
) -> str | None:
    """The sentence when a resumed run's first baseline has an angle outside the band its stored
    baselines lie in (:data:`HOLD_MARGIN` times their largest distance from their median, plus
    :data:`RESUME_FLOORS` floors): the arm is not where an unloaded arm of this run rests.

    The angles alone judge: the chambers are supplied again at a resume, so their pressures
    start afresh, while a weight still hanging bends the arm whatever the air does."""
    a = np.array([u == "rad" for u in watch.units], dtype=bool)
    if not a.any():
        return None
    c = list(watch.cols)
    mean = np.asarray(now.mean()[c], dtype=float)
    middle = np.median(stored, axis=0)
    band = HOLD_MARGIN * np.abs(stored - middle).max(axis=0) + RESUME_FLOORS * watch.floors(now)
    off = np.where(a, np.abs(mean - middle) - band, -np.inf)
    j = int(np.argmax(off))
    if not off[j] > 0:
        return None
    return (
        f"{which} has {watch.names[j]} at {math.degrees(mean[j]):+.2f} deg, "
        f"outside the {math.degrees(band[j]):.2f} deg about {math.degrees(middle[j]):+.2f} deg where the run's "
        f"{len(stored)} stored baselines lie"
    )


def supply_problem(names: Sequence[str], pressures_MPa: Sequence[float], minimum_MPa: float) -> str | None:
    """What is wrong with the supplied pressures (each channel at least ``minimum_MPa``), or None."""
    p = np.asarray(pressures_MPa, dtype=float)
    low = [(n, v) for n, v in zip(names, p, strict=False) if not v >= minimum_MPa]
    if not low:
        return None
    listed = ", ".join(f"{n} reads {v:.3f} MPa" for n, v in low)
    if len(low) == len(p):
        return (
            f"After the air supply {listed}, below the {minimum_MPa:g} MPa the protocol asks for "
            "(acquisition.supply_min_MPa): check the compressor, the regulator and that the valves are open."
        )
    rest = float(np.median([v for n, v in zip(names, p, strict=False) if v >= minimum_MPa]))
    return f"After the air supply {listed} while the others read about {rest:.2f} MPa: check " + (
        "that actuator's tube, fitting and valve." if len(low) == 1 else "those actuators' tubes, fittings and valves."
    )


class BaselineHistory:
    """The accepted unloaded baselines of a session: the leak's drift per trial and how far
    friction moves an unloaded arm from one baseline to the next (the *hold*).

    ``prior(mean)``: the most the rig's physics lets friction move each watched channel
    between two baselines (SI), from a baseline's mean readings; None: no physical bound known.
    """

    def __init__(self, watch: Watch, prior: Callable[[np.ndarray], np.ndarray] | None = None) -> None:
        self.watch = watch
        self.prior = prior
        self._last: Any = None
        self._moves: list[np.ndarray] = []
        self.means: list[np.ndarray] = []  # the accepted baselines' means (SI, per watched channel)

    def add(self, baseline: Any) -> None:
        """An accepted baseline: its move from the one before joins the history."""
        if self._last is not None:
            self._moves.append(np.asarray(self.watch.change(self._last, baseline), dtype=float))
        self._last = baseline
        self.means.append(np.asarray(baseline.mean()[list(self.watch.cols)], dtype=float))

    def restart(self) -> None:
        """The next baseline follows a supply (or valves closed at last): its move is not counted."""
        self._last = None

    def drift(self) -> np.ndarray | None:
        """The leak's move per trial: the median of the last :data:`DRIFT_MOVES` baseline moves
        (friction's offsets change sign with the loads' directions; a leak's does not)."""
        if not self._moves:
            return None
        return np.median(np.array(self._moves[-DRIFT_MOVES:]), axis=0)

    def hold(self, baseline: Any) -> Callable[[np.ndarray], float] | None:
        """``w -> `` the largest ``|m . w|`` over the moves ``m`` friction may leave between two
        unloaded baselines (SI per watched channel), or None when nothing bounds them.

        The run's own bound, once :data:`HOLD_MIN_MOVES` moves are known: :data:`HOLD_MARGIN`
        times the largest projection of a move less the leak's drift (friction's offsets lie
        along the arm's few directions of motion, so a projection bounds them far tighter than
        each channel's largest move would); never more than the physical prior allows anywhere
        within its per-channel bound.
        """
        c = list(self.watch.cols)
        prior = None if self.prior is None else np.asarray(self.prior(baseline.mean()[c]), dtype=float)
        offsets = np.array(self._moves) - self.drift() if len(self._moves) >= HOLD_MIN_MOVES else None

        def along(w: np.ndarray) -> float:
            bounds = []
            if prior is not None:
                bounds.append(float(np.abs(w) @ prior))
            if offsets is not None:
                bounds.append(HOLD_MARGIN * float(np.abs(offsets @ w).max()))
            return min(bounds)

        return None if prior is None and offsets is None else along


class Guard:
    """The checks of one session: a response model per kind of load (``key``), the last loaded
    trial and the accepted baselines (``hold_prior``: see :class:`BaselineHistory`)."""

    def __init__(
        self,
        protocol: Any,
        hold_prior: Callable[[np.ndarray], np.ndarray] | None = None,
        prior: ResponsePrior | None = None,
    ) -> None:
        self.watch = Watch.of(protocol)
        self.supply_min_MPa: float | None = getattr(protocol, "supply_min_MPa", None)
        self.unsealed = False  # the last load's finding was the seal's (its sentence says what to do)
        self._models: dict[Hashable, ResponseModel] = {}
        self._last: tuple[Any, Any] | None = None
        self.baselines = BaselineHistory(self.watch, hold_prior)
        self.prior = prior
        self._stored: np.ndarray | None = (
            None  # baselines the next one is checked against (resumed, or after a warning)
        )
        self._which = ""

    def resumed(self, baselines: Sequence[Sequence[float]]) -> None:
        """The run was resumed: ``baselines`` are its stored trials' baselines (SI, per watched
        channel); the first new baseline is checked against the band they lie in."""
        b = np.asarray(baselines, dtype=float)
        self._stored = b if b.ndim == 2 and len(b) >= MIN_BASELINES and b.shape[1] == len(self.watch.cols) else None
        self._which = "the first baseline since the run was resumed"

    def model(self, key: Hashable = None) -> ResponseModel:
        return self._models.setdefault(key, ResponseModel())

    def learn(self, load: Sequence[float], baseline: Any, loaded: Any, key: Hashable = None) -> None:
        """A trial accepted without a warning: its change per unit of load joins the model."""
        self.model(key).add(load, self.watch.change(baseline, loaded))
        if key is None and self.prior is not None:
            self.prior.learn(load, baseline, loaded)

    def after_load(self, load: Sequence[float], baseline: Any, loaded: Any, key: Hashable = None) -> str | None:
        self._last = (baseline, loaded)
        unsealed = unsealed_response(self.watch, baseline, loaded, self.supply_min_MPa)
        self.unsealed = unsealed is not None
        if unsealed is not None:
            return unsealed
        prediction = self.model(key).predict(load)
        vague = prediction is None or not clear_enough(self.watch, baseline, loaded, prediction)
        if self.prior is not None and key is None and (prediction is None or (vague and self.prior.refined)):
            weak = prior_response(self.watch, self.prior, load, baseline, loaded)
        else:
            weak = weak_response(self.watch, baseline, loaded, prediction)
        if weak is not None and len(self.baselines.means) >= MIN_BASELINES and self._stored is None:
            # A load the readings did not follow may be on the pulley yet (an Enter out of step):
            # the next baseline is checked against where this run's unloaded arm rests.
            self._stored, self._which = np.array(self.baselines.means), "the baseline after that trial"
        return weak

    def resupplied(self) -> None:
        """The chambers were supplied again, or closed at last: the jump to the next baseline is no
        leak, nor friction.  The moves measured before are kept: a supply changes neither."""
        self.baselines.restart()

    def after_baseline(self, baseline: Any) -> str | None:
        """Does the new baseline still carry the last load?  (Forgets the last load once it has not.)

        The leak's drift per trial and friction's hold come from the baselines accepted so far
        (:class:`BaselineHistory`): a chamber at a high supply can lose a few kPa over a trial,
        and friction can leave an unloaded arm off by as much as a light load's response
        (tests/core/test_guard.py).
        """
        finding = None
        if self._stored is not None:
            finding = off_stored_baselines(self.watch, self._stored, baseline, self._which)
            if finding is not None:
                return finding
            self._stored = None
        if self._last is not None:
            h = self.baselines
            finding = still_loaded(self.watch, *self._last, baseline, h.drift(), h.hold(baseline))
        if finding is None:
            self._last = None
            self.baselines.add(baseline)
        return finding
