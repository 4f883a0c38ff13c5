"""What the estimator gives back: estimates, one per block, and events.

Both are frozen, typed and in SI; :meth:`Estimate.as_json` and :meth:`Event.as_json` give the
JSON-line form people and other programs read (degrees for angles, the unit in every key:
``theta1_deg``, ``Fx_N``, each with its ``_se`` twin).
"""

from __future__ import annotations

import functools
import json
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

# Estimator states, in the order a load passes through them.
STARTING = "starting"  # learning the baseline (the first seconds)
IDLE = "idle"  # no load: the baseline follows the leak and the rest posture
LOADING = "loading"  # a load came on and the rig has not settled yet
LOADED = "loaded"  # the load has settled
RELEASING = "releasing"  # the load came off and the rig has not settled yet
STATES = (STARTING, IDLE, LOADING, LOADED, RELEASING)

# Event kinds.
LOAD = "load"
SETTLED = "settled"
RELEASE = "release"

DISPLAY = {"rad": ("deg", 180.0 / math.pi), "N": ("N", 1.0), "MPa": ("MPa", 1.0), "m": ("mm", 1e3)}


def _num(x: float, digits: int = 6) -> float | None:
    return round(float(x), digits) if math.isfinite(x) else None


@dataclass(frozen=True, slots=True)
class Estimate:
    """The estimate at the end of one block.

    ``seq`` and ``t_device_s`` are those of the block's last frame; ``values`` and ``se`` map
    each quantity to its value and standard error (SI: rad, N); ``units`` its SI unit;
    ``flags`` say what to beware of (``"transient"``, ``"unobservable:Fy"``, ...;
    :mod:`.model`); ``state`` is the estimator's (:data:`STATES`).
    """

    seq: int
    t_device_s: float
    state: str
    values: Mapping[str, float]
    se: Mapping[str, float]
    units: Mapping[str, str]
    flags: tuple[str, ...] = ()

    def as_json(self) -> dict[str, Any]:
        """``{"seq", "t_device_s", "state", "theta1_deg", "theta1_deg_se", ..., "flags"}``."""
        out: dict[str, Any] = {"seq": self.seq, "t_device_s": _num(self.t_device_s), "state": self.state}
        for q, v in self.values.items():
            unit, factor = DISPLAY.get(self.units[q], (self.units[q], 1.0))
            out[f"{q}_{unit}"] = _num(v * factor)
            out[f"{q}_{unit}_se"] = _num(self.se[q] * factor)
        out["flags"] = list(self.flags)
        return out

    def json_line(self, t_host_s: float) -> str:
        """:meth:`as_json` and ``t_host_s`` as one JSON line, character for character what
        ``json.dumps(..., separators=(", ", ": "), allow_nan=False)`` writes of them, with the numbers
        formatted straight into the text (a live session writes one a block)."""
        parts = [f'{{"seq": {int(self.seq)}, "t_device_s": {_text(self.t_device_s)}, "state": {_quoted(self.state)}']
        for q, v in self.values.items():
            key, key_se, factor = _keys(q, self.units[q])
            parts.append(f", {key}: {_text(v * factor)}, {key_se}: {_text(self.se[q] * factor)}")
        parts.append(
            f', "flags": [{", ".join(_quoted(f) for f in self.flags)}], "t_host_s": {float.__repr__(float(t_host_s))}}}'
        )
        return "".join(parts)


def _text(x: float) -> str:
    """A number as json.dumps writes :func:`_num`'s rounding of it (``null`` when not finite)."""
    v = _num(x)
    return "null" if v is None else float.__repr__(v)


@functools.lru_cache(maxsize=256)
def _quoted(text: str) -> str:
    return json.dumps(text)


@functools.lru_cache(maxsize=256)
def _keys(q: str, si: str) -> tuple[str, str, float]:
    """A quantity's two JSON keys (value, standard error), quoted, and its display factor."""
    unit, factor = DISPLAY.get(si, (si, 1.0))
    return json.dumps(f"{q}_{unit}"), json.dumps(f"{q}_{unit}_se"), factor


@dataclass(frozen=True, slots=True)
class Event:
    """Something happened: ``kind`` is ``"load"``, ``"settled"``, ``"release"`` (or a paper's own,
    e.g. ``"push"``).

    ``t_device_s``: when it happened (a load's or release's estimated start; the block at which
    the rig was judged settled); ``t_detected_s``: the block that revealed it; ``seq`` that
    block's last frame; ``estimate``: for ``settled``, the settled estimate; ``data``: what a
    settled-load hook added (a push's stiffness and category).
    """

    kind: str
    t_device_s: float
    t_detected_s: float
    seq: int
    estimate: Estimate | None = None
    data: Mapping[str, Any] = field(default_factory=dict)

    def as_json(self) -> dict[str, Any]:
        """``{"event": kind, "t_device_s": ..., "t_detected_s": ..., "seq": ...}`` plus ``data``."""
        out: dict[str, Any] = {
            "event": self.kind,
            "t_device_s": _num(self.t_device_s),
            "t_detected_s": _num(self.t_detected_s),
            "seq": self.seq,
        }
        out.update(self.data)
        return out
