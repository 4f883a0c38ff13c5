"""Link-length optimisation of the rPAM joint (Section IV of the rPAM joint paper).

Maximise the joint angle alpha at fixed pressures (Pa = 96 kPa, Pb = 41 kPa) over the link
lengths L1, L2, L3 under the paper's constraints and two that keep the joint holding:

- g1, the torque balance (Eq. 6), holds by construction: alpha *is* the balance's solution
  on the valid branch (:func:`labcli.papers.rpam2015.models.rpam.solve_equilibrium`); a design whose joint
  runs onto the toggle angle has no equilibrium and is infeasible.
- g2-g4 are the search box.
- g5, g6 (actuator lengths within 0.07-0.14 m) and g7 (0 <= alpha <= 90 deg) are penalties.
- K_min: the joint stiffness ``-d tau / d alpha`` at the balance must reach
  ``min_stiffness_Nm_per_rad``.  Maximising alpha alone drives the design to a fold of the
  balance (zero stiffness) or onto the toggle, the compliance and toggling the paper's
  Section V reports from its built joint.  The shipped value is the stiffness that keeps
  the link upright under its own weight (``m g d``; see the protocol).
- A margin to the toggle angle ``atan(L2 / L3)`` of at least ``min_toggle_margin_deg``.

Every feasible design costs -alpha_deg (in [-90, 0]) and every infeasible one more than
100, so the ranking never trades a violation for angle.  scipy's differential evolution
stands in for the paper's genetic algorithm; with a seed it is reproducible.  The whole
population is evaluated in one vectorised call per generation.

The optimum is reported as a :class:`DesignReport` (angle, margin, stiffness, both
actuators' forces and moment arms, active constraints), together with the design rounded
to 0.1 mm as printed (it must balance within :data:`ROUNDING_TOLERANCE_DEG` of the
optimum) and the paper's published design evaluated with the same model.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from ....core.keyspecs import Checker, show
from ....errors import ModelError
from ..protocol import checked_actuator, load_rpam, named, with_overrides
from ..settings import Bounds, OptimizeSettings, RpamSettings
from . import rpam

_TOGGLE_COST = 1000.0
_VIOLATION_COST = 100.0
_STEPS_PER_M = 10_000  # the printed design: links to 0.1 mm
ROUND_M = 1 / _STEPS_PER_M
ROUNDING_TOLERANCE_DEG = 0.5
_LINKS = ("L1", "L2", "L3")


@dataclass
class DesignReport:
    """One design at the optimiser's pressures: its balance and how it meets g1-g7 and K_min.

    Forces are the actuators' pushes (N), arms the signed moment arms (m); every balance
    quantity is NaN when the joint runs onto the toggle (``balanced`` False).
    """

    geometry: rpam.JointGeometry
    alpha_rad: float
    toggle_rad: float
    stiffness_Nm_per_rad: float
    L_a_m: float
    L_b_m: float
    F_a_N: float
    F_b_N: float
    arm_a_m: float
    arm_b_m: float
    active: list[str]
    violated: list[str]

    @property
    def alpha_deg(self) -> float:
        return math.degrees(self.alpha_rad)

    @property
    def toggle_margin_deg(self) -> float:
        """Degrees between the balance and the toggle angle atan(L2 / L3)."""
        return math.degrees(self.toggle_rad - self.alpha_rad)

    @property
    def balanced(self) -> bool:
        return math.isfinite(self.alpha_rad)

    @property
    def feasible(self) -> bool:
        return self.balanced and not self.violated

    def to_dict(self) -> dict[str, Any]:
        return {
            "L1_m": self.geometry.L1_m,
            "L2_m": self.geometry.L2_m,
            "L3_m": self.geometry.L3_m,
            "balanced": self.balanced,
            "alpha_deg": self.alpha_deg,
            "toggle_deg": math.degrees(self.toggle_rad),
            "toggle_margin_deg": self.toggle_margin_deg,
            "stiffness_Nm_per_rad": self.stiffness_Nm_per_rad,
            "L_a_m": self.L_a_m,
            "L_b_m": self.L_b_m,
            "F_a_N": self.F_a_N,
            "F_b_N": self.F_b_N,
            "arm_a_m": self.arm_a_m,
            "arm_b_m": self.arm_b_m,
            "active_constraints": list(self.active),
            "violated_constraints": list(self.violated),
            "feasible": self.feasible,
        }


@dataclass
class OptimumResult:
    """The optimum design, the same design rounded as printed, and the paper's design beside it."""

    optimum: DesignReport
    rounded: DesignReport
    paper: DesignReport | None
    settings: OptimizeSettings
    nit: int
    nfev: int
    message: str
    history: list[dict[str, float]] = field(default_factory=list)
    force_reading: str = "derived"
    # Where the actuator came from: "protocol", or the stretch fit (a path) it was fitted in.
    actuator_source: str = "protocol"
    actuator: rpam.Actuator | None = None

    @property
    def geometry(self) -> rpam.JointGeometry:
        return self.optimum.geometry

    @property
    def alpha_rad(self) -> float:
        return self.optimum.alpha_rad

    @property
    def alpha_deg(self) -> float:
        return self.optimum.alpha_deg

    @property
    def toggle_rad(self) -> float:
        return self.optimum.toggle_rad

    @property
    def toggle_margin_deg(self) -> float:
        return self.optimum.toggle_margin_deg

    @property
    def active(self) -> list[str]:
        return self.optimum.active

    def to_dict(self) -> dict[str, Any]:
        s = self.settings
        d = self.optimum.to_dict()
        for key in ("balanced", "violated_constraints", "feasible"):
            del d[key]  # an optimum always balances and meets its constraints
        return _nan_to_none(
            {
                **d,
                "Pa_kPa": s.Pa_MPa * 1e3,
                "Pb_kPa": s.Pb_MPa * 1e3,
                "min_stiffness_Nm_per_rad": s.min_stiffness_Nm_per_rad,
                "min_toggle_margin_deg": s.min_toggle_margin_deg,
                "rounded": {"resolution_m": ROUND_M, **self.rounded.to_dict()},
                "paper": None
                if self.paper is None
                else {"reported_alpha_deg": s.paper_alpha_deg, **self.paper.to_dict()},
                "seed": s.seed,
                "popsize": s.popsize,
                "maxiter": s.maxiter,
                "stretch_correction": s.stretch_correction,
                "force_reading": self.force_reading,
                "actuator_source": self.actuator_source,
                "actuator": self.actuator.to_dict() if self.actuator is not None else None,
                "generations": self.nit,
                "evaluations": self.nfev,
                "message": self.message,
            }
        )


def _nan_to_none(x: Any) -> Any:
    if isinstance(x, float) and not math.isfinite(x):
        return None
    if isinstance(x, dict):
        return {k: _nan_to_none(v) for k, v in x.items()}
    return x


def optimizer_settings(settings: RpamSettings, source: str) -> tuple[Bounds, OptimizeSettings]:
    """The protocol's ``[joint.bounds]`` and ``[optimize]``, refused in one sentence (naming
    ``source``) when they are missing or allow a joint that holds nothing."""
    chk = Checker(source)
    if settings.bounds is None:
        chk.fail("missing key 'joint.bounds', expected a table (the link and angle bounds g2-g7 of Section IV).")
    o = settings.optimize
    if o is None:
        chk.fail("missing key 'optimize', expected a table [optimize] (the pressures and settings of the search).")
    if o.min_stiffness_Nm_per_rad is None:
        chk.fail(
            "missing key 'optimize.min_stiffness_Nm_per_rad', expected a number in N m/rad "
            "(the least joint stiffness at the balance)."
        )
    # Both must be positive: a design at the toggle or with no stiffness holds nothing.
    for key in ("min_toggle_margin_deg", "min_stiffness_Nm_per_rad"):
        value = getattr(o, key)
        if not value > 0:
            chk.fail(f"key 'optimize.{key}' must be greater than 0, not {show(value)}.")
    return settings.bounds, o


def _shortfalls(
    alpha_deg: Any, toggle_deg: Any, L_a: Any, L_b: Any, stiffness: Any, bounds: Bounds, settings: OptimizeSettings
) -> dict[str, np.ndarray]:
    """How far a balanced design misses g5-g7, the toggle margin and K_min (0 where met).

    In each constraint's own unit: m (g5, g6), deg (g7, margin), N m/rad (K_min).
    """
    lo, hi = bounds.actuator_length_m
    a_lo, a_hi = bounds.alpha_deg

    def outside(v: Any, low: float, high: float) -> np.ndarray:
        return np.clip(low - v, 0.0, None) + np.clip(v - high, 0.0, None)

    return {
        "g5": outside(L_a, lo, hi),
        "g6": outside(L_b, lo, hi),
        "g7": outside(alpha_deg, a_lo, a_hi),
        "margin": np.clip(settings.min_toggle_margin_deg - (toggle_deg - alpha_deg), 0.0, None),
        "K_min": np.clip(settings.k_min - stiffness, 0.0, None),
    }


def _balance(X: np.ndarray, act: rpam.Actuator, settings: OptimizeSettings) -> dict[str, np.ndarray]:
    """Balance of designs ``X = (L1, L2, L3)`` of shape ``(3, S)``: angle, stiffness, lengths, forces, arms.

    The one evaluation behind both the optimiser's cost and the reports, so that a design
    the search accepted is reported as meeting its constraints to the last digit.
    """
    geom = rpam.JointGeometry(X[0], X[1], X[2])
    P = (settings.Pa_MPa, settings.Pb_MPa)
    stretch = settings.stretch_correction
    eq = rpam.solve_equilibrium(*P, geom, act, stretch=stretch)
    ma, mb = rpam.moment_arms(eq.alpha_rad, geom)
    return {
        "alpha_rad": eq.alpha_rad,
        "toggle_rad": eq.toggle_rad,
        "L_a_m": eq.L_a_m,
        "L_b_m": eq.L_b_m,
        "stiffness": rpam.joint_stiffness(eq.alpha_rad, *P, geom, act, stretch=stretch),
        "F_a_N": rpam.push_force(P[0], eq.L_a_m, act, stretch=stretch),
        "F_b_N": rpam.push_force(P[1], eq.L_b_m, act, stretch=stretch),
        "arm_a_m": ma,
        "arm_b_m": mb,
    }


def _misses(b: dict[str, np.ndarray], bounds: Bounds, settings: OptimizeSettings) -> dict[str, np.ndarray]:
    alpha = np.degrees(b["alpha_rad"])
    return _shortfalls(alpha, np.degrees(b["toggle_rad"]), b["L_a_m"], b["L_b_m"], b["stiffness"], bounds, settings)


def design_cost(x: np.ndarray, act: rpam.Actuator, bounds: Bounds, settings: OptimizeSettings) -> np.ndarray:
    """Cost of designs ``x = (L1, L2, L3)``, shape ``(3,)`` or ``(3, S)``: -alpha_deg or a penalty."""
    x = np.asarray(x, dtype=float)
    single = x.ndim == 1
    b = _balance(x.reshape(3, -1), act, settings)
    alpha = np.degrees(b["alpha_rad"])
    miss = _misses(b, bounds, settings)
    # Scale so that 1 mm, 1 deg and a tenth of K_min weigh alike.
    violation = 1e3 * (miss["g5"] + miss["g6"]) + miss["g7"] + miss["margin"] + 10 * miss["K_min"] / settings.k_min
    cost = np.where(violation > 0, _VIOLATION_COST + violation, -alpha)
    cost = np.where(np.isfinite(alpha), cost, _TOGGLE_COST)
    return cost[0] if single else cost


def evaluate_design(
    geom: rpam.JointGeometry, act: rpam.Actuator, bounds: Bounds, settings: OptimizeSettings
) -> DesignReport:
    """Balance, stiffness, forces and arms of one design, and the constraints it meets or misses."""
    b = {k: float(v[0]) for k, v in _balance(np.array([[geom.L1_m], [geom.L2_m], [geom.L3_m]]), act, settings).items()}
    K, La, Lb = b["stiffness"], b["L_a_m"], b["L_b_m"]
    report = DesignReport(
        geometry=geom,
        alpha_rad=b["alpha_rad"],
        toggle_rad=b["toggle_rad"],
        stiffness_Nm_per_rad=K,
        L_a_m=La,
        L_b_m=Lb,
        F_a_N=b["F_a_N"],
        F_b_N=b["F_b_N"],
        arm_a_m=b["arm_a_m"],
        arm_b_m=b["arm_b_m"],
        active=[],
        violated=[],
    )
    box = [
        (f"g{i + 2}", name, getattr(geom, f"{name}_m"), getattr(bounds, f"{name}_m")) for i, name in enumerate(_LINKS)
    ]
    for g, name, v, (lo, hi) in box:
        if not lo - 1e-12 <= v <= hi + 1e-12:
            report.violated.append(f"{g}: {name} = {v:.4f} m outside {lo:g}-{hi:g} m")
    if not report.balanced:
        report.violated.insert(0, "g1: no balance below the toggle angle, the joint runs onto it")
        return report
    miss = _misses({k: np.asarray(v) for k, v in b.items()}, bounds, settings)
    lo, hi = bounds.actuator_length_m
    texts = {
        "g5": f"g5: L_a = {La:.4f} m outside {lo:g}-{hi:g} m",
        "g6": f"g6: L_b = {Lb:.4f} m outside {lo:g}-{hi:g} m",
        "g7": f"g7: alpha = {report.alpha_deg:.2f} deg outside {bounds.alpha_deg[0]:g}-{bounds.alpha_deg[1]:g} deg",
        "margin": f"toggle margin {report.toggle_margin_deg:.2f} deg below {settings.min_toggle_margin_deg:g} deg",
        "K_min": f"K_min: stiffness {K:.4f} N m/rad below {settings.k_min:g} N m/rad",
    }
    report.violated.extend(texts[k] for k, v in miss.items() if float(v) > 0)
    report.active.extend(active_constraints(geom, report.alpha_deg, La, Lb, bounds, settings.active_tolerance))
    # The holding constraints, within the same relative tolerance of their bound.
    tol = settings.active_tolerance
    if abs(K - settings.k_min) <= tol * settings.k_min:
        report.active.append(f"K_min: stiffness at its minimum {settings.k_min:g} N m/rad")
    if abs(report.toggle_margin_deg - settings.min_toggle_margin_deg) <= tol * max(settings.min_toggle_margin_deg, 1.0):
        report.active.append(f"toggle margin at its minimum {settings.min_toggle_margin_deg:g} deg")
    return report


def active_constraints(
    geom: rpam.JointGeometry, alpha_deg: float, L_a: float, L_b: float, bounds: Bounds, tol: float
) -> list[str]:
    """Names like ``"g2: L1 at lower bound 0.03 m"`` for every bound met within ``tol`` of its range."""
    out = []
    checks = (
        ("g2", "L1", float(geom.L1_m), bounds.L1_m, "m"),
        ("g3", "L2", float(geom.L2_m), bounds.L2_m, "m"),
        ("g4", "L3", float(geom.L3_m), bounds.L3_m, "m"),
        ("g5", "L_a", L_a, bounds.actuator_length_m, "m"),
        ("g6", "L_b", L_b, bounds.actuator_length_m, "m"),
        ("g7", "alpha", alpha_deg, bounds.alpha_deg, "deg"),
    )
    for g, name, v, (lo, hi), unit in checks:
        width = tol * (hi - lo)
        if abs(v - lo) <= width:
            out.append(f"{g}: {name} at lower bound {lo:g} {unit}")
        elif abs(v - hi) <= width:
            out.append(f"{g}: {name} at upper bound {hi:g} {unit}")
    return out


def round_design(optimum: DesignReport, act: rpam.Actuator, bounds: Bounds, settings: OptimizeSettings) -> DesignReport:
    """The design as printed: links on the :data:`ROUND_M` grid, evaluated.

    At the optimum the stiffness and length constraints are typically active, so rounding
    each link to the nearest 0.1 mm can leave the design just infeasible; the printed
    design is the best feasible grid point within two steps of the optimum in every link
    (the nearest grid point when none is feasible).  Raises :class:`ModelError` when it
    does not balance within :data:`ROUNDING_TOLERANCE_DEG` of the optimum.
    """
    g = optimum.geometry
    centre = np.rint(np.array([g.L1_m, g.L2_m, g.L3_m]) * _STEPS_PER_M)
    steps = np.array(np.meshgrid(*[np.arange(-2, 3)] * 3, indexing="ij")).reshape(3, -1)
    # Whole steps divided out, so each link is the double nearest its printed digits.
    grid = (centre[:, None] + steps) / _STEPS_PER_M
    box = (bounds.L1_m, bounds.L2_m, bounds.L3_m)
    nearest = np.all(steps == 0, axis=0)
    keep = np.all([(lo <= x) & (x <= hi) for x, (lo, hi) in zip(grid, box, strict=False)], axis=0) | nearest
    grid, nearest = grid[:, keep], nearest[keep]
    cost = design_cost(grid, act, bounds, settings)
    pick = int(np.argmin(cost)) if cost.min() <= 0 else int(np.flatnonzero(nearest)[0])
    best = evaluate_design(rpam.JointGeometry(*(float(v) for v in grid[:, pick])), act, bounds, settings)
    if not (best.balanced and abs(best.alpha_deg - optimum.alpha_deg) <= ROUNDING_TOLERANCE_DEG):
        found = f"balances at {best.alpha_deg:.2f} deg" if best.balanced else "has no balance"
        raise ModelError(
            f"The optimum (alpha = {optimum.alpha_deg:.2f} deg) is too sensitive to build: on a "
            f"{ROUND_M * 1e3:g} mm grid the best design {found}; raise optimize.min_stiffness_Nm_per_rad."
        )
    return best


Progress = Callable[[int, dict[str, float]], None]


def optimize_joint(
    act: rpam.Actuator,
    bounds: Bounds,
    settings: OptimizeSettings,
    *,
    progress: Progress | None = None,
) -> OptimumResult:
    """Run differential evolution; ``progress(generation, best)`` is called after each generation.

    ``best`` holds ``L1_m, L2_m, L3_m, alpha_deg, convergence`` of the best design so far
    (alpha NaN while no design is feasible) and the generation limit ``maxiter``.
    Raises :class:`ModelError` when no design satisfies g1-g7, the toggle margin and K_min.
    """
    from scipy.optimize import differential_evolution

    history: list[dict[str, float]] = []

    def cost(x: np.ndarray) -> np.ndarray:
        return design_cost(x, act, bounds, settings)

    def callback(xk: np.ndarray, convergence: float = 0.0) -> None:
        c = float(cost(np.asarray(xk)))
        best = {
            "L1_m": float(xk[0]),
            "L2_m": float(xk[1]),
            "L3_m": float(xk[2]),
            "alpha_deg": -c if c <= 0 else float("nan"),
            "convergence": float(convergence),
            "maxiter": float(settings.maxiter),
        }
        history.append(best)
        if progress is not None:
            progress(len(history), best)

    res = differential_evolution(
        cost,
        bounds=[bounds.L1_m, bounds.L2_m, bounds.L3_m],
        seed=settings.seed,
        popsize=settings.popsize,
        maxiter=settings.maxiter,
        tol=settings.tol,
        mutation=settings.mutation,
        recombination=settings.recombination,
        callback=callback,
        polish=True,
        vectorized=True,
        updating="deferred",
    )
    if not res.fun <= 0:
        raise ModelError(
            f"No link lengths within g2-g4 give a balanced joint (g1) that also meets g5-g7, a toggle margin of "
            f"{settings.min_toggle_margin_deg:g} deg and a stiffness of {settings.k_min:g} N m/rad "
            f"at Pa = {settings.Pa_MPa * 1e3:g} kPa, Pb = {settings.Pb_MPa * 1e3:g} kPa; "
            "check the pressures and the actuator constants."
        )
    optimum = evaluate_design(rpam.JointGeometry(*(float(v) for v in res.x)), act, bounds, settings)
    if not optimum.feasible:  # the penalties make this unreachable; a guard, not a path
        raise ModelError(f"The optimiser returned a design that misses {'; '.join(optimum.violated)}.")
    paper = None
    if settings.paper_links_m is not None:
        paper = evaluate_design(rpam.JointGeometry(*settings.paper_links_m), act, bounds, settings)
    return OptimumResult(
        optimum=optimum,
        rounded=round_design(optimum, act, bounds, settings),
        paper=paper,
        settings=settings,
        nit=int(res.nit),
        nfev=int(res.nfev),
        message=str(res.message),
        history=history,
        force_reading=act.force_reading,
        actuator=act,
    )


def optimize_protocol(
    path_or_name: str | Path,
    *,
    overrides: tuple[str, ...] | list[str] = (),
    seed: int | None = None,
    Pa_kPa: float | None = None,
    Pb_kPa: float | None = None,
    force: str | None = None,
    min_stiffness: float | None = None,
    progress: Progress | None = None,
    actuator: tuple[str, rpam.Actuator] | None = None,
) -> OptimumResult:
    """Load an rPAM protocol, apply ``key=value`` overrides, and optimise its joint.

    ``force`` reads the actuator's force the other way (``"derived"`` or ``"paper"``,
    default the protocol's); ``min_stiffness`` (N m/rad) replaces the protocol's K_min;
    ``actuator`` is ``(where it was fitted, the lab's fitted actuator)``, which replaces the
    protocol's actuator, Ogden wall and stretch correction, reading included.
    """
    if actuator is not None:
        where, fitted = actuator
        mixed = [a for a in overrides if a.split("=", 1)[0].strip().split(".", 1)[0] in _ACTUATOR_TABLES]
        if mixed:
            raise ModelError(
                f"--set {mixed[0]} changes the protocol's actuator, which the fitted actuator of {where} replaces; "
                "leave out one or the other."
            )
        if force is not None and force != fitted.force_reading:
            raise ModelError(
                f"The actuator of {where} was fitted with the {fitted.force_reading} force reading, so its moduli "
                f"belong to it; optimise with --force {fitted.force_reading}, or fit the stretch test again with "
                f"--force {force}."
            )
    base = load_rpam(path_or_name)
    extra = list(overrides)
    if seed is not None:
        extra.append(f"optimize.seed={int(seed)}")
    if Pa_kPa is not None:
        extra.append(f"optimize.Pa_kPa={float(Pa_kPa)!r}")
    if Pb_kPa is not None:
        extra.append(f"optimize.Pb_kPa={float(Pb_kPa)!r}")
    # A value set on the command line is not in the file: say so when it is the one refused.
    label = named(base.path) if overrides else base.source_label
    proto = with_overrides(base, extra, label, shown=overrides)
    source = f"{label} with --set {' '.join(overrides)}" if overrides else label
    act = checked_actuator(proto.settings, source).with_force_reading(force)
    if actuator is not None:
        act = actuator[1]
    if min_stiffness is not None:
        if not (math.isfinite(min_stiffness) and min_stiffness > 0):
            raise ModelError(
                f"--min-stiffness must be greater than 0 N m/rad, not {min_stiffness:g}: a joint with no stiffness "
                "holds nothing."
            )
        if proto.settings.optimize is not None:
            proto = replace(
                proto,
                settings=replace(
                    proto.settings, optimize=replace(proto.settings.optimize, min_stiffness_Nm_per_rad=min_stiffness)
                ),
            )
    bounds, settings = optimizer_settings(proto.settings, source)
    result = optimize_joint(act, bounds, settings, progress=progress)
    if actuator is not None:
        result.actuator_source = actuator[0]
    return result


# The protocol's tables the fitted actuator of --actuator replaces.
_ACTUATOR_TABLES = ("actuator", "ogden", "stretch_correction")
