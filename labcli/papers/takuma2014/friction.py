"""How far the sleeves' friction can move the closed chambers' pressures: the removal check's bound.

The session's removal check (:mod:`labcli.core.guard`) must tell a weight left hanging from an
arm that friction stopped short of its old posture.  With the valves closed both show only as
pressures off their last baseline; friction's share is bounded, and this module gives the bound
from the rig's physics before the run has shown its own (:class:`labcli.core.guard.BaselineHistory`).

One actuator, valves closed.  Its sleeve's Coulomb friction is a share ``mu`` of its pressure
force, ``mu P A`` (P gauge, ``A = -dV/dL`` its effective area; Tondu & Lopez 2000).  Friction
holds it off its frictionless length by at most that force over its closed-chamber stiffness,
whose air part is ``P_abs A^2 / (V + V_dead)`` (Boyle's law; the rubber only stiffens it
further), and that length moves its pressure by ``P_abs A / (V + V_dead)`` per metre.  The
product is ``mu P``: the actuator's size and dead volume cancel, so the bound needs only the
pressure the chamber holds, read from the baseline.  An unloaded baseline thus lies within
``mu P`` of the frictionless rest on each chamber, and two baselines differ by at most
``2 mu P``.  On the joint the pairs share their frictions through the bottom arm; measured on the
simulated rig (the shipped plans, upright and bent, friction 0.5 % to 4 %, seeds 1-3),
baseline-to-baseline moves reach 0.36-0.8 ``mu P``, within the bound
(tests/papers/takuma2014/test_friction_bound.py).

``SLEEVE_FRICTION_MAX`` is the largest share the literature reports: force-length loops up to
over 10 % of the force (Chou & Hannaford 1996; Tondu & Lopez 2000; Tondu 2012), a friction of 5 %
of the pressure force.  At the paper's 0.30 MPa the bound is 30 kPa per chamber, more than any of
the plan's loads moves a pressure: until the run has shown its own friction the removal check
stays silent rather than mistake friction for a weight.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np

SLEEVE_FRICTION_MAX = 0.05  # share of an actuator's pressure force its sleeve's friction can hold


def baseline_hold(units: Sequence[str], share: float = SLEEVE_FRICTION_MAX) -> Callable[[np.ndarray], np.ndarray]:
    """The bound for the guard's watched channels of ``units`` ("MPa" or "rad"): ``2 share P``
    on each pressure channel (its reading P, gauge, floored at 0), nothing on the angles (the
    removal check leaves them out)."""
    pressure = np.array([u == "MPa" for u in units], dtype=bool)

    def hold(mean: np.ndarray) -> np.ndarray:
        p = np.clip(np.asarray(mean, dtype=float), 0.0, None)
        return np.where(pressure, 2.0 * share * p, 0.0)

    return hold
