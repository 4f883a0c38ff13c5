"""The live terminal view of ``labcli sense``: estimates with intervals, the detector's state,
the last events, and a rolling plot of the pressures and the estimates.

Drawn with rich (imported here, and this module only by the command that shows it, so
``labcli --help`` stays light).  The rolling plot is one line of block characters per trace
over the last ``window_s`` of device time, each scaled to its own range, the range printed
beside it.
"""

from __future__ import annotations

import math
from collections import deque
from typing import Any

import numpy as np

from .inputs import DeviceClock
from .results import Estimate, Event

BARS = " ▁▂▃▄▅▆▇█"
Z95 = 1.959964  # the two-sided 95 % interval of a normal error
_SHOW = {"rad": ("deg", 180.0 / math.pi, 2), "N": ("N", 1.0, 2)}


def spark(values: Any, width: int) -> str:
    """``values`` as ``width`` block characters, low to high over their own range."""
    v = np.asarray(values, dtype=float)
    v = v[np.isfinite(v)]
    if not v.size:
        return " " * width
    if v.size > width:  # the last value of each of ``width`` equal stretches
        v = v[np.linspace(0, v.size - 1, width).round().astype(int)]
    lo, hi = float(v.min()), float(v.max())
    k = np.ones(v.size, dtype=int) if hi - lo <= 0 else np.rint((v - lo) / (hi - lo) * (len(BARS) - 2)).astype(int) + 1
    return "".join(BARS[i] for i in k).rjust(width)


class LiveView:
    """Keeps the last ``window_s`` of pressures (kPa) and estimates, and renders them."""

    def __init__(self, estimator: Any, title: str, *, window_s: float = 30.0, width: int = 30) -> None:
        self.est = estimator
        self.title = title
        self.width = width
        self.names = [n for n in estimator.inputs.names[: estimator.inputs.n_pressures]]
        self._clock = DeviceClock()
        self.window_s = window_s
        self._p: deque[tuple[float, np.ndarray]] = deque()  # (device time, batch mean kPa)
        self._q: dict[str, deque[float]] = {q: deque(maxlen=int(window_s * 10)) for q in estimator.model.quantities}
        self.latest: Estimate | None = None
        self.events: deque[Event] = deque(maxlen=4)
        self.frames = 0
        self.board: dict[str, float] = {}  # the board's latest own estimate (SI), when it has a model
        self.board_names: tuple[str, ...] = ()

    def take_board(self, estimate: Any) -> None:
        """One of the board's own estimates (a ``$S`` line, SI, in ``board_names`` order)."""
        self.board = dict(zip(self.board_names, estimate.values, strict=False))

    def take(self, frames: Any, items: list[Estimate | Event]) -> None:
        """One batch and what the estimator made of it (:func:`.live.run`'s ``on_batch``)."""
        if len(frames):
            t = self._clock.seconds(frames.t_us)
            si = self.est.inputs.si(frames.values)[:, : self.est.inputs.n_pressures] * 1e3
            # A tenth of a second per point, whatever the size of the batches the link delivers.
            edges = np.arange(t[0], t[-1] + 0.1, 0.1)
            idx = np.searchsorted(edges, t, side="right")
            for k in np.unique(idx):
                sel = idx == k
                self._p.append((float(t[sel][-1]), si[sel].mean(axis=0)))
            while self._p and self._p[0][0] < self._p[-1][0] - self.window_s:
                self._p.popleft()
            self.frames += len(frames)
        for item in items:
            if isinstance(item, Event):
                self.events.append(item)
            else:
                self.latest = item
                for q, v in item.values.items():
                    self._q[q].append(v)

    def render(self, plain: bool = False) -> Any:
        from rich import box
        from rich.console import Group
        from rich.table import Table
        from rich.text import Text

        e = self.latest
        state = e.state if e is not None else "waiting for frames"
        head = Text(f"{self.title} · state {state}")
        if e is not None:
            head.append(f" · t {e.t_device_s:.1f} s (device) · {self.frames} frames")
        table = Table(box=None if plain else box.SIMPLE_HEAD, title_justify="left")
        headings = ["quantity", "estimate", "95 % interval", *(["board"] if self.board_names else []), "flags"]
        for heading in (*headings, "last 30 s"):
            table.add_column(heading, justify="right" if heading in ("estimate", "95 % interval", "board") else "left")
        for q, unit in zip(self.est.model.quantities, self.est.model.units, strict=True):
            shown, k, digits = _SHOW.get(unit, (unit, 1.0, 3))
            on_board = []
            if self.board_names:
                b = self.board.get(q)
                on_board = [f"{b * k:.{digits}f} {shown}" if b is not None and math.isfinite(b) else "—"]
            if e is None:
                table.add_row(q, "", "", *on_board, "", "")
                continue
            v, se = e.values[q] * k, e.se[q] * k
            flags = ",".join(f for f in e.flags if f.endswith(f":{q}") or ":" not in f)
            value = f"{v:.{digits}f} {shown}" if math.isfinite(v) else "—"
            interval = f"± {Z95 * se:.{digits}f} {shown}" if math.isfinite(se) else "—"
            table.add_row(q, value, interval, *on_board, flags, spark(np.asarray(self._q[q]) * k, self.width - 8))
        plot = Table(box=None, show_header=False)
        plot.add_column("channel")
        plot.add_column("range", justify="right")
        plot.add_column("trace")
        p = np.asarray([v for _, v in self._p])
        for j, name in enumerate(self.names):
            trace = p[:, j] if p.size else np.empty(0)
            rng = f"{trace.min():.1f}..{trace.max():.1f} kPa" if trace.size else ""
            plot.add_row(name, rng, spark(trace, self.width))
        events = Text(
            "events: "
            + (" · ".join(f"{ev.kind} at {ev.t_device_s:.1f} s" for ev in self.events) if self.events else "none yet")
        )
        return Group(head, table, plot, events)
