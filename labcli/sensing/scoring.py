"""How well a run of the estimator did against the truth of a scripted session.

Used by the scripted-scenario test and ``tests/benchmarks/sensing_online.py``.  The truth is
plain data: per frame the device time and the true value of each quantity (SI, the model's
order), and per scripted change when it came on and off and how large it was.

* Detection: a change is found when a ``load`` event is detected within ``window_s`` after it
  came on (the event's estimated start may lie a little before); its release when a
  ``release`` event is detected within ``window_s`` after it came off.  Every other ``load`` or
  ``release`` event is false.  Latency: detection time less the true time.
* Settled error: every estimate from a load's ``settled`` event to its release, against the
  truth at that estimate's time; per change the mean square, then the root of the mean over
  changes (so a long hold does not outweigh a short one).  An estimate flagged
  ``unobservable:q`` reports no q and is left out of q's; a change none of whose settled
  estimates reports q has no q (NaN), and is left out of q's mean.
* Coverage: the share of estimates whose 95 % interval (+-1.96 standard errors) holds the
  truth, per quantity, over every estimate after the baseline was learnt, transients included;
  an estimate flagged ``unobservable:q`` reports no q and is left out of q's.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .model import BASELINE, UNOBSERVABLE
from .results import LOAD, RELEASE, SETTLED, Estimate, Event

Z95 = 1.959963984540054


@dataclass
class Change:
    """One true change: on and off times (s), its size (N for a load), and its own truth if any."""

    on_s: float
    off_s: float
    size: float
    detected_s: float | None = None
    released_s: float | None = None
    settled_s: float | None = None
    settled_sq: np.ndarray | None = None  # mean squared error of its settled estimates, per quantity
    extra: dict[str, Any] = field(default_factory=dict)


@dataclass
class Score:
    """The figures of one run (see the module docstring); NaN where undefined."""

    changes: list[Change]
    false_events: int  # anywhere
    false_idle: int  # within the idle stretches
    idle_s: float
    coverage: dict[str, float]
    coverage_n: dict[str, int]
    settled_rmse: dict[str, float]
    settled_n: int

    def detection(self, min_size: float = 0.0) -> dict[str, float]:
        """Hits, misses and latencies over the changes of at least ``min_size``."""
        ch = [c for c in self.changes if c.size >= min_size]
        on = [c.detected_s - c.on_s for c in ch if c.detected_s is not None]
        off = [c.released_s - c.off_s for c in ch if c.released_s is not None]
        return {
            "n": len(ch),
            "found": len(on),
            "released": len(off),
            "onset_latency_median_s": float(np.median(on)) if on else float("nan"),
            "release_latency_median_s": float(np.median(off)) if off else float("nan"),
            "false_per_10min": self.false_idle / (self.idle_s / 600.0) if self.idle_s > 0 else float("nan"),
        }


def _match(
    events: Sequence[Event], kind: str, times: Sequence[float], window_s: float
) -> tuple[dict[int, Event], list[Event]]:
    """Each true time's first unused event of ``kind`` detected within the window; the rest are false."""
    evs = [e for e in events if e.kind == kind]
    used: set[int] = set()
    found: dict[int, Event] = {}
    for i, t in enumerate(times):
        for j, e in enumerate(evs):
            if j not in used and t - 0.5 <= e.t_detected_s <= t + window_s:
                found[i] = e
                used.add(j)
                break
    return found, [e for j, e in enumerate(evs) if j not in used]


def score(
    items: Sequence[Estimate | Event],
    t_truth: np.ndarray,
    truth: np.ndarray,
    changes: Sequence[Change],
    quantities: Sequence[str],
    *,
    window_s: float = 5.0,
    idle: Sequence[tuple[float, float]] = (),
) -> Score:
    """Score the estimator's output against the truth (module docstring).

    ``t_truth`` (n,) and ``truth`` (n, q): per frame; ``idle``: stretches (s) of the idle rig,
    over which false events are counted per 10 minutes (they are counted everywhere).
    """
    events = [i for i in items if isinstance(i, Event)]
    ests = [i for i in items if isinstance(i, Estimate)]
    hits, false_on = _match(events, LOAD, [c.on_s for c in changes], window_s)
    rels, false_off = _match(events, RELEASE, [c.off_s for c in changes], window_s)
    settled = [e for e in events if e.kind == SETTLED]
    t_est = np.array([e.t_device_s for e in ests])
    idx = np.clip(np.searchsorted(t_truth, t_est), 0, max(len(t_truth) - 1, 0))
    true_at = truth[idx] if len(t_truth) else np.empty((0, len(quantities)))
    values = np.array([[e.values[q] for q in quantities] for e in ests])
    ses = np.array([[e.se[q] for q in quantities] for e in ests])
    reports = np.array([[f"{UNOBSERVABLE}:{q}" not in e.flags for q in quantities] for e in ests], dtype=bool)
    for i, c in enumerate(changes):
        c.detected_s = hits[i].t_detected_s if i in hits else None
        c.released_s = rels[i].t_detected_s if i in rels else None
        s = [e for e in settled if c.on_s <= e.t_device_s < c.off_s]
        if i in hits and s:
            c.settled_s = s[0].t_device_s
            end = c.released_s if c.released_s is not None else c.off_s
            sel = (t_est >= c.settled_s) & (t_est < min(end, c.off_s))
            if sel.any():
                c.settled_sq = _settled_sq(values[sel] - true_at[sel], reports[sel])
    cov, cov_n = _coverage(ests, values, ses, true_at, quantities)
    sq = [c.settled_sq for c in changes if c.settled_sq is not None]
    rmse = _root_mean(sq, len(quantities))
    false = false_on + false_off
    return Score(
        list(changes),
        len(false),
        sum(1 for e in false if any(a <= e.t_detected_s <= b for a, b in idle)),
        float(sum(b - a for a, b in idle)),
        cov,
        cov_n,
        dict(zip(quantities, rmse.tolist(), strict=True)),
        len(sq),
    )


def _settled_sq(err: np.ndarray, reports: np.ndarray) -> np.ndarray:
    """Per quantity, the mean square of the errors (n, q) of the estimates that report it (NaN: none does)."""
    with np.errstate(invalid="ignore"):
        return (np.where(reports, err, 0.0) ** 2).sum(axis=0) / reports.sum(axis=0)


def _root_mean(sq: Sequence[np.ndarray], q: int) -> np.ndarray:
    """The root of the mean over changes, per quantity, of the changes that report it (NaN: none)."""
    if not sq:
        return np.full(q, np.nan)
    a = np.array(sq, dtype=float)
    n = np.isfinite(a).sum(axis=0)
    with np.errstate(invalid="ignore"):
        return np.sqrt(np.where(np.isfinite(a), a, 0.0).sum(axis=0) / n)


def _coverage(
    ests: Sequence[Estimate], values: np.ndarray, ses: np.ndarray, truth: np.ndarray, quantities: Sequence[str]
) -> tuple[dict[str, float], dict[str, int]]:
    cov, n = {}, {}
    learnt = np.array([BASELINE not in e.flags for e in ests], dtype=bool)
    for j, q in enumerate(quantities):
        reported = learnt & np.array([f"{UNOBSERVABLE}:{q}" not in e.flags for e in ests], dtype=bool)
        inside = np.abs(values[:, j] - truth[:, j]) <= Z95 * ses[:, j] if len(ests) else np.zeros(0, bool)
        n[q] = int(reported.sum())
        cov[q] = float(inside[reported].mean()) if n[q] else float("nan")
    return cov, n


def pooled(scores: Sequence[Score], quantities: Sequence[str], min_size: float = 0.0) -> dict[str, Any]:
    """Figures over several runs: detection pooled, coverage weighted by estimates, RMSE over changes."""
    ch = [c for s in scores for c in s.changes if c.size >= min_size]
    on = [c.detected_s - c.on_s for c in ch if c.detected_s is not None]
    off = [c.released_s - c.off_s for c in ch if c.released_s is not None]
    idle = sum(s.idle_s for s in scores)
    sq = [c.settled_sq for s in scores for c in s.changes if c.settled_sq is not None]
    cov = {}
    for q in quantities:
        n = sum(s.coverage_n[q] for s in scores)
        cov[q] = sum(s.coverage[q] * s.coverage_n[q] for s in scores if s.coverage_n[q]) / n if n else float("nan")
    return {
        "loads": len(ch),
        "found": len(on),
        "released": len(off),
        "false_events": sum(s.false_events for s in scores),
        "false_idle": sum(s.false_idle for s in scores),
        "idle_min": idle / 60.0,
        "false_per_10min": sum(s.false_idle for s in scores) / (idle / 600.0) if idle else float("nan"),
        "onset_latency_median_s": float(np.median(on)) if on else float("nan"),
        "onset_latency_p90_s": float(np.percentile(on, 90)) if on else float("nan"),
        "release_latency_median_s": float(np.median(off)) if off else float("nan"),
        "coverage": cov,
        "settled_rmse": dict(zip(quantities, _root_mean(sq, len(quantities)).tolist(), strict=True)),
        "settled_n": len(sq),
    }


def changes_from(rows: Sequence[Mapping[str, Any]]) -> list[Change]:
    """:class:`Change` rows from dicts with ``on_s``, ``off_s``, ``size`` (and anything else, kept)."""
    keys = ("on_s", "off_s", "size")
    return [
        Change(
            float(r["on_s"]), float(r["off_s"]), float(r["size"]), extra={k: v for k, v in r.items() if k not in keys}
        )
        for r in rows
    ]
