"""The transient model: how the pressures move after a load goes on or comes off.

A load moves the arm through the muscles' lag: the posture, and with it each closed
chamber's volume, approaches its new equilibrium as a first-order lag of time constant
``tau`` (about 0.7 s on the simulated rig, "about 1 s" in the protocol).  A fast stretch
also heats the air (nearly adiabatic, ``kappa = 1.4``): the pressure overshoots the Boyle
value and relaxes as the heat flows to the wall (``thermal_tau``, a few seconds).  For a
step at ``t0`` the change of a channel's pressure is::

    e(s) = A lag(s) + B heat(s),      s = t - t0
    lag(s)  = 1 - exp(-s / tau)
    heat(s) = thermal_tau / (thermal_tau - tau) (exp(-s / thermal_tau) - exp(-s / tau))

``A`` is the settled change, the one the model wants; ``B`` the heat's share (``(kappa - 1) A``
when the air starts at the wall's temperature; :func:`heat` is the solution of
``dx/dt = -(kappa - 1) dlnV/dt - x / thermal_tau`` for a lagged volume change, as the simulated
rig's :mod:`~labcli.papers.takuma2014.sim.nonideal` writes it).

:class:`ResponseFit` estimates ``A`` of every channel from the blocks seen since the step, by
least squares under each hypothesis of a grid of lag time constants, step times and heat
shares ``kappa = B / A`` (shared by the chambers: it is the air's), averaged over them weighted
by how well each explains the data (the rig's lag varies from change to change, the
detector's step time is a block or so off, and the heat depends on how fast the change was).
Its variance of ``A`` holds that spread and the noise's share; with a share ``shape_sd`` of
what is still to come (:mod:`.excursion`) it is the transient's part of an estimate's
standard error.
"""

from __future__ import annotations

import functools
import math
from collections import deque
from dataclasses import dataclass
from typing import Any

import numpy as np

TAIL_KEEP = 200  # blocks after the span kept one by one (10 s at 20 blocks/s)
A_SPAN = 0.1  # MPa: no load moves a chamber's pressure by more (a prior so wide it only keeps the algebra finite)


def lag(s: np.ndarray, tau: float | np.ndarray) -> np.ndarray:
    """``1 - exp(-s / tau)`` for ``s > 0``, else 0."""
    if np.ndim(s) == 0 and np.ndim(tau) == 0 and float(tau) > 0:  # one time (the estimator's calls): floats
        x = float(s)
        return np.float64(-math.expm1(-x / float(tau)) if x > 0 else 0.0)
    s = np.asarray(s, dtype=float)
    return np.where(s > 0, -np.expm1(-np.maximum(s, 0.0) / tau), 0.0)


def heat(s: np.ndarray, tau: float | np.ndarray, thermal_tau: float) -> np.ndarray:
    """The heat kernel (module docstring): 0 at the step, a hump, back to 0 after several ``thermal_tau``."""
    if np.ndim(s) == 0 and np.ndim(tau) == 0 and float(tau) > 0 and thermal_tau > 0:
        return np.float64(_heat_one(float(s), float(tau), thermal_tau))
    s = np.maximum(np.asarray(s, dtype=float), 0.0)
    tau = np.asarray(tau, dtype=float)
    near = np.abs(thermal_tau - tau) < 1e-9 * thermal_tau
    with np.errstate(divide="ignore", invalid="ignore"):
        g = thermal_tau / (thermal_tau - tau) * (np.exp(-s / thermal_tau) - np.exp(-s / tau))
    return np.where(near, s / tau * np.exp(-s / tau), g)


def _heat_one(s: float, tau: float, thermal_tau: float) -> float:
    """:func:`heat` at one time, in plain floats."""
    s = s if s > 0.0 or s != s else 0.0  # np.maximum's: NaN stays NaN
    if abs(thermal_tau - tau) < 1e-9 * thermal_tau:
        return s / tau * math.exp(-s / tau)
    return thermal_tau / (thermal_tau - tau) * (math.exp(-s / thermal_tau) - math.exp(-s / tau))


@dataclass(frozen=True)
class Step:
    """A fitted step response: ``A lag(t - t0) + B heat(t - t0)`` per channel."""

    t0: float
    A: np.ndarray
    B: np.ndarray
    tau: float
    thermal_tau: float
    var_A: np.ndarray | None = None
    var_B: np.ndarray | None = None

    # Each method is asked about one time, every block: the kernels are taken in plain floats
    # (lag's and heat's own one-time paths) rather than through their array forms.
    def _lag(self, s: float) -> float:
        if self.tau > 0:
            return -math.expm1(-s / self.tau) if s > 0 else 0.0
        return float(lag(np.array(s), self.tau))

    def _heat(self, s: float) -> float:
        if self.tau > 0 and self.thermal_tau > 0:
            return _heat_one(s, self.tau, self.thermal_tau)
        return float(heat(np.array(s), self.tau, self.thermal_tau))

    def at(self, t: float) -> np.ndarray:
        s = t - self.t0
        return self.A * self._lag(s) + self.B * self._heat(s)

    def heat_at(self, t: float) -> np.ndarray:
        return self.B * self._heat(t - self.t0)

    def lag_between(self, t_from: float, t_to: float) -> np.ndarray:
        """The lagged part's move from ``t_from`` to ``t_to``: ``A (lag(t_to) - lag(t_from))`` (k,)."""
        return self.A * (self._lag(t_to - self.t0) - self._lag(t_from - self.t0))

    def remaining(self, t: float) -> np.ndarray:
        """What is still to come after ``t``: ``A`` minus the response so far."""
        return self.A - self.at(t)

    def unresolved(self, t: float) -> np.ndarray:
        """How much of the change its shape still has to carry after ``t``: the lag still to come and
        the heat still to leave, in size (they may cancel in :meth:`remaining`, not in doubt) (k,)."""
        s = t - self.t0
        return np.abs(self.A * (1.0 - self._lag(s))) + np.abs(self.B * self._heat(s))

    def remaining_var(self, t: float, shape_error: float) -> np.ndarray:
        """The variance of :meth:`remaining`: the heat's amplitude, and a share of the rest for its shape."""
        g = self._heat(t - self.t0)
        var_B = self.var_B if self.var_B is not None else 0.0
        return var_B * g**2 + (shape_error * self.remaining(t)) ** 2


@dataclass(frozen=True)
class FitResult:
    """``A``, ``B`` (k,) and their variances; the lag time constant the fit favours; the
    weighted normalised misfit (chi2 per degree of freedom, about 1 when the shape fits)."""

    A: np.ndarray
    B: np.ndarray
    var_A: np.ndarray
    var_B: np.ndarray
    tau: float
    misfit: float
    n: int


class ResponseFit:
    """A step's response fitted block by block (module docstring).

    ``taus``: the grid of lag time constants (s); ``shifts``: offsets (s) tried around ``t0``;
    ``kappas``: the grid of heat shares ``B / A`` (``kappa - 1`` of air is 0.4 for a fast stretch);
    ``heated``: 1 for the channels whose air heats, 0 for the others (potentiometers).
    """

    def __init__(
        self,
        t0: float,
        k: int,
        *,
        taus: np.ndarray,
        shifts: np.ndarray,
        thermal_tau: float,
        kappas: np.ndarray,
        capacity: int,
        heated: np.ndarray | None = None,
        shared: np.ndarray | None = None,
        shape_sd: float = 0.3,
    ) -> None:
        self.t0 = float(t0)
        self.taus = np.asarray(taus, dtype=float)
        self.shifts = np.asarray(shifts, dtype=float)
        self.thermal_tau = float(thermal_tau)
        self.kappas = np.asarray(kappas, dtype=float)
        # The channels whose air heats (the pressures); a potentiometer's reading has no heat.
        self.heated = np.ones(k) if heated is None else np.asarray(heated, dtype=float)
        # The heat shares per hypothesis and channel (K, 1, 1, k), and the multiples the solve takes
        # of them: worked out once, the span is solved every block.
        # Tiled to the whole grid (K, T, S, k): numpy's loops over a grid broadcast along its middle
        # axes run six numbers at a time, over a whole one at full speed.
        grid = (len(self.kappas), len(self.taus), len(self.shifts), k)
        self._kap = np.ascontiguousarray(np.broadcast_to(self.kappas[:, None, None, None] * self.heated, grid))
        self._kap2 = self._kap**2
        self._two_kap = 2 * self._kap
        self._t = np.empty(capacity)
        self._e = np.empty((capacity, k))
        self._w = np.empty((capacity, k))  # 1 / variance
        # The channels whose fit weighs the hypotheses (and whose misfit counts): the pressures;
        # a potentiometer's backlash makes its response no clean lag.
        self.shared = np.ones(k, bool) if shared is None else np.asarray(shared, dtype=bool)
        # Those channels as a slice when they lead (the pressures before the angles): a view, not a copy.
        lead = int(self.shared.sum())
        self._shared_at: Any = slice(0, lead) if self.shared[:lead].all() else self.shared
        self.shape_sd = float(shape_sd)  # share of what the shape still carries counted as uncertain
        self.n = 0
        self.result: FitResult | None = None
        self._reset_sums()
        self._shift = 0.0
        self._step: tuple[FitResult, float, Step] | None = None
        self._grid: tuple[np.ndarray, ...] | None = None
        self._one: tuple[np.ndarray, np.ndarray, np.ndarray | None, np.ndarray, np.ndarray] | None = None
        # After the span: the shape frozen, the level refined by sums over the later blocks (the last
        # TAIL_KEEP of them kept one by one, so a change found among them can take them back).
        self._frozen: FitResult | None = None
        self._tail: deque[tuple[float, np.ndarray, np.ndarray, float]] = deque()
        self._tail_n = 0  # blocks folded into the sums for good
        self._sum_e = np.zeros(k)
        self._sum_g = 0.0
        self._sum_v = np.zeros(k)

    @property
    def full(self) -> bool:
        return self.n >= self._t.shape[0]

    def add(self, t: float, e: np.ndarray, var: np.ndarray) -> None:
        """One block's change from the baseline (k,) and its variance.

        Once the fit's span is full its shape is kept, and later blocks only refine the level:
        each, less the heat the shape says is left, is an observation of ``A`` itself.
        """
        if not self.full:
            self._t[self.n], self._e[self.n], self._w[self.n] = t, e, 1.0 / var
            self.n += 1
            if self.full:
                self._frozen = self.solve()
            return
        f = self._frozen
        assert f is not None
        g = float(heat(np.array(t - self.t0 - self._shift), f.tau, self.thermal_tau))
        self._tail.append((t, e - f.B * g, var, g))
        self._sum_e += e - f.B * g
        self._sum_g += g
        self._sum_v += var
        self.result = None

    def truncate(self, t: float) -> list[tuple[float, np.ndarray, np.ndarray]]:
        """Drop the blocks after ``t`` (they belong to the next change); return them (t, e, var)."""
        dropped = []
        while self._tail and self._tail[-1][0] > t:
            tt, level, var, g = self._tail.pop()
            self._sum_e -= level
            self._sum_g -= g
            self._sum_v -= var
            assert self._frozen is not None
            dropped.append((tt, level + self._frozen.B * g, var))
        if not self._tail and self._count_tail() == 0:
            keep = int(np.searchsorted(self._t[: self.n], t, side="right"))
            dropped += [(float(self._t[i]), self._e[i].copy(), 1.0 / self._w[i]) for i in range(keep, self.n)][::-1]
            if keep < self.n:
                self.n = keep
                self._frozen = None
                self._reset_sums()
        self.result = None
        return dropped[::-1]

    def _count_tail(self) -> int:
        return self._tail_n + len(self._tail)

    def solve(self) -> FitResult:
        """The fit: over the span (:meth:`_solve_span`), then refined by the blocks after it."""
        if self._frozen is None or not self._count_tail():
            self.result = self._frozen or self._solve_span()
            return self.result
        while len(self._tail) > TAIL_KEEP:
            self._tail.popleft()
            self._tail_n += 1
        f, m = self._frozen, self._count_tail()
        level = self._sum_e / m
        var_level = self._sum_v / m**2 + f.var_B * (self._sum_g / m) ** 2
        # The span's A is an extrapolation: what its shape still carried at the span's end counts.
        end = Step(self.t0 + self._shift, f.A, f.B, f.tau, self.thermal_tau).unresolved(float(self._t[self.n - 1]))
        var_f = f.var_A * max(1.0, f.misfit) + (self.shape_sd * end) ** 2
        w = var_level / (var_f + var_level)  # the fit's share
        A = w * f.A + (1.0 - w) * level
        self.result = FitResult(A, f.B, var_f * var_level / (var_f + var_level), f.var_B, f.tau, f.misfit, self.n + m)
        return self.result

    def _solve_span(self) -> FitResult:
        """Fit every channel's ``A`` under each hypothesis of the shared lag, step time and heat
        share (B = kappa A), and average over them weighted by how well each explains the data.

        The heat's share is the same for every chamber (it is the air's), so with it shared the
        four pressures fix three numbers together and each its own ``A``; the model average's
        variance holds the noise's share and the spread of the hypotheses that fit.
        """
        n = self.n
        Spp, Spg, Sgg, Spe, Sge, See = self._sums()
        kap = self._kap  # (K, T, S, k): no heat on unheated channels
        # The grid's arrays are worked in buffers the fit keeps (the same arithmetic in the same
        # order; nothing returned refers to them): solved every block, they stay in the cache.
        Sqq, Sqe, A, work, wk, B = self._grid_buffers()
        np.multiply(self._two_kap, Spg, out=Sqq)
        Sqq += Spp
        Sqq += np.multiply(self._kap2, Sgg, out=work)
        Sqq += 1.0 / A_SPAN**2  # (K, T, S, k)
        np.multiply(kap, Sge, out=Sqe)
        Sqe += Spe
        np.divide(Sqe, Sqq, out=A)
        resid = np.subtract(See, np.multiply(Sqe, A, out=work), out=work)
        chi2 = _channel_sum(resid, self._shared_at)  # (K, T, S)
        dof = max(1, (n - 3) * int(self.shared.sum()))
        least = chi2.min()
        misfit = float(least) / dof
        # The noise scale is the best hypothesis's residual when that is above the blocks' own.
        wt = np.exp(-0.5 * (chi2 - least) / max(1.0, misfit))
        wt /= wt.sum()
        # The averages over the hypotheses: summed one hypothesis after another (np.add.reduce over
        # the grid's axes), the order the estimates are held to; the weights tiled over the channels once.
        wk[:] = wt[..., None]
        grid = (0, 1, 2)
        Am = np.add.reduce(np.multiply(wk, A, out=work), axis=grid)
        np.multiply(kap, A, out=B)
        Bm = np.add.reduce(np.multiply(wk, B, out=work), axis=grid)
        best = np.unravel_index(int(np.argmin(chi2)), chi2.shape)
        spread = np.subtract(A, Am, out=work)
        spread *= spread
        spread += 1.0 / Sqq
        spread *= wk
        var_A = np.add.reduce(spread, axis=grid) + _grid_var(A, best)
        spread = np.subtract(B, Bm, out=work)
        spread *= spread
        spread += self._kap2 / Sqq
        spread *= wk
        var_B = np.add.reduce(spread, axis=grid) + _grid_var(B, best)
        marg = wt.sum(axis=0)  # (T, S)
        tau_w = float(np.exp((marg.sum(axis=1) * np.log(self.taus)).sum()))
        self._shift = float((marg.sum(axis=0) * self.shifts).sum())
        self.result = FitResult(Am, Bm, var_A, var_B, tau_w, misfit, n)
        return self.result

    def _grid_buffers(self) -> tuple[np.ndarray, ...]:
        """Six (K, T, S, k) arrays for :meth:`_solve_span`'s work, made once per fit."""
        if self._grid is None:
            self._grid = tuple(np.empty(self._kap.shape) for _ in range(6))
        return self._grid

    def _reset_sums(self) -> None:
        T, S, k = len(self.taus), len(self.shifts), self._e.shape[1]
        self._sums_n = 0
        self._S = np.zeros((5, 1, T, S, k))  # Spp, Spg, Sgg, Spe, Sge, each (1, T, S, k)
        self._See = np.zeros(k)

    def _sums(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """The least squares' sums over the span's blocks under every (lag, step time) hypothesis:
        sum w phi^2, w phi g, w g^2, w phi e, w g e (1, T, S, k) and sum w e^2 (k,).

        Kept from solve to solve: the fit is solved every block, so each block is summed in once
        (all of them again after :meth:`truncate` takes some back), not the whole span every block.
        """
        lo, n = self._sums_n, self.n
        if n - lo == 1:  # one new block (every solve but the first after a truncate)
            self._sum_one(lo)
        elif lo < n:
            t, e, w = self._t[lo:n], self._e[lo:n], self._w[lo:n]
            s = t[None, None, :] - (self.t0 + self.shifts)[None, :, None]
            tau = self.taus[:, None, None]
            phi, g = lag(s, tau), heat(s, tau, self.thermal_tau)  # (T, S, n - lo)
            self._S[0, 0] += np.einsum("tsn,tsn,nk->tsk", phi, phi, w)
            self._S[1, 0] += np.einsum("tsn,tsn,nk->tsk", phi, g, w)
            self._S[2, 0] += np.einsum("tsn,tsn,nk->tsk", g, g, w)
            self._S[3, 0] += np.einsum("tsn,nk->tsk", phi, w * e)
            self._S[4, 0] += np.einsum("tsn,nk->tsk", g, w * e)
            self._See += np.sum(w * e * e, axis=0)
            self._sums_n = n
        S = self._S
        return S[0], S[1], S[2], S[3], S[4], self._See

    def _sum_one(self, i: int) -> None:
        """Block ``i`` into the sums (:meth:`_sums`): :func:`lag`'s and :func:`heat`'s arithmetic at
        its time under every (lag, step time) hypothesis, then plain products, written into buffers
        the fit keeps (the fit is solved every block; numpy's general paths cost more than the sums)."""
        b = self._one
        if b is None:
            T, S, k = len(self.taus), len(self.shifts), self._e.shape[1]
            tau = self.taus[:, None, None]
            with np.errstate(divide="ignore", invalid="ignore"):
                coef = self.thermal_tau / (self.thermal_tau - tau)
            close = np.abs(self.thermal_tau - tau) < 1e-9 * self.thermal_tau
            b = self._one = (tau, coef, close if close.any() else None, np.empty((5, T, S, 1)), np.empty((5, 1, 1, k)))
        tau, coef, near, kernels, weights = b
        t, e, w = self._t[i], self._e[i], self._w[i]
        s = t - (self.t0 + self.shifts)[None, :, None]  # (1, S, 1)
        m = np.maximum(s, 0.0)
        neg = -m
        x = neg / tau  # (T, S, 1)
        phi, g = kernels[3], kernels[4]
        np.negative(np.expm1(x), out=phi)
        phi[...] = np.where(s > 0, phi, 0.0)
        with np.errstate(divide="ignore", invalid="ignore"):
            ex = np.exp(x)
            np.multiply(coef, np.exp(neg / self.thermal_tau) - ex, out=g)
        if near is not None:
            g[...] = np.where(near, m / tau * ex, g)
        np.multiply(phi, phi, out=kernels[0])
        np.multiply(phi, g, out=kernels[1])
        np.multiply(g, g, out=kernels[2])
        weights[:3, 0, 0] = w
        np.multiply(w, e, out=weights[3, 0, 0])
        weights[4] = weights[3]
        self._S[:, 0] += kernels * weights
        self._See += weights[3, 0, 0] * e
        self._sums_n = i + 1

    def step(self) -> Step:
        """The fitted response as a :class:`Step` (at the lag and step time found); the same object
        until the fit changes (the estimator asks for it several times a block)."""
        r = self.result or self.solve()
        cached = self._step
        if cached is not None and cached[0] is r and cached[1] == self._shift:
            return cached[2]
        inflate = max(1.0, r.misfit)
        step = Step(self.t0 + self._shift, r.A, r.B, r.tau, self.thermal_tau, r.var_A * inflate, r.var_B * inflate)
        self._step = (r, self._shift, step)
        return step


def _channel_sum(x: np.ndarray, channels: Any) -> np.ndarray:
    """``x[..., channels].sum(axis=-1)``, a leading slice of channels added one after another (the
    order np.add.reduce takes over a few numbers) instead of reduced over an axis six numbers long."""
    if not isinstance(channels, slice) or channels.stop - channels.start < 2:
        return np.add.reduce(x[..., channels], axis=-1)
    out = x[..., channels.start] + x[..., channels.start + 1]
    for j in range(channels.start + 2, channels.stop):
        out += x[..., j]
    return out


def _grid_var(values: np.ndarray, best: tuple[Any, ...]) -> np.ndarray:
    """The uncertainty a grid leaves between its points: along each axis, the value's change from
    the best point's neighbours as the variance of a uniform spread over one spacing ((k,))."""
    lo, hi, width = _neighbours(tuple(int(i) for i in best), values.shape[:3])
    if not width.size:
        return np.zeros(values.shape[-1])
    step = (values[hi] - values[lo]) / width[:, None]  # (axes, k)
    return np.add.reduce(step * step / 12.0, axis=0)  # the axes' shares summed in turn


@functools.lru_cache(maxsize=4096)
def _neighbours(
    best: tuple[int, ...], shape: tuple[int, ...]
) -> tuple[tuple[np.ndarray, ...], tuple[np.ndarray, ...], np.ndarray]:
    """The grid points either side of ``best`` along each axis of more than one point (index
    arrays, one entry per axis) and their distance in points."""
    lo_idx: list[list[int]] = [[] for _ in shape]
    hi_idx: list[list[int]] = [[] for _ in shape]
    width = []
    for axis, i in enumerate(best):
        n = shape[axis]
        if n < 2:
            continue
        lo, hi = max(i - 1, 0), min(i + 1, n - 1)
        for a in range(len(shape)):
            lo_idx[a].append(lo if a == axis else best[a])
            hi_idx[a].append(hi if a == axis else best[a])
        width.append(float(hi - lo))
    to = lambda idx: tuple(np.array(x, dtype=np.intp) for x in idx)  # noqa: E731
    return to(lo_idx), to(hi_idx), np.array(width)


def onset(tc: np.ndarray, z: np.ndarray, tau: float, block_s: float) -> tuple[float, np.ndarray]:
    """When a lagged step most likely began, given blocks (centre times ``tc``) of ``z`` (n, d).

    Candidate starts are the blocks' boundaries (``tc - block_s / 2``); for each the step's
    amplitude is the least-squares ``sum lag z / sum lag^2`` over the blocks after it, and the
    start that explains most of ``z`` wins.  Returns its time and the amplitude (d,).
    """
    starts = tc - 0.5 * block_s
    phi = lag(tc[None, :] - starts[:, None], tau)  # (candidates, n)
    num = phi @ z  # (c, d)
    den = np.maximum((phi * phi).sum(axis=1), 1e-300)
    gain = (num * num).sum(axis=1) / den
    best = int(np.argmax(gain))
    return float(starts[best]), num[best] / den[best]
