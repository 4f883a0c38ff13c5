"""The simulated rig acting out a script (:mod:`.script`), with the truth kept beside the stream.

:class:`ScriptedRig` wraps a :class:`~.rig.SimRig` and offers what the simulated firmware
reads (``samples``, ``advance``, ``advance_to``, ...): each scripted action happens at the
frame boundary at or just before its time (within one frame period), so the stream the host
reads and the truth recorded agree frame by frame.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from functools import partial
from typing import Any

import numpy as np

from .script import Change, Script


class ScriptedRig:
    """A rig that acts out ``script`` on its own clock; everything else is the wrapped rig's."""

    def __init__(self, rig: Any, script: Script, *, record: bool = True) -> None:
        self.rig = rig
        self.script = script
        self.record = record
        self._actions = _actions(script)
        self._next = 0
        self._t: list[np.ndarray] = []
        self._theta: list[np.ndarray] = []
        self._force: list[np.ndarray] = []
        self.changes: list[dict[str, Any]] = []  # per scripted change: what happened, with its truth
        self._act_until(rig.time_s)

    def __getattr__(self, name: str) -> Any:
        return getattr(self.rig, name)

    # ------------------------------------------------------------------ clock
    def _act_until(self, t: float) -> None:
        """Do every action due at or before ``t`` (the rig's clock stands at or before it)."""
        while self._next < len(self._actions) and self._actions[self._next][0] <= t + 1e-12:
            at, what, change = self._actions[self._next]
            self.rig.advance_to(at)
            what(self.rig)
            if change is not None:
                self._note(at, change)
            self._next += 1

    def _due(self) -> float:
        return self._actions[self._next][0] if self._next < len(self._actions) else math.inf

    def advance(self, seconds: float) -> None:
        self.advance_to(self.rig.time_s + float(seconds))

    def advance_to(self, time_s: float) -> None:
        self._act_until(float(time_s))
        self.rig.advance_to(time_s)

    def samples(self, n: int, rate_hz: float) -> tuple[np.ndarray, np.ndarray]:
        """``n`` frames as the rig's ``samples``, the actions between them done on time."""
        ts, cs = [], []
        left = int(n)
        while left > 0:
            due = self._due()
            now = self.rig.time_s
            room = left if not math.isfinite(due) else int(math.floor((due - now) * rate_hz + 1e-9))
            take = max(0, min(left, room))
            if take == 0:
                self._act_until(now + 1.0 / rate_hz)
                take = min(left, 1)
            t_us, counts = self.rig.samples(take, rate_hz)
            self._keep(t_us)
            ts.append(t_us)
            cs.append(counts)
            left -= take
        if not ts:
            return self.rig.samples(0, rate_hz)
        return np.concatenate(ts), np.concatenate(cs)

    # ------------------------------------------------------------------ truth
    def _keep(self, t_us: np.ndarray) -> None:
        if not self.record or not len(t_us):
            return
        truth = self.rig.truth_at(t_us * 1e-6)
        self._t.append(t_us * 1e-6)
        self._theta.append(truth["deflection_rad"])
        self._force.append(truth["force_N"])

    def _note(self, at: float, change: tuple[str, Change]) -> None:
        edge, c = change
        state = self.rig.true_state()
        if edge == "on":
            deflection = state["target_theta_rad"] - state["rest_theta_rad"]
            self.changes.append(
                {
                    "kind": c.kind,
                    "name": c.name,
                    "on_s": at,
                    "off_s": math.nan,
                    "force_N": _settled_force(self.rig, state),
                    "deflection_rad": deflection,
                    "rest_rad": state["rest_theta_rad"],
                    "change": c,
                }
            )
        else:
            for row in reversed(self.changes):  # stacked weights come off in any order
                if row["change"] is c:
                    row["off_s"] = at
                    break

    def truth(self) -> dict[str, Any]:
        """Per frame ``t_s``, ``deflection_rad`` (n, 2), ``force_N`` (n, 2); ``changes`` as noted."""
        if not self._t:
            return {"t_s": np.empty(0), "deflection_rad": np.empty((0, 2)), "force_N": np.empty((0, 2)), "changes": []}
        return {
            "t_s": np.concatenate(self._t),
            "deflection_rad": np.concatenate(self._theta),
            "force_N": np.concatenate(self._force),
            "changes": list(self.changes),
        }


def _settled_force(rig: Any, state: dict[str, Any]) -> np.ndarray:
    """The force at the equilibrium being approached (a weight's is constant; a push's settles)."""
    return np.asarray(rig.truth_at(np.array([math.inf]))["force_N"][0], dtype=float)


def _on(c: Change, hanger: list[Change], rig: Any) -> None:
    if c.kind == "load":
        hanger.append(c)
        rig.hang_weight(sum(w.mass_kg for w in hanger), c.direction_rad)
    else:
        rig.push_object(c.radius_m, c.distance_m, c.phi_rad, c.stiffness_N_per_m)


def _off(c: Change, hanger: list[Change], rig: Any) -> None:
    """Take a push away, or a weight off the hanger: the rig holds the others' sum (stacked weights, :mod:`.script`)."""
    if c.kind != "load":
        rig.release_object()
        return
    hanger[:] = [w for w in hanger if w is not c]
    if hanger:
        rig.hang_weight(sum(w.mass_kg for w in hanger), hanger[0].direction_rad)
    else:
        rig.remove_weight()


def _actions(script: Script) -> list[tuple[float, Callable[[Any], None], tuple[str, Change] | None]]:
    """(time, what the operator does, the change it begins or ends) in time order."""
    out: list[tuple[float, Callable[[Any], None], tuple[str, Change] | None]] = [
        (script.supply_s, lambda rig: rig.supply_air(), None),
        (script.close_s, lambda rig: rig.close_valves(), None),
    ]
    hanger: list[Change] = []  # the weights hanging (stacked ones share it)
    for c in script.changes:
        out += [(c.on_s, partial(_on, c, hanger), ("on", c)), (c.off_s, partial(_off, c, hanger), ("off", c))]
    out.sort(key=lambda a: a[0])
    return out
