"""Trials and pushes on the simulated rig taken as ``labcli acquire`` takes them, for the benchmarks.

Shared by the sensing benchmarks (``sensing_accuracy.trials``) and the stiffness ones
(``classify_accuracy.trials_and_pushes``, ``phi_bent.run``), so that their figures are of runs
with the same timing:

* every baseline and every load waits the protocol's earliest acceptance of equilibrium
  (:func:`protocol_settle_s`: three windows and the hold, 15 s on the takuma2014 protocols, five
  time constants of the air's thermal relaxation), as ``labcli acquire`` waits at the least;
* the chambers are supplied again once a baseline drifted the protocol's
  ``acquisition.repressurise_kPa`` (3.1 kPa) since the last supply, as ``labcli acquire`` does on
  a board that drives its valves (drive.py's ``_Air``, by the session's own rule ``AirDrift``);
* each row's rest posture is its own baseline window's potentiometers, as a run file stores it
  (:class:`Windows`), a baseline taken again after a supply replacing the one that drifted.
"""

from __future__ import annotations

from typing import Any

import numpy as np


def protocol_settle_s(protocol: Any) -> float:
    """When the protocol's settling rule accepts equilibrium at the earliest (s): three windows and the hold."""
    st = protocol.settling
    if st is None:
        raise ValueError(f"the protocol {protocol.name} has no [settling] section")
    return 3.0 * float(st.window_s) + float(st.hold_s)


def acquired_air(
    *protocols: Any, settle_s: float | None = None, repressurise_kPa: float | None = None
) -> dict[str, float]:
    """drive.py's ``settle_s`` and ``repressurise_kPa`` for runs of ``protocols`` as acquired: the
    longest of their earliest equilibria and the first one's drift limit, unless given (a given
    ``repressurise_kPa`` of 0 holds the valves for the whole run)."""
    if settle_s is None:
        settle_s = max(protocol_settle_s(p) for p in protocols)
    if repressurise_kPa is None:
        repressurise_kPa = float(protocols[0].air.repressurise_kPa)
    return {"settle_s": float(settle_s), "repressurise_kPa": float(repressurise_kPa)}


def add_air_options(ap: Any) -> None:
    """``--settle S`` and ``--repressurise KPA`` on an argument parser (``args.settle``,
    ``args.repressurise``; None: the protocol's), for :func:`acquired_air`."""
    ap.add_argument(
        "--settle", type=float, help="settling time per window, s (default: the protocol's earliest equilibrium, 15)"
    )
    ap.add_argument(
        "--repressurise",
        type=float,
        help="supply the chambers again past this baseline drift, kPa (default: the protocol's; 0: hold the valves)",
    )


class Windows:
    """The rig with every sample window kept (baseline, loaded, baseline, ...; a baseline retaken
    after the chambers were supplied again replaces the one that drifted)."""

    def __init__(self, rig: Any) -> None:
        self._rig, self.windows = rig, []

    def __getattr__(self, name: str) -> Any:
        return getattr(self._rig, name)

    def samples(self, n: int, rate_hz: float) -> Any:
        out = self._rig.samples(n, rate_hz)
        self.windows.append(out[1])
        return out

    def supply_air(self) -> None:
        if len(self.windows) % 2:  # a baseline that drifted: taken again once the chambers are supplied
            self.windows.pop()
        self._rig.supply_air()

    def rest_columns(self, table: Any, calibration: Any) -> None:
        """Each row's baseline potentiometers as ``theta1_0_deg``, ``theta2_0_deg`` (the rest
        posture a run file stores); the windows are then cleared for the next run on this rig."""
        pots = [list(self._rig.channels).index(c) for c in ("POT1", "POT2")]
        base = np.array([np.asarray(calibration.to_si(w), dtype=float).mean(axis=0)[pots] for w in self.windows[0::2]])
        table["theta1_0_deg"], table["theta2_0_deg"] = np.degrees(base[:, 0]), np.degrees(base[:, 1])
        self.windows.clear()
