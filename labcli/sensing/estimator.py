"""The run-time estimator: frames in, estimates and events out, no I/O.

::

    est = Estimator(model, calibration=protocol.calibration, channels=device.info.channels, rate_hz=200)
    for item in est.update(device.read()):     # raw FrameBatch, as the reader delivers it
        ...                                     # Estimate (one per block) or Event (load, settled, release)

The estimator walks through :data:`~.results.STATES`: ``starting`` (learning the baseline),
``idle`` (tracking it, :mod:`.baseline`, and watching for a change, :mod:`.detector`),
``loading`` (a load came on: its response is fitted, :mod:`.transient`), ``loaded`` (it has
settled), ``releasing`` (it came off; once settled the baseline is set anew and the rig is
idle again).  A change while a load is on is its release or another load (:mod:`.release`).
Every block gives one :class:`~.results.Estimate` (:mod:`.evaluate`).

Baseline P0 and the leak.  The model gets the baseline line at the block's time when it was
fitted on leak-corrected baselines (``model.p0_leak_corrected``).  A model fitted on
baselines as measured, ``baseline_gap_s`` before their loaded capture, gets the line as it
stood that long before the block: the same leak the fit saw.  With neither known (older model
files), the baseline at the load's start, as a trial's baseline window would have it.

The history of loads.  For a model that reads it (:class:`~.model.HistoryModel`: a friction
that opposes the last motion), each load is estimated with the joints' motion into its baseline:
the rest posture at its start less the posture of the load before it (that load's rest plus the
deflections the model reads from its last pressures before it came off, while no change was
under way), as ``labcli predict`` works it out from a table's rows in trial order.  The first load
has none, and the idle rig none: at its baseline nothing has moved since.

The valves' closing.  The frames do not say when the valves close, and the closing moves the
pressures: each sensor reads afresh (its repeatability, up to 1 kPa on the literature's simulated
rig) and the sleeves' friction may let the arm slide.  So once the air has been seen being
supplied (the baseline begun again for moving pressures), the first change found is held up to
``closing_s``: a load moves the joints and is a load from where it began; a change the
potentiometers do not follow is the closing, and the baseline is learnt again once the sensors'
new readings have settled.  A closing that slides the arm still reads as a load.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Sequence
from dataclasses import replace
from typing import Any, Protocol

import numpy as np

from ..errors import ModelError
from .baseline import TrendTracker
from .blocks import BlockAverager, Blocks, Recent
from .config import EstimatorConfig
from .detector import ChangeDetector, whiten
from .evaluate import Inputs2, evaluate
from .excursion import Excursion
from .inputs import DeviceClock, Inputs, frame_arrays
from .model import BASELINE, STATE, TRANSIENT, SensingModel, check_model, uses_history
from .release import force_at_zero, is_release, lagged_step, slides_back
from .results import IDLE, LOAD, LOADED, LOADING, RELEASE, RELEASING, SETTLED, STARTING, Estimate, Event
from .transient import ResponseFit, Step, onset

MAX_VAR = 0.05**2  # MPa^2: an input known to no better than 50 kPa is simply not known
STATE_FLAGS = {STARTING: (BASELINE,), LOADING: (TRANSIENT,), RELEASING: (TRANSIENT,)}  # what a state adds to the flags


class SettledHook(Protocol):
    """Called with each settled load's estimate and the rest posture (rad); returns the data of an
    event of its ``kind`` (a push's stiffness), or None."""

    kind: str

    def __call__(self, estimate: Estimate, rest: np.ndarray) -> dict[str, Any] | None: ...


def check_streamable(model: Any) -> SensingModel:
    """``model`` (:func:`~.model.check_model`) if the estimator can stream it, else ModelError.

    The detector and the release's readings remove the pressures' common mode (the leak, the
    room): one chamber leaves nothing to see a load in.  A table's settled rows need no detector,
    so :func:`~.offline.predict_rows` takes a model of one chamber."""
    m = check_model(model)
    if len(m.actuators) < 2:
        raise ModelError(
            f"A sensing model needs at least two pressure channels (an antagonistic pair), "
            f"got {len(m.actuators)}: with one, the leak cannot be told from a load."
        )
    return m


class Estimator:
    """Incremental estimates from a stream of frames (module docstring).

    ``calibration`` (a protocol's) and ``channels`` (the device's, in data-line order) say how
    raw frames become SI; without a calibration :meth:`update_si` takes SI values in the model's
    order (pressures in MPa, then the rest-posture angles in rad).  ``rate_hz``: the frame rate
    (None: read from the first frames' times).  ``on_settled``: a :class:`SettledHook`.
    """

    def __init__(
        self,
        model: SensingModel,
        *,
        calibration: Any = None,
        channels: Sequence[str] | None = None,
        rate_hz: float | None = None,
        config: EstimatorConfig | None = None,
        on_settled: SettledHook | None = None,
    ) -> None:
        self.model = check_streamable(model)
        self.config = config or EstimatorConfig()
        self.inputs = (
            Inputs.from_calibration(calibration, model, channels) if calibration is not None else Inputs.identity(model)
        )
        self.on_settled = on_settled
        self._state_kind = np.array([k == STATE for k in self.model.kinds])
        self._history_model = uses_history(self.model)
        self.rate_hz = rate_hz
        self._clock = DeviceClock()
        self._count = 0  # frames given without their seq (update_si)
        self._floors: dict[int, np.ndarray] = {}  # the noise floor per block size (_noise)
        self.reset()

    # ------------------------------------------------------------------ public
    def reset(self) -> None:
        """Forget everything: the next frames start a new baseline."""
        c, k, p = self.config, self.inputs.width, self.inputs.n_pressures
        self.state = STARTING
        self._blocks: BlockAverager | None = None
        self._held: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = []
        self._last_t = -math.inf
        q_level = np.array([c.level_q] * p + [c.angle_level_q] * (k - p))
        q_slope = np.array([c.slope_q] * p + [c.slope_q * 1e-6] * (k - p))
        slope_sd = np.array([c.slope_sd] * p + [1e-6] * (k - p))
        self.tracker = TrendTracker(q_level, q_slope, slope_sd)
        self.detector = ChangeDetector(c.windows, c.threshold, p - 1)
        self._history: deque[tuple[float, np.ndarray, np.ndarray, Any, np.ndarray]] = deque(
            maxlen=max(8, int(round(c.history_s / c.block_s)))
        )
        self._r: np.ndarray | None = None  # block-mean noise variance per channel
        self._spreads = Recent(max(8, int(round(10.0 / c.block_s))), k)  # the last 10 s
        self._excess = 1.0  # idle innovations' variance over the predicted one
        self._prev_y: np.ndarray | None = None
        self._started = 0.0
        # The valves (module docstring, "The valves' closing"): None until the air is seen being
        # supplied, "open" from then, "closed" once a change has been taken for their closing.
        self._valves: str | None = None
        self._quiet_until = -math.inf
        self._closing: tuple[float, list[tuple[np.ndarray, np.ndarray]]] | None = None  # a change on hold
        self._exc: Excursion | None = None
        self._tails: list[Step] = []  # finished changes whose settled value the baseline holds
        self._rest = np.zeros(k - p)
        self._p0_onset = np.zeros(p)
        # The history of loads (module docstring): the present load's last blocks (tc, P0, P, rest),
        # the posture the last one left the arm in, the motion into the present load's baseline.
        self._load_blocks: deque[tuple[float, np.ndarray, np.ndarray, np.ndarray]] = deque(
            maxlen=max(8, int(round(c.history_s / c.block_s)))
        )
        self._before: np.ndarray | None = None
        self._motion: np.ndarray | None = None

    def update(self, frames: Any) -> list[Estimate | Event]:
        """Take frames as the reader delivers them (a :class:`~labcli.core.wire.FrameBatch`, or
        :class:`~labcli.core.wire.Frame` objects): the estimates of the blocks they complete
        and the events found, in time order (a block's events before its estimate)."""
        seq, t_us, values = frame_arrays(frames)
        if not len(seq):
            return []
        return self.update_si(self._clock.seconds(t_us), self.inputs.si(values), seq)

    def update_si(self, t_s: Any, values: Any, seq: Any = None) -> list[Estimate | Event]:
        """As :meth:`update`, from device times (s) and SI values in the model's order (n, k)."""
        t = np.asarray(t_s, dtype=float).reshape(-1)
        x = np.asarray(values, dtype=float).reshape(len(t), self.inputs.width)
        s = self._count + np.arange(len(t), dtype=np.int64) if seq is None else np.asarray(seq, dtype=np.int64)
        self._count += len(t)
        if not len(t):
            return []
        if t[0] < self._last_t:  # the firmware restarted: its clock began again
            self.reset()
        self._last_t = float(t[-1])
        blocks = self._block(t, s, x)
        out: list[Estimate | Event] = []
        for i in range(len(blocks) if blocks is not None else 0):
            out.extend(self._step(blocks, i))  # type: ignore[arg-type]
        return out

    @property
    def rest(self) -> np.ndarray:
        """The rest posture the estimates refer to (rad, the model's joints)."""
        if self._exc is None and self.tracker.t is not None:
            return self.tracker.x[self.inputs.n_pressures :, 0].copy()
        return self._rest.copy()

    # ------------------------------------------------------------------ blocks
    def _block(self, t: np.ndarray, seq: np.ndarray, x: np.ndarray) -> Blocks | None:
        if self._blocks is None:
            self._held.append((t, seq, x))
            t_all = np.concatenate([h[0] for h in self._held])
            if self.rate_hz is None:
                if len(t_all) < 2 or not np.any(np.diff(t_all) > 0):
                    return None
                self.rate_hz = 1.0 / float(np.median(np.diff(t_all)[np.diff(t_all) > 0]))
            size = max(1, int(round(self.config.block_s * self.rate_hz)))
            self._blocks = BlockAverager(self.inputs.width, size)
            held, self._held = self._held, []
            t, seq, x = (np.concatenate([h[j] for h in held]) for j in range(3))
        return self._blocks.push(t, seq, x)

    def _step(self, b: Blocks, i: int) -> list[Estimate | Event]:
        tc, t, seq = float(b.tc[i]), float(b.t[i]), int(b.seq[i])
        tails, tail_var = self._tails_at(tc)
        y = b.mean[i] - tails
        if self.state in (STARTING, IDLE):
            self._learn_noise(b.var[i], b.mean[i])
        r = self._noise() + tail_var
        if self.state in (STARTING, IDLE):
            events = self._watch(tc, seq, y, r)
        elif self.state in (LOADING, LOADED):
            events = self._follow(tc, seq, y, r)
        else:
            events = self._release(tc, y, r)
        est = self._estimate(tc, t, seq, y, r)
        out: list[Estimate | Event] = []
        for ev in events:
            if ev.kind == SETTLED:
                ev = replace(ev, estimate=est)
                out.append(ev)
                if self.on_settled is not None:
                    data = self.on_settled(est, self._rest.copy())
                    if data is not None:
                        out.append(Event(self.on_settled.kind, ev.t_device_s, ev.t_detected_s, seq, est, data))
            else:
                out.append(ev)
        out.append(est)
        return out

    # ------------------------------------------------------------------ noise
    def _learn_noise(self, var: np.ndarray, y: np.ndarray) -> None:
        """The noise of a block mean: the median over the last blocks of the spread of each one's
        frames (or of successive blocks' difference, with one frame a block).  A median: a block
        that holds the start of a change, or the air being supplied, does not count."""
        if np.all(np.isfinite(var)):
            obs = var
        elif self._prev_y is not None:
            obs = 0.5 * (y - self._prev_y) ** 2
        else:
            obs = None
        self._prev_y = y.copy()
        if obs is None:
            return
        self._spreads.append(obs)
        self._r = self._spreads.median()

    def _noise(self) -> np.ndarray:
        size = self._blocks.size if self._blocks is not None else 1
        floor = self._floors.get(size)
        if floor is None:
            floor = self._floors[size] = 1e-14 + self.inputs.resolution**2 / (
                12.0 * size
            )  # the ADC's rounding, averaged
        base = self._r if self._r is not None else np.full(self.inputs.width, 1e-8)
        return np.maximum(base * self._excess, floor)

    # ------------------------------------------------------------------ idle
    def _watch(self, tc: float, seq: int, y: np.ndarray, r: np.ndarray) -> list[Event]:
        """Starting or idle: follow the baseline, and look for a change in it."""
        p, tr = self.inputs.n_pressures, self.tracker
        if tr.t is None:
            tr.start(tc, y, 4 * r)
            self._started = tc
            return []
        level, lvar = tr.at(tc)
        e, v = y - level, r + lvar
        if self.state == STARTING:
            if tc < self._quiet_until:
                self._restart_baseline(tc, y, r)  # the sensors still settling after the valves' closing
            elif np.any(np.abs(e[:p]) > 6 * np.sqrt(v[:p])):
                self._restart_baseline(tc, y, r)  # still moving (air being supplied): begin again
                self._valves = self._valves or "open"
            else:
                tr.update(tc, y, r)
            if tc - self._started >= self.config.warmup_s:
                self.state = IDLE
                self.detector.reset()
                self._history.clear()
            return []
        z = whiten(e[:p], v[:p])
        self._history.append((tc, y.copy(), r.copy(), tr.snapshot(), z))
        if self._closing is not None or self.detector.push(z, self._wander(v)):
            if self._valves == "open" and len(e) > p:
                return self._closing_or_load(tc, seq, y, r, e[p:], v[p:])
            return self._begin(tc, seq)
        tr.update(tc, y, r)
        ratio = float(np.mean(np.minimum(e[:p] ** 2 / v[:p], 25.0)))
        a = min(1.0, self.config.block_s / 60.0)
        self._excess = float(np.clip(self._excess + a * (ratio - self._excess), 1.0, 25.0))
        return []

    def _closing_or_load(
        self, tc: float, seq: int, y: np.ndarray, r: np.ndarray, e_pots: np.ndarray, v_pots: np.ndarray
    ) -> list[Event]:
        """The first change since the air was seen supplied: a load moves the joints, the valves'
        closing does not (module docstring).  Wait up to ``closing_s`` for the potentiometers."""
        if self._closing is None:
            self._closing = (tc, [])
        since, seen = self._closing
        seen.append((e_pots, v_pots))
        last = seen[-4:]  # a few blocks' mean: a small load's motion is a few times a block's noise
        mean = sum(x for x, _ in last) / len(last)
        sd = np.sqrt(sum(w for _, w in last) / len(last) ** 2)
        if np.any(np.abs(mean) > 4 * sd):
            self._valves, self._closing = "closed", None
            return self._begin(tc, seq)
        if tc - since >= self.config.closing_s - 1e-9:
            self._valves, self._closing = "closed", None
            self._restart_baseline(tc, y, r)
            self._quiet_until = tc + 3 * self.config.tau_s  # the sensors' new readings settle with the lag
            self.state = STARTING
        return []

    def _restart_baseline(self, tc: float, y: np.ndarray, r: np.ndarray) -> None:
        """Learn the baseline again from this block on (the rig is still changing)."""
        self.tracker.start(tc, y, 4 * r)
        self._started = tc
        self._spreads.clear()

    def _wander(self, var: np.ndarray) -> float:
        """The baseline's wander in the detector's whitened units (:meth:`ChangeDetector.push`)."""
        p = self.inputs.n_pressures
        return float(self.config.wander_MPa / math.sqrt(np.add.reduce(var[:p]) / p))  # np.mean's arithmetic

    def _new_fit(self, t0: float) -> ResponseFit:
        c = self.config
        k, p = self.inputs.width, self.inputs.n_pressures
        return ResponseFit(
            t0,
            k,
            taus=c.tau_s * np.asarray(c.tau_factors),
            shifts=c.block_s * np.asarray(c.onset_shifts_blocks),
            thermal_tau=c.thermal_tau_s,
            kappas=np.asarray(c.thermal_kappas),
            capacity=max(4, int(round(c.fit_span_s / c.block_s))),
            heated=(np.arange(k) < p).astype(float),
            shared=np.arange(k) < p,
            shape_sd=c.shape_sd,
        )

    def _begin(self, tc: float, seq: int) -> list[Event]:
        """A load came on: place its start, rewind the baseline to it, start fitting its response."""
        hist = list(self._history)
        tcs = np.array([h[0] for h in hist])
        t0, _ = onset(tcs, np.array([h[4] for h in hist]), self.config.tau_s, self.config.block_s)
        i0 = int(np.searchsorted(tcs, t0, side="right"))
        self.tracker.restore(hist[i0][3])
        blocks = [(h[0], h[1] - self.tracker.at(h[0])[0], h[2]) for h in hist[i0:]]
        return self._begin_at(t0, blocks, tc, seq)

    def _begin_at(
        self, t0: float, blocks: list[tuple[float, np.ndarray, np.ndarray]], tc: float, seq: int
    ) -> list[Event]:
        """Start an excursion at ``t0`` (the tracker frozen there) with the blocks seen since (tc, change, var)."""
        level0, _ = self.tracker.at(t0)
        p = self.inputs.n_pressures
        self._rest, self._p0_onset = level0[p:].copy(), level0[:p].copy()
        self._motion = None if self._before is None else self._rest - self._before
        fit = self._new_fit(t0)
        for block in blocks:
            fit.add(*block)
        if fit.n:
            fit.solve()
        self._exc = Excursion(t0, LOAD, fit)
        self.state = LOADING
        self.detector.reset()
        return [Event(LOAD, t0, tc, seq)]

    # ------------------------------------------------------------------ loaded
    def _follow(self, tc: float, seq: int, y: np.ndarray, r: np.ndarray) -> list[Event]:
        """Loading or loaded: fit the response, watch for the next change, say when settled."""
        exc, c, p = self._exc, self.config, self.inputs.n_pressures
        assert exc is not None
        b, _ = self.tracker.at(tc)
        e = y - b - exc.finished(tc)
        fit = exc.fit
        if fit.result is not None and tc - fit.t0 > c.release_guard_s:
            step = fit.step()
            res = e - step.at(tc)
            # The fitted shape is not exact: a share of the change it describes counts as noise.
            shape = (c.shape_error * exc.settled_total()) ** 2
            pvar = np.minimum(exc.transient_var(tc, c.shape_sd) + shape, MAX_VAR)
            z = whiten(res[:p], (r + pvar)[:p])
            exc.residuals.append((tc, z, res[:p]))
            if exc.pending is None and self.detector.push(z, self._wander(r + pvar)):
                exc.pending = tc
            if exc.pending is not None:
                # A change is under way: its first blocks say little of what it is; wait for a few.
                exc.held.append((tc, e, r))
                return self._change(tc, seq, r) if tc - exc.pending >= c.classify_s - 1e-9 else []
        fit.add(tc, e, r)
        fit.solve()
        if self.state == LOADING and self._settled(tc):
            self.state = LOADED
            return [Event(SETTLED, tc, tc, seq)]
        return []

    def _change(self, tc: float, seq: int, r: np.ndarray) -> list[Event]:
        """A change while loaded: the release (it takes the load back) or another load."""
        exc, c, p = self._exc, self.config, self.inputs.n_pressures
        assert exc is not None
        tcs = np.array([h[0] for h in exc.residuals])
        t1, _ = onset(tcs, np.array([h[1] for h in exc.residuals]), c.tau_s, c.block_s)
        if tc - t1 > c.creep_s:  # no step: the reference creeping under the load (config), folded in silently
            exc.next_change(t1, self._new_fit(t1))
            self.detector.reset()
            return []
        step, total = lagged_step(tcs, np.array([h[2] for h in exc.residuals]), t1, c.tau_s), exc.settled_total()
        release = is_release(step, total[:p], r[:p], c, lambda: self._at_zero(tc, step, total, r))
        kind = RELEASE if release or self._slid_back(t1, total, r) else LOAD
        if kind == LOAD and self.state == LOADED and np.max(np.abs(total[:p])) < c.small_load_MPa:
            return self._restart(t1, tc, seq)
        self._load_done(t1)
        exc.kind = kind
        exc.next_change(t1, self._new_fit(t1))
        self.detector.reset()
        self.state = RELEASING if kind == RELEASE else LOADING
        return [Event(kind, t1, tc, seq)]

    def _slid_back(self, t1: float, total: np.ndarray, r: np.ndarray) -> bool:
        """Do the joints slide on the way they came back from the load before, at the change
        begun at ``t1`` (:func:`.release.slides_back`)?  Their change: the blocks held since it
        was seen, less the active load's fitted response, on the muscles' lag."""
        exc, p = self._exc, self.inputs.n_pressures
        assert exc is not None
        if self._motion is None or not exc.held or exc.fit.result is None:
            return False
        step = exc.fit.step()
        tcs = np.array([h[0] for h in exc.held])
        raw = np.array([h[1][p:] - step.at(h[0])[p:] for h in exc.held])
        moved = lagged_step(tcs, raw, t1, self.config.tau_s)
        noise = math.sqrt(float(np.sum(r[p:])))  # the joints' noise, as the length of their change
        return slides_back(moved, self._motion, total[p:], noise, self.config.release_cosine)

    def _at_zero(self, tc: float, step: np.ndarray, total: np.ndarray, r: np.ndarray) -> bool:
        """Does the model read the pressures after a change (the loads so far, ``total``, and the
        change's settled ``step``) as no force against the baseline (:func:`.release.force_at_zero`)?"""
        exc, c, p = self._exc, self.config, self.inputs.n_pressures
        assert exc is not None
        level, lvar = self.tracker.at(tc)
        after = level[:p] + total[:p] + step
        extra = exc.step_var[:p] if exc.step_var is not None else 0.0
        # Not the change's size in doubt (its shape's share, which grows with it): a slide to
        # another rest reads no force whatever its size, and a load of any size reads one.  The
        # sensors' new readings are in doubt.
        var = lvar[:p] + extra + exc.transient_var(tc, c.shape_sd)[:p] + c.reread_MPa**2 + r[:p]
        var = np.minimum(var, MAX_VAR)
        x = Inputs2(self._p0(level[:p]), self._rest, after, var, after, var, self._motion)
        return force_at_zero(self.model, x, c.release_force_se)

    def _restart(self, t1: float, tc: float, seq: int) -> list[Event]:
        """A load on top of one too small to have shown its release (sleeve friction holds the arm
        through such a release): the rig is taken to rest where it stood just before, and the
        change is a new load from there, as a trial's baseline window would have it."""
        exc = self._exc
        assert exc is not None
        dropped = exc.finish(t1) + exc.held
        last = exc.steps[-1]
        self._load_done(t1)
        b, bvar = self.tracker.at(t1)
        total = sum((s.A for s in exc.steps), np.zeros(self.inputs.width))
        extra = exc.step_var if exc.step_var is not None else 0.0
        self.tracker.reset(t1, b + total, np.minimum(bvar + extra, MAX_VAR))
        self._tails.extend(exc.steps)
        self._exc = None
        self._history.clear()
        # In the new reference (the old line plus every step, the steps' unfinished parts as tails)
        # a dropped block's change is its old change less the last step's response.
        blocks = [(td, e_old - last.at(td), var) for td, e_old, var in dropped]
        return self._begin_at(t1, blocks, tc, seq)

    def _settled(self, tc: float) -> bool:
        """Has the active change's uncertainty about where it settles stayed small for a while?"""
        exc, c, p = self._exc, self.config, self.inputs.n_pressures
        assert exc is not None
        if exc.fit.result is None or tc - exc.fit.t0 < c.min_settle_s:
            return False
        if np.all(np.sqrt(exc.transient_var(tc, c.shape_sd)[:p]) <= c.settle_MPa):
            if exc.settled_since is None:
                exc.settled_since = tc
            return tc - exc.settled_since >= c.settle_hold_s - 1e-9
        exc.settled_since = None
        return False

    # ------------------------------------------------------------------ release
    def _release(self, tc: float, y: np.ndarray, r: np.ndarray) -> list[Event]:
        """Releasing: fit the way back; once settled, the baseline is set anew there."""
        exc = self._exc
        assert exc is not None
        b, bvar = self.tracker.at(tc)
        exc.fit.add(tc, y - b - exc.finished(tc), r)
        exc.fit.solve()
        if not self._settled(tc):
            return []
        var = bvar + exc.transient_var(tc, self.config.shape_sd) + (exc.step_var if exc.step_var is not None else 0.0)
        self.tracker.reset(tc, b + exc.settled_total(), np.minimum(var, MAX_VAR))
        self._tails.extend([*exc.steps, exc.fit.step()])
        self._exc = None
        self.state = IDLE
        self.detector.reset()
        self._history.clear()
        return []

    def _load_done(self, t1: float) -> None:
        """A change began at ``t1`` on a load (its release, or another load on it): the posture the
        load held the arm in just before, for the next load's motion into its baseline (module
        docstring, "The history of loads")."""
        held = [b for b in self._load_blocks if b[0] <= t1]
        if self._history_model and held:
            _, P0, P, rest = held[-1]
            self._before = rest + self.model.deflections(P0[None], P[None])[0]  # type: ignore[attr-defined]
        self._load_blocks.clear()

    def _tails_at(self, tc: float) -> tuple[np.ndarray, np.ndarray]:
        """What finished changes still add to the pressures (their lag and heat) and its variance,
        dropping spent ones."""
        c = self.config
        keep = [s for s in self._tails if tc - s.t0 < 6 * (c.thermal_tau_s + c.tau_s * max(c.tau_factors))]
        self._tails = keep
        out, var = np.zeros(self.inputs.width), np.zeros(self.inputs.width)
        for s in keep:
            out -= s.remaining(tc)
            var += s.remaining_var(tc, c.shape_error)
        return out, var

    # ------------------------------------------------------------------ estimates
    def _p0(self, line_now: np.ndarray) -> np.ndarray:
        """The baseline the model is given (module docstring, "Baseline P0 and the leak")."""
        p = self.inputs.n_pressures
        if self.model.p0_leak_corrected:
            return line_now
        gap = self.model.baseline_gap_s
        if gap is not None:
            return line_now - self.tracker.slope[:p] * gap
        return self._p0_onset if self._exc is not None else line_now

    def _estimate(self, tc: float, t: float, seq: int, y: np.ndarray, r: np.ndarray) -> Estimate:
        p, exc = self.inputs.n_pressures, self._exc
        if self.tracker.t is None:
            level, lvar = y, 4 * r
        else:
            level, lvar = self.tracker.at(tc)
        P0 = self._p0(level[:p])
        if exc is None:
            var = np.minimum(r[:p] + lvar[:p], MAX_VAR)
            x = Inputs2(P0, level[p:], y[:p], var, y[:p], var)
        else:
            # The block's mean is the pressures at its middle; the estimate is stamped at its end:
            # the fitted changes carry the lagged part over that half block, the heat is taken out.
            heat_now = exc.finished_heat(tc) + (exc.fit.step().heat_at(tc) if exc.fit.result else 0.0)
            carry = exc.finished_lag(tc, t) + (exc.fit.step().lag_between(tc, t) if exc.fit.result else 0.0)
            heat_now = heat_now - carry
            var_state = np.minimum(r[:p] + lvar[:p] + exc.heat_var(tc)[:p], MAX_VAR)
            if exc.fit.result is None:
                P_load, var_load = y[:p], np.full(p, MAX_VAR)
            else:
                P_load = level[:p] + exc.settled_total()[:p]
                extra = exc.step_var[:p] if exc.step_var is not None else 0.0
                var_load = np.minimum(exc.transient_var(tc, self.config.shape_sd)[:p] + extra + r[:p] / 4, MAX_VAR)
            x = Inputs2(P0, self._rest, y[:p] - heat_now[:p], var_state, P_load, var_load, self._motion)
            if self._history_model and exc.pending is None and self.state in (LOADING, LOADED):
                self._load_blocks.append((tc, P0, x.P_state, self._rest))
        values, se, flags = evaluate(self.model, x)
        if exc is not None:  # a load is on: the angles' standard error as the rig shows it (config)
            se = np.where(self._state_kind, se * self.config.loaded_state_se_factor, se)
        extra_flags = STATE_FLAGS.get(self.state, ())
        m = self.model
        return Estimate(
            seq,
            t,
            self.state,
            dict(zip(m.quantities, values.tolist(), strict=True)),
            dict(zip(m.quantities, se.tolist(), strict=True)),
            dict(zip(m.quantities, m.units, strict=True)),
            tuple(extra_flags) + tuple(flags),
        )
