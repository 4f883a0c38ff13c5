"""The live terminal view of ``labcli sense``: estimates with intervals, the detector's state,
the last events, and a rolling plot of the pressures and the estimates.

Drawn with rich (imported here, and this module only by the command that shows it, so
``labcli --help`` stays light).  The rolling plot is ``labcli monitor``'s own widget
(:mod:`labcli.core.rolling`): the pressures and the estimates over the last ``window_s`` of
device time in bins of a tenth of a second, one line of block characters per trace, each
scaled to its own range, the range printed beside it.
"""

from __future__ import annotations

import math
from collections import deque
from typing import Any

import numpy as np

from ..core.rolling import Rolling, spark, trace_table
from .inputs import DeviceClock
from .results import Estimate, Event

Z95 = 1.959964  # the two-sided 95 % interval of a normal error
_SHOW = {"rad": ("deg", 180.0 / math.pi, 2), "N": ("N", 1.0, 2)}


class LiveView:
    """Keeps the last ``window_s`` of pressures (kPa) and estimates, and renders them."""

    def __init__(self, estimator: Any, title: str, *, window_s: float = 30.0, width: int = 30) -> None:
        self.est = estimator
        self.title = title
        self.width = width
        self.names = [n for n in estimator.inputs.names[: estimator.inputs.n_pressures]]
        self._clock = DeviceClock()
        self.window_s = window_s
        self.pressures = Rolling(len(self.names), window_s)  # kPa
        self.estimates = Rolling(len(estimator.model.quantities), window_s)  # SI, at each estimate's time
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
            self.pressures.add(t, self.est.inputs.si(frames.values)[:, : self.est.inputs.n_pressures] * 1e3)
            self.frames += len(frames)
        quantities = self.est.model.quantities
        for item in items:
            if isinstance(item, Event):
                self.events.append(item)
            else:
                self.latest = item
                self.estimates.add(np.array([item.t_device_s]), np.array([[item.values[q] for q in quantities]]))

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
        for heading in (*headings, f"last {self.window_s:g} s"):
            table.add_column(heading, justify="right" if heading in ("estimate", "95 % interval", "board") else "left")
        for j, (q, unit) in enumerate(zip(self.est.model.quantities, self.est.model.units, strict=True)):
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
            table.add_row(q, value, interval, *on_board, flags, spark(self.estimates.trace(j) * k, self.width - 8))
        plot = trace_table(self.pressures, self.names, ["kPa"] * len(self.names), self.width)
        events = Text(
            "events: "
            + (" · ".join(f"{ev.kind} at {ev.t_device_s:.1f} s" for ev in self.events) if self.events else "none yet")
        )
        return Group(head, table, plot, events)
