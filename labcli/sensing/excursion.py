"""One excursion of the rig from its baseline: the load(s) on it and the release.

From the moment a load is detected until the rig has settled after its release, each
channel is modelled as (SI, per channel)::

    y(t) = b(t) + sum over finished changes of their Step(t) + the change being fitted + noise

with ``b`` the baseline line frozen at the load's start (:mod:`.baseline`, extrapolated: the
leak goes on under the load).  A change is finished when the next one begins: a second weight
added to the first, or the release.  The change being fitted is a :class:`ResponseFit`; its
settled value ``A`` is what the rig is heading for, ``B`` the heat that is still to leave.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .transient import FitResult, ResponseFit, Step, heat


@dataclass
class Excursion:
    """The changes of one excursion and the active fit (module docstring)."""

    t0: float  # when the first load began
    kind: str  # the active change: "load" or "release"
    fit: ResponseFit
    steps: list[Step] = field(default_factory=list)  # finished changes, oldest first
    step_var: np.ndarray | None = None  # summed variance of the finished changes' settled values
    settled_since: float | None = None  # when the transient's uncertainty last fell below the limit
    settled: bool = False
    residuals: list[tuple[float, np.ndarray, np.ndarray]] = field(default_factory=list)  # (tc, whitened, raw) residuals
    pending: float | None = None  # when the next change was seen, while its first blocks come in
    held: list[tuple[float, np.ndarray, np.ndarray]] = field(default_factory=list)  # those blocks (tc, change, var)
    _transient: tuple[Any, float, float, np.ndarray] | None = field(default=None, repr=False, compare=False)

    def finished(self, t: float) -> np.ndarray:
        """The finished changes' response at ``t`` (k,)."""
        out = np.zeros(self.fit._e.shape[1])
        for s in self.steps:
            out += s.at(t)
        return out

    def finished_heat(self, t: float) -> np.ndarray:
        out = np.zeros(self.fit._e.shape[1])
        for s in self.steps:
            out += s.heat_at(t)
        return out

    def finished_lag(self, t_from: float, t_to: float) -> np.ndarray:
        """How far the finished changes' lagged part moves between two times (k,)."""
        out = np.zeros(self.fit._e.shape[1])
        for s in self.steps:
            out += s.lag_between(t_from, t_to)
        return out

    def settled_total(self) -> np.ndarray:
        """The settled value of every change so far, the active one's included (k,)."""
        r = self.fit.result
        total = sum((s.A for s in self.steps), np.zeros(self.fit._e.shape[1]))
        return total + (r.A if r is not None else 0.0)

    def transient_var(self, t: float, shape_sd: float) -> np.ndarray:
        """The active change's uncertainty about where it settles (k,): the fit's variance of A
        (inflated by its misfit) and a share of what its shape still has to carry."""
        r = self.fit.result
        if r is None:
            return np.full(self.fit._e.shape[1], np.inf)
        last = self._transient  # the estimator asks up to three times a block
        if last is not None and last[0] is r and last[1] == t and last[2] == shape_sd:
            return last[3]
        out = r.var_A * max(1.0, r.misfit) + (shape_sd * self.fit.step().unresolved(t)) ** 2
        self._transient = (r, t, shape_sd, out)
        return out

    def heat_var(self, t: float) -> np.ndarray:
        """The variance of the active change's heat at ``t`` (k,)."""
        r = self.fit.result
        if r is None:
            return np.zeros(self.fit._e.shape[1])
        g = heat(np.array(t - self.fit.step().t0), r.tau, self.fit.thermal_tau)
        return r.var_B * g**2

    def finish(self, t1: float) -> list[tuple[float, np.ndarray, np.ndarray]]:
        """End the active change at ``t1``: refit it without the blocks after ``t1``, keep it
        as a finished step, return those blocks (tc, change, variance) for the next fit."""
        dropped = self.fit.truncate(t1)
        if self.fit.n:
            res: FitResult = self.fit.solve()
            self.steps.append(self.fit.step())
            var = res.var_A * max(1.0, res.misfit)
            self.step_var = var if self.step_var is None else self.step_var + var
        return dropped

    def next_change(self, t1: float, fit: ResponseFit) -> None:
        """End the active change at ``t1`` (:meth:`finish`) and fit the next one with ``fit``, from
        the blocks after ``t1`` and those held while it was told apart (their change less the
        finished one's response)."""
        dropped = self.finish(t1) + self.held
        self.fit = fit
        last = self.steps[-1] if self.steps else None
        for td, e_old, var in dropped:
            fit.add(td, e_old - (last.at(td) if last is not None else 0.0), var)
        if fit.n:
            fit.solve()
        self.residuals.clear()
        self.held.clear()
        self.pending = None
        self.settled_since = None
