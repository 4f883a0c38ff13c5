"""The simulated rPAM rig: the antagonistic 1-DoF joint and the stretch-test stand.

:class:`RpamRig` is the test bed of the rPAM joint paper (Figs. 5-8) behind a 12-bit ADC,
built from the constants of a protocol file (the shipped ``rpam2015`` by default) with its
own physics (:mod:`labcli.papers.rpam2015.sim.rpam_physics`), not the model it is there
to check.  Like :class:`labcli.papers.takuma2014.sim.rig.SimRig` it is not part of the wire
protocol: the simulated firmware reads it through ``channels``, ``device``, ``firmware``,
``samples(n, rate_hz)``, ``advance``, ``advance_to`` and ``time_s``; ``sim://?mode=rpam``
selects it.

Channels (data-line order; ``ID?`` answers ``ID,rpam-joint-sim,1.0,P_A,P_B,POT,LEN``)

=======  ==========================================================  ========================
name     sensor                                                      counts -> SI
=======  ==========================================================  ========================
``P_A``  pressure of actuator a, SMC PSE530-class, 1-5 V for 0-1      ``P[MPa] = (c*5/4095 - 1)/4``
         MPa gauge (the reference rig's sensor; 0.31 kPa per count,
         ample for the paper's 0-190 kPa once a capture is averaged)
``P_B``  pressure of actuator b, same sensor                         same
``POT``  joint angle alpha, COPAL JC22E-class potentiometer, 340      ``deg = (c - 2048)*340/4095``
         deg electrical, centred (the McKibben rig's calibration)
``LEN``  length of actuator a between its end caps: a draw-wire      ``L[m] = c * 0.300/4095``
         (string) potentiometer, 0-300 mm over 0-5 V (0.073 mm per
         count; the stretch test reaches about 0.23 m)
=======  ==========================================================  ========================

The same constants are :data:`CALIBRATION` (gain and zero count per channel) and
:func:`counts_to_si` / :func:`si_to_counts`.

Configurations (``experiment``; :meth:`RpamRig.set_experiment` re-rigs the stand)

* ``"joint"`` (default): actuators a and b drive the joint of Figs. 4 and 8; ``LEN`` reads
  ``L_a(alpha)`` (Eq. 4), a cross-check of the potentiometer.
* ``"stretch"``: actuator a is taken off the joint and hung vertically with a payload
  (Figs. 5, 6); ``LEN`` reads its length, ``P_A`` its pressure; the joint is locked at
  0 deg, so ``POT`` reads 0 deg (plus its offset).

Physics.  Every operator action solves the new static balance once and the state relaxes
towards it as a first-order lag (time constant ``tau_s``, with about 15 % seeded jitter per
change); pressures follow their regulators with the same lag.

* Each actuator's force comes from the Cauchy stresses of its thick Ogden wall and the
  statics of its thread cage (:func:`~.rpam_physics.tension`), plus its own true
  ``F_stretch``.
* Stretch stand: the hanging actuator settles where its tension equals ``m g``.
* Joint: the torque on the upper plate is the cross product of each upper mount's
  position with the push along its actuator (:class:`~.rpam_physics.Links`).
  From the current angle the joint moves in the direction of the torque to the first
  balance; one it cannot reach before the toggle angle ``atan(L2/L3)`` leaves it on the
  hard stop of the swivel plates, :data:`STOP_MARGIN_DEG` short of the toggle (the
  paper's runaway "toggle" state).

The true stretch correction is the protocol's cubic scaled per actuator by a seeded factor
(about 5 % rms, within 0.8-1.25) and never clamped, so a stretch test can recover it and
tell it from the protocol's default.  Every change also draws a friction offset (the
paper's "variable friction in the joints"): about 0.15 N on the hanging actuator and
2 mN m on the joint, the scatter of Fig. 6 and of the measured map.  The potentiometer has
a seeded mechanical offset (0.5 deg rms).  The pressure sensors are taken as zeroed and
the rest of the actuator (wall section, thread cage, Ogden wall, the reading of its force)
as the protocol says, so every discrepancy a fit sees comes from the stretch correction, friction and noise.
``variation=False`` gives the nominal rig: symmetric actuators with the protocol's cubic,
no friction, no offsets.

Sensors: Gaussian noise of 0.5 count (pressures), 0.7 count (potentiometers) rms times
``noise``, rounded and clipped to 0..4095; ``drift`` adds slow zero drift (sinusoids of a
few counts, periods 10-40 min); the McKibben rig's front end
(:class:`labcli.core.sim.sensors.SensorFrontEnd`, ``rig.sensors``).
"""

from __future__ import annotations

import math
import threading
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from ....core.sim.clock import SimClock
from ....core.sim.sensors import Linear, SensorChannel, SensorFrontEnd
from ..actuator import FORCE_READINGS
from . import rpam_physics as physics
from .rpam_physics import G_N_PER_KG, read_stand

CHANNELS = ("P_A", "P_B", "POT", "LEN")
ADC_MAX = 4095
VREF = 5.0
POT_SPAN_DEG = 340.0
LEN_SPAN_M = 0.300
STOP_MARGIN_DEG = 1.0
NOISE_COUNTS = np.array([0.5, 0.5, 0.7, 0.7])
DRIFT_COUNTS = np.array([3.0, 3.0, 2.0, 2.0])  # zero drift at drift = 1
STRETCH_SCALE_RMS = 0.05
FRICTION_FORCE_N = 0.15
FRICTION_TORQUE_NM = 0.002
POT_OFFSET_DEG = 0.5
EXPERIMENTS = ("joint", "stretch")

# Linear calibration per channel: SI value = gain * (counts - zero_counts); SI units are
# MPa (gauge), rad and m.  The zeros are exact: 819 counts = 0 MPa, 2048 = 0 rad, 0 = 0 m.
CALIBRATION: dict[str, dict[str, Any]] = {
    "P_A": {"quantity": "pressure", "unit": "MPa", "gain": VREF / (4 * ADC_MAX), "zero_counts": ADC_MAX / VREF},
    "P_B": {"quantity": "pressure", "unit": "MPa", "gain": VREF / (4 * ADC_MAX), "zero_counts": ADC_MAX / VREF},
    "POT": {"quantity": "angle", "unit": "rad", "gain": math.radians(POT_SPAN_DEG) / ADC_MAX, "zero_counts": 2048.0},
    "LEN": {"quantity": "length", "unit": "m", "gain": LEN_SPAN_M / ADC_MAX, "zero_counts": 0.0},
}
TRANSFERS = tuple(Linear(CALIBRATION[c]["gain"], CALIBRATION[c]["zero_counts"]) for c in CHANNELS)
_GAIN = np.array([t.gain for t in TRANSFERS])
_ZERO = np.array([t.zero_counts for t in TRANSFERS])


def counts_to_si(counts: Any) -> np.ndarray:
    """Counts ``(..., 4)`` in channel order to SI: P_A, P_B in MPa, POT in rad, LEN in m."""
    return (np.asarray(counts, dtype=float) - _ZERO) * _GAIN


def si_to_counts(values: Any) -> np.ndarray:
    """Ideal (unrounded) counts for SI values ``(..., 4)``; inverse of :func:`counts_to_si`."""
    return np.asarray(values, dtype=float) / _GAIN + _ZERO


@dataclass(frozen=True)
class _Segment:
    """The state between two operator actions: a first-order lag to the target."""

    t0: float
    tau: float
    p_from: np.ndarray  # (2,) MPa
    p_to: np.ndarray
    alpha_from: float
    alpha_to: float
    len_from: float  # actuator a's length on the stretch stand, m
    len_to: float
    status: str  # "ok" | "stop"


class RpamRig(SimClock):
    """Physical model of the rPAM joint and stretch stand with operator hooks and an ADC.

    ``RpamRig(seed=0, noise=1.0, drift=0.0, experiment="joint", protocol="rpam2015")``;
    ``force_reading`` builds its actuators on the other reading of the force than the
    protocol's (:mod:`.rpam_physics`), so a model can be checked against a stand it was not
    built on.  Starts vented (both pressures 0), no payload, at its balance.
    """

    channels: tuple[str, ...] = CHANNELS
    device = "rpam-joint-sim"
    firmware = "1.0"

    @property
    def console_commands(self) -> dict:
        """The operator's actions on ``labcli sim``'s console (:mod:`.console`)."""
        from .console import COMMANDS

        return COMMANDS

    def __init__(
        self,
        seed: int = 0,
        noise: float = 1.0,
        drift: float = 0.0,
        *,
        experiment: str = "joint",
        protocol: str | Path = "rpam2015",
        variation: bool = True,
        tau_s: float = 0.7,
        force_reading: str | None = None,
    ) -> None:
        if noise < 0 or drift < 0 or not tau_s > 0:
            raise ValueError("noise and drift must be >= 0 and tau_s > 0")
        links, nominal = read_stand(protocol)
        if force_reading is not None:
            if force_reading not in FORCE_READINGS:
                raise ValueError(f"force_reading must be one of {', '.join(FORCE_READINGS)}")
            nominal = replace(nominal, force_reading=force_reading)
        self.links = links
        self.nominal_actuator = nominal
        self.seed = int(seed)
        self.tau_s = float(tau_s)
        self.variation = bool(variation)
        srng = np.random.default_rng([self.seed, 3])
        if variation:
            scales = np.clip(1.0 + STRETCH_SCALE_RMS * srng.standard_normal(2), 0.8, 1.25)
            self.pot_offset_rad = math.radians(POT_OFFSET_DEG) * float(srng.standard_normal())
        else:
            scales = np.ones(2)
            self.pot_offset_rad = 0.0
        # The true correction holds everywhere (no clamp), so a fit over any range sees a cubic.
        self.actuators = tuple(
            nominal.with_stretch_correction([float(s * c) for c in nominal.stretch_coefficients_N]) for s in scales
        )
        self.toggle_rad = links.toggle_rad
        self.stop_rad = self.toggle_rad - math.radians(STOP_MARGIN_DEG)
        self._friction = (FRICTION_FORCE_N, FRICTION_TORQUE_NM) if variation else (0.0, 0.0)
        self._event_rng = np.random.default_rng([self.seed, 2])
        # The potentiometer's mechanical offset is the one fixed sensor error (the pressure
        # sensors are taken as zeroed); the drift is drawn after it, from the same generator.
        offsets = (0.0, 0.0, self.pot_offset_rad, 0.0)
        self.sensors = SensorFrontEnd(
            [
                SensorChannel(name, transfer, float(sd), float(amp), offset)
                for name, transfer, sd, amp, offset in zip(
                    CHANNELS, TRANSFERS, NOISE_COUNTS, DRIFT_COUNTS, offsets, strict=True
                )
            ],
            noise=noise,
            drift=drift,
            noise_rng=np.random.default_rng([self.seed, 1]),
            drift_rng=srng,
            rails=(0, ADC_MAX),
        )
        self._lock = threading.RLock()
        self._t = 0.0
        if experiment not in EXPERIMENTS:
            raise ValueError(f"experiment must be 'joint' or 'stretch', not {experiment!r}")
        self.experiment = experiment
        self._setpoint = np.zeros(2)
        self._payload_kg = 0.0
        self._seg = _Segment(0.0, self.tau_s, np.zeros(2), np.zeros(2), 0.0, 0.0, nominal.L0_m, nominal.L0_m, "ok")
        self._change(initial=True)

    @property
    def noise(self) -> float:
        """The sensors' noise, a multiple of their datasheet figures."""
        return self.sensors.noise

    @property
    def drift(self) -> float:
        """The sensors' zero drift, a multiple of its nominal amplitude."""
        return self.sensors.drift

    # ------------------------------------------------------------ state

    @property
    def true_stretch_coefficients_N(self) -> dict[str, tuple[float, ...]]:
        """The rig's true ``F_stretch`` cubic per actuator (c0..c3, N)."""
        return {"A": self.actuators[0].stretch_coefficients_N, "B": self.actuators[1].stretch_coefficients_N}

    def _state_at(self, t: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Pressures (..., 2) MPa, joint angle (...) rad, actuator a's length (...) m at times t."""
        s = self._seg
        t = np.asarray(t, dtype=float)
        w = np.exp(-np.clip(t - s.t0, 0.0, None) / s.tau)
        p = s.p_to + (s.p_from - s.p_to) * w[..., None]
        alpha = s.alpha_to + (s.alpha_from - s.alpha_to) * w
        if self.experiment == "joint":
            length = self.links.lengths(alpha)[0]
        else:
            length = s.len_to + (s.len_from - s.len_to) * w
        return p, alpha, length

    def true_state(self) -> dict[str, Any]:
        """The truth at the current simulated time (for tests and checks).

        Keys: ``time_s``, ``experiment``, ``pressures_MPa`` (2,) a, b; ``alpha_rad`` joint
        angle; ``length_m`` actuator a's length; ``lambda`` its stretch ``L / L0``;
        ``payload_kg``; ``setpoints_MPa`` (2,); ``target_alpha_rad`` and ``target_length_m``
        being approached; ``status`` ("ok" or "stop": the joint rests on its hard stop);
        ``stop_rad``, ``toggle_rad``, ``tau_s`` and ``stretch_coefficients_N`` (per actuator).
        """
        with self._lock:
            p, alpha, length = self._state_at(self._t)
            s = self._seg
            return {
                "time_s": self._t,
                "experiment": self.experiment,
                "pressures_MPa": p.copy(),
                "alpha_rad": float(alpha),
                "length_m": float(length),
                "lambda": float(length) / self.nominal_actuator.L0_m,
                "payload_kg": self._payload_kg,
                "setpoints_MPa": self._setpoint.copy(),
                "target_alpha_rad": s.alpha_to,
                "target_length_m": s.len_to
                if self.experiment == "stretch"
                else float(self.links.lengths(s.alpha_to)[0]),
                "status": s.status,
                "stop_rad": self.stop_rad,
                "toggle_rad": self.toggle_rad,
                "tau_s": s.tau,
                "stretch_coefficients_N": self.true_stretch_coefficients_N,
            }

    # ------------------------------------------------------------ physics

    def joint_torque(self, alpha: Any, pa_MPa: float, pb_MPa: float) -> np.ndarray:
        """Eq. 6 residual (N m) of the true rig, each actuator with its own correction; > 0 raises alpha."""
        La, Lb = self.links.lengths(alpha)
        a, b = self.actuators
        return self.links.torque(alpha, physics.push(a, pa_MPa, La), physics.push(b, pb_MPa, Lb))

    def _joint_balance(self, alpha0: float, pa: float, pb: float, friction: float) -> tuple[float, str]:
        from scipy.optimize import brentq

        def tau(x: Any) -> Any:
            return self.joint_torque(x, pa, pb) + friction

        t0 = float(tau(alpha0))
        if t0 == 0.0:
            return alpha0, "ok"
        direction = 1.0 if t0 > 0 else -1.0
        end = direction * self.stop_rad
        if (end - alpha0) * direction <= 0:  # already on (or past) the stop it is pushed against
            return end, "stop"
        grid = np.linspace(alpha0, end, 400)
        outward = np.asarray(tau(grid)) * direction
        k = np.flatnonzero(outward[1:] <= 0)
        if k.size == 0:
            return float(end), "stop"
        i = int(k[0]) + 1
        lo, hi = grid[i - 1], grid[i]
        if float(tau(hi)) == 0.0:
            return float(hi), "ok"
        return float(brentq(tau, lo, hi, xtol=1e-13)), "ok"

    def _stretch_length(self, p_MPa: float, mass_kg: float, friction_N: float) -> float:
        # Friction carries part of the load: the actuator settles where its tension is m g - F_f.
        L = physics.hanging_length(self.actuators[0], p_MPa, mass_kg * G_N_PER_KG - friction_N)
        if not math.isfinite(L):
            raise ValueError(
                f"the simulated stretch stand finds no length for {mass_kg * 1e3:g} g at "
                f"{p_MPa * 1e3:g} kPa; the load is beyond the actuator's range"
            )
        return L

    def _change(self, initial: bool = False) -> None:
        with self._lock:
            p_now, alpha_now, len_now = self._state_at(self._t)
            f_force, f_torque = self._friction
            # One friction draw per change, also on the initial balance (keeps the streams aligned).
            z = float(self._event_rng.standard_normal())
            pa, pb = (float(v) for v in self._setpoint)
            if self.experiment == "joint":
                alpha_to, status = self._joint_balance(float(alpha_now), pa, pb, f_torque * z)
                len_to = float(len_now)
            else:
                alpha_to, status = 0.0, "ok"
                len_to = self._stretch_length(pa, self._payload_kg, f_force * z)
            jitter = float(np.clip(np.exp(0.15 * self._event_rng.standard_normal()), 0.7, 1.4))
            tau = self.tau_s * (1.0 if initial else jitter)
            if initial:  # power-up: already settled
                p_now, alpha_now, len_now = self._setpoint.copy(), np.asarray(alpha_to), np.asarray(len_to)
            self._seg = _Segment(
                self._t,
                tau,
                np.asarray(p_now, float).copy(),
                self._setpoint.copy(),
                float(alpha_now),
                alpha_to,
                float(len_now),
                len_to,
                status,
            )

    # ------------------------------------------------------------ operator

    def set_pressures(self, pa_MPa: float, pb_MPa: float) -> None:
        """Set the two regulators (MPa gauge); the pressures and the posture follow with the lag."""
        p = np.array([pa_MPa, pb_MPa], dtype=float)
        if not np.all(np.isfinite(p)) or np.any(p < 0) or np.any(p > 1.0):
            raise ValueError("regulator pressures must be within 0..1 MPa gauge (the sensors' span)")
        with self._lock:
            old = self._setpoint
            self._setpoint = p
            try:
                self._change()
            except ValueError:
                self._setpoint = old
                raise

    def vent(self) -> None:
        """Vent both actuators (regulators to 0)."""
        self.set_pressures(0.0, 0.0)

    def set_experiment(self, experiment: str) -> None:
        """Re-rig the stand: ``"joint"`` (a and b on the joint) or ``"stretch"`` (a hanging).

        The stand is re-rigged vented and without payload, as a person would do it.
        """
        if experiment not in EXPERIMENTS:
            raise ValueError(f"experiment must be 'joint' or 'stretch', not {experiment!r}")
        with self._lock:
            self.experiment = experiment
            self._payload_kg = 0.0
            self._setpoint = np.zeros(2)
            self._change(initial=True)

    def hang_payload(self, mass_kg: float) -> None:
        """Hang ``mass_kg`` from actuator a on the stretch stand (replaces any payload)."""
        if self.experiment != "stretch":
            raise ValueError("payloads hang from the stretch stand; call set_experiment('stretch') first")
        if not (math.isfinite(mass_kg) and mass_kg >= 0):
            raise ValueError("payload mass must be >= 0 kg")
        with self._lock:
            old = self._payload_kg
            self._payload_kg = float(mass_kg)
            try:
                self._change()
            except ValueError:
                self._payload_kg = old
                raise

    def remove_payload(self) -> None:
        """Take the payload off (no-op without one)."""
        if self.experiment == "stretch" and self._payload_kg:
            self.hang_payload(0.0)

    # ------------------------------------------------------------ sensors

    @staticmethod
    def _sensed(p_MPa: Any, alpha: Any, length: Any) -> np.ndarray:
        """What the sensors see, channel order, SI: P_A, P_B (MPa), the joint angle (rad), L_a (m)."""
        p = np.asarray(p_MPa)
        return np.column_stack([p[:, 0], p[:, 1], np.asarray(alpha), np.asarray(length)])

    def ideal_counts(self, p_MPa: Any, alpha: Any, length: Any, t: Any) -> np.ndarray:
        """Noise-free, unrounded counts (n, 4) for states at times ``t`` (offset and drift included)."""
        return self.sensors.ideal_counts(self._sensed(p_MPa, alpha, length), t)

    def samples(self, n: int, rate_hz: float) -> tuple[np.ndarray, np.ndarray]:
        """``n`` ADC samples at ``rate_hz``: ``(t_us int64 (n,), counts int64 (n, 4))``.

        The first sample is one period after the current time; the clock ends at the last.
        """
        if n < 0 or not rate_hz > 0:
            raise ValueError("need n >= 0 and rate_hz > 0")
        with self._lock:
            if n == 0:
                return np.zeros(0, np.int64), np.zeros((0, 4), np.int64)
            t = self._t + np.arange(1, n + 1) / float(rate_hz)
            p, alpha, length = self._state_at(t)
            counts = self.sensors.read(self._sensed(p, alpha, length), t)
            self._t = float(t[-1])
            return np.rint(t * 1e6).astype(np.int64), counts
