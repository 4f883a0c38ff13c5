"""The simulated two-joint McKibben rig: physics, operator, sensors and ADC.

:class:`SimRig` is the test bed of Takuma et al. (2014) behind a 12-bit ADC.
It is not part of the wire protocol; the simulated firmware
(:mod:`labcli.core.sim.firmware`) reads it through two generic members that any other
rig model can provide as well:

* ``channels`` (names, in data-line order), ``device`` and ``firmware`` (for ``ID?``);
* ``samples(n, rate_hz) -> (t_us int64 (n,), counts int64 (n, k))``, advancing
  the rig's own simulated clock, and ``advance(seconds)``.

Operator hooks (``supply_air``, ``close_valves``, ``hang_weight``, ...) act at
the rig's current simulated time.  Each solves the new static equilibrium once
(:func:`labcli.papers.takuma2014.sim.physics.solve_equilibrium`); the posture then relaxes towards it
as a first-order lag with time constant ``tau`` (seeded jitter of about 15 %
per change).  With the valves closed the pressures follow the posture through Boyle's
law, so angles and pressures are always consistent.

Each chamber has its own valve (``valve_channels``, the pressure channels in order), which a
wire-protocol 1.1 board drives through :meth:`SimRig.set_valves`: ``supply`` (open to the
regulator), ``hold`` (closed) or ``vent`` (open to the atmosphere), one per chamber; the hand
operations ``supply_air``, ``close_valves`` and ``vent`` set all four at once.  A valve switches
at once; the air then takes time: an open chamber fills from the regulator (an ideal, relieving
source at its set pressure) or empties to the atmosphere through the valve's orifice, ISO 6358
flow (``valve``, :data:`VALVE` by default), isothermal, at the volume the chamber has when the
valve acts (:mod:`labcli.core.sim.orifice`).  It reaches the regulator's pressure, or the
atmosphere's, exactly and in a finite time: 0.46 s to 99 % of 0.3 MPa for an outside chamber,
0.21 s for an inside one.  A chamber closed part way keeps the air it has (``flow="lag"``: the earlier rig's first-order
lag instead, which reproduces its runs frame for frame).  The rig has no relief
valve of its own: the pressure limit is the board's (:mod:`labcli.core.sim.valves`, ``PMAX``).
A closed chamber in a mixed state leaks but has no thermal tail.

Sensors: pressure counts per the reference calibration
``P[MPa] = (counts * 5 / 4095 - 1) / 4`` and potentiometer counts per
``deg = (counts - 2048) * 340 / 4095``, Gaussian noise of 0.5 count (pressure)
and 0.7 count (potentiometer) rms times ``noise``, rounded and clipped to
0..4095.  With ``variation`` on (the default) each potentiometer has a
mechanical offset (1.5 deg rms) and each pressure sensor a zero offset
(1.5 kPa rms), and the actuators differ (:func:`labcli.papers.takuma2014.sim.physics.varied_params`).
``drift`` scales sensor zero drift (slow sinusoids of a few counts, periods of
10-40 min); None takes the non-idealities' own default (1 on the literature's rig, 0 on the
kind one).  Both rigs read their sensors through one front end,
:class:`labcli.core.sim.sensors.SensorFrontEnd` (``rig.sensors``).

``nonideal`` (:class:`labcli.papers.takuma2014.sim.nonideal.NonIdeal`, on at the levels of its
``realism`` by default, the literature's unless ``realism="kind"``) adds sleeve friction with hysteresis, a leak of the closed chambers,
thermal relaxation after fast loads, potentiometer backlash and the links'
weight, friction at a pushed object's contact and in the weight's pulley, and the sensors'
errors: the potentiometers' scale and linearity (:class:`labcli.core.sim.sensors.GainLinearity`)
and the pressure sensors' repeatability (a new error drawn at every change of the rig, settling
with it); ``NonIdeal.ideal()`` turns them off, and the rig then computes exactly
what it computed before they existed (same parameters, same frames).  The
leak moves the pressures at once; its small effect on posture enters at the
next operator action.  ``design`` picks the actuators (:data:`labcli.papers.takuma2014.sim.physics.DESIGNS`:
``"paper"``, the paper-scale default, or ``"thin"``, the earlier soft tuning);
``supply_MPa`` is one supply pressure or four (L1, R1, L2, R2).  ``valves_open`` leaves every
valve open to the regulator whatever closes it (by hand or by the board, whose commanded states
``valve_states`` still reports): the operator's mistake of the two-terminal walk-through, where
each load leaves the pressures where they were.
"""

from __future__ import annotations

import threading
from dataclasses import dataclass, replace

import numpy as np

from ....core.sim import orifice
from ....core.sim.clock import SimClock
from ....core.sim.orifice import Orifice
from ....core.sim.sensors import GainLinearity, SensorChannel, SensorFrontEnd, Transfer, repeat_error
from . import nonideal as ni
from . import physics as ph

CHANNELS = ("P_L1", "P_R1", "P_L2", "P_R2", "POT1", "POT2")
ADC_MAX = 4095
VREF = 5.0
POT_SPAN_DEG = 340.0
PRESSURE_NOISE_COUNTS = 0.5
POT_NOISE_COUNTS = 0.7
# Zero drift at drift = 1 (counts): the pressure sensors a little more than the potentiometers.
PRESSURE_DRIFT_COUNTS = 3.0
POT_DRIFT_COUNTS = 2.0
# Each chamber's valve with its fittings and tubing (ISO 6358): 0.1 dm^3/(s bar) and b = 0.3, a
# small 3/2 solenoid valve behind a metre of 4 mm tube.  It fills an outside chamber (44 mL with its
# tubing) from vented to 99 % of 0.3 MPa in 0.46 s, an inside one (20 mL) in 0.21 s, and vents them
# to within 1 % in 0.71 s and 0.33 s.
VALVE_C_DM3_PER_S_BAR = 0.1
VALVE_B = 0.3
VALVE = Orifice(VALVE_C_DM3_PER_S_BAR * orifice.DM3_PER_S_BAR, VALVE_B)
# ``lag``: an open chamber follows its regulator with the posture's first-order lag, as the rig did
# before the orifice, so that runs recorded then are reproduced frame for frame.
FLOWS = ("orifice", "lag")


def pressure_to_counts(p_MPa):
    """Ideal (unrounded) ADC counts for a gauge pressure, inverse of the reference calibration."""
    return (4.0 * np.asarray(p_MPa) + 1.0) * ADC_MAX / VREF


def angle_to_counts(theta_rad):
    """Ideal (unrounded) ADC counts for a potentiometer angle."""
    return 2048.0 + np.degrees(theta_rad) * ADC_MAX / POT_SPAN_DEG


@dataclass(frozen=True)
class _Segment:
    """The state between two operator actions: a first-order lag to ``target``."""

    t0: float
    tau: float
    theta_from: np.ndarray
    theta_to: np.ndarray
    p_from: np.ndarray  # gauge Pa (used with open valves)
    p_to: np.ndarray
    chambers: ph.Chambers
    load: ph.NoLoad | ph.Weight | ph.Push
    target: ph.Equilibrium
    x0: np.ndarray  # gas temperature excess T/T0 - 1 at t0 (closed chambers)
    dlnV: np.ndarray  # change of ln(V + V_dead) the lag drives (closed chambers)
    kappa1: float  # kappa - 1 of the fast compression (0: isothermal)
    shaft0: np.ndarray  # potentiometer shaft angles at t0 (backlash)
    repeat_from: np.ndarray  # the pressure sensors' non-repeatability at t0 (MPa)
    repeat_to: np.ndarray  # the one the new readings settle to (MPa)
    flow_rate: np.ndarray  # each open chamber's orifice rate k = C R T0 rho0 / V (1/s), :mod:`.orifice`


class SimRig(SimClock):
    """Physical model of the reference rig with operator hooks and an ADC.

    ``SimRig(seed=0, noise=1.0, drift=0.0)``; ``params`` overrides the
    actuator/geometry parameters (:class:`labcli.papers.takuma2014.sim.physics.RigParams`),
    ``variation=False`` gives the symmetric design rig with ideal sensors,
    ``nonideal=NonIdeal.ideal()`` the ideal model.
    The rig starts vented (no air), at its unloaded posture.
    """

    channels: tuple[str, ...] = CHANNELS
    valve_channels: tuple[str, ...] = CHANNELS[:4]  # a valve per chamber (wire protocol 1.1)
    device = "mckibben-2dof-sim"
    firmware = "1.1"

    @property
    def console_commands(self) -> dict:
        """The operator's actions on ``labcli sim``'s console (:mod:`.console`)."""
        from .console import COMMANDS

        return COMMANDS

    def __init__(
        self,
        seed: int = 0,
        noise: float = 1.0,
        drift: float | None = None,
        params: ph.RigParams | None = None,
        *,
        variation: bool = True,
        tau_s: float = 0.7,
        supply_MPa=ph.SUPPLY_MPA,
        nonideal: ni.NonIdeal | None = None,
        design: str | ph.Design = "paper",
        valves_open: bool = False,
        valve: Orifice | None = None,
        flow: str = "orifice",
    ) -> None:
        if noise < 0 or (drift is not None and drift < 0) or tau_s <= 0:
            raise ValueError("noise and drift must be >= 0 and tau_s > 0")
        supply = ph.supply_array(supply_MPa)
        if np.any(supply < 0) or np.any(supply > 1.0e6):
            raise ValueError("supply pressures must be within 0..1 MPa gauge (the sensors' span)")
        self.seed = int(seed)
        self.tau_s = float(tau_s)
        self.variation = bool(variation)
        self.nonideal = ni.NonIdeal() if nonideal is None else nonideal
        if drift is not None:
            self.nonideal = replace(self.nonideal, drift=float(drift))
        if params is None:
            params = (
                ph.varied_params(self.seed, supply_MPa=supply_MPa, design=design)
                if variation
                else ph.nominal_params(supply_MPa=supply_MPa, design=design)
            )
            if self.nonideal.links:
                params = replace(params, link_mass_kg=np.array(ni.LINK_MASS_KG) * self.nonideal.links)
        self.params = params
        self.valve, self.flow = VALVE if valve is None else valve, _checked_flow(flow)
        levels = self.nonideal.magnitudes()
        self._friction = float(levels["friction_fraction"])
        self._contact_mu, self._pulley_loss = float(levels["contact_mu"]), float(levels["pulley_loss"])
        self._repeat_sd = float(levels["pressure_repeat_sd_MPa"])
        self._repeat_rng = np.random.default_rng([self.seed, 5])  # its own stream: the kind rig's stay as they were
        self._kappa1 = (ni.KAPPA - 1.0) * self.nonideal.thermal
        self._thermal_tau = ni.THERMAL_TAU_S  # read when the rig is built (a test may set another)
        self._backlash = ni.BACKLASH_RAD * self.nonideal.backlash
        self._leak_rate = ni.leak_factors(self.seed, self.nonideal.leak)
        self._lock = threading.RLock()
        self._event_rng = np.random.default_rng([self.seed, 2])
        self.sensors = self._sensor_front_end(noise, self.nonideal.drift)
        self._t = 0.0
        self._t_closed = 0.0
        chambers = ph.Chambers.open(np.zeros(4))
        eq = ph.solve_equilibrium(self.params, chambers, ph.NoLoad())
        self._seg = _Segment(
            0.0,
            self.tau_s,
            eq.theta_rad,
            eq.theta_rad,
            np.zeros(4),
            np.zeros(4),
            chambers,
            ph.NoLoad(),
            eq,
            x0=np.zeros(4),
            dlnV=np.zeros(4),
            kappa1=0.0,
            shaft0=eq.theta_rad.copy(),
            repeat_from=np.zeros(4),
            repeat_to=np.zeros(4),
            flow_rate=self._flow_rate(eq.theta_rad),
        )
        self._rest_theta = eq.theta_rad.copy()
        self._valves = "vented"
        self._valve_states: tuple[str, ...] = ("vent",) * 4
        # The valves as commanded (by hand or by the board); with ``valves_open`` a held chamber
        # stays open to the regulator, as when the operator leaves the valves open.
        self.valves_open = bool(valves_open)
        self._commanded: tuple[str, ...] = self._valve_states

    def _sensor_front_end(self, noise: float, drift: float) -> SensorFrontEnd:
        """The sensors and their fixed errors: offsets drawn first, then the drift, from one seed."""
        srng = np.random.default_rng([self.seed, 3])
        if self.variation:
            self.pot_offset_rad = np.radians(1.5) * srng.standard_normal(2)
            self.sensor_offset_MPa = 0.0015 * srng.standard_normal(4)
        else:
            self.pot_offset_rad = np.zeros(2)
            self.sensor_offset_MPa = np.zeros(4)
        pressures = [
            SensorChannel(name, pressure_to_counts, PRESSURE_NOISE_COUNTS, PRESSURE_DRIFT_COUNTS, float(off))
            for name, off in zip(CHANNELS[:4], self.sensor_offset_MPa, strict=True)
        ]
        pots = [
            SensorChannel(name, transfer, POT_NOISE_COUNTS, POT_DRIFT_COUNTS, float(off))
            for name, off, transfer in zip(CHANNELS[4:], self.pot_offset_rad, self._pot_transfers(), strict=True)
        ]
        return SensorFrontEnd(
            pressures + pots,
            noise=noise,
            drift=drift,
            noise_rng=np.random.default_rng([self.seed, 1]),
            drift_rng=srng,
            rails=(0, ADC_MAX),
        )

    def _pot_transfers(self) -> list[Transfer]:
        """Each potentiometer's transfer: the nominal one, or with its scale and linearity errors
        (drawn from a stream of their own; a rig without ``variation`` has exact ones)."""
        levels = self.nonideal.magnitudes()
        scale_sd, linearity = float(levels["pot_scale_sd"]), float(levels["pot_linearity"])
        if not self.variation or not (scale_sd or linearity):
            return [angle_to_counts, angle_to_counts]
        rng = np.random.default_rng([self.seed, 6])
        span = np.radians(POT_SPAN_DEG)
        return [GainLinearity.seeded(rng, angle_to_counts, span, scale_sd, linearity) for _ in range(2)]

    def pot_reading(self, angle_rad: np.ndarray) -> np.ndarray:
        """What the potentiometers read (rad, ``(..., 2)``) for shaft angles from their electrical centres."""
        a = np.asarray(angle_rad, dtype=float)
        out = a.copy()
        for j, c in enumerate(self.sensors.channels[4:]):
            if isinstance(c.transfer, GainLinearity):
                out[..., j] = c.transfer.reading(a[..., j])
        return out

    def pot_slope(self, angle_rad: np.ndarray, step: float = 1e-6) -> np.ndarray:
        """``d reading / d angle`` of each potentiometer (``(..., 2)``): 1 plus the scale error a
        small deflection at ``angle_rad`` (from the electrical centres) reads with."""
        a = np.asarray(angle_rad, dtype=float)
        return (self.pot_reading(a + step) - self.pot_reading(a - step)) / (2 * step)

    @property
    def noise(self) -> float:
        """The sensors' noise, a multiple of their datasheet figures."""
        return self.sensors.noise

    @property
    def drift(self) -> float:
        """The sensors' zero drift, a multiple of its nominal amplitude."""
        return self.sensors.drift

    # ------------------------------------------------------------ state

    def _theta_at(self, t):
        """Posture (..., 2) at times ``t`` of the current segment (``inf``: where it settles)."""
        s = self._seg
        w = np.exp(-np.clip(np.asarray(t, dtype=float) - s.t0, 0.0, None) / s.tau)[..., None]
        return s.theta_to + (s.theta_from - s.theta_to) * w, w

    def _state_at(self, t, isothermal: bool = False):
        """Posture (..., 2), gauge pressures Pa (..., 4) at times ``t``."""
        s = self._seg
        t = np.asarray(t, dtype=float)
        theta, _ = self._theta_at(t)
        if s.chambers.state == "open":
            p = self._open_pressure(t)
        else:
            L = ph.actuator_lengths(theta, self.params)
            V = ph.mckibben_volume(L, self.params.b, self.params.n)
            amount = s.chambers.amount * self._leak_factor(t)
            p_abs = amount / (V + self.params.V_dead)
            if not isothermal and (s.kappa1 or np.any(s.x0)):
                p_abs = p_abs * (1.0 + self._thermal_at(t))
            p = p_abs - ph.P_ATM
            if s.chambers.state == "mixed":
                p = np.where(s.chambers.held_mask, p, self._open_pressure(t))
        return theta, p

    def _open_pressure(self, t) -> np.ndarray:
        """Gauge pressures (Pa, ``(..., 4)``) of the chambers open to the regulator or the atmosphere
        at times ``t``: the air flows through each valve's orifice (:func:`.orifice.pressure_at`)."""
        s = self._seg
        if self.flow == "lag":
            w = np.exp(-np.clip(np.asarray(t, dtype=float) - s.t0, 0.0, None) / s.tau)[..., None]
            return s.p_to + (s.p_from - s.p_to) * w
        p_abs = orifice.pressure_at(
            np.asarray(t, dtype=float) - s.t0, s.p_from + ph.P_ATM, s.p_to + ph.P_ATM, s.flow_rate, self.valve.b
        )
        return p_abs - ph.P_ATM

    def chamber_volumes(self, theta=None) -> np.ndarray:
        """Each chamber's volume with its dead volume (m^3, ``(..., 4)``) at posture ``theta``
        (absolute joint angles, rad; None: the posture now)."""
        p = self.params
        if theta is None:
            theta = self.true_state()["theta_rad"]
        return ph.mckibben_volume(ph.actuator_lengths(theta, p), p.b, p.n) + p.V_dead

    def _flow_rate(self, theta) -> np.ndarray:
        """Each chamber's orifice rate (1/s) at the volume it has at posture ``theta``."""
        return self.valve.rate(self.chamber_volumes(theta))

    def _leak_factor(self, t):
        """Fraction of each closed chamber's air left at times ``t`` (``(..., 4)``)."""
        t = np.asarray(t, dtype=float)
        if not np.any(self._leak_rate) or self._seg.chambers.state == "open":
            return np.ones(t.shape + (4,))
        return np.exp(-(t - self._t_closed)[..., None] * self._leak_rate)

    def _shaft_at(self, t, theta):
        """Potentiometer shaft angles (..., 2) for joint angles ``theta`` at times ``t`` (backlash)."""
        return ni.play(self._seg.shaft0, theta, self._backlash)

    def _repeat_at(self, t) -> np.ndarray:
        """The pressure sensors' non-repeatability (MPa, ``(..., 4)``) at times ``t``: the new
        readings' error settles with the posture's lag."""
        s = self._seg
        w = np.exp(-np.clip(np.asarray(t, dtype=float) - s.t0, 0.0, None) / s.tau)[..., None]
        return s.repeat_to + (s.repeat_from - s.repeat_to) * w

    def _thermal_at(self, t) -> np.ndarray:
        """Gas temperature excess ``T/T0 - 1`` of each chamber at times ``t`` (``(..., 4)``)."""
        s = self._seg
        if s.chambers.state != "closed" or not (s.kappa1 or np.any(s.x0)):
            return np.zeros(np.shape(t) + (4,))
        return ni.thermal_excess(t - s.t0, s.x0, s.dlnV, s.kappa1, s.tau, self._thermal_tau)

    def true_state(self) -> dict:
        """The truth at the current simulated time (for tests and checks).

        Keys: ``theta_rad`` (2,) absolute joint angles, ``pressures_MPa`` (4,)
        gauge L1 R1 L2 R2, ``force_N`` (2,) on the contact point, ``time_s``;
        also ``valves`` ("vented" | "open" | "closed" | "mixed"), ``contact_m`` (2,),
        ``target_theta_rad`` (2,) the equilibrium being approached, ``tau_s``,
        ``valve_states`` (4,) each chamber's ("supply" | "hold" | "vent"),
        ``load`` (dict describing the load) and ``residual_Nm`` of the target;
        ``rest_theta_rad`` (2,) the unloaded posture the arm last rested at (or
        is settling to), i.e. the absolute angles of the current baseline;
        ``pressures_isothermal_MPa`` (4,) what the pressures relax to once the
        air has the wall's temperature; ``pot_shaft_rad`` (2,) where the
        potentiometers' shafts stand (backlash); ``pot_slope`` (2,) what a small
        deflection reads per radian there (1 plus the scale and linearity error);
        ``repeat_MPa`` (4,) the pressure sensors' non-repeatability now; ``supply_MPa`` (4,) the
        regulator settings; ``nonideal`` the configured magnitudes.
        """
        with self._lock:
            theta, p = self._state_at(self._t)
            _, p_iso = self._state_at(self._t, isothermal=True)
            s = self._seg
            return {
                "theta_rad": theta.copy(),
                "pressures_MPa": p / 1e6,
                "force_N": np.asarray(s.load.force(theta, self.params.geometry), dtype=float),
                "time_s": self._t,
                "valves": self._valves,
                "valve_states": self._valve_states,
                "contact_m": ph.contact_point(theta, self.params.geometry),
                "target_theta_rad": s.target.theta_rad.copy(),
                "tau_s": s.tau,
                "load": _describe(s.load, self.params.geometry),
                "residual_Nm": s.target.residual_Nm,
                "rest_theta_rad": self._rest_theta.copy(),
                "pressures_isothermal_MPa": p_iso / 1e6,
                "pot_shaft_rad": self._shaft_at(self._t, theta),
                "pot_slope": self.pot_slope(theta + self.pot_offset_rad),
                "repeat_MPa": self._repeat_at(self._t),
                "supply_MPa": self.params.supply_pa / 1e6,
                "nonideal": {**self.nonideal.magnitudes(), "thermal_tau_s": self._thermal_tau},
            }

    def truth_at(self, t) -> dict:
        """The truth at times ``t`` (s) of the current segment, for scripted runs and checks.

        ``deflection_rad`` (n, 2): the joint angles less the rest posture the arm last rested at
        (what the models estimate); ``force_N`` (n, 2) on the tip; ``theta_rad`` (n, 2) absolute.
        ``t = inf`` gives where the segment settles.
        """
        with self._lock:
            theta, _ = self._theta_at(np.atleast_1d(np.asarray(t, dtype=float)))
            force = np.asarray(self._seg.load.force(theta, self.params.geometry), dtype=float)
            return {"deflection_rad": theta - self._rest_theta, "force_N": force, "theta_rad": theta}

    # ------------------------------------------------------------ operator

    def _change(self, chambers: ph.Chambers | None = None, load=None, valves: str | None = None) -> None:
        with self._lock:
            theta_now, p_now = self._state_at(self._t)
            s = self._seg
            x_now = self._thermal_at(self._t)
            shaft_now = self._shaft_at(self._t, theta_now)
            repeat_now = self._repeat_at(self._t)
            if chambers is None:
                chambers = s.chambers
                if chambers.state != "open" and np.any(self._leak_rate):
                    # Fold the leak so far into the amount of air; posture sees it from now on.
                    chambers = replace(chambers, amount=chambers.amount * self._leak_factor(self._t))
                    self._t_closed = self._t
            else:
                x_now = np.zeros(4)  # new air from the regulator (or none): at the wall's temperature
            load = s.load if load is None else load
            try:
                eq = ni.friction_equilibrium(self.params, chambers, load, theta_now, self._friction)
            except ValueError:
                raise ValueError(
                    f"the simulated rig finds no static equilibrium with {_load_text(load)};"
                    " the load is beyond the rig's range"
                ) from None
            p_to = chambers.gauge_pa if chambers.state == "open" else eq.pressures_MPa * 1e6
            if chambers.state == "mixed":
                p_to = np.where(chambers.held_mask, np.asarray(p_to), np.asarray(chambers.gauge_pa))
            tau = self.tau_s * float(np.clip(np.exp(0.15 * self._event_rng.standard_normal()), 0.7, 1.4))
            dlnV, kappa1 = np.zeros(4), 0.0
            if chambers.state == "closed" and (self._kappa1 or np.any(x_now)):

                def vol(th: np.ndarray) -> np.ndarray:
                    p = self.params
                    return ph.mckibben_volume(ph.actuator_lengths(th, p), p.b, p.n) + p.V_dead

                dlnV, kappa1 = np.log(vol(eq.theta_rad)) - np.log(vol(theta_now)), self._kappa1
            self._seg = _Segment(
                self._t,
                tau,
                theta_now,
                eq.theta_rad,
                p_now,
                np.asarray(p_to, float),
                chambers,
                load,
                eq,
                x0=x_now,
                dlnV=dlnV,
                kappa1=kappa1,
                shaft0=np.asarray(shaft_now, float),
                repeat_from=repeat_now,
                repeat_to=repeat_error(self._repeat_rng, self._repeat_sd, 4),
                flow_rate=self._flow_rate(theta_now),
            )
            if isinstance(load, ph.NoLoad):
                self._rest_theta = eq.theta_rad.copy()
            if valves is not None:
                self._valves = valves

    def supply_air(self, pressures_MPa=None) -> None:
        """Open the valves and pressurise to the supply (scalar or 4 values, MPa gauge); pressures are held."""
        p = self.params.supply_pa if pressures_MPa is None else np.asarray(pressures_MPa, float) * 1e6
        p = np.broadcast_to(p, (4,)).astype(float)
        if np.any(p < 0) or np.any(p > 1.0e6):
            raise ValueError("supply pressures must be within 0..1 MPa gauge (the sensors' span)")
        self._change(chambers=ph.Chambers.open(p), valves="open")
        self._valve_states = self._commanded = ("supply",) * 4

    def close_valves(self) -> None:
        """Close the valves: from now on each chamber keeps its air (Boyle's law)."""
        with self._lock:
            self._commanded = ("hold",) * 4
            if self.valves_open:
                return
            if self._seg.chambers.state == "closed":
                return  # closing a closed valve changes nothing
            theta_now, p_now = self._state_at(self._t)
            L = ph.actuator_lengths(theta_now, self.params)
            self._t_closed = self._t
            self._change(chambers=ph.Chambers.closed_at(L, p_now, self.params), valves="closed")
            self._valve_states = ("hold",) * 4

    def vent(self) -> None:
        """Open the valves to atmosphere: the rig goes limp (rubber only)."""
        self._change(chambers=ph.Chambers.open(np.zeros(4)), valves="vented")
        self._valve_states = self._commanded = ("vent",) * 4

    @property
    def valve_states(self) -> tuple[str, ...]:
        """Each chamber's valve as commanded: ``supply``, ``hold`` or ``vent`` (L1, R1, L2, R2)."""
        return self._commanded

    def set_valves(self, states) -> None:
        """Set each chamber's valve (four of ``supply``, ``hold``, ``vent``, L1 R1 L2 R2), as a board does.

        A chamber already closed keeps its air; one closed now keeps what it has.
        """
        states = tuple(states)
        if len(states) != 4 or not set(states) <= {"supply", "hold", "vent"}:
            raise ValueError(f"valve states are four of supply, hold, vent; got {states!r}")
        with self._lock:
            commanded = states
            if self.valves_open:
                states = tuple("supply" if v == "hold" else v for v in states)
            self._commanded = commanded
            if states == self._valve_states:
                return
            if len(set(states)) == 1:
                {"supply": self.supply_air, "hold": self.close_valves, "vent": self.vent}[states[0]]()
                self._commanded = commanded
                return
            theta_now, p_now = self._state_at(self._t)
            s = self._seg
            held_before = s.chambers.held_mask
            L = ph.actuator_lengths(theta_now, self.params)
            amount = np.asarray(ph.Chambers.closed_at(L, p_now, self.params).amount)
            if held_before.any():
                amount = np.where(held_before, np.asarray(s.chambers.amount) * self._leak_factor(self._t), amount)
            held = np.array([v == "hold" for v in states])
            gauge = np.where(np.array([v == "supply" for v in states]), self.params.supply_pa, 0.0)
            self._t_closed = self._t
            self._change(chambers=ph.Chambers.mixed(held, gauge, amount), valves="mixed")
            self._valve_states = states
            self._commanded = commanded

    def hang_weight(self, mass_kg: float, direction_rad: float) -> None:
        """Hang ``mass_kg`` from the tip over a pulley pulling along ``direction_rad`` (replaces any load)."""
        if not mass_kg >= 0:
            raise ValueError("mass must be >= 0 kg")
        self._change(load=ph.Weight(float(mass_kg), float(direction_rad), loss=self._pulley_loss))

    def remove_weight(self) -> None:
        """Take the weight off (no-op if none hangs)."""
        if isinstance(self._seg.load, ph.Weight):
            self._change(load=ph.NoLoad())

    def push_object(self, radius_m: float, distance_m: float, phi_rad: float, stiffness_N_per_m: float) -> None:
        """Place Section 4's cylinder just touching the tip, then push it ``distance_m`` along ``phi_rad``."""
        if not (radius_m > 0 and distance_m >= 0 and stiffness_N_per_m > 0):
            raise ValueError("object radius and stiffness must be > 0 and the push distance >= 0")
        with self._lock:
            theta_now, _ = self._state_at(self._t)
            cx, cy = (float(v) for v in ph.contact_point(theta_now, self.params.geometry))
            push = ph.Push(
                float(radius_m),
                float(distance_m),
                float(phi_rad),
                float(stiffness_N_per_m),
                (cx, cy),
                friction_mu=self._contact_mu,
                tangential_ratio=ni.CONTACT_STIFFNESS,
            )
            self._change(load=push)

    def release_object(self) -> None:
        """Withdraw the object (no-op if none is pushed)."""
        if isinstance(self._seg.load, ph.Push):
            self._change(load=ph.NoLoad())

    # ------------------------------------------------------------ sensors

    @staticmethod
    def _sensed(theta, p_gauge_pa) -> np.ndarray:
        """What the sensors see, channel order, SI: gauge pressures (MPa), then shaft angles (rad)."""
        return np.concatenate([np.asarray(p_gauge_pa) / 1e6, np.asarray(theta)], axis=-1)

    def ideal_counts(self, theta, p_gauge_pa, t) -> np.ndarray:
        """Noise-free, unrounded counts (n, 6) for states at times ``t`` (offsets and drift included)."""
        return self.sensors.ideal_counts(self._sensed(theta, p_gauge_pa), t)

    def samples(self, n: int, rate_hz: float) -> tuple[np.ndarray, np.ndarray]:
        """``n`` ADC samples at ``rate_hz``: ``(t_us int64 (n,), counts int64 (n, 6))``.

        The first sample is one period after the current time; the clock ends
        at the last sample.
        """
        if n < 0 or not rate_hz > 0:
            raise ValueError("need n >= 0 and rate_hz > 0")
        with self._lock:
            t = self._t + np.arange(1, n + 1) / float(rate_hz)
            if n == 0:
                return np.zeros(0, np.int64), np.zeros((0, 6), np.int64)
            theta, p = self._state_at(t)
            if self._repeat_sd:
                p = p + self._repeat_at(t) * 1e6
            counts = self.sensors.read(self._sensed(self._shaft_at(t, theta), p), t)
            self._t = float(t[-1])
            return np.rint(t * 1e6).astype(np.int64), counts


def _checked_flow(flow: str) -> str:
    if flow not in FLOWS:
        raise ValueError(f"flow is one of {', '.join(FLOWS)}")
    return flow


def _load_text(load) -> str:
    if isinstance(load, ph.Weight):
        return f"{load.mass_kg * 1e3:g} g hanging at {np.degrees(load.direction_rad):g} deg"
    if isinstance(load, ph.Push):
        return (
            f"an object of radius {load.radius_m * 1e3:g} mm pushed {load.distance_m * 1e3:g} mm"
            f" at {np.degrees(load.phi_rad):g} deg"
        )
    return "no load"


def _describe(load, geom) -> dict:
    if isinstance(load, ph.Weight):
        return {
            "kind": "weight",
            "mass_kg": load.mass_kg,
            "direction_rad": load.direction_rad,
            "pulley_loss": load.loss,
        }
    if isinstance(load, ph.Push):
        return {
            "kind": "push",
            "radius_m": load.radius_m,
            "distance_m": load.distance_m,
            "phi_rad": load.phi_rad,
            "stiffness_N_per_m": load.stiffness_N_per_m,
            "center_m": load.center(geom).tolist(),
            "contact_mu": load.friction_mu,
        }
    return {"kind": "none"}
