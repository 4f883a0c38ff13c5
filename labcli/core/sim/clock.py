"""The simulated time every simulated rig keeps (device time, not the wall clock)."""

from __future__ import annotations

import threading


class SimClock:
    """Mixin: ``time_s`` and the ways to let it pass.  A rig sets ``_t`` and ``_lock``."""

    _t: float
    _lock: threading.RLock

    @property
    def time_s(self) -> float:
        """The rig's simulated time, s."""
        return self._t

    def advance(self, seconds: float) -> None:
        """Let ``seconds`` of simulated time pass without sampling."""
        if seconds < 0:
            raise ValueError("time only runs forward")
        with self._lock:
            self._t += float(seconds)

    def advance_to(self, time_s: float) -> None:
        """Let simulated time run up to ``time_s`` (no-op if already past it)."""
        with self._lock:
            self._t = max(self._t, float(time_s))
