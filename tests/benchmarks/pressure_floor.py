"""The pressure sensors' floor: the smallest error any unbiased estimator of one trial's readings can have.

A trial gives an estimator its baseline window (four pressures P0 and the two potentiometers, the
rest posture) and its loaded window (four pressures P).  Each window's pressure comes back off by
the sensors' repeatability, a fresh error per reading (sim/nonideal.py, ``PRESSURE_REPEAT_SD_MPA``,
0.33 kPa rms on the literature's rig), plus the white noise and rounding of the window's samples
averaged over the window; the potentiometers by their own noise so averaged.  Propagating those
errors through the Jacobian of the rig's own forward map at each validation trial's state gives the
Cramér-Rao bound ``(J^T W J)^-1`` (W the readings' inverse variances): no unbiased estimator of those
readings has a smaller covariance.  Two forward maps (physics.py's statics, the rig of the seed
with its actuators' variation, its links' weight and its supply):

* ``boyle`` (angles only): unknowns the four chambers' air (ln of P_abs (V + V_dead)), the rest
  posture and the loaded posture; readings P0 = air / (V(theta0) + V_dead), P = air / (V(theta) +
  V_dead) and the potentiometers at rest.  It assumes nothing of what holds the arm where it is, so
  it holds on a rig with sleeve friction (friction decouples the posture from the load);
* ``statics`` (angles and forces): unknowns the air and the tip force (Fx, Fy); the postures the
  frictionless equilibria they give.  It is the floor of an estimator that knew the rig had no
  friction: on a rig with friction the force is not even determined by the pressures (the
  friction band), so this floor is a lower bound there too, a loose one.

The statics' floor is the lower of the two on the angles (fewer unknowns).  Per arm and quantity,
the floor is the root mean of the bound's variance over the validation trials (18 a seed), pooled
over the seeds, with a 95 % interval from a bootstrap over seeds, and Fy's floor standard error
is counted against the protocol's reporting limit (``[sensing] max_force_se_N``).  The states are
the frictionless equilibria of the plan's loads with the chambers closed at the supplied rest.

    nice python tests/benchmarks/pressure_floor.py [--seeds 11-30] [--repeat 1] [--figures OUT]
    nice python tests/benchmarks/pressure_floor.py --empirical [--seeds 11-30]   # also the check

``--empirical``: the check on the simulated rig with only the repeatability on (and the white noise,
``NonIdeal.ideal(repeat=1)``) against the same rig without it: the posture form's validation RMSE on
each, and the part the repeatability adds, ``sqrt(rmse_repeat^2 - rmse_ideal^2)``, beside the floor
of that rig (no links' weight) and the toolkit's posture form; with ``--repeat 0`` as a control the
floor shrinks to the white noise's.
"""

from __future__ import annotations

import json
import math
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

ROOT = Path(__file__).resolve().parents[2]
ARMS = {"straight": "takuma2014", "bent": "takuma2014-bent"}
QUANTITIES = ("theta1", "theta2", "Fx", "Fy")
ANGLES = QUANTITIES[:2]
BOOTSTRAP = 2000
# The issue's estimator (the posture form at the commit baseline_estimator.py names), held-out
# seeds 11-30, RMSE over every validation trial: the figures file the floor is set against.
ISSUE_FIGURES = ROOT / "docs" / "figures" / "baseline-estimator-new-rig.json"
TARGET = 0.7  # the issue's aim: 30 % below its estimator


# ----------------------------------------------------------------------------- the bound


def crb(jac: np.ndarray, sd: np.ndarray, prior_sd: np.ndarray | None = None) -> np.ndarray:
    """The Cramér-Rao bound ``(J^T W J)^-1`` of the unknowns of readings ``y = h(x) + e`` with
    independent errors of standard deviations ``sd`` (m,), ``jac`` = dh/dx (m, k).

    ``prior_sd`` (k,): a prior's spread of each unknown (inf: none), added to the information as
    ``1 / prior_sd^2`` (the Bayesian bound of any estimator, biased or not, whose truth has that
    spread).  Raises ValueError when the readings do not determine the unknowns (rank below k)."""
    jac, sd = np.asarray(jac, dtype=float), np.asarray(sd, dtype=float)
    if jac.ndim != 2 or sd.shape != (jac.shape[0],):
        raise ValueError(f"the Jacobian must be (m, k) and the errors (m,), got {jac.shape} and {sd.shape}")
    if np.any(~(sd > 0)):
        raise ValueError("every reading's standard deviation must be positive")
    a = jac / sd[:, None]
    info = a.T @ a
    if prior_sd is not None:
        info = info + np.diag(1.0 / np.asarray(prior_sd, dtype=float) ** 2)
    elif np.linalg.matrix_rank(a) < jac.shape[1]:
        raise ValueError("the readings do not determine the unknowns (the Jacobian's rank is below their number)")
    return np.linalg.inv(info)


def numeric_jacobian(f: Callable[[np.ndarray], np.ndarray], x: np.ndarray, steps: np.ndarray) -> np.ndarray:
    """Central differences of ``f`` at ``x``, one step per unknown: (len(f(x)), len(x))."""
    x, steps = np.asarray(x, dtype=float), np.asarray(steps, dtype=float)
    cols = []
    for k in range(x.size):
        dx = np.zeros_like(x)
        dx[k] = steps[k]
        cols.append((np.asarray(f(x + dx)) - np.asarray(f(x - dx))) / (2.0 * steps[k]))
    return np.stack(cols, axis=1)


def quantity_covariance(
    readings: Callable[[np.ndarray], np.ndarray],
    quantities: Callable[[np.ndarray], np.ndarray],
    x: np.ndarray,
    steps: np.ndarray,
    sd: np.ndarray,
    variants: dict[str, tuple[np.ndarray, np.ndarray | None]] | None = None,
) -> dict[str, np.ndarray]:
    """The bound on the quantities ``q(x)``: ``Q (J^T W J)^-1 Q^T``, Q = dq/dx, J = dh/dx, for each
    variant ``name: (free, prior_sd)``: the unknowns ``free`` (bool mask) estimated, the others
    known, with a prior's spread on the free ones (None: none); default one variant, ``""``, all free."""
    jac = numeric_jacobian(readings, x, steps)
    q = numeric_jacobian(quantities, x, steps)
    out = {}
    for name, (free, prior) in (variants or {"": (np.ones(x.size, bool), None)}).items():
        out[name] = q[:, free] @ crb(jac[:, free], sd, prior) @ q[:, free].T
    return out


# ----------------------------------------------------------------------------- the rig's readings


def reading_sd(protocol: Any, repeat_sd_MPa: float) -> tuple[float, float]:
    """One window's standard deviation of a pressure (MPa) and of a potentiometer (rad).

    A pressure: the repeatability (fresh per reading) and the samples' noise and rounding averaged
    over the window (``rate_hz * capture_s`` samples); a potentiometer: its noise and rounding so
    averaged (its scale and linearity errors are the same at every reading: not noise)."""
    from labcli.papers.takuma2014.sim import rig as sr

    n = max(1, round(float(protocol.rate_hz) * float(protocol.settling.capture_s)))
    count_MPa = sr.VREF / sr.ADC_MAX / 4.0  # P = (counts * 5 / 4095 - 1) / 4
    count_rad = math.radians(sr.POT_SPAN_DEG / sr.ADC_MAX)
    white_p = math.sqrt(sr.PRESSURE_NOISE_COUNTS**2 + 1.0 / 12.0) * count_MPa / math.sqrt(n)
    white_pot = math.sqrt(sr.POT_NOISE_COUNTS**2 + 1.0 / 12.0) * count_rad / math.sqrt(n)
    return math.hypot(repeat_sd_MPa, white_p), white_pot


class TrialMaps:
    """The forward maps of one rig (``params``, physics.RigParams) with its chambers closed at the
    frictionless supplied rest: readings and quantities of each unknown vector."""

    def __init__(self, params: Any, supply_MPa: Any) -> None:
        from labcli.papers.takuma2014.sim import physics as ph

        self.ph, self.params = ph, params
        supplied = ph.Chambers.open(ph.supply_array(supply_MPa))
        self.rest = ph.solve_equilibrium(params, supplied).theta_rad
        closed = ph.Chambers.closed_at(ph.actuator_lengths(self.rest, params), ph.supply_array(supply_MPa), params)
        self.ln_air = np.log(np.asarray(closed.amount, dtype=float))

    def _gauge_MPa(self, ln_air: np.ndarray, theta: np.ndarray) -> np.ndarray:
        ph = self.ph
        chambers = ph.Chambers("closed", amount=np.exp(ln_air))
        return chambers.gauge(ph.actuator_lengths(theta, self.params), self.params) / 1e6

    def _equilibrium(
        self, ln_air: np.ndarray, force: np.ndarray | None, start: np.ndarray, friction: np.ndarray | None = None
    ) -> np.ndarray:
        """The posture under ``force`` (None: none) with each pair's sleeve friction ``friction``
        (2,) N: a pull added to L and taken from R of the pair (None: no friction)."""
        ph = self.ph
        load = None
        if force is not None:
            mag = float(np.hypot(force[0], force[1]))
            load = ph.Weight(mag / ph.G, math.atan2(float(force[1]), float(force[0])))
        chambers = ph.Chambers("closed", amount=np.exp(ln_air))
        extra = None if friction is None else np.array([friction[0], -friction[0], friction[1], -friction[1]])
        return ph.solve_equilibrium(
            self.params, chambers, load, theta0=start, tol=1e-12, extra_tension_N=extra
        ).theta_rad

    def friction_band(self, fraction: float) -> np.ndarray:
        """Each pair's sleeve friction at the rest (N, (2,)): ``fraction`` of its actuators' mean
        pressure force ``P (-dV/dL)`` (sim/nonideal.py), the half-width of the band it holds the arm in."""
        ph = self.ph
        L = ph.actuator_lengths(self.rest, self.params)
        p = ph.Chambers("closed", amount=np.exp(self.ln_air)).gauge(L, self.params)
        f = fraction * p * np.abs(ph.mckibben_dvolume(L, self.params.b, self.params.n))
        return np.array([f[:2].mean(), f[2:].mean()])

    def statics_state(self, force: np.ndarray) -> np.ndarray:
        """The statics' unknowns at a trial: the closed chambers' air and the tip force (N)."""
        return np.concatenate([self.ln_air, np.asarray(force, dtype=float)])

    def statics(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Readings (P0 MPa, P MPa, rest posture rad) and quantities (deflection rad, force N); with
        ten unknowns the last four are the pairs' friction under the load and at the rest (N)."""
        ln_air, force = x[:4], x[4:6]
        loaded, rest = (x[6:8], x[8:10]) if x.size == 10 else (None, None)
        theta0 = self._equilibrium(ln_air, None, self.rest, rest)
        theta = self._equilibrium(ln_air, force, theta0, loaded)
        readings = np.concatenate([self._gauge_MPa(ln_air, theta0), self._gauge_MPa(ln_air, theta), theta0])
        return readings, np.concatenate([theta - theta0, force])

    def boyle_state(self, force: np.ndarray) -> np.ndarray:
        """The Boyle map's unknowns at a trial: the air, the rest posture, the loaded posture (rad)."""
        theta0 = self._equilibrium(self.ln_air, None, self.rest)
        theta = self._equilibrium(self.ln_air, np.asarray(force, dtype=float), theta0)
        return np.concatenate([self.ln_air, theta0, theta])

    def boyle(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Readings (P0, P, rest posture) and quantities (deflection) of the Boyle map's unknowns."""
        ln_air, theta0, theta = x[:4], x[4:6], x[6:8]
        readings = np.concatenate([self._gauge_MPa(ln_air, theta0), self._gauge_MPa(ln_air, theta), theta0])
        return readings, theta - theta0


STEPS = {
    "statics": np.array([1e-6] * 4 + [1e-2] * 2),
    "friction": np.array([1e-6] * 4 + [1e-2] * 6),
    "boyle": np.array([1e-6] * 4 + [1e-5] * 4),
}
# The variants of each map: all unknowns estimated from the trial's readings; the air known (the
# chambers' air taken from elsewhere: the regulator, other baselines); the force's spread over the
# plan as a prior (``_prior``).  The friction map is the statics with each pair's sleeve friction
# under the load and at the rest as unknowns within the literature's band (a uniform prior).
VARIANTS = {
    "statics": ("statics", "statics_air", "statics_prior"),
    "friction": ("friction", "friction_prior"),
    "boyle": ("boyle", "boyle_air"),
}
ALL_VARIANTS = tuple(v for vs in VARIANTS.values() for v in vs)


def quantities_of(variant: str) -> tuple[str, ...]:
    return ANGLES if variant.startswith("boyle") else QUANTITIES


def _variants(name: str, prior_N: float, band_N: np.ndarray) -> dict[str, tuple[np.ndarray, np.ndarray | None]]:
    n = STEPS[name].size
    free = np.ones(n, bool)
    if name == "boyle":
        return {"boyle": (free, None), "boyle_air": (np.arange(n) >= 4, None)}
    force = [prior_N] * 2
    if name == "statics":
        prior = np.array([np.inf] * 4 + force)
        return {"statics": (free, None), "statics_air": (np.arange(n) >= 4, None), "statics_prior": (free, prior)}
    friction = list(np.tile(np.asarray(band_N, dtype=float) / math.sqrt(3.0), 2))
    return {
        "friction": (free, np.array([np.inf] * 6 + friction)),
        "friction_prior": (free, np.array([np.inf] * 4 + force + friction)),
    }


def trial_floor(
    maps: TrialMaps,
    force: np.ndarray,
    sd_p: float,
    sd_pot: float,
    prior_N: float = np.inf,
    band_N: np.ndarray | None = None,
) -> dict[str, np.ndarray]:
    """Each map's and variant's bound on its quantities' variances (rad^2, N^2) at one trial's load
    (``band_N``: the pairs' friction band, :meth:`TrialMaps.friction_band`; None: no friction map)."""
    sd = np.array([sd_p] * 8 + [sd_pot] * 2)
    out: dict[str, np.ndarray] = {}
    for name in ("statics", "friction", "boyle"):
        if name == "friction" and band_N is None:
            continue
        fn = maps.boyle if name == "boyle" else maps.statics
        x = maps.boyle_state(force) if name == "boyle" else maps.statics_state(force)
        if name == "friction":
            x = np.concatenate([x, np.zeros(4)])  # the frictionless posture: the band's middle
        covs = quantity_covariance(
            lambda v, fn=fn: fn(v)[0], lambda v, fn=fn: fn(v)[1], x, STEPS[name], sd, _variants(name, prior_N, band_N)
        )
        out.update({k: np.diag(c) for k, c in covs.items()})
    return out


# ----------------------------------------------------------------------------- per seed


def rig_of(arm: str, seed: int, nonideal: Any) -> tuple[Any, Any, Any]:
    """The arm's protocol, its rig's parameters and supply (the bent arm's from sensing_accuracy)."""
    from sensing_accuracy import BENT_SUPPLY_MPA

    from labcli.core.protocol import load_protocol
    from labcli.papers.takuma2014.sim.physics import SUPPLY_MPA
    from labcli.papers.takuma2014.sim.rig import SimRig

    proto = load_protocol(ARMS[arm])
    supply = BENT_SUPPLY_MPA if arm == "bent" else SUPPLY_MPA
    return proto, SimRig(seed=seed, nonideal=nonideal, supply_MPa=supply).params, supply


def validation_forces(proto: Any) -> np.ndarray:
    """The plan's validation loads as tip forces (n, 2) N, ``m g (cos dir, sin dir)``."""
    from labcli.papers.takuma2014.protocol import load_plan
    from labcli.papers.takuma2014.sim.physics import G

    plan = load_plan(proto)
    val = plan[plan["set"] == "validation"]
    m, d = val["mass_g"].to_numpy(float) / 1000.0, np.radians(val["direction_deg"].to_numpy(float))
    return np.stack([m * G * np.cos(d), m * G * np.sin(d)], axis=1)


def levels(realism: str, repeat: float, only_repeat: bool = False) -> Any:
    """The rig's NonIdeal: the realism's levels with the repeatability scaled by ``repeat``, or
    (``only_repeat``) every effect off but the repeatability at the realism's level times ``repeat``."""
    from dataclasses import replace

    from labcli.papers.takuma2014.sim.nonideal import NonIdeal

    base = NonIdeal(realism=realism)
    if only_repeat:
        return replace(NonIdeal.ideal(realism), repeat=(base.repeat or 1.0) * repeat)
    return replace(base, repeat=base.repeat * repeat)


def measure_floor(
    seed: int, realism: str = "literature", repeat: float = 1.0, only_repeat: bool = False
) -> dict[str, Any]:
    """Per arm and variant, each validation trial's bound on each quantity's variance (rad^2, N^2):
    the realism's rig with its repeatability scaled by ``repeat`` (``only_repeat``: every other effect
    off; the friction band stays the realism's, for the friction map)."""
    nonideal = levels(realism, repeat, only_repeat)
    magnitudes = nonideal.magnitudes()
    fraction = float(levels(realism, repeat).magnitudes()["friction_fraction"])
    out: dict[str, Any] = {}
    for arm in ARMS:
        proto, params, supply = rig_of(arm, seed, nonideal)
        sd_p, sd_pot = reading_sd(proto, float(magnitudes["pressure_repeat_sd_MPa"]))
        maps = TrialMaps(params, supply)
        forces = validation_forces(proto)
        prior = float(np.sqrt(np.mean(forces**2)))  # the plan's spread of a force component
        floors = [trial_floor(maps, f, sd_p, sd_pot, prior, maps.friction_band(fraction)) for f in forces]
        for name in ALL_VARIANTS:
            var = np.array([f[name] for f in floors])
            for k, q in enumerate(quantities_of(name)):
                out[f"{arm}/{name}/{q}/var"] = var[:, k].tolist()
        out[f"{arm}/limit_N"] = float(proto.settings.sensing["max_force_se_N"])
    return out


def measure_empirical(seed: int, realism: str = "literature") -> dict[str, Any]:
    """The posture form's validation errors on the rig with only the repeatability on, and without it."""
    from sensing_accuracy import trials

    from labcli.papers.takuma2014.models.metrics import evaluate
    from labcli.papers.takuma2014.models.posture import PostureModel, limits_from_protocol
    from labcli.papers.takuma2014.sim.nonideal import NonIdeal

    out: dict[str, Any] = {}
    for level, nonideal in (("repeat", levels(realism, 1.0, True)), ("ideal", NonIdeal.ideal(realism))):
        for arm, name in ARMS.items():
            proto, table = trials(name, seed, rig_kw={"nonideal": nonideal})
            model = PostureModel(geometry=proto.settings.rig, limits=limits_from_protocol(proto), friction=False)
            ev = evaluate(model.fit(table), table)
            for q in QUANTITIES:
                err = np.asarray(ev["calculated"][q] - ev["observed"][q], dtype=float)
                out[f"{arm}/{level}/{q}/err"] = err.tolist()
    return out


# ----------------------------------------------------------------------------- figures


def _boot(per_seed: list[np.ndarray], stat: Callable[[np.ndarray], float], rng: Any) -> tuple[float, list[float]]:
    """``stat`` of the pooled values, and its 95 % interval from a bootstrap over seeds."""
    whole = stat(np.concatenate(per_seed))
    n = len(per_seed)
    boots = [stat(np.concatenate([per_seed[i] for i in rng.integers(0, n, n)])) for _ in range(BOOTSTRAP)]
    lo, hi = np.nanpercentile(boots, [2.5, 97.5])
    return whole, [float(lo), float(hi)]


def _scale(q: str) -> float:
    return math.degrees(1.0) if q.startswith("theta") else 1.0


def floor_figures(raw: dict[int, dict[str, Any]], issue: dict[str, Any]) -> dict[str, Any]:
    """The floor (deg, N) per arm, map and quantity with its interval; its ratio to the issue's
    estimator's RMSE (``issue``: the figures file, ``ARM/posture/Q/rmse_all``); Fy's trials whose
    floor standard error is within the protocol's limit."""
    rng = np.random.default_rng(20261127)
    seeds = sorted(raw)
    out: dict[str, Any] = {}
    for arm in ARMS:
        for name in ALL_VARIANTS:
            for q in quantities_of(name):
                var = [np.asarray(raw[s][f"{arm}/{name}/{q}/var"]) for s in seeds]
                rms, ci = _boot(var, lambda v: float(np.sqrt(np.mean(v))), rng)
                key = f"{arm}/{name}/{q}"
                out[f"{key}/floor"], out[f"{key}/floor_ci95"] = rms * _scale(q), [c * _scale(q) for c in ci]
                ref = issue.get(f"{arm}/posture/{q}/rmse_all")
                if ref is not None and q != "Fy":
                    out[f"{key}/over_issue"] = rms * _scale(q) / float(ref)
                    out[f"{key}/target_reachable"] = bool(rms * _scale(q) <= TARGET * float(ref))
        limit = float(raw[seeds[0]][f"{arm}/limit_N"])
        out[f"{arm}/Fy/limit_N"] = limit
        for name in ("statics", "statics_prior", "friction", "friction_prior"):
            sd_fy = np.sqrt(np.concatenate([np.asarray(raw[s][f"{arm}/{name}/Fy/var"]) for s in seeds]))
            out[f"{arm}/{name}/Fy/within_limit"] = int(np.sum(sd_fy <= limit))
            out[f"{arm}/{name}/Fy/se_median"] = float(np.median(sd_fy))
            out[f"{arm}/{name}/Fy/se_min"] = float(np.min(sd_fy))
        out[f"{arm}/Fy/trials"] = int(sd_fy.size)
    for arm in ARMS:
        for q in ANGLES + ("Fx",):
            out[f"{arm}/{q}/issue_rmse"] = float(issue[f"{arm}/posture/{q}/rmse_all"])
            out[f"{arm}/{q}/target"] = TARGET * float(issue[f"{arm}/posture/{q}/rmse_all"])
    return out


def empirical_figures(raw: dict[int, dict[str, Any]], floors: dict[int, dict[str, Any]]) -> dict[str, Any]:
    """RMSE on the rig with only the repeatability on and without it, the part it adds, the floor
    of that rig (statics and Boyle), each pooled over seeds with a bootstrap interval."""
    rng = np.random.default_rng(20261128)
    seeds = sorted(raw)
    out: dict[str, Any] = {}

    def rmse(v: np.ndarray) -> float:
        return float(np.sqrt(np.mean(v**2)))

    for arm in ARMS:
        for q in QUANTITIES:
            err = {lv: [np.asarray(raw[s][f"{arm}/{lv}/{q}/err"]) for s in seeds] for lv in ("repeat", "ideal")}
            for lv in ("repeat", "ideal"):  # evaluate's errors are in degrees and newtons
                v, ci = _boot(err[lv], rmse, rng)
                out[f"empirical/{arm}/{q}/{lv}_rmse"] = v
                out[f"empirical/{arm}/{q}/{lv}_rmse_ci95"] = ci
            added = math.sqrt(
                max(0.0, out[f"empirical/{arm}/{q}/repeat_rmse"] ** 2 - out[f"empirical/{arm}/{q}/ideal_rmse"] ** 2)
            )
            out[f"empirical/{arm}/{q}/added_by_repeat"] = added
            for name in ALL_VARIANTS:
                if q not in quantities_of(name):
                    continue
                var = np.concatenate([np.asarray(floors[s][f"{arm}/{name}/{q}/var"]) for s in seeds])
                out[f"empirical/{arm}/{q}/{name}_floor"] = float(np.sqrt(np.mean(var))) * _scale(q)
    return out


# ----------------------------------------------------------------------------- command


def _print(figs: dict[str, Any]) -> None:
    print("floor (statics / Boyle) against the issue's estimator, RMSE in deg and N [95 % interval]:")
    for arm in ARMS:
        for q in QUANTITIES:
            k = f"{arm}/statics/{q}"
            row = f"{arm:8s} {q:6s} statics {figs[f'{k}/floor']:.3f} [{figs[f'{k}/floor_ci95'][0]:.3f}, {figs[f'{k}/floor_ci95'][1]:.3f}]"
            row += f"  air known {figs[f'{arm}/statics_air/{q}/floor']:.3f}  prior {figs[f'{arm}/statics_prior/{q}/floor']:.3f}"
            row += f"  friction {figs[f'{arm}/friction/{q}/floor']:.3f} (+prior {figs[f'{arm}/friction_prior/{q}/floor']:.3f})"
            if q in ANGLES:
                b = f"{arm}/boyle/{q}"
                row += f"  boyle {figs[f'{b}/floor']:.3f} (x{figs[f'{b}/over_issue']:.2f} of the issue's)"
                row += f", air known {figs[f'{arm}/boyle_air/{q}/floor']:.3f}"
            if q != "Fy":
                row += f"  issue {figs[f'{arm}/{q}/issue_rmse']:.3f}, target {figs[f'{arm}/{q}/target']:.3f}"
            print(row)
        for name in ("statics", "statics_prior", "friction", "friction_prior"):
            k = f"{arm}/{name}/Fy"
            print(
                f"{arm:8s} Fy {name:15s} floor se median {figs[f'{k}/se_median']:.2f} N, min {figs[f'{k}/se_min']:.2f}; "
                f"within the {figs[f'{arm}/Fy/limit_N']:.1f} N limit on {figs[f'{k}/within_limit']} of {figs[f'{arm}/Fy/trials']}"
            )
    for k, v in figs.items():
        if k.startswith("empirical/") and not k.endswith("ci95"):
            print(f"{k:42s} {v:.3f}")


def main(argv: list[str] | None = None) -> None:
    from figures_file import cached, write_figures
    from rig_options import add_rig_options, bench_parser, seeds_text

    ap = bench_parser(__doc__)
    add_rig_options(ap, realism="literature", seeds="11-30")  # 11-30: the held-out seeds
    ap.add_argument("--repeat", type=float, default=1.0, help="scale of the repeatability (1: the realism's level)")
    ap.add_argument("--empirical", action="store_true", help="also the check on the rig with only the repeatability on")
    ap.add_argument("--cache", type=Path, default=None, help="JSON-lines file of measured seeds (resumable)")
    ap.add_argument(
        "--figures", "--json", dest="json", type=Path, default=ROOT / "docs" / "figures" / "pressure-floor.json"
    )
    args = ap.parse_args(argv)
    tag = f"{args.realism} repeat={args.repeat}"
    raw = cached(args.cache, f"floor {tag}", args.seeds, lambda s: measure_floor(s, args.realism, args.repeat))
    figs = floor_figures(raw, json.loads(ISSUE_FIGURES.read_text()))
    if args.empirical:
        only = f"floor-repeat-only {tag}"
        floors = cached(args.cache, only, args.seeds, lambda s: measure_floor(s, args.realism, args.repeat, True))
        emp = cached(args.cache, f"empirical {args.realism}", args.seeds, lambda s: measure_empirical(s, args.realism))
        figs.update(empirical_figures(emp, floors))
    _print(figs)
    meta = {"meta/seeds": seeds_text(args.seeds), "meta/realism": args.realism, "meta/repeat": args.repeat}
    write_figures(args.json, {**meta, "meta/bootstrap": BOOTSTRAP}, figs)


if __name__ == "__main__":
    main()
