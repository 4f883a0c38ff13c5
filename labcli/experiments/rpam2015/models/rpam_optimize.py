"""Link-length optimisation of the rPAM joint (Section IV of the rPAM joint paper).

Maximise the joint angle alpha at fixed pressures (Pa = 96 kPa, Pb = 41 kPa) over the link
lengths L1, L2, L3 under the paper's constraints:

- g1, the torque balance (Eq. 6), holds by construction: alpha *is* the balance's solution
  on the valid branch (:func:`labcli.experiments.rpam2015.models.rpam.solve_equilibrium`); a design whose joint
  runs onto the toggle angle has no equilibrium and is infeasible.
- g2-g4 are the search box.
- g5, g6 (actuator lengths within 0.07-0.14 m), g7 (0 <= alpha <= 90 deg) and, when
  asked for, a minimum distance from the toggle angle (not in the paper; 0 by default) are
  penalties: every feasible design costs -alpha_deg (in [-90, 0]) and every infeasible one
  costs more than 100, so the ranking never trades a violation for angle.

scipy's differential evolution stands in for the paper's genetic algorithm; with a seed it
is reproducible.  The whole population is evaluated in one vectorised call per generation.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

import numpy as np

from ....errors import ConfigError, ModelError
from ..protocol import read_rpam_protocol
from . import rpam

_TOGGLE_COST = 1000.0
_VIOLATION_COST = 100.0


@dataclass(frozen=True)
class Bounds:
    """g2-g7 of Section IV, SI except the angle bounds (degrees, as printed)."""

    L1_m: tuple[float, float]
    L2_m: tuple[float, float]
    L3_m: tuple[float, float]
    actuator_length_m: tuple[float, float]
    alpha_deg: tuple[float, float]


@dataclass(frozen=True)
class OptimizeSettings:
    """Pressures of the optimisation and the differential-evolution settings."""

    Pa_MPa: float
    Pb_MPa: float
    seed: int
    popsize: int = 20
    maxiter: int = 300
    tol: float = 1e-6
    mutation: tuple[float, float] = (0.5, 1.0)
    recombination: float = 0.7
    active_tolerance: float = 0.005
    stretch_correction: bool = True
    min_toggle_margin_deg: float = 0.0


@dataclass
class OptimumResult:
    """The optimum design and how it sits against its constraints."""

    geometry: rpam.JointGeometry
    alpha_rad: float
    toggle_rad: float
    L_a_m: float
    L_b_m: float
    active: list[str]
    settings: OptimizeSettings
    nit: int
    nfev: int
    message: str
    history: list[dict[str, float]] = field(default_factory=list)

    @property
    def alpha_deg(self) -> float:
        return math.degrees(self.alpha_rad)

    @property
    def toggle_margin_deg(self) -> float:
        """Degrees between the optimum and the toggle angle atan(L2 / L3)."""
        return math.degrees(self.toggle_rad - self.alpha_rad)

    def to_dict(self) -> dict[str, Any]:
        s = self.settings
        return {
            "L1_m": self.geometry.L1_m,
            "L2_m": self.geometry.L2_m,
            "L3_m": self.geometry.L3_m,
            "alpha_deg": self.alpha_deg,
            "toggle_deg": math.degrees(self.toggle_rad),
            "toggle_margin_deg": self.toggle_margin_deg,
            "L_a_m": self.L_a_m,
            "L_b_m": self.L_b_m,
            "active_constraints": list(self.active),
            "Pa_kPa": s.Pa_MPa * 1e3,
            "Pb_kPa": s.Pb_MPa * 1e3,
            "seed": s.seed,
            "popsize": s.popsize,
            "maxiter": s.maxiter,
            "stretch_correction": s.stretch_correction,
            "generations": self.nit,
            "evaluations": self.nfev,
            "message": self.message,
        }


def settings_from_protocol(raw: dict[str, Any], path: Path | str = "<protocol>") -> tuple[Bounds, OptimizeSettings]:
    """The ``[joint.bounds]`` and ``[optimize]`` tables as typed settings."""
    r = rpam._range
    bounds = Bounds(
        L1_m=r(raw, "joint.bounds.L1_m", path),
        L2_m=r(raw, "joint.bounds.L2_m", path),
        L3_m=r(raw, "joint.bounds.L3_m", path),
        actuator_length_m=r(raw, "joint.bounds.actuator_length_m", path),
        alpha_deg=r(raw, "joint.bounds.alpha_deg", path),
    )
    if any(lo <= 0 for lo in (bounds.L1_m[0], bounds.L2_m[0], bounds.L3_m[0])):
        raise ConfigError(f"Link-length bounds in {rpam.where(path)} must be positive.")
    seed = rpam._get(raw, "optimize.seed", path)
    popsize = rpam._get(raw, "optimize.popsize", path)
    maxiter = rpam._get(raw, "optimize.maxiter", path)
    for key, v in (("seed", seed), ("popsize", popsize), ("maxiter", maxiter)):
        if not isinstance(v, int) or isinstance(v, bool) or v < (0 if key == "seed" else 1):
            raise ConfigError(f"Protocol key 'optimize.{key}' in {rpam.where(path)} must be a whole number, got {v!r}.")
    stretch = rpam._get(raw, "optimize.stretch_correction", path)
    if not isinstance(stretch, bool):
        raise ConfigError(f"Protocol key 'optimize.stretch_correction' in {rpam.where(path)} must be true or false.")
    settings = OptimizeSettings(
        Pa_MPa=rpam._num(raw, "optimize.Pa_kPa", path, positive=False) / 1e3,
        Pb_MPa=rpam._num(raw, "optimize.Pb_kPa", path, positive=False) / 1e3,
        seed=seed,
        popsize=popsize,
        maxiter=maxiter,
        tol=rpam._num(raw, "optimize.tol", path),
        mutation=rpam._nums(raw, "optimize.mutation", path, 2),  # type: ignore[arg-type]
        recombination=rpam._num(raw, "optimize.recombination", path),
        active_tolerance=rpam._num(raw, "optimize.active_tolerance", path),
        stretch_correction=stretch,
        min_toggle_margin_deg=rpam._num(raw, "optimize.min_toggle_margin_deg", path, positive=False),
    )
    if settings.min_toggle_margin_deg < 0:
        raise ConfigError(f"Protocol key 'optimize.min_toggle_margin_deg' in {rpam.where(path)} must not be negative.")
    return bounds, settings


def design_cost(
    x: np.ndarray, act: rpam.Actuator, bounds: Bounds, settings: OptimizeSettings
) -> np.ndarray:
    """Cost of designs ``x = (L1, L2, L3)``, shape ``(3,)`` or ``(3, S)``: -alpha_deg or a penalty."""
    x = np.asarray(x, dtype=float)
    single = x.ndim == 1
    X = x.reshape(3, -1)
    eq = rpam.solve_equilibrium(
        settings.Pa_MPa, settings.Pb_MPa, rpam.JointGeometry(X[0], X[1], X[2]), act,
        stretch=settings.stretch_correction,
    )
    alpha = eq.alpha_deg
    lo, hi = bounds.actuator_length_m
    a_lo, a_hi = bounds.alpha_deg
    violation = sum(
        np.clip(v, 0.0, None)
        for v in (lo - eq.L_a_m, eq.L_a_m - hi, lo - eq.L_b_m, eq.L_b_m - hi)
    )
    # Lengths in metres, angles in degrees: scale so a 1 mm or 1 deg violation weigh alike.
    violation = 1e3 * violation + np.clip(a_lo - alpha, 0.0, None) + np.clip(alpha - a_hi, 0.0, None)
    # Optional margin from the toggle (the paper's problem has none: 0 deg).
    margin = np.degrees(eq.toggle_rad) - alpha
    violation = violation + np.clip(settings.min_toggle_margin_deg - margin, 0.0, None)
    cost = np.where(violation > 0, _VIOLATION_COST + violation, -alpha)
    cost = np.where(np.isfinite(alpha), cost, _TOGGLE_COST)
    return cost[0] if single else cost


def active_constraints(
    geom: rpam.JointGeometry, alpha_deg: float, L_a: float, L_b: float, bounds: Bounds, tol: float
) -> list[str]:
    """Names like ``"g2: L1 at lower bound 0.03 m"`` for every bound met within ``tol`` of its range."""
    out = []
    checks = (
        ("g2", "L1", geom.L1_m, bounds.L1_m, "m"),
        ("g3", "L2", geom.L2_m, bounds.L2_m, "m"),
        ("g4", "L3", geom.L3_m, bounds.L3_m, "m"),
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
    Raises :class:`ModelError` when no design satisfies g1-g7.
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
            f"No link lengths within g2-g4 give a balanced joint (g1) that also meets g5-g7 at "
            f"Pa = {settings.Pa_MPa * 1e3:g} kPa, Pb = {settings.Pb_MPa * 1e3:g} kPa; "
            "check the pressures and the actuator constants."
        )
    geom = rpam.JointGeometry(*(float(v) for v in res.x))
    alpha = rpam.equilibrium_angle(settings.Pa_MPa, settings.Pb_MPa, geom, act, stretch=settings.stretch_correction)
    La, Lb = (float(v) for v in rpam.actuator_lengths(alpha, geom))
    return OptimumResult(
        geometry=geom,
        alpha_rad=alpha,
        toggle_rad=float(rpam.toggle_angle(geom)),
        L_a_m=La,
        L_b_m=Lb,
        active=active_constraints(geom, math.degrees(alpha), La, Lb, bounds, settings.active_tolerance),
        settings=settings,
        nit=int(res.nit),
        nfev=int(res.nfev),
        message=str(res.message),
        history=history,
    )


def optimize_protocol(
    path_or_name: str | Path,
    *,
    overrides: tuple[str, ...] | list[str] = (),
    seed: int | None = None,
    Pa_kPa: float | None = None,
    Pb_kPa: float | None = None,
    progress: Progress | None = None,
) -> OptimumResult:
    """Load an rPAM protocol, apply ``key=value`` overrides, and optimise its joint."""
    path, raw = read_rpam_protocol(path_or_name)
    extra = list(overrides)
    if seed is not None:
        extra.append(f"optimize.seed={int(seed)}")
    if Pa_kPa is not None:
        extra.append(f"optimize.Pa_kPa={float(Pa_kPa)!r}")
    if Pb_kPa is not None:
        extra.append(f"optimize.Pb_kPa={float(Pb_kPa)!r}")
    raw = rpam.apply_overrides(raw, extra)
    # A value set on the command line is not in the file: say so when it is the one refused.
    where = f"{rpam.where(path)} with --set {' '.join(overrides)}" if overrides else path
    act = rpam.actuator_from_protocol(raw, where)
    bounds, settings = settings_from_protocol(raw, where)
    return optimize_joint(act, bounds, settings, progress=progress)
