"""The reverse pneumatic artificial muscle (rPAM) and its 1-DoF antagonistic joint.

Model of Sections II-III of the rPAM joint paper ("Optimized Design of a Rigid Kinematic
Module for Antagonistic Soft Actuation", 2015), with its misprints (Eq. 2's dimensions,
Eq. 5's undefined L23 and its (S_b - L_a)) resolved as documented here.  Pure numpy; scipy
only inside the functions that need it.  Units: SI (m, m^2, N, rad); pressures and moduli
in MPa (gauge), as everywhere in labcli.

Joint geometry (Eq. 4, Table I, Fig. 4)
    The pivot O is the origin, on the bottom plate.  The lower swivel mounts sit at
    ``a_low = (-L1, 0)`` (actuator a) and ``b_low = (+L1, 0)`` (actuator b), which is what
    Eq. 4's ``(a_x + L1)`` and ``(b_x - L1)`` say.  The upper plate carries m, a, b of
    Table I: at alpha = 0, ``m = (0, L2)``, ``a = (-L3, L2)``, ``b = (+L3, L2)``.  Positive
    alpha turns the upper plate clockwise (m moves to +x), lengthens a and shortens b, so a
    push of a raises alpha and a push of b lowers it.  The paper's optimiser maximises
    alpha with Pa > Pb and g7 says 0 <= alpha <= 90 deg; its printed "-58.4 deg" is the
    cost (-alpha), read here as alpha = +58.4 deg.

Moment arms (Eq. 5)
    Heron's formula on the triangles (O, a_low, a) and (O, b_low, b) with
    ``L23 = sqrt(L2^2 + L3^2) = |O a| = |O b|``; the printed ``(S_b - L_a)`` is read as
    ``(S_b - L_b)``.  Heron gives an unsigned height.  The signed arm used by the solver is
    the exact point-to-line distance with the sign of the cross product,
    ``m_a = L1 a_y / L_a`` and ``m_b = L1 b_y / L_b``: positive on the valid branch.
    ``b_y = L2 cos(alpha) - L3 sin(alpha)`` vanishes at the toggle angle
    ``alpha_t = atan(L2 / L3)``, where the line of b passes through O; beyond it Heron's
    height grows again (a spurious branch) while the true arm changes sign and b's push
    drives the joint further instead of holding it.  By symmetry a toggles at -alpha_t.
    The solver only ever brackets roots inside ``(-alpha_t, alpha_t)``.

Actuator force (Eqs. 1-3, 7), tension-positive as in Eq. 1
    ``F_ext = F_cons + F_int + F_stretch`` is the tensile load that holds the actuator at
    length L under gauge pressure P; the force it exerts on the joint (its push) is
    ``-F_ext``.  ``F_cons + F_int`` has two readings, named by ``act.force_reading``
    (:mod:`labcli.papers.rpam2015.models.rpam_force`, where both derivations are written
    out).  The paper's (``"paper"``) is the lumen's free body,

        F_cons = P (3 L^2 - b^2) / (4 pi n^2) + P A0 / lambda,     F_int = Eq. 3 (uniaxial),

    and the derived one (``"derived"``, the default) comes from the potential of the
    helix-constrained Ogden wall and the gas.  In brief, while the gas holds the wall on the
    thread cage
    (every pressure above about 10 kPa for the shipped actuator):

        F_cons = -P dV_c/dL = P (3 L^2 - b^2) / (4 pi n^2),     F_int = dU_wall/dL,

    with ``V_c = L (b^2 - L^2) / (4 pi n^2)`` the volume a thread of length b in n turns
    encloses at length L and ``U_wall`` the Ogden strain energy of a wall stretched axially
    to ``lambda = L / L0`` while the cage sets its radius.  Eq. 2 as printed,
    ``P (3 L^2 / (4 pi n^2) - 1 - A0 / lambda)``, subtracts the number 1 from an area (the
    "1" stands where ``b^2 / (4 pi n^2)`` must be) and carries a wall term ``A0 / lambda``
    that virtual work does not give: the incompressible wall keeps its volume inside the
    cage, so the gas volume changes exactly as the cage's.  The rPAM's threads are wound as
    small-pitch helices that approximate hoops, so ``L << b / sqrt 3`` (about 86 deg from
    the axis for the shipped actuator): the cage term is negative, the cage pushes, and the
    actuator extends when pressurised; in the hoop limit it tends to the full end-cap force
    ``-P pi r^2``.  With the cage slack (low pressure, stretched wall) the tube is free and
    at P = 0 ``F_int`` is Eq. 3 exactly, ``sum 2 mu_i A0 / alpha_i (lambda^(alpha_i - 1) -
    lambda^(-alpha_i / 2 - 1))`` (:func:`material_force`).

    Stretch correction (Eq. 7): ``F_stretch = c0 + c1 lambda + c2 lambda^2 + c3 lambda^3``
    (newtons), an empirical fit to a stretch test; lambda is clamped to the range the fit
    was made on, so the polynomial is never extrapolated.

Torque balance (Eq. 6)
    ``tau(alpha) = F_a m_a - F_b m_b`` with F the pushes; tau > 0 drives alpha up.  A joint
    released at alpha = 0 moves in the direction of tau(0) until tau changes sign: the
    equilibrium is the first such crossing (a stable one: tau goes from + to - along the
    way).  No crossing before the toggle angle means the joint runs onto the toggle and has
    no equilibrium on the valid branch: the angle is NaN and the status says "toggle".
    The crossing is bracketed on a grid from 0 to just short of the toggle and refined by a
    vectorised bracketed root finder (Illinois regula falsi with bisection steps), so a
    whole pressure map or optimiser population is solved in one call;
    :func:`equilibrium_angle` polishes a single point with scipy's ``brentq``.

Stretch test (Fig. 5, 6)
    A hanging actuator under payload m at pressure P settles where ``F_ext(L) = m g``
    (:func:`loaded_length`); a measured length gives the stretch force
    ``m g - F_cons - F_int`` (:func:`stretch_residual`), and a cubic through those points
    (:func:`fit_stretch_correction`) replaces the shipped placeholder coefficients.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ....errors import ModelError
from ..actuator import Actuator
from ..joint import JointGeometry
from . import rpam_force

G_N_PER_KG = 9.80665
_MPA = 1e6  # Pa per MPa: forces are P[MPa] * area[m^2] * 1e6

# Status codes of the equilibrium solver: arrays of small ints vectorise.
OK, TOGGLE, BAD_INPUT = 0, 1, 2


# --------------------------------------------------------------------------- geometry


def mount_points(alpha: Any, geom: JointGeometry) -> dict[str, np.ndarray]:
    """Table I points and the lower swivel mounts as arrays of shape ``(..., 2)``."""
    alpha = np.asarray(alpha, dtype=float)
    L1, L2, L3 = (np.asarray(v, dtype=float) for v in (geom.L1_m, geom.L2_m, geom.L3_m))
    s, c = np.sin(alpha), np.cos(alpha)
    zero = np.zeros(np.broadcast(alpha, L1, L2, L3).shape)
    return {
        "m": np.stack([L2 * s + zero, L2 * c + zero], axis=-1),
        "a": np.stack([L2 * s - L3 * c + zero, L2 * c + L3 * s + zero], axis=-1),
        "b": np.stack([L2 * s + L3 * c + zero, L2 * c - L3 * s + zero], axis=-1),
        "a_low": np.stack([-L1 + zero, zero], axis=-1),
        "b_low": np.stack([L1 + zero, zero], axis=-1),
    }


def actuator_lengths(alpha: Any, geom: JointGeometry) -> tuple[np.ndarray, np.ndarray]:
    """Eq. 4: lengths (L_a, L_b) in metres at joint angle alpha (rad)."""
    alpha = np.asarray(alpha, dtype=float)
    L1, L2, L3 = geom.L1_m, geom.L2_m, geom.L3_m
    base = L1**2 + L2**2 + L3**2 - 2 * L1 * L3 * np.cos(alpha)
    cross = 2 * L1 * L2 * np.sin(alpha)
    return np.sqrt(base + cross), np.sqrt(base - cross)


def toggle_angle(geom: JointGeometry) -> Any:
    """Angle (rad) where actuator b's line passes through the pivot: atan(L2 / L3)."""
    return np.arctan2(geom.L2_m, geom.L3_m)


def moment_arms_heron(alpha: Any, geom: JointGeometry) -> tuple[np.ndarray, np.ndarray]:
    """Eq. 5 (unsigned heights by Heron's formula), with L23 = |O a| and (S_b - L_b)."""
    La, Lb = actuator_lengths(alpha, geom)
    L1 = np.asarray(geom.L1_m, dtype=float)
    L23 = np.hypot(geom.L2_m, geom.L3_m)

    def height(Lx: np.ndarray) -> np.ndarray:
        S = (L1 + L23 + Lx) / 2
        # A degenerate triangle (at the toggle) can round to a tiny negative product.
        area2 = np.clip(S * (S - L1) * (S - L23) * (S - Lx), 0.0, None)
        return 2 * np.sqrt(area2) / Lx

    return height(La), height(Lb)


def moment_arms(alpha: Any, geom: JointGeometry) -> tuple[np.ndarray, np.ndarray]:
    """Signed moment arms (m_a, m_b) in metres: exact point-to-line distances from O.

    The sign is that of the cross product (line direction x lever), oriented so that both
    are positive on the valid branch; ``m_b`` turns negative beyond the toggle angle.
    """
    p = mount_points(alpha, geom)
    da = p["a"] - p["a_low"]
    db = p["b"] - p["b_low"]
    La = np.hypot(da[..., 0], da[..., 1])
    Lb = np.hypot(db[..., 0], db[..., 1])
    # z of (lower mount - O) x (line direction): distance of O from the line, signed.
    ma = -(p["a_low"][..., 0] * da[..., 1] - p["a_low"][..., 1] * da[..., 0]) / La
    mb = (p["b_low"][..., 0] * db[..., 1] - p["b_low"][..., 1] * db[..., 0]) / Lb
    return ma, mb


def _moment_arms_closed(alpha: Any, geom: JointGeometry, La: Any, Lb: Any) -> tuple[Any, Any]:
    # The cross products of moment_arms() written out (L1 a_y / L_a, L1 b_y / L_b): the
    # solver calls this thousands of times and the stacked points cost more than the maths.
    s, c = np.sin(alpha), np.cos(alpha)
    return (geom.L1_m * (geom.L2_m * c + geom.L3_m * s) / La, geom.L1_m * (geom.L2_m * c - geom.L3_m * s) / Lb)


# --------------------------------------------------------------------------- actuator force


def helical_tension(P_MPa: Any, L: Any, n_turns: float, thread_length_m: float) -> np.ndarray:
    """McKibben cage term ``-P dV/dL = P (3 L^2 - b^2) / (4 pi n^2)`` in N (tension +)."""
    return rpam_force.cage_gas_force(P_MPa, L, n_turns, thread_length_m)


def constraint_force(P_MPa: Any, L: Any, act: Actuator) -> np.ndarray:
    """Eq. 2 re-derived: the gas's part of the force (N, tension +), the cage term on the cage.

    See :func:`.rpam_force.force_parts`; with a slack cage it is ``-P pi r_o^2``.
    """
    return rpam_force.force_parts(P_MPa, L, act)[0]


def wall_force(P_MPa: Any, L: Any, act: Actuator) -> np.ndarray:
    """Eq. 3 re-derived: the helix-constrained Ogden wall's part of the force (N, tension +)."""
    return rpam_force.force_parts(P_MPa, L, act)[1]


def material_force(lam: Any, act: Actuator) -> np.ndarray:
    """Eq. 3: Ogden uniaxial wall force in N (tension +): the paper reading's wall, and the
    derived reading's free wall at P = 0."""
    return rpam_force.uniaxial_force(lam, act)


def stretch_force(lam: Any, act: Actuator) -> np.ndarray:
    """Eq. 7's correction: the cubic in lambda (N, tension +), clamped to its fit range."""
    lo, hi = act.stretch_lambda_range
    lam = np.clip(np.asarray(lam, dtype=float), lo, hi)
    c = act.stretch_coefficients_N
    return c[0] + lam * (c[1] + lam * (c[2] + lam * c[3]))


def external_force(P_MPa: Any, L: Any, act: Actuator, *, stretch: bool = True) -> np.ndarray:
    """Eq. 1 / Eq. 7: tensile load (N) that holds the actuator at length L under P."""
    F = rpam_force.internal_force(P_MPa, L, act)
    if stretch:
        F = F + stretch_force(np.asarray(L, dtype=float) / act.L0_m, act)
    return F


def push_force(P_MPa: Any, L: Any, act: Actuator, *, stretch: bool = True) -> np.ndarray:
    """Force (N) the actuator exerts on its mounts, positive when it pushes them apart."""
    return -external_force(P_MPa, L, act, stretch=stretch)


def loaded_length(P_MPa: Any, mass_kg: Any, act: Actuator, *, stretch: bool = True, iterations: int = 80) -> np.ndarray:
    """Length (m) of a hanging actuator carrying ``mass_kg`` at pressure P (stretch test).

    Solves ``F_ext(L) = m g`` by bisection on ``L0/2 .. 4 L0`` (vectorised; the lower end
    is raised to keep the lumen of a thick wall open); NaN where the load is outside what the
    actuator can hold in that range.
    """
    P, m = np.broadcast_arrays(np.asarray(P_MPa, float), np.asarray(mass_kg, float))
    target = m * G_N_PER_KG
    # Shortened, the wall thickens; at lambda = A0 / (pi R_o^2) it would fill the cage.
    closed = act.A0_m2 / (np.pi * act.rest_radius_m**2)
    lo = np.full(P.shape, max(0.5, 1.05 * closed) * act.L0_m)
    hi = np.full(P.shape, 4.0 * act.L0_m)
    f_lo = external_force(P, lo, act, stretch=stretch) - target
    f_hi = external_force(P, hi, act, stretch=stretch) - target
    valid = (f_lo <= 0) & (f_hi >= 0)
    for _ in range(iterations):
        mid = 0.5 * (lo + hi)
        f_mid = external_force(P, mid, act, stretch=stretch) - target
        up = f_mid < 0
        lo = np.where(up, mid, lo)
        hi = np.where(up, hi, mid)
    return np.where(valid, 0.5 * (lo + hi), np.nan)


def stretch_residual(P_MPa: Any, L: Any, mass_kg: Any, act: Actuator) -> np.ndarray:
    """Stretch force (N) a stretch-test point implies: ``m g - F_cons - F_int`` (Eqs. 1, 7).

    ``L`` is the measured length under payload ``mass_kg`` at pressure P; these residuals
    against ``L / L0`` are what :func:`fit_stretch_correction` fits (Fig. 6).
    """
    return np.asarray(mass_kg, dtype=float) * G_N_PER_KG - rpam_force.internal_force(P_MPa, L, act)


def fit_stretch_correction(lam: Any, force_N: Any) -> tuple[float, float, float, float]:
    """Least-squares cubic ``c0 + c1 lam + c2 lam^2 + c3 lam^3`` through measured stretch forces."""
    lam = np.asarray(lam, dtype=float).ravel()
    force = np.asarray(force_N, dtype=float).ravel()
    keep = np.isfinite(lam) & np.isfinite(force)
    if keep.sum() < 4 or np.unique(lam[keep]).size < 4:
        raise ModelError(
            "The stretch correction is a cubic and needs at least 4 distinct stretches; "
            f"the stretch test gave {np.unique(lam[keep]).size}."
        )
    coef = np.polynomial.polynomial.polyfit(lam[keep], force[keep], 3)
    return tuple(float(c) for c in coef)  # type: ignore[return-value]


# --------------------------------------------------------------------------- joint balance


def joint_torque(
    alpha: Any, Pa_MPa: Any, Pb_MPa: Any, geom: JointGeometry, act: Actuator, *, stretch: bool = True
) -> np.ndarray:
    """Eq. 6 residual ``F_a m_a - F_b m_b`` (N m) with signed arms; > 0 drives alpha up."""
    La, Lb = actuator_lengths(alpha, geom)
    ma, mb = _moment_arms_closed(alpha, geom, La, Lb)
    Fa = push_force(Pa_MPa, La, act, stretch=stretch)
    Fb = push_force(Pb_MPa, Lb, act, stretch=stretch)
    return Fa * ma - Fb * mb


def joint_stiffness(
    alpha: Any,
    Pa_MPa: Any,
    Pb_MPa: Any,
    geom: JointGeometry,
    act: Actuator,
    *,
    stretch: bool = True,
    step_rad: float = 1e-6,
) -> np.ndarray:
    """Joint stiffness ``-d tau / d alpha`` (N m/rad) by a central difference of Eq. 6.

    Positive at a stable balance; zero at a fold, where the balance is about to vanish.
    """
    alpha = np.asarray(alpha, dtype=float)
    up = joint_torque(alpha + step_rad, Pa_MPa, Pb_MPa, geom, act, stretch=stretch)
    down = joint_torque(alpha - step_rad, Pa_MPa, Pb_MPa, geom, act, stretch=stretch)
    return -(up - down) / (2 * step_rad)


@dataclass
class Equilibrium:
    """Solution of Eq. 6 over a batch: angles (rad, NaN where none), status codes."""

    alpha_rad: np.ndarray
    status: np.ndarray
    toggle_rad: np.ndarray
    L_a_m: np.ndarray = field(default_factory=lambda: np.empty(0))
    L_b_m: np.ndarray = field(default_factory=lambda: np.empty(0))

    @property
    def alpha_deg(self) -> np.ndarray:
        return np.degrees(self.alpha_rad)


def solve_equilibrium(
    Pa_MPa: Any,
    Pb_MPa: Any,
    geom: JointGeometry,
    act: Actuator,
    *,
    stretch: bool = True,
    samples: int = 129,
    iterations: int = 100,
) -> Equilibrium:
    """Solve Eq. 6 for alpha on the valid branch, vectorised over every input.

    ``Pa_MPa``, ``Pb_MPa`` and the geometry's link lengths broadcast together (a pressure
    grid for the joint map, a population of designs for the optimiser).  From alpha = 0
    the solver walks in the direction of the torque over ``samples`` points up to the
    toggle angle, brackets the first sign change, and refines it with a vectorised bracketed
    root finder (:func:`_refine`).
    """
    Pa, Pb, L1, L2, L3 = np.broadcast_arrays(
        *(np.asarray(v, dtype=float) for v in (Pa_MPa, Pb_MPa, geom.L1_m, geom.L2_m, geom.L3_m))
    )
    shape = Pa.shape
    Pa, Pb, L1, L2, L3 = (v.ravel() for v in (Pa, Pb, L1, L2, L3))
    g = JointGeometry(L1, L2, L3)
    t_toggle = toggle_angle(g)
    bad = ~((L1 > 0) & (L2 > 0) & (L3 > 0) & np.isfinite(Pa) & np.isfinite(Pb))

    tau0 = joint_torque(np.zeros_like(Pa), Pa, Pb, g, act, stretch=stretch)
    direction = np.where(tau0 >= 0, 1.0, -1.0)
    # Grid from 0 towards the toggle in the torque's direction, stopping a hair short of
    # the toggle itself, where b's (or a's) arm is exactly zero.
    frac = np.linspace(0.0, 1.0 - 1e-9, samples)
    grid = direction[:, None] * t_toggle[:, None] * frac[None, :]
    gcol = JointGeometry(L1[:, None], L2[:, None], L3[:, None])
    tau = joint_torque(grid, Pa[:, None], Pb[:, None], gcol, act, stretch=stretch)
    # Torque seen along the walk: positive while it keeps pushing the joint outward.
    outward = tau * direction[:, None]
    crossing = outward <= 0
    crossing[:, 0] = False
    exact0 = tau0 == 0
    has = crossing.any(axis=1)
    k = np.argmax(crossing, axis=1)
    lo = np.where(has, grid[np.arange(len(k)), np.maximum(k - 1, 0)], np.nan)
    hi = np.where(has, grid[np.arange(len(k)), k], np.nan)
    # tau(0) == 0 on a stable centre: the first step already crosses; keep the exact zero.
    stable_centre = exact0 & has & (k == 1)
    idx = np.flatnonzero(has & ~stable_centre)
    alpha = np.full(Pa.shape, np.nan)
    alpha[idx] = _refine(
        lambda x, i: joint_torque(
            x, Pa[idx][i], Pb[idx][i], JointGeometry(L1[idx][i], L2[idx][i], L3[idx][i]), act, stretch=stretch
        ),
        lo[idx],
        hi[idx],
        tau[idx, np.maximum(k[idx] - 1, 0)],
        tau[idx, k[idx]],
        iterations,
    )
    alpha[stable_centre] = 0.0
    status = np.where(np.isfinite(alpha), OK, TOGGLE)
    status = np.where(bad, BAD_INPUT, status)
    alpha = np.where(bad, np.nan, alpha)
    La, Lb = actuator_lengths(alpha, g)
    return Equilibrium(
        alpha_rad=alpha.reshape(shape),
        status=status.reshape(shape),
        toggle_rad=t_toggle.reshape(shape),
        L_a_m=La.reshape(shape),
        L_b_m=Lb.reshape(shape),
    )


def _refine(f: Any, a: np.ndarray, b: np.ndarray, fa: np.ndarray, fb: np.ndarray, iterations: int) -> np.ndarray:
    """Vectorised bracketed root finder: Illinois regula falsi, every third step a bisection.

    ``f(x, i)`` evaluates the residual at ``x`` for the bracket subset ``i``; the bracket
    [a, b] always keeps the sign change, so the root never leaves it.
    """
    a, b, fa, fb = (np.array(v, dtype=float) for v in (a, b, fa, fb))
    side = np.zeros(a.shape, dtype=int)
    active = np.flatnonzero((fa != 0) & (fb != 0))
    b = np.where(fa == 0, a, b)
    a = np.where(fb == 0, b, a)
    for it in range(iterations):
        if active.size == 0:
            break
        A, B, FA, FB = a[active], b[active], fa[active], fb[active]
        if it % 3 == 2:
            x = 0.5 * (A + B)
        else:
            x = B - FB * (B - A) / (FB - FA)
            x = np.where((x > np.minimum(A, B)) & (x < np.maximum(A, B)), x, 0.5 * (A + B))
        fx = np.asarray(f(x, active), dtype=float)
        left = np.sign(fx) == np.sign(FA)  # root lies between x and B
        # Illinois: halve the stale end's value when the same end survives twice.
        s = side[active]
        FB = np.where(left & (s == 1), FB / 2, FB)
        FA = np.where(~left & (s == -1), FA / 2, FA)
        A, FA = np.where(left, x, A), np.where(left, fx, FA)
        B, FB = np.where(left, B, x), np.where(left, FB, fx)
        side[active] = np.where(left, 1, -1)
        a[active], b[active], fa[active], fb[active] = A, B, FA, FB
        done = (fx == 0) | (np.abs(B - A) <= 1e-14 * np.maximum(1.0, np.abs(B)))
        b[active[fx == 0]] = x[fx == 0]
        a[active[fx == 0]] = x[fx == 0]
        active = active[~done]
    return 0.5 * (a + b)


def equilibrium_angle(
    Pa_MPa: float, Pb_MPa: float, geom: JointGeometry, act: Actuator, *, stretch: bool = True
) -> float:
    """Joint angle (rad) at one pressure pair, refined with scipy's Brent method.

    Raises :class:`ModelError` when the joint has no equilibrium on the valid branch.
    """
    from scipy.optimize import brentq

    coarse = solve_equilibrium(Pa_MPa, Pb_MPa, geom, act, stretch=stretch)
    alpha = float(coarse.alpha_rad)
    if not np.isfinite(alpha):
        raise ModelError(
            f"The joint has no equilibrium below its toggle angle "
            f"{math.degrees(float(coarse.toggle_rad)):.1f} deg at Pa = {Pa_MPa * 1e3:.0f} kPa, "
            f"Pb = {Pb_MPa * 1e3:.0f} kPa: it runs onto the toggle (check the pressures and links)."
        )
    if alpha == 0.0:
        return 0.0
    step = float(coarse.toggle_rad) / 256
    lo, hi = sorted((alpha - step, alpha + step))
    t_lim = float(coarse.toggle_rad) * (1 - 1e-9)
    lo, hi = max(lo, -t_lim), min(hi, t_lim)

    def f(x: float) -> float:
        return float(joint_torque(x, Pa_MPa, Pb_MPa, geom, act, stretch=stretch))

    if f(lo) * f(hi) > 0:
        return alpha
    return float(brentq(f, lo, hi, xtol=1e-14, rtol=1e-14))


def joint_map(
    Pa_MPa: Iterable[float], Pb_MPa: Iterable[float], geom: JointGeometry, act: Actuator, *, stretch: bool = True
) -> Equilibrium:
    """Equilibrium over the grid Pa x Pb (Fig. 8): arrays of shape ``(len(Pa), len(Pb))``."""
    Pa = np.asarray(list(Pa_MPa), dtype=float)
    Pb = np.asarray(list(Pb_MPa), dtype=float)
    return solve_equilibrium(Pa[:, None], Pb[None, :], geom, act, stretch=stretch)
