"""The simulated board's wire-protocol 1.1 part: its valves, its pressure limit and its event lines.

:class:`BoardValves` answers ``CAPS?``, ``VALVE``, ``VALVE?``, ``PMAX`` and ``PMAX?`` for the
firmware model (:mod:`.firmware`), sets the rig's valves (``rig.set_valves``) and watches the
pressures of the frames the firmware makes against the limit: a chamber above it is vented, with
a ``PMAX`` and a ``VALVE`` event line, as the AVR firmware does (``firmware/src/valves.c``).

A rig without ``valve_channels`` (the rPAM stand) gets a 1.1 board without valves: ``CAPS?``
says so and the valve commands are refused with ``ERR``.  ``version="1.0"`` is a 1.0 board:
none of these commands exist (``ERR unknown command``), so a host can be tested against both.

The board's valve states are the rig's (``rig.valve_states``): the hand operations of the
simulated rig (``supply_air``, ``close_valves``, ``vent``, the console's) are the operator
overriding the board, and the board reads them back, without an event line.  The limit is checked on the frames made while
streaming, once per block of frames, or every 20 ms of rig time while a chamber is supplied or
near the limit; an idle simulated board checks at 50 Hz while a chamber is supplied or near the
limit (:meth:`labcli.core.sim.firmware.Firmware.idle`: the pty server runs it with the wall clock).
A chamber the host left supplying for ``supply_max_s`` (60 s of rig time) is held by the board,
with a ``VALVE`` event of cause ``timeout``: a host killed while the chambers fill does not leave
them on the regulator.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from ..board import EVENT_PMAX, EVENT_VALVE, VALVE_LETTERS, BoardCaps, format_states
from ..boardlines import format_event

VERSIONS = ("1.0", "1.1")
# 0.7 MPa on the reference calibration (819 + 0.7 / (5 / 16380)): the AVR firmware's default too.
PMAX_DEFAULT_COUNTS = 3112
ADC_MAX = 4095
# A chamber supplied this long (rig time) since the host's last VALVE command is held by the board
# itself: a host that dies while the chambers fill never leaves them supplying unattended.
SUPPLY_MAX_S = 60.0
NEAR_LIMIT = 0.9  # above this share of the limit, frames are checked every CHECK_S
CHECK_S = 0.02


class BoardValves:
    """A simulated 1.1 board's valves, limit and events over ``rig`` (see the module docstring)."""

    def __init__(self, rig: Any, version: str = "1.1") -> None:
        if version not in VERSIONS:
            raise ValueError(f"wire protocol version is one of {', '.join(VERSIONS)}")
        self.rig = rig
        self.version = version
        self.valves: tuple[str, ...] = tuple(getattr(rig, "valve_channels", ())) if version != "1.0" else ()
        self.index = np.array([list(rig.channels).index(c) for c in self.valves], dtype=np.int64)
        self.pmax = np.full(len(self.valves), PMAX_DEFAULT_COUNTS, dtype=np.int64)
        self.n_events = 0
        self._near = False  # the last frames checked came near the limit
        self.supply_max_s = SUPPLY_MAX_S
        self._supplied_us: int | None = None  # rig time (us, unwrapped) of the host's last VALVE with a supply

    @property
    def states(self) -> list[str]:
        """Each valve's state, as the rig's valves stand."""
        return list(self.rig.valve_states) if self.valves else []

    @property
    def caps(self) -> BoardCaps:
        return BoardCaps("1.1", valves=self.valves, pmax=bool(self.valves), events=True)

    # ------------------------------------------------------------ commands

    def command(self, word: str, arg: str, t_us: int) -> bytes | None:
        """The reply (event lines first) to a 1.1 command, or None if ``word`` is not one."""
        if self.version == "1.0":
            return None
        if word == "CAPS?" and not arg:
            return (self.caps.format() + "\n").encode()
        if word in ("VALVE", "VALVE?", "PMAX", "PMAX?") and not self.valves:
            return f"ERR this board has no valves, so no {word.rstrip('?')}\n".encode()
        if word == "VALVE?" and not arg:
            return f"OK VALVE {format_states(self.states)}\n".encode()
        if word == "VALVE":
            return self._valve(arg, t_us)
        if word == "PMAX?" and not arg:
            return self._pmax_reply()
        if word == "PMAX":
            return self._set_pmax(arg)
        return None

    def _valve(self, arg: str, t_us: int) -> bytes:
        parts = arg.split()
        if len(parts) != 2 or parts[1].lower() not in VALVE_LETTERS or (parts[0] not in (*self.valves, "ALL")):
            return f"ERR VALVE needs <{'|'.join(self.valves)}|ALL> <SUPPLY|HOLD|VENT>, got '{arg[:40]}'\n".encode()
        state = parts[1].lower()
        new = [state if parts[0] in ("ALL", name) else old for name, old in zip(self.valves, self.states, strict=True)]
        events = self._set(new, "host", t_us)
        self._supplied_us = int(round(self.rig.time_s * 1e6)) if "supply" in self.states else None
        return events + f"OK VALVE {format_states(self.states)}\n".encode()

    def _pmax_reply(self) -> bytes:
        return ("OK PMAX " + " ".join(str(int(c)) for c in self.pmax) + "\n").encode()

    def _set_pmax(self, arg: str) -> bytes:
        parts = arg.split()
        n = len(self.valves)
        if len(parts) not in (1, n) or not all(p.isdigit() and int(p) <= ADC_MAX for p in parts):
            return f"ERR PMAX needs one limit or {n}, in counts 0..{ADC_MAX}, got '{arg[:40]}'\n".encode()
        self.pmax = np.broadcast_to(np.array([int(p) for p in parts], dtype=np.int64), (n,)).copy()
        return self._pmax_reply()

    # ------------------------------------------------------------ valves and events

    def event(self, t_us: int, kind: str, fields: Sequence[object]) -> bytes:
        line = format_event(self.n_events, t_us, kind, fields)
        self.n_events += 1
        return line

    def _set(self, new: list[str], cause: str, t_us: int) -> bytes:
        if new == self.states:
            return b""
        self.rig.set_valves(new)
        return self.event(t_us, EVENT_VALVE, [format_states(new), cause])

    def check_every(self, rate_hz: float) -> int | None:
        """Frames between limit checks: a block at once (None) unless a chamber is supplied or near the limit."""
        if not self.valves or not (self._near or "supply" in self.states):
            return None
        return max(1, int(round(rate_hz * CHECK_S)))

    def check(self, t_us: np.ndarray, counts: np.ndarray) -> bytes:
        """Vent every chamber whose pressure went above the limit in these frames, and hold the
        chambers supplied for longer than ``supply_max_s``; their event lines."""
        if not self.valves or not len(counts):
            return b""
        return self._check_limit(t_us, counts) + self._check_supply(int(t_us[-1]))

    def _check_supply(self, t_us: int) -> bytes:
        if self._supplied_us is None or "supply" not in self.states:
            return b""
        if self.rig.time_s * 1e6 - self._supplied_us < self.supply_max_s * 1e6:
            return b""
        self._supplied_us = None
        return self._set(["hold" if v == "supply" else v for v in self.states], "timeout", t_us)

    def _check_limit(self, t_us: np.ndarray, counts: np.ndarray) -> bytes:
        p = np.asarray(counts)[:, self.index]
        self._near = bool(np.any(p[-1] > NEAR_LIMIT * self.pmax))
        over = (p > self.pmax) & np.array([s != "vent" for s in self.states])
        if not over.any():
            return b""
        out = bytearray()
        new = list(self.states)
        for k in np.flatnonzero(over.any(axis=0)):
            i = int(np.argmax(over[:, k]))
            out += self.event(int(t_us[i]), EVENT_PMAX, [self.valves[k], int(p[i, k])])
            new[k] = "vent"
        out += self._set(new, EVENT_PMAX.lower(), int(t_us[-1]))
        return bytes(out)
