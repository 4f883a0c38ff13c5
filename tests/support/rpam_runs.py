"""Drive the simulated rPAM rig from Python (its operator hooks) and read it through its ADC.

The tables built here are what an acquisition of the stretch test and of the joint map
would store: averaged, calibrated sensor readings, never the rig's truth.
"""

from __future__ import annotations

import math

import numpy as np

from labcli.papers.rpam2015.protocol import load_rpam
from labcli.papers.rpam2015.sim.rig import RpamRig, counts_to_si

PROTOCOL = load_rpam("rpam2015")
SETTINGS = PROTOCOL.settings
PATH, RAW = PROTOCOL.path, PROTOCOL.document
SETTLE_S = 8.0  # at least 8 time constants of the rig's lag (0.7 s, up to 1.4x)
CAPTURE = 50  # samples averaged per point
RATE_HZ = 100.0


def capture(rig: RpamRig, settle_s: float = SETTLE_S, n: int = CAPTURE) -> np.ndarray:
    """Wait for the lag to die out, then average ``n`` calibrated samples: P_A, P_B, POT, LEN."""
    rig.advance(settle_s)
    _, counts = rig.samples(n, RATE_HZ)
    return counts_to_si(counts).mean(axis=0)


def stretch_table(rig: RpamRig) -> dict[str, list[float]]:
    """The protocol's stretch test (payloads x pressures) on ``rig``'s stretch stand."""
    rig.set_experiment("stretch")
    masses, pressures = np.array(SETTINGS.stretch_test.payloads_kg), np.array(SETTINGS.stretch_test.pressures_MPa)
    rows: dict[str, list[float]] = {"point": [], "mass_g": [], "P_A": [], "L_m": []}
    for m in masses:
        rig.hang_payload(float(m))
        for p in pressures:
            rig.set_pressures(float(p), 0.0)
            v = capture(rig)
            rows["point"].append(len(rows["point"]))
            rows["mass_g"].append(float(m) * 1e3)
            rows["P_A"].append(float(v[0]))
            rows["L_m"].append(float(v[3]))
    rig.remove_payload()
    rig.vent()
    return rows


def joint_table(rig: RpamRig, Pa=None, Pb=None) -> dict[str, list[float]]:
    """The joint map over the protocol's Pa x Pb grid, venting between points."""
    rig.set_experiment("joint")
    grid_a, grid_b = np.array(SETTINGS.joint_map.Pa_MPa), np.array(SETTINGS.joint_map.Pb_MPa)
    Pa = grid_a if Pa is None else Pa
    Pb = grid_b if Pb is None else Pb
    rows: dict[str, list[float]] = {"point": [], "P_A": [], "P_B": [], "alpha_deg": []}
    for a in Pa:
        for b in Pb:
            rig.vent()
            rig.advance(SETTLE_S)
            rig.set_pressures(float(a), float(b))
            v = capture(rig)
            rows["point"].append(len(rows["point"]))
            rows["P_A"].append(float(v[0]))
            rows["P_B"].append(float(v[1]))
            rows["alpha_deg"].append(math.degrees(float(v[2])))
    return rows
