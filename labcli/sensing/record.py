"""``labcli sense --record RUN.h5``: the raw frames, every estimate and every event into a run file.

The run file is the one acquisition writes (:class:`labcli.core.store.RunFile`), of the run
kind the model's paper gives for live sessions (``model.record_kind``; the McKibben paper's
``sense`` records): one record per estimate, its block's frames as its raw window, and one
per event.  What arrives is gathered and committed every ``commit_s`` of the rig's clock
(default 1 s) in one commit (:meth:`~labcli.core.store.records.Records.write_many`), so a
kill or a power cut loses at most the last second, and what is in the file verifies
(``labcli inspect RUN.h5 --verify``) and exports (``labcli export``) like any run.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import TYPE_CHECKING, Any, cast

import numpy as np

from ..errors import ModelError
from .results import Estimate, Event

if TYPE_CHECKING:
    from ..core.record import Record


class RunRecorder:
    """Takes each batch of frames and the estimator's items (:func:`.live.run`'s ``on_batch``)."""

    def __init__(
        self,
        path: str | Path,
        *,
        model: Any,
        protocol: Any,
        device_info: Any,
        port: str,
        scale: Any,
        commit_s: float = 1.0,
        force: bool = False,
    ) -> None:
        from ..core.store import RunFile

        kind = getattr(model, "record_kind", None)
        if kind is None:
            raise ModelError("The model's paper keeps no record of live sessions; run without --record.")
        self.scale = scale  # counts -> SI for every channel the rig sends
        self.commit_s = commit_s
        self.run = RunFile.create(
            path, protocol=protocol, kind=kind, device_info=device_info, port=port, force=force,
            exists_hint="choose a new file name for the session's run file",
        )  # fmt: skip
        self._quantities = tuple(model.quantities)
        self._frames: list[Any] = []  # batches not yet given to an estimate
        self._pending: list[dict[str, Any]] = []
        self._next_id = 1
        self._last_commit = -math.inf
        self.committed = 0

    def take(self, frames: Any, items: list[Estimate | Event]) -> None:
        if len(frames):
            self._frames.append(frames)
        for item in items:
            if isinstance(item, Event):
                self._pending.append(self._event(item))
            else:
                self._pending.append(self._estimate(item))
        if self._pending and self._pending[-1]["t_device_s"] - self._last_commit >= self.commit_s:
            self.commit()

    def _window(self, upto_seq: int) -> Any:
        """The frames held up to ``upto_seq`` (the block's last frame), as a window; the rest kept."""
        from ..core.window import Window

        if not self._frames:
            return None
        seq = np.concatenate([b.seq for b in self._frames])
        t_us = np.concatenate([b.t_us for b in self._frames])
        counts = np.concatenate([b.values for b in self._frames])
        k = int(np.searchsorted(seq, upto_seq, side="right")) if np.all(np.diff(seq) >= 0) else len(seq)
        if k < len(seq):
            from ..core.wire import FrameBatch

            self._frames = [FrameBatch(seq[k:], t_us[k:], counts[k:])]
        else:
            self._frames = []
        if k == 0:
            return None
        return Window.of(seq[:k], counts[:k], self.scale.to_si(counts[:k]), t_us=t_us[:k])

    def _base(self, item: str, seq: int, t: float) -> dict[str, Any]:
        rid = self._next_id
        self._next_id += 1
        return {"record": rid, "item": item, "seq": int(seq), "t_device_s": float(t), "accepted": "auto"}

    def _estimate(self, e: Estimate) -> dict[str, Any]:
        rec = self._base("estimate", e.seq, e.t_device_s)
        v = [e.values.get(q, math.nan) for q in self._quantities]
        s = [e.se.get(q, math.nan) for q in self._quantities]
        rec.update(
            state=e.state, theta_rad=v[:2], theta_se_rad=s[:2], force_N=v[2:4], force_se_N=s[2:4], flags=list(e.flags)
        )
        window = self._window(e.seq)
        if window is not None:
            rec["raw"] = {"load": window}
        return rec

    def _event(self, ev: Event) -> dict[str, Any]:
        rec = self._base(ev.kind, ev.seq, ev.t_device_s)
        data = {k: v for k, v in ev.as_json().items() if k not in ("event", "t_device_s", "seq")}
        rec["data"] = data
        return rec

    def commit(self) -> None:
        """Everything gathered so far, in one commit."""
        if not self._pending:
            return
        pending, self._pending = self._pending, []
        self.run.records.write_many(cast("list[Record]", pending))  # checked by write_many itself
        self.committed += len(pending)
        self._last_commit = pending[-1]["t_device_s"]

    def close(self) -> None:
        try:
            self.commit()
        finally:
            self.run.close()
