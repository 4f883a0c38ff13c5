"""What a wire-protocol 1.1 board offers (``CAPS?``) and the words of its valve commands.

A 1.0 board answers ``CAPS?`` with ``ERR``: it offers nothing beyond the 1.0 stream
(:data:`V1`).  A 1.1 board answers ``CAPS,1.1,<token>,...`` (``docs/wire-protocol.md``)::

    valves=P_L1:P_R1:P_L2:P_R2   the pressure channels whose chamber the board's valves serve
    pmax                         PMAX: a pressure limit the board enforces by venting
    events                       $E event lines
    wdt=1000                     a watchdog that vents a hung board after this many ms
    est=theta1:theta2:Fx:Fy      $S estimate lines carrying these quantities (a board with a model)
    model=1a2b3c4d               which model (the first 8 hex digits of its file's SHA-256)
    baseline                     BASELINE: the board retakes its model's baseline

Tokens this host does not know are kept (``extra``), never refused: a later minor version
may add some.  Valve states travel as one letter per chamber, ``S`` (supply: open to the
regulator), ``H`` (hold: closed) and ``V`` (vent: open to the atmosphere), in ``valves``
order.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

VALVE_LETTERS = {"supply": "S", "hold": "H", "vent": "V"}
VALVE_WORDS = {v: k for k, v in VALVE_LETTERS.items()}
EVENT_VALVE = "VALVE"  # $E,...,VALVE,<states>,<cause>
EVENT_PMAX = "PMAX"  # $E,...,PMAX,<channel>,<counts>
EVENT_RESET = "RESET"  # $E,...,RESET,<cause>
EVENT_BASELINE = "BASELINE"  # $E,...,BASELINE,<cause>,<frames>,<sum of counts per channel>...


@dataclass(frozen=True)
class BoardCaps:
    """A board's capabilities, from its ``CAPS?`` reply (:data:`V1` for a 1.0 board)."""

    protocol: str = "1.0"
    valves: tuple[str, ...] = ()
    pmax: bool = False
    events: bool = False
    watchdog_ms: int = 0
    estimates: tuple[str, ...] = ()
    model: str = ""
    baseline: bool = False
    extra: tuple[str, ...] = ()

    @classmethod
    def parse(cls, reply: str) -> BoardCaps:
        """The capabilities of a ``CAPS,<version>,<token>,...`` reply; ValueError if it is not one."""
        fields = [f.strip() for f in reply.split(",")]
        if len(fields) < 2 or fields[0] != "CAPS" or not _is_version(fields[1]):
            raise ValueError(f"not a CAPS reply: {reply!r}")
        found: dict[str, object] = {"protocol": fields[1]}
        extra = []
        for token in filter(None, fields[2:]):
            key, eq, value = token.partition("=")
            names = tuple(v for v in value.split(":") if v)
            if key == "valves" and eq and names:
                found["valves"] = names
            elif key == "est" and eq and names:
                found["estimates"] = names
            elif key == "wdt" and eq and value.isdigit():
                found["watchdog_ms"] = int(value)
            elif key == "model" and eq and value:
                found["model"] = value
            elif key in ("pmax", "events", "baseline") and not eq:
                found[key] = True
            else:
                extra.append(token)
        return cls(**found, extra=tuple(extra))  # type: ignore[arg-type]

    def format(self) -> str:
        """The ``CAPS`` reply line (without ``\\n``) a board with these capabilities sends."""
        tokens = [f"valves={':'.join(self.valves)}"] if self.valves else []
        tokens += [name for name in ("pmax", "events") if getattr(self, name)]
        tokens += [f"wdt={self.watchdog_ms}"] if self.watchdog_ms else []
        tokens += [f"est={':'.join(self.estimates)}"] if self.estimates else []
        tokens += [f"model={self.model}"] if self.model else []
        tokens += ["baseline"] if self.baseline else []
        return ",".join(["CAPS", self.protocol, *tokens, *self.extra])


V1 = BoardCaps()


def _is_version(text: str) -> bool:
    major, dot, minor = text.partition(".")
    return bool(dot) and major.isdigit() and minor.isdigit()


def parse_states(letters: str, valves: Sequence[str]) -> dict[str, str]:
    """``"SSHV"`` -> ``{"P_L1": "supply", ...}`` for the board's ``valves``; ValueError if malformed."""
    if len(letters) != len(valves) or any(c not in VALVE_WORDS for c in letters):
        raise ValueError(f"valve states {letters!r} are not one of S, H, V for each of {len(valves)} valves")
    return {name: VALVE_WORDS[c] for name, c in zip(valves, letters, strict=True)}


def format_states(states: Sequence[str]) -> str:
    """``["supply", "hold"]`` -> ``"SH"``."""
    return "".join(VALVE_LETTERS[s] for s in states)


def limit_counts(pmax_mpa: float, gains: Sequence[float], zeros: Sequence[float], adc_max: int = 4095) -> list[int]:
    """The PMAX counts of each pressure channel for a limit of ``pmax_mpa`` (MPa gauge).

    ``gains`` (MPa per count) and ``zeros`` (the counts reading 0 MPa) are the channels'
    calibration; each limit is rounded down, so the board vents at or below the limit.
    """
    out = []
    for gain, zero in zip(gains, zeros, strict=True):
        if not (gain > 0 and math.isfinite(gain) and math.isfinite(pmax_mpa)):
            raise ValueError("a pressure limit needs a finite limit and a positive gain per channel")
        out.append(int(min(adc_max, max(0, math.floor(zero + pmax_mpa / gain)))))
    return out


def baseline_counts(fields: Sequence[str]) -> list[float]:
    """The mean counts per channel of a ``BASELINE`` event's fields (cause, frames, sums); ValueError if malformed."""
    frames = int(fields[1])
    if frames <= 0 or len(fields) < 3:
        raise ValueError("a BASELINE event names its frames and at least one channel's sum")
    return [int(x) / frames for x in fields[2:]]
