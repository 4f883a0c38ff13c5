"""The setup check: the rig on the port is the protocol's, and what it reads is plausible.

Before the first prompt the engine (:mod:`labcli.core.engine`) asks the rig who it is (its
``ID?`` reply against the protocol's device and channels), sets its rate, and reads half a
second of frames: a pressure outside its sensor's span or an angle no joint reaches means a
cable, a supply or a potentiometer to check, said in one sentence before anything is stored.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

from ..errors import DeviceError
from .window import Window

PRESSURE_MARGIN_MPA = 0.02  # sensor noise and offset allowed outside the 0-1 MPa span


def check_rig_matches(info: Any, protocol: Any) -> None:
    """Refuse, in one sentence, a rig (``info``: its ``ID?`` reply) that is not the protocol's."""
    spec = getattr(protocol, "device", None)
    if spec is not None and not spec.matches(info.device):
        raise DeviceError(
            f"The device on {info.port} is '{info.device}', but protocol {protocol.name} is for "
            f"'{spec.name}': connect that rig, or pass the matching --protocol."
        )
    want = tuple(protocol.channels)
    have = tuple(info.channels)
    if have != want:
        raise DeviceError(
            f"The rig on {info.port} reports channels {','.join(have)} but protocol "
            f"{protocol.name} expects {','.join(want)}: check the firmware, or pass the "
            "matching --protocol."
        )


def check_readings(window: Window, protocol: Any, pcols: Sequence[int], acols: Sequence[int]) -> list[str]:
    """What is implausible in the setup check's frames: pressures (channels ``pcols``) outside their
    sensor's span, angles (``acols``) outside the protocol's range; one phrase each."""
    names = list(protocol.channels)
    ranges = protocol.calibration.ranges
    lo = window.si.min(axis=0)
    hi = window.si.max(axis=0)
    problems = []
    for i in pcols:
        a, b = ranges[i]
        if lo[i] < a - PRESSURE_MARGIN_MPA or hi[i] > b + PRESSURE_MARGIN_MPA:
            problems.append(
                f"{names[i]} reads {lo[i]:.3f} to {hi[i]:.3f} MPa, outside the sensor span {a:g} to {b:g} MPa "
                "(check that sensor's cable and supply)"
            )
    for i in acols:
        a, b = ranges[i]
        if lo[i] < a or hi[i] > b:
            problems.append(
                f"{names[i]} reads {math.degrees(lo[i]):.1f} to {math.degrees(hi[i]):.1f} deg, outside the "
                f"plausible {math.degrees(a):.0f} to {math.degrees(b):.0f} deg (check the potentiometer's "
                "wiring and centring)"
            )
    return problems
