"""A board that carries its own model, at the wire of the simulated rig's link.

The simulated board has no model of its own (the AVR firmware built with one does:
tests/core/test_firmware_model.py), so this stub adds one: once asked (``EST 1``), it hands back
one ``$S`` estimate per data frame read, of values known from the frame's ``seq``.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

from labcli.core.board import BoardCaps
from labcli.core.boardlines import Estimate as BoardEstimate
from labcli.core.device import Device


class BoardWithModel:
    """The simulated link, with a board that sends ``values(seq)`` for each data frame once asked."""

    def __init__(self, dev: Device, names: Sequence[str], values: Callable[[int], tuple[float, ...]]) -> None:
        self.dev, self.values = dev, values
        self.caps = BoardCaps("1.1", estimates=tuple(names))
        self.every = 0
        self._pending: list[BoardEstimate] = []

    def __getattr__(self, name: str):
        return getattr(self.dev, name)

    def stream_estimates(self, every: int = 1) -> int:
        self.every = every
        return every

    def _add(self, batch) -> None:
        if self.every and batch is not None:
            self._pending += [
                BoardEstimate(int(s), int(t), self.values(int(s)), 0)
                for s, t in zip(batch.seq, batch.t_us, strict=True)
            ]

    def read(self, timeout: float = 0.05):
        batch = self.dev.read(timeout=timeout)
        self._add(batch)
        return batch

    def stop(self):
        batch = self.dev.stop()
        self._add(batch)
        return batch

    def take_estimates(self) -> list[BoardEstimate]:
        out, self._pending = self._pending, []
        return out
