"""The rPAM's axial force in its two readings (Eqs. 1-3 of the rPAM paper).

The paper adds a helical constraint force (Eq. 2, misprinted) to the uniaxial Ogden force of
the wall (Eq. 3).  Eq. 2 can be read two ways, and the reading decides the joint's optimum
(``docs/rpam.md``), so both are here, named, and an actuator says which one it is read with
(``Actuator.force_reading``); :mod:`labcli.papers.rpam2015.models.rpam` calls these
functions and adds Eq. 7's empirical stretch correction.

``"derived"``
    The force as the L-derivative of one potential, the Ogden strain energy of the wall held
    by the cage plus the gas's virtual work (below, from "The actuator" on).  It changes the
    paper's model in two ways: the wall's force is that of a cage-held, near-planar wall
    (``4 mu A0`` per unit stretch at rest) instead of Eq. 3's uniaxial one (``3 mu A0``),
    and Eq. 2's ``A0 / lambda`` term is gone (the wall keeps its volume, so the gas's
    volume changes exactly as the cage's).

``"paper"``
    The paper's own model, read as the free body of the lumen: cut the actuator across the
    lumen and the gas pushes the end cap over the lumen's section ``pi r_c^2 - A0 / lambda``
    (the wall's section at stretch lambda is ``A0 / lambda`` by incompressibility), the
    thread, carrying the full hoop load ``P r_c`` per unit length, pulls
    ``P L^2 / (2 pi n^2)`` (the virtual work of its lateral surface), and the wall adds its
    uniaxial force, Eq. 3 as printed:

        F = P (3 L^2 - b^2) / (4 pi n^2) + P A0 / lambda + sum 2 mu_i A0 / alpha_i
            (lambda^(alpha_i - 1) - lambda^(-alpha_i / 2 - 1)),

    since ``P L^2 / (2 pi n^2) - P pi r_c^2 = P (3 L^2 - b^2) / (4 pi n^2)``.  It is Eq. 2
    with the printed "1" read as ``b^2 / (4 pi n^2)`` and the printed ``- A0 / lambda``
    read as ``+ A0 / lambda`` (the printed sign makes the wall pull the lumen shut, and its
    optimum has neither L1 nor L3 at the bound the paper reports).  It is conservative too: ``F = dPi/dL`` with
    ``Pi = A0 L0 W_u(lambda) - P (V_c(L) - A0 L0 ln lambda)``, ``W_u = sum 2 mu_i /
    alpha_i^2 (lambda^alpha_i + 2 lambda^(-alpha_i / 2) - 3)`` the uniaxial energy
    (:func:`paper_potential_energy`).  What the free body leaves out is that the
    pressurised wall carries a radial stress of -P at the lumen (hence an axial stress
    shifted by about -P over its section, which cancels the ``A0 / lambda`` term) and that
    the cage holds its hoop stretch; the derived reading keeps both.  The two readings agree
    on a vented, stretched actuator (both Eq. 3) and differ by ``P A0 / lambda`` in the gas
    term and by the planar-vs-uniaxial wall elsewhere.

The actuator
    A silicone tube (wall section ``A0``, rest length ``L0``, incompressible) inside a cage of
    inextensible thread: ``n`` turns of a thread of length ``b`` in two symmetric helices, so
    the actuator does not twist.  At length ``L`` the cage has the radius and volume

        r_c(L)^2 = (b^2 - L^2) / (4 pi^2 n^2),     V_c(L) = pi r_c^2 L = L (b^2 - L^2) / (4 pi n^2).

    At rest the wall fills the cage: outer radius ``R_o = r_c(L0)``, inner radius
    ``R_i = sqrt(R_o^2 - A0 / pi)``.  A thread holds the wall in but cannot pull it out:
    the wall's outer radius is ``r_o <= r_c(L)``.

The wall's deformation
    Axisymmetric, without twist: the ring at rest radius R moves to radius r and the whole
    wall stretches axially by ``lambda = L / L0``.  Incompressibility
    (``(r^2 - r_i^2) L = (R^2 - R_i^2) L0`` for every ring) gives

        r^2 = r_o^2 - (R_o^2 - R^2) / lambda,

    so the principal stretches are ``lambda`` (axial), ``lambda_t = r / R`` (hoop) and
    ``1 / (lambda lambda_t)`` (radial): two numbers, L and r_o, fix the whole deformation.

The potential
    Wall: ``U(L, r_o) = L0 pi int_{R_i^2}^{R_o^2} W d(R^2)`` with the Ogden energy whose
    uniaxial force is Eq. 3, ``W = sum 2 mu_i / alpha_i^2 (l1^alpha_i + l2^alpha_i +
    l3^alpha_i - 3)`` (initial shear modulus ``sum mu_i``; convex, so stable, when every
    ``mu_i > 0``).  The integral is done by Gauss-Legendre quadrature in R^2 over
    :data:`QUADRATURE_NODES` nodes: the integrand is smooth, and 6 nodes give the force within
    5e-8 N of 64 nodes for the shipped actuator between 0.06 and 0.2 m.

    Gas at the regulated gauge pressure P fills the lumen, ``V_g = pi r_i^2 L = pi r_o^2 L -
    A0 L0`` (the wall keeps its volume ``A0 L0``).  A tension F at the end caps completes

        Pi(L, r_o) = U(L, r_o) - P V_g(L, r_o) - F L.

Equilibrium (dPi = 0 for every admissible variation)
    *On the cage* (the gas holds the wall against the thread, ``P >= P_lift``): r_o = r_c(L),
    so L is the only freedom and

        F = dU/dL|cage - P dV_c/dL = F_wall + P (3 L^2 - b^2) / (4 pi n^2).

    The gas term is exactly the cage term of the McKibben derivation (``-P dV_c/dL``)
    because the wall's volume inside the cage is constant, ``dV_g = dV_c``: there is **no**
    ``+P A0 / lambda`` wall term.  A free-body cut through the lumen alone misses that the
    pressurised wall carries a radial stress of -P (lumen) to -p_c (thread) and so an axial
    stress shifted by about the same pressure; the simulated rig computes the force that way,
    from the wall's Cauchy stresses and the thread's statics
    (:mod:`labcli.papers.rpam2015.sim.rpam_physics`), and the tests hold the two routes
    together.  ``F_wall = dU/dL`` along the cage is the
    force of a wall stretched axially while the cage holds its hoop stretch near 1 (nearly
    planar extension, stiffer than uniaxial: ``4 mu A0`` per unit stretch at rest, against
    Eq. 3's ``3 mu A0``).

    *Free* (``P < P_lift``): the cage is slack, the tube inflates to ``dU/d(r_o^2) = P pi L``
    and ``F = dU/dL|r_o - P pi r_o^2``.  At P = 0 the tube stretches homogeneously
    (``r_o^2 = R_o^2 / lambda``) and F is Eq. 3 exactly, the paper's internal force.

    The lift-off pressure ``P_lift(L) = dU/d(r_o^2)|_{r_o = r_c} / (pi L)`` is where the two
    branches meet (continuously: the contact pressure vanishes there).  For the shipped
    actuator it stays below 10.2 kPa at every stretch, so the joint map (41-138 kPa) and the
    optimiser's pressures (41, 96 kPa) are always on the cage; only the stretch test's lowest
    pressures and a vented actuator are free.  Below ``lambda = 1`` the cage holds the wall
    even when vented.

    Tension is positive throughout (Eq. 1's sign): the push the actuator exerts on its mounts
    is ``-F``.  Pressures in MPa (gauge), as everywhere in labcli; forces in N; energies in J.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ..actuator import Actuator

_MPA = 1e6  # Pa per MPa
QUADRATURE_NODES = 6
_X, _W = np.polynomial.legendre.leggauss(QUADRATURE_NODES)
_BISECTIONS = 60  # halvings of the free-branch bracket: far below double precision


def cage_radius_sq(L: Any, act: Actuator) -> np.ndarray:
    """``r_c(L)^2`` (m^2): squared radius of the thread cage at length L."""
    L = np.asarray(L, dtype=float)
    return (act.thread_length_m**2 - L**2) / (4 * np.pi**2 * act.n_turns**2)


def cage_gas_force(P_MPa: Any, L: Any, n_turns: float, thread_length_m: float) -> np.ndarray:
    """``-P dV_c/dL = P (3 L^2 - b^2) / (4 pi n^2)`` (N, tension +): the gas on the cage."""
    P = np.asarray(P_MPa, dtype=float) * _MPA
    L = np.asarray(L, dtype=float)
    return P * (3 * L**2 - thread_length_m**2) / (4 * np.pi * n_turns**2)


def wall_radii_sq(act: Actuator) -> tuple[float, float]:
    """``(R_i^2, R_o^2)`` (m^2): the wall's rest radii, the outer one on the cage."""
    Ro2 = float(cage_radius_sq(act.L0_m, act))
    return Ro2 - act.A0_m2 / np.pi, Ro2


def _power(x: np.ndarray, a: float, logs: dict[str, np.ndarray], key: str) -> np.ndarray:
    """``x ** a``; by repeated products for a whole exponent (the solver's hot loop spends
    most of its time here, and a product costs a small fraction of an ``exp``)."""
    if a == int(a) and 0 < abs(a) <= 16:
        n, base = abs(int(a)), x
        out: np.ndarray | None = None  # the first factor as it is: no product with ones in the hot loop
        while n:
            if n & 1:
                out = base if out is None else out * base
            n >>= 1
            if n:
                base = base * base
        assert out is not None  # 0 < |a| here
        return out if a > 0 else 1.0 / out
    if key not in logs:
        with np.errstate(invalid="ignore", divide="ignore"):
            logs[key] = np.log(x)
    return np.exp(a * logs[key])


def _wall(
    L: np.ndarray, ro2: np.ndarray, act: Actuator, energy: bool = False
) -> tuple[np.ndarray | None, np.ndarray, np.ndarray]:
    """``(U, dU/dL at fixed r_o^2, dU/d(r_o^2) at fixed L)`` by quadrature over R^2.

    NaN where the wall would fill the lumen (a very short actuator): the model stops there.
    """
    Ri2, Ro2 = wall_radii_sq(act)
    s = 0.5 * (Ro2 + Ri2) + 0.5 * (Ro2 - Ri2) * _X  # nodes in R^2
    w = 0.5 * (Ro2 - Ri2) * _W
    lam = (L / act.L0_m)[..., None]
    u = ro2[..., None] - (Ro2 - s) / lam  # r^2 of each ring
    with np.errstate(invalid="ignore", divide="ignore"):
        lt = np.sqrt(u / s)  # hoop stretch r / R
    logs: dict[str, np.ndarray] = {}
    # Sums over the Ogden terms of c_i alpha_i (l^a - l_r^a) and c_i alpha_i (l_t^a - l_r^a),
    # c_i = 2 mu_i / alpha_i^2, with the radial stretch l_r = 1 / (lambda lambda_t).
    sum_l = np.zeros(u.shape)
    sum_t = np.zeros(u.shape)
    W = np.zeros(u.shape) if energy else None
    for mu, a in zip(act.ogden_mu_MPa, act.ogden_alpha, strict=False):
        ca = 2 * mu * _MPA / a
        pl = _power(lam, a, logs, "l")
        pt = _power(lt, a, logs, "t")
        pr = 1.0 / (pl * pt)
        sum_l += ca * (pl - pr)
        sum_t += ca * (pt - pr)
        if W is not None:
            W += ca / a * (pl + pt + pr - 3)
    dW_dl = sum_l / lam
    # dW/dlambda_t * dlambda_t/du, with dlambda_t/du = lambda_t / (2 u).
    dW_du = sum_t / (2 * u)
    # U = L0 pi sum w W;  d/dL = (1/L0) d/dlambda, and u moves with lambda at fixed r_o^2.
    dU_dL = np.pi * ((dW_dl + dW_du * (Ro2 - s) / lam**2) @ w)
    dU_dro2 = act.L0_m * np.pi * (dW_du @ w)
    U = act.L0_m * np.pi * (W @ w) if W is not None else None
    return U, dU_dL, dU_dro2


def liftoff_pressure(L: Any, act: Actuator) -> np.ndarray:
    """``P_lift(L)`` (MPa): the least pressure that holds the wall on the cage at length L."""
    L = np.asarray(L, dtype=float)
    _, _, dU_dro2 = _wall(L, cage_radius_sq(L, act), act)
    return dU_dro2 / (np.pi * L) / _MPA


def _free_radius_sq(P: np.ndarray, L: np.ndarray, act: Actuator, hi: np.ndarray) -> np.ndarray:
    """r_o^2 of a free (slack-cage) tube: the root of ``dU/d(r_o^2) = P pi L`` below ``hi``.

    The root lies between the homogeneous state ``R_o^2 / lambda`` (its P = 0 root, exact)
    and the cage; bisection, since U is convex in r_o^2 for a stable wall.
    """
    _, Ro2 = wall_radii_sq(act)
    out = Ro2 * act.L0_m / L
    pressed = P > 0
    if pressed.any():
        lo, hi, L, target = out[pressed], hi[pressed], L[pressed], P[pressed] * _MPA * np.pi * L[pressed]
        for _ in range(_BISECTIONS):
            mid = 0.5 * (lo + hi)
            above = _wall(L, mid, act)[2] > target
            lo, hi = np.where(above, lo, mid), np.where(above, mid, hi)
        out[pressed] = 0.5 * (lo + hi)
    return out


def _settled(P: np.ndarray, L: np.ndarray, act: Actuator) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """``(r_o^2, on_cage, dU/dL, dU/d(r_o^2))`` at the wall's equilibrium radius."""
    rc2 = cage_radius_sq(L, act)
    _, dU_dL, dU_dro2 = (np.array(v, dtype=float) for v in _wall(L, rc2, act))
    # P >= P_lift; a NaN (a closed lumen) stays on the cage branch and NaN, not a search.
    on_cage = ~(P * _MPA * np.pi * L < dU_dro2)
    ro2 = np.array(rc2, dtype=float, copy=True)
    free = ~on_cage
    if free.any():
        ro2[free] = _free_radius_sq(P[free], L[free], act, rc2[free])
        _, dU_dL[free], dU_dro2[free] = _wall(L[free], ro2[free], act)
    return ro2, on_cage, dU_dL, dU_dro2


def _broadcast(P_MPa: Any, L: Any) -> tuple[np.ndarray, np.ndarray]:
    P, L = np.broadcast_arrays(np.asarray(P_MPa, dtype=float), np.asarray(L, dtype=float))
    return np.array(P, dtype=float), np.array(L, dtype=float)


def wall_state(P_MPa: Any, L: Any, act: Actuator) -> tuple[np.ndarray, np.ndarray]:
    """``(r_o^2, on_cage)``: the wall's outer radius squared (m^2) and whether the cage holds it."""
    ro2, on_cage, _, _ = _settled(*_broadcast(P_MPa, L), act)
    return ro2, on_cage


def uniaxial_force(lam: Any, act: Actuator) -> np.ndarray:
    """Eq. 3: the uniaxial Ogden force of the wall (N, tension +) at stretch lambda."""
    lam = np.asarray(lam, dtype=float)
    total = np.zeros_like(lam)
    for mu, a in zip(act.ogden_mu_MPa, act.ogden_alpha, strict=False):
        total = total + 2 * mu * _MPA * act.A0_m2 / a * (lam ** (a - 1) - lam ** (-a / 2 - 1))
    return total


def force_parts(P_MPa: Any, L: Any, act: Actuator) -> tuple[np.ndarray, np.ndarray]:
    """``(F_gas, F_wall)`` (N, tension +) in the actuator's reading (``act.force_reading``).

    Derived: on the cage ``F_gas`` is :func:`cage_gas_force` (Eq. 2 re-derived) and
    ``F_wall`` is ``dU/dL`` along the cage; on the free branch they are ``-P pi r_o^2`` and
    ``dU/dL`` at fixed r_o.  Paper: ``F_gas`` is the cage term plus ``P A0 / lambda`` and
    ``F_wall`` is Eq. 3 (:func:`paper_force_parts`).  Only their sum is a measurable force.
    """
    if act.force_reading == "paper":
        return paper_force_parts(P_MPa, L, act)
    return derived_force_parts(P_MPa, L, act)


def paper_force_parts(P_MPa: Any, L: Any, act: Actuator) -> tuple[np.ndarray, np.ndarray]:
    """The paper's reading: ``(cage term + P A0 / lambda, Eq. 3)`` (N, tension +), the lumen's free body."""
    P, L = _broadcast(P_MPa, L)
    lam = L / act.L0_m
    gas = cage_gas_force(P, L, act.n_turns, act.thread_length_m) + P * _MPA * act.A0_m2 / lam
    return gas, uniaxial_force(lam, act)


def derived_force_parts(P_MPa: Any, L: Any, act: Actuator) -> tuple[np.ndarray, np.ndarray]:
    """The derived reading: ``(F_gas, F_wall)`` (N, tension +), the parts of ``dPi/dL`` above."""
    P, L = _broadcast(P_MPa, L)
    ro2, on_cage, dU_dL, dU_dro2 = _settled(P, L, act)
    drc2_dL = -L / (2 * np.pi**2 * act.n_turns**2)
    wall = np.where(on_cage, dU_dL + dU_dro2 * drc2_dL, dU_dL)
    gas = np.where(on_cage, cage_gas_force(P, L, act.n_turns, act.thread_length_m), -P * _MPA * np.pi * ro2)
    return gas, wall


def internal_force(P_MPa: Any, L: Any, act: Actuator) -> np.ndarray:
    """``dPi/dL`` without the load (N, tension +): the load that holds the actuator at L under P."""
    gas, wall = force_parts(P_MPa, L, act)
    return gas + wall


def potential_energy(P_MPa: Any, L: Any, act: Actuator) -> np.ndarray:
    """The potential (J) of the actuator's reading: its L-derivative is the force, minus it the push.

    Derived: ``U - P V_g`` at the wall's equilibrium radius; paper: :func:`paper_potential_energy`.
    """
    if act.force_reading == "paper":
        return paper_potential_energy(P_MPa, L, act)
    P, L = _broadcast(P_MPa, L)
    ro2, _, _, _ = _settled(P, L, act)
    U, _, _ = _wall(L, ro2, act, energy=True)
    return U - P * _MPA * (np.pi * ro2 * L - act.A0_m2 * act.L0_m)


def paper_potential_energy(P_MPa: Any, L: Any, act: Actuator) -> np.ndarray:
    """``A0 L0 W_u(lambda) - P (V_c(L) - A0 L0 ln lambda)`` (J): the paper's reading as a potential.

    ``W_u`` is the uniaxial Ogden energy whose derivative is Eq. 3; the ``ln lambda`` term is
    what ``P A0 / lambda`` integrates to, a lumen that loses ``A0 L0 ln lambda`` of volume to
    a wall that does not in fact grow.
    """
    P, L = _broadcast(P_MPa, L)
    lam = L / act.L0_m
    W = np.zeros_like(lam)
    for mu, a in zip(act.ogden_mu_MPa, act.ogden_alpha, strict=False):
        W = W + 2 * mu * _MPA / a**2 * (lam**a + 2 * lam ** (-a / 2) - 3)
    V_c = np.pi * cage_radius_sq(L, act) * L
    return act.A0_m2 * act.L0_m * W - P * _MPA * (V_c - act.A0_m2 * act.L0_m * np.log(lam))
