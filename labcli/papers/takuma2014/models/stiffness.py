"""Object stiffness from pushes (Takuma et al. 2014, Section 4, Eqs. 38-42).

Geometry (origin at the bottom joint, x to the right, y up, angles
counter-clockwise): the contact point of the arm is

    C(theta) = (-h2 sin t1 - h3 sin(t1 + t2),  h2 cos t1 + h3 cos(t1 + t2)),

which is the point Section 4 prints and the one the Jacobian of Section 2.2.2
belongs to (the (x, y) printed in 2.2.2 drops h3 and adds h1; see
``docs/errata.md``).  A cylinder of radius R just touches the upright tip
C0 = (0, h2 + h3) before the push, so its centre is O1 = (R, h2 + h3).  Pushed
by d along phi the centre moves to (Eq. 39)

    O2 = (R - d cos phi,  h2 + h3 - d sin phi),

so phi = 0 pushes the object straight at the upright arm (towards -x).
The paper's rig stands upright before each push; a hand-built one leans by a
degree or so, which shifts the whole construction.  Given the baseline posture
theta0 (absolute, e.g. from the potentiometers), C0 = C(theta0),
O1 = C0 + (R, 0), and the tip is at C(theta0 + theta) for the estimated
deflection theta; theta0 = 0 is the paper's case.  (A 0.5-0.9 deg lean left
out costs up to 5 % of k_o with phi given and a third with phi solved.)  The
object is a ring of radial springs: it pushes the tip along O2 -> C with
|F| = k_o * delta_x, delta_x = R - |O2 C| (Eq. 42), hence (Eq. 38, read with
the exponent +1/2; the printed -1/2 is a misprint)

    k_o = |F| / delta_x,   |F| = sqrt(Fx^2 + Fy^2).

Unknown push direction.  Eqs. 40 and 41 disagree as printed, so the condition
used here is the one they are meant to express: the estimated force points
along O2 -> C.  O2 then lies on the ray from C along -F (O2 = C - s F/|F|,
s = |O2 C| > 0) and on the circle of radius d about O1; the solutions are the
ray-circle intersections.  Among them the one with delta_x = R - s > 0 and the
smallest |phi| is kept; pushes with none are flagged.  The solution is found in
closed form (a quadratic in s), which yields every root exactly; a scan with
bracketed root finding over (-pi, pi] finds the same set (see the tests).

Conditioning.  Turning the force direction by d_alpha moves O2 sideways by
s * d_alpha with s ~ R, while phi moves O2 along a circle of radius d, so
d_phi / d_alpha ~ R / d: several degrees of phi per degree of force direction,
and without bound where the ray grazes the circle (the only place where two
admissible solutions exist).  delta_x, a small difference of lengths near R,
suffers most.  For a can (R = 33 mm) pushed 10 mm by an arm of tip stiffness
~360 N/m: |phi_gain| = 3-4 at phi = 0-30 deg and 13 at 60 deg; one degree of
force-direction error costs 11 %, 30 % and 105 % of k_o at phi = 30 deg for
k_o = 500, 2000 and 8000 N/m (almost nothing at phi = 0, by symmetry).  With
phi given, the estimated joint angles still enter delta_x through the arm's
lever (about h2 + h3 = 0.195 m per rad): 0.1 deg costs 8 %, 20 % and 70 % of
k_o for the same three objects.  Every push carries ``dx_theta_gain``
(|d delta_x / d theta|, m per rad), and every solved one ``phi_gain`` (rad per
rad) and ``dx_gain`` (m per rad), so a reader sees how far to trust it.

One force component near singular.  Section 4's upright arm keeps theta2
within a few degrees of 0, where a force along the straight arm makes no torque:
the model then flags Fy (``singular-jacobian``, ``ok["Fy"]`` False) while Fx, the
force across the arm, stays well determined.  On the simulated rig the flagged
Fy is noise (rms error 0.28 N against a true |Fy| of 0.30 N rms), and a solved
phi from it is worthless (k_o off by a factor of two).  The policy
``singular_component = "project"`` uses what the geometry already knows: the
object can only push along O2 -> C, so with phi given the force is the usable
component divided by that direction's share of it, F = (F_x / u_x) u with u
the unit vector O2 -> C (pushes where |u_x| < ``min_projection`` or F_x points
against u are flagged).  With phi unknown the direction is exactly what is
missing, so such pushes are flagged.  ``"exclude"`` flags every push with a
flagged component.  Measured on the simulated rig over ten seeds
(``tests/benchmarks/classify_accuracy.py``, phi given, pressure-only): PET bottles
(420-610 N/m) come out at 1.003 of their true k_o with 1.4 % spread per push
when projected, against 1.045 (up to 1.15) and 5.6 % spread with the model's
own Fy accepted; aluminium cans 1.02 against 1.025; the steel can (8000 N/m,
0.45 mm deformation) 1.06 either way, its error set by the angles.

Flags never average anything away: a flagged push keeps its numbers where they
exist and says why in ``reason``; per-object statistics use unflagged pushes
only.
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import asdict, dataclass, fields
from typing import Any

import numpy as np

from ....errors import ConfigError
from .geometry import contact_point, jacobian

# Reasons are fixed sentences so that tables and tests can match them.
REASON_NO_PHI = (
    "no push direction makes the force point from the object's centre to the contact point with a positive deformation"
)
REASON_NO_DEFORMATION = "deformation is not positive (the contact point lies outside the object)"
REASON_SMALL_DEFORMATION = "deformation is below the resolution min_deformation_m"
REASON_SINGULAR = "pose is near singular (|sin theta2| below singular_sin_theta2), so the force estimate is unreliable"
REASON_SMALL_FORCE = "force magnitude is below min_force_N"
REASON_DIRECTION = "force direction differs from O2 -> C by more than max_direction_error_deg"
REASON_INPUT = "estimated angles or forces are not finite"
REASON_UNOBSERVED_DIRECTION = (
    "one force component is near singular (theta2 near 0), so the force direction cannot give phi; "
    "give the push direction phi_deg"
)
REASON_PROJECTION = (
    "the usable force component is below min_projection of the force along O2 -> C, or points against it"
)
REASON_UNDETERMINED_DIRECTION = (
    "the push direction is not determined: the force direction's standard error makes phi's exceed max_phi_se_deg"
)
SINGULAR_FLAG = "singular-jacobian"
# Flags that, with exactly one force component usable, name that component's loss: the paper
# form's cut near theta2 = 0, and the posture-aware form's standard error over its limit.
ONE_COMPONENT_FLAGS = frozenset({SINGULAR_FLAG, "uncertain"})
SINGULAR_POLICIES = ("exclude", "project")


@dataclass(frozen=True)
class StiffnessParams:
    """Thresholds for flagging pushes (plain data; SI except the one angle in degrees).

    ``min_force_N``: forces below this carry no usable direction or magnitude.
    ``min_deformation_m``: deformations below this are within the angle
    estimate's resolution (h2 + h3 = 0.195 m times a few mrad), so k_o is
    unbounded there.  ``singular_sin_theta2``: |sin theta2| below this puts the
    pose near the Jacobian's singularity; used only when the model supplies no
    flags of its own.  ``max_direction_error_deg``: for a known phi, the force
    may deviate from O2 -> C by at most this much (90 deg: an object can only
    push).  ``accept_model_flags``: model flags (e.g. ``"singular-jacobian"``)
    that do not exclude a push; they are kept in the push's ``note``.
    ``singular_component``: what a push whose model flags exactly one force
    component ``singular-jacobian`` gets: ``"project"`` (the force from the
    usable component along O2 -> C when phi is given, flagged when phi is
    solved) or ``"exclude"`` (flagged).  ``min_projection``: the smallest share
    |u_x| (or |u_y|) of the direction O2 -> C the usable component may carry,
    since its error is divided by it.  ``max_phi_se_deg``: a solved phi whose standard error (the
    force direction's, from the model's standard errors of Fx and Fy, times ``phi_gain``) exceeds
    this is not determined, and its push is flagged; pushes without standard errors are not.
    """

    min_force_N: float = 0.05
    min_deformation_m: float = 1.0e-4
    singular_sin_theta2: float = 0.02
    max_direction_error_deg: float = 90.0
    accept_model_flags: tuple[str, ...] = ()
    singular_component: str = "project"
    min_projection: float = 0.5
    max_phi_se_deg: float = 90.0

    def to_dict(self) -> dict[str, Any]:
        out = asdict(self)
        out["accept_model_flags"] = list(self.accept_model_flags)
        return out

    @classmethod
    def from_dict(cls, data: Mapping[str, Any] | None, where: str = "the stiffness parameters") -> StiffnessParams:
        """Build from a mapping (e.g. a protocol's ``[stiffness]`` table); unknown keys are errors."""
        if not data:
            return cls()
        known = {f.name for f in fields(cls)}
        unknown = sorted(set(data) - known)
        if unknown:
            raise ConfigError(f"Unknown key {unknown[0]!r} in {where}; accepted keys are {', '.join(sorted(known))}.")
        values: dict[str, Any] = {}
        for key, value in data.items():
            if key == "accept_model_flags":
                if isinstance(value, str) or not all(isinstance(v, str) for v in value):
                    raise ConfigError(f"Key {key!r} in {where} must be a list of flag names, got {value!r}.")
                values[key] = tuple(value)
                continue
            if key == "singular_component":
                if value not in SINGULAR_POLICIES:
                    raise ConfigError(
                        f"Key {key!r} in {where} must be one of {', '.join(SINGULAR_POLICIES)}, got {value!r}."
                    )
                values[key] = value
                continue
            try:
                number = float(value)
            except (TypeError, ValueError):
                number = math.nan
            if not math.isfinite(number) or number < 0:
                raise ConfigError(f"Key {key!r} in {where} must be a non-negative number, got {value!r}.")
            values[key] = number
        return cls(**values)


@dataclass
class PushEstimates:
    """Per-push results of :func:`estimate_pushes`; every array has length n.

    ``C`` and ``O2`` are (n, 2) in m; ``phi`` in rad (NaN where no solution);
    ``phi_solved`` says whether phi was solved (True) or given (False);
    ``n_phi_solutions`` counts admissible roots (delta_x > 0); ``delta_x`` in m;
    ``force`` = |F| in N; ``k`` in N/m (NaN where delta_x <= 0);
    ``direction_error`` is the signed angle (rad) from O2 -> C to F;
    ``phi_gain`` (rad/rad) and ``dx_gain`` (m/rad) are the sensitivities of a
    solved phi and delta_x to the force direction (NaN for a given phi);
    ``dx_theta_gain`` (m/rad) is the norm of d delta_x / d(theta1, theta2);
    ``flag`` is True for pushes not to be used and ``reason`` says why ("" if
    unflagged; several reasons joined by "; "); ``note`` lists accepted model
    flags and forces rebuilt from one component; ``F`` (n, 2) in N is the
    force used (the model's, or the projected one); ``phi_se`` (rad) is a solved phi's standard
    error from the force direction's (NaN where phi is given or no standard errors were given).
    """

    C: np.ndarray
    phi: np.ndarray
    phi_solved: np.ndarray
    n_phi_solutions: np.ndarray
    O2: np.ndarray
    delta_x: np.ndarray
    force: np.ndarray
    k: np.ndarray
    direction_error: np.ndarray
    phi_gain: np.ndarray
    dx_gain: np.ndarray
    dx_theta_gain: np.ndarray
    flag: np.ndarray
    reason: np.ndarray
    note: np.ndarray
    F: np.ndarray | None = None
    phi_se: np.ndarray | None = None

    def __len__(self) -> int:
        return int(self.phi.shape[0])

    def to_frame(self):
        """Return the estimates as a DataFrame (SI columns plus phi in degrees for people)."""
        import pandas as pd

        F = self.F if self.F is not None else np.full((len(self), 2), np.nan)
        return pd.DataFrame(
            {
                "Fx_used_N": F[:, 0],
                "Fy_used_N": F[:, 1],
                "xc_m": self.C[:, 0],
                "yc_m": self.C[:, 1],
                "phi_rad": self.phi,
                "phi_deg": np.degrees(self.phi),
                "phi_se_deg": np.degrees(self.phi_se) if self.phi_se is not None else np.full(len(self), np.nan),
                "phi_solved": self.phi_solved,
                "n_phi_solutions": self.n_phi_solutions,
                "xo_m": self.O2[:, 0],
                "yo_m": self.O2[:, 1],
                "delta_x_m": self.delta_x,
                "force_N": self.force,
                "k_N_per_m": self.k,
                "direction_error_deg": np.degrees(self.direction_error),
                "phi_gain": self.phi_gain,
                "dx_gain_m_per_rad": self.dx_gain,
                "dx_theta_gain_m_per_rad": self.dx_theta_gain,
                "flag": self.flag,
                "reason": self.reason,
                "note": self.note,
            }
        )


def object_centre(
    R: np.ndarray, d: np.ndarray, phi: np.ndarray, h2: float, h3: float, C0: np.ndarray | None = None
) -> np.ndarray:
    """Centre O2 of the pushed object (Eq. 39), shape (n, 2) in m.

    ``C0`` is where the object touched the tip before the push ((n, 2) or
    (2,)); None is the paper's upright (0, h2 + h3).
    """
    R, d, phi = np.broadcast_arrays(*(np.asarray(a, dtype=float) for a in (R, d, phi)))
    x0, y0 = (
        (0.0, h2 + h3) if C0 is None else (np.asarray(C0, dtype=float)[..., 0], np.asarray(C0, dtype=float)[..., 1])
    )
    return np.stack(np.broadcast_arrays(x0 + R - d * np.cos(phi), y0 - d * np.sin(phi)), axis=-1).reshape(-1, 2)


@dataclass
class PhiSolution:
    """Solved push directions: ``phi`` (rad, NaN where none), ``s`` = |O2 C| (m),
    ``n_solutions`` (admissible roots with 0 < s < R), ``phi_gain``, ``dx_gain``."""

    phi: np.ndarray
    s: np.ndarray
    n_solutions: np.ndarray
    phi_gain: np.ndarray
    dx_gain: np.ndarray


def solve_phi(
    C: np.ndarray, F: np.ndarray, R: np.ndarray, d: np.ndarray, h2: float, h3: float, C0: np.ndarray | None = None
) -> PhiSolution:
    """Solve the push direction phi from the condition that F points along O2 -> C.

    O2 = C - s F/|F| with s > 0 and |O2 - O1| = d gives
    s^2 - 2 s (F^ . w) + |w|^2 - d^2 = 0 with w = C - O1.  Of the roots with
    0 < s < R (positive deformation) the one with the smallest |phi| is kept.
    """
    C = np.asarray(C, dtype=float).reshape(-1, 2)
    F = np.asarray(F, dtype=float).reshape(-1, 2)
    n = C.shape[0]
    R = np.broadcast_to(np.asarray(R, dtype=float), (n,))
    d = np.broadcast_to(np.asarray(d, dtype=float), (n,))
    norm = np.hypot(F[:, 0], F[:, 1])
    with np.errstate(invalid="ignore", divide="ignore"):
        Fh = F / norm[:, None]
    O1 = object_centre(R, np.zeros(n), np.zeros(n), h2, h3, C0)
    w = C - O1
    b = np.einsum("ij,ij->i", Fh, w)
    disc = b * b - (np.einsum("ij,ij->i", w, w) - d * d)
    root = np.sqrt(np.where(disc >= 0, disc, np.nan))
    roots = np.stack([b - root, b + root], axis=-1)  # (n, 2)
    # Eq. 39 inverted: O1 - O2 = d (cos phi, sin phi).
    O2 = C[:, None, :] - roots[..., None] * Fh[:, None, :]
    rel = O1[:, None, :] - O2
    phis = np.arctan2(rel[..., 1], rel[..., 0])
    with np.errstate(invalid="ignore"):
        ok = np.isfinite(roots) & (roots > 0) & (roots < R[:, None]) & (d[:, None] > 0) & np.isfinite(phis)
    # A double root (tangent ray) counts once.
    ok[:, 1] &= ~(ok[:, 0] & (roots[:, 1] == roots[:, 0]))
    n_sol = ok.sum(axis=1)
    cost = np.where(ok, np.abs(phis), np.inf)
    pick = np.argmin(cost, axis=1)
    rows = np.arange(n)
    has = n_sol > 0
    phi = np.where(has, phis[rows, pick], np.nan)
    s = np.where(has, roots[rows, pick], np.nan)

    # Sensitivity to a turn d_alpha of the force direction (implicit differentiation).
    Fp = np.stack([-Fh[:, 1], Fh[:, 0]], axis=-1)
    v = np.stack([-d * np.cos(phi), -d * np.sin(phi)], axis=-1)  # O2 - O1
    with np.errstate(invalid="ignore", divide="ignore"):
        ds = -s * np.einsum("ij,ij->i", v, Fp) / np.einsum("ij,ij->i", v, Fh)
        dO2 = -ds[:, None] * Fh - s[:, None] * Fp
        u_perp = np.stack([-np.sin(phi), np.cos(phi)], axis=-1)
        dphi = -np.einsum("ij,ij->i", dO2, u_perp) / d
    return PhiSolution(phi=phi, s=s, n_solutions=n_sol, phi_gain=dphi, dx_gain=-ds)


def _flags_from_model(flags: Any, reasons: Any, n: int) -> list[list[str]] | None:
    """A model's prediction flags as one list of flag names per push (empty = fine).

    Accepted: one list of strings per push (as ``TakumaModel.predict`` gives),
    one string per push (non-empty = flagged), or one bool per push with
    optional ``reasons``.
    """
    if flags is None:
        return None
    items = (
        list(flags.reshape(-1))
        if isinstance(flags, np.ndarray) and flags.ndim <= 1
        else (None if isinstance(flags, np.ndarray) else list(flags))
    )
    if items is None or len(items) != n:
        got = np.shape(flags) if items is None else (len(items),)
        raise ConfigError(f"Model flags have shape {got}, expected ({n},) for {n} pushes.")
    if all(isinstance(item, list) for item in items):  # TakumaModel.predict's form: most lists empty
        return [list(filter(None, map(str, item))) if item else [] for item in items]
    given = list(np.asarray(reasons, dtype=object).reshape(n)) if reasons is not None else [""] * n
    out: list[list[str]] = []
    for item, why in zip(items, given, strict=False):
        if isinstance(item, (list, tuple, set)):  # TakumaModel.predict's form first: one test per push
            out.append(list(filter(None, map(str, item))))
        elif item is None or (isinstance(item, float) and math.isnan(item)):
            out.append([])
        elif isinstance(item, str):
            out.append([item] if item else [])
        else:
            out.append([str(why) if why else "flagged by the model"] if bool(item) else [])
    return out


def _deformation(
    C: np.ndarray,
    F: np.ndarray,
    force: np.ndarray,
    R: Any,
    d: Any,
    phi: np.ndarray,
    h2: float,
    h3: float,
    C0: np.ndarray | None,
) -> tuple[np.ndarray, ...]:
    """Eqs. 38-42 for each push: the object's centre O2, the tip's offset g from it and its length,
    the deformation delta_x = R - |g|, the stiffness k = |F| / delta_x, and the angle between the
    force and the normal g (0 for the radial force Eq. 38 assumes)."""
    O2 = object_centre(R, d, phi, h2, h3, C0)
    g = C - O2
    dist = np.hypot(g[:, 0], g[:, 1])
    delta_x = R - dist
    with np.errstate(invalid="ignore", divide="ignore"):
        k = np.where(delta_x > 0, force / delta_x, np.nan)
    direction_error = np.arctan2(g[:, 0] * F[:, 1] - g[:, 1] * F[:, 0], g[:, 0] * F[:, 0] + g[:, 1] * F[:, 1])
    return O2, g, dist, delta_x, k, direction_error


def estimate_pushes(
    theta1: Sequence[float] | np.ndarray,
    theta2: Sequence[float] | np.ndarray,
    Fx: Sequence[float] | np.ndarray,
    Fy: Sequence[float] | np.ndarray,
    R: Sequence[float] | np.ndarray | float,
    d: Sequence[float] | np.ndarray | float,
    phi: Sequence[float] | np.ndarray | float | None = None,
    *,
    h2: float,
    h3: float,
    theta0: Sequence[float] | np.ndarray | None = None,
    params: StiffnessParams | None = None,
    model_flags: Any = None,
    model_reasons: Any = None,
    force_ok: Any = None,
    push_ids: Sequence[Any] | None = None,
    force_se: Any = None,
) -> PushEstimates:
    """Stiffness of the pushed object for each push (Eqs. 38-42), with flags.  ``theta1, theta2``
    (rad) are the estimated joint deflections and ``Fx, Fy`` (N) the estimated
    force for each push; ``R`` and ``d`` in m (scalars or per push); ``phi`` in rad, NaN (or None
    for all) where unknown, then solved.  ``theta0`` is the absolute baseline posture ((2,) or
    (n, 2) rad; None: the paper's upright arm).  ``model_flags`` (per push: list of flag names,
    string or bool) replaces the built-in singular-pose check when given, since the model knows
    where its estimate fails; names in ``params.accept_model_flags`` do not exclude the push.
    ``force_ok`` ((n, 2) bool: Fx, Fy usable, as ``TakumaModel.predict`` gives in ``ok``) tells
    which component a ``singular-jacobian`` flag concerns; with it, ``params.singular_component``
    applies (see the module docstring).  ``force_se`` ((n, 2) N): Fx, Fy's standard errors.
    """
    params = params or StiffnessParams()
    t1, t2, F, R, d, phi_in, base = _push_inputs(theta1, theta2, Fx, Fy, R, d, phi, theta0, push_ids)
    n = t1.shape[0]
    a1, a2 = base[:, 0] + t1, base[:, 1] + t2  # absolute posture under the push
    C = contact_point(a1, a2, h2, h3)
    C0 = None if theta0 is None else contact_point(base[:, 0], base[:, 1], h2, h3)
    known = np.isfinite(phi_in)
    model = _flags_from_model(model_flags, model_reasons, n)
    reasons: list[list[str]] = [[] for _ in range(n)]
    notes: list[list[str]] = [[] for _ in range(n)]
    # Pushes whose singular-jacobian the policy dealt with; pushes with phi to solve and no force direction.
    handled, unobserved = np.zeros(n, dtype=bool), np.zeros(n, dtype=bool)
    if force_ok is not None and model is not None and params.singular_component == "project":
        F, handled, unobserved = _project_singular(
            F, force_ok, model, known, C, object_centre(R, d, phi_in, h2, h3, C0), params, reasons, notes, n
        )
    force = np.hypot(F[:, 0], F[:, 1])
    sol = solve_phi(C, F, R, d, h2, h3, C0)
    phi_out = np.where(known, phi_in, np.where(unobserved, np.nan, sol.phi))
    O2, g, dist, delta_x, k, direction_error = _deformation(C, F, force, R, d, phi_out, h2, h3, C0)
    dx_theta = _deformation_per_angle(a1, a2, h2, h3, R, C0, O2, g, dist, F, force, known)
    finite_in = np.isfinite(t1) & np.isfinite(t2) & np.isfinite(F).all(axis=1)
    _flag(reasons, finite_in, force, known, unobserved, sol.n_solutions, phi_out, delta_x, direction_error, params)
    phi_gain = np.where(known | unobserved, np.nan, sol.phi_gain)
    phi_se = _phi_standard_error(F, force_se, phi_gain, reasons, finite_in & np.isfinite(phi_out), params)
    _within_noise(reasons, C, F, R, d, object_centre(R, np.zeros(n), np.zeros(n), h2, h3, C0), force_se)
    if model is None:
        _add(reasons, finite_in & (np.abs(np.sin(a2)) < params.singular_sin_theta2), REASON_SINGULAR)
    else:
        _flag_model(reasons, notes, model, handled, params)
    reason = np.array(list(map("; ".join, reasons)), dtype=object)
    return PushEstimates(
        C=C,
        phi=phi_out,
        phi_solved=~known,
        n_phi_solutions=np.where(known, 1, np.where(unobserved, 0, sol.n_solutions)).astype(int),
        O2=O2,
        delta_x=delta_x,
        force=force,
        k=k,
        direction_error=direction_error,
        phi_gain=phi_gain,
        dx_gain=np.where(known | unobserved, np.nan, sol.dx_gain),
        dx_theta_gain=np.hypot(dx_theta[:, 0], dx_theta[:, 1]),
        flag=reason != "",
        reason=reason,
        note=np.array(list(map("; ".join, notes)), dtype=object),
        F=F,
        phi_se=phi_se,
    )


def _phi_standard_error(
    F: np.ndarray, force_se: Any, phi_gain: np.ndarray, reasons: list[list[str]], solved: np.ndarray, params: Any
) -> np.ndarray:
    """A solved phi's standard error (rad): the force direction's times ``phi_gain``; pushes whose
    error exceeds ``params.max_phi_se_deg`` get the reason that their direction is not determined.

    The direction alpha = atan2(Fy, Fx) moves by (Fx dFy - Fy dFx) / |F|^2, so with independent
    component errors se_alpha^2 = (Fy^2 se_x^2 + Fx^2 se_y^2) / |F|^4.  Where the ray from C grazes
    the d-circle phi_gain is unbounded, and so is the error: such a push is not determined.
    """
    n = F.shape[0]
    if force_se is None:
        return np.full(n, np.nan)
    se = np.asarray(force_se, dtype=float)
    if se.shape != (n, 2):
        raise ConfigError(f"Force standard errors have shape {se.shape}, expected ({n}, 2) for {n} pushes.")
    with np.errstate(invalid="ignore", divide="ignore"):
        se_alpha = np.hypot(F[:, 1] * se[:, 0], F[:, 0] * se[:, 1]) / (F[:, 0] ** 2 + F[:, 1] ** 2)
        phi_se = np.abs(phi_gain) * se_alpha
        _add(reasons, solved & (phi_se > math.radians(params.max_phi_se_deg)), REASON_UNDETERMINED_DIRECTION)
    return phi_se


def _within_noise(
    reasons: list[list[str]], C: np.ndarray, F: np.ndarray, R: np.ndarray, d: np.ndarray, O1: np.ndarray, force_se: Any
) -> None:
    """A push whose force points from no admissible object centre, but within twice the force
    direction's standard error of one that does, is not determined rather than inconsistent: its
    reason becomes that of an undetermined direction (it stays left out either way).

    The admissible directions are found on a half-degree grid: the ray from C against the force
    must meet the circle of radius d about O1 at a distance 0 < s < R.
    """
    rows = [i for i, r in enumerate(reasons) if REASON_NO_PHI in r]
    if force_se is None or not rows:
        return
    se = np.asarray(force_se, dtype=float)[rows]
    Fr = F[rows]
    with np.errstate(invalid="ignore", divide="ignore"):
        se_alpha = np.hypot(Fr[:, 1] * se[:, 0], Fr[:, 0] * se[:, 1]) / (Fr[:, 0] ** 2 + Fr[:, 1] ** 2)
    grid = np.radians(np.arange(0.0, 360.0, 0.5))
    u = np.stack([np.cos(grid), np.sin(grid)], axis=-1)  # (k, 2) candidate force directions
    w = (C - O1)[rows]
    b = w @ u.T  # (m, k)
    disc = b * b - (np.einsum("ij,ij->i", w, w) - d[rows] ** 2)[:, None]
    root = np.sqrt(np.where(disc >= 0, disc, np.nan))
    Rm = R[rows, None]
    with np.errstate(invalid="ignore"):
        ok = (((b - root) > 0) & ((b - root) < Rm)) | (((b + root) > 0) & ((b + root) < Rm))
    alpha = np.arctan2(Fr[:, 1], Fr[:, 0])
    miss = np.abs(np.angle(np.exp(1j * (grid[None, :] - alpha[:, None]))))
    nearest = np.where(ok, miss, np.inf).min(axis=1)
    for i, near, spread in zip(rows, nearest.tolist(), se_alpha.tolist(), strict=True):
        if math.isfinite(near) and near <= 2.0 * spread:
            reasons[i] = [REASON_UNDETERMINED_DIRECTION if r == REASON_NO_PHI else r for r in reasons[i]]


def _push_inputs(
    theta1: Any, theta2: Any, Fx: Any, Fy: Any, R: Any, d: Any, phi: Any, theta0: Any, push_ids: Sequence[Any] | None
) -> tuple[np.ndarray, ...]:
    """The pushes' inputs as arrays of one value per push, checked (ConfigError naming the push)."""
    t1 = np.atleast_1d(np.asarray(theta1, dtype=float))
    n = t1.shape[0]
    ids = list(push_ids) if push_ids is not None else list(range(n))

    def vec(name: str, value: Any, unit: str) -> np.ndarray:
        arr = np.asarray(value, dtype=float)
        if arr.ndim == 0:
            arr = np.full(n, float(arr))
        if arr.shape != (n,):
            raise ConfigError(
                f"{name} has {arr.size} values for {n} pushes; give one per push or a single {unit} value."
            )
        return arr

    t2 = vec("theta2", theta2, "rad")
    F = np.stack([vec("Fx", Fx, "N"), vec("Fy", Fy, "N")], axis=-1)
    R = vec("R_m", R, "m")
    d = vec("d_m", d, "m")
    phi_in = np.full(n, np.nan) if phi is None else vec("phi", phi, "rad")
    base = np.zeros((n, 2)) if theta0 is None else np.broadcast_to(np.asarray(theta0, dtype=float), (n, 2))
    for name, arr, ok in (("object radius R_m", R, R > 0), ("push distance d_m", d, d >= 0)):
        bad = np.flatnonzero(~(np.isfinite(arr) & ok))
        if bad.size:
            i = bad[0]
            raise ConfigError(
                f"Push {ids[i]}: {name} must be a {'positive' if 'radius' in name else 'non-negative'} "
                f"number of metres, got {float(arr[i]):g}; check the push table."
            )
    if not np.isfinite(base).all():
        raise ConfigError("The baseline posture theta0 must be finite angles in rad.")
    return t1, t2, F, R, d, phi_in, base


def _deformation_per_angle(
    a1: np.ndarray,
    a2: np.ndarray,
    h2: float,
    h3: float,
    R: np.ndarray,
    C0: Any,
    O2: np.ndarray,
    g: np.ndarray,
    dist: np.ndarray,
    F: np.ndarray,
    force: np.ndarray,
    known: np.ndarray,
) -> np.ndarray:
    """d delta_x / d theta (m/rad, per push): how an angle error moves the deformation.

    Through C alone for a given phi (-n^T J, n the unit vector O2 -> C); for a solved phi,
    O2 slides along the d-circle as C moves, which gives -v^T J / (v . F^) with v = O2 - O1.
    """
    n = len(a1)
    J = jacobian(a1, a2, h2, h3)
    with np.errstate(invalid="ignore", divide="ignore"):
        v = O2 - object_centre(R, np.zeros(n), np.zeros(n), h2, h3, C0)
        dir_row = np.where(known[:, None], g / dist[:, None], v / np.einsum("ij,ij->i", v, F / force[:, None])[:, None])
    return -np.einsum("ij,ijk->ik", dir_row, J)


def _add(reasons: list[list[str]], mask: np.ndarray, text: str) -> None:
    for i in np.flatnonzero(mask):
        reasons[i].append(text)


def _flag(
    reasons: list[list[str]],
    finite_in: np.ndarray,
    force: np.ndarray,
    known: np.ndarray,
    unobserved: np.ndarray,
    n_solutions: np.ndarray,
    phi_out: np.ndarray,
    delta_x: np.ndarray,
    direction_error: np.ndarray,
    params: StiffnessParams,
) -> None:
    """Why a push's stiffness cannot be trusted: inputs, force, direction, deformation."""
    _add(reasons, ~finite_in, REASON_INPUT)
    _add(reasons, finite_in & (force < params.min_force_N), REASON_SMALL_FORCE)
    _add(reasons, finite_in & ~known & ~unobserved & (n_solutions == 0) & (force >= params.min_force_N), REASON_NO_PHI)
    has_phi = np.isfinite(phi_out)
    with np.errstate(invalid="ignore"):
        _add(reasons, finite_in & has_phi & (delta_x <= 0), REASON_NO_DEFORMATION)
        _add(
            reasons,
            finite_in & has_phi & (delta_x > 0) & (delta_x < params.min_deformation_m),
            REASON_SMALL_DEFORMATION,
        )
        _add(
            reasons,
            finite_in
            & known
            & (force >= params.min_force_N)
            & (np.abs(direction_error) > math.radians(params.max_direction_error_deg)),
            REASON_DIRECTION,
        )


def _flag_model(
    reasons: list[list[str]],
    notes: list[list[str]],
    model: list[list[str]],
    handled: np.ndarray,
    params: StiffnessParams,
) -> None:
    """The model's own flags: kept as reasons, or noted where the settings accept them."""
    accepted = set(params.accept_model_flags)
    for i, names in enumerate(model):
        if handled[i]:
            names = [t for t in names if t not in ONE_COMPONENT_FLAGS]
        if not names:
            continue
        kept = [t for t in names if t not in accepted]
        if kept:
            reasons[i].append("model: " + ", ".join(kept))
        notes[i].extend(f"accepted model flag: {t}" for t in names if t in accepted)


def _project_singular(
    F: np.ndarray,
    force_ok: Any,
    model: list[list[str]],
    known: np.ndarray,
    C: np.ndarray,
    O2_given: np.ndarray,
    params: StiffnessParams,
    reasons: list[list[str]],
    notes: list[list[str]],
    n: int,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Rebuild F from its usable component along O2 -> C where the model flags only the other.

    Returns the force to use, which pushes had their ``singular-jacobian``
    flag dealt with here (projected, or flagged with a reason of their own),
    and which of them have phi to solve with no usable force direction.
    """
    ok = np.asarray(force_ok, dtype=bool)
    if ok.shape != (n, 2):
        raise ConfigError(f"Model force flags have shape {ok.shape}, expected ({n}, 2) for {n} pushes.")
    # Only pushes whose sole complaint is one lost force component, with exactly one component usable.
    only_singular = np.array([bool(names) and set(names) <= ONE_COMPONENT_FLAGS for names in model], dtype=bool)
    one = only_singular & (ok.sum(axis=1) == 1)
    F = F.copy()
    g = C - O2_given
    with np.errstate(invalid="ignore", divide="ignore"):
        u = g / np.hypot(g[:, 0], g[:, 1])[:, None]
    names = ("Fx", "Fy")
    unobserved = one & ~known
    # Every push at once; only the sentences are appended push by push.
    c = np.where(ok[:, 0], 0, 1)
    share = u[np.arange(n), c]
    usable = F[np.arange(n), c]
    with np.errstate(invalid="ignore"):
        good = (np.abs(share) >= params.min_projection) & (usable * share > 0)
    project = one & known & good
    F[project] = (usable[project] / share[project])[:, None] * u[project]
    for i in np.flatnonzero(unobserved):
        reasons[i].append(REASON_UNOBSERVED_DIRECTION)
    for i in np.flatnonzero(one & known & ~good):
        reasons[i].append(REASON_PROJECTION)
    text = [f"force from {names[k]} along O2 -> C ({names[1 - k]} near singular)" for k in (0, 1)]
    for i, k in zip(np.flatnonzero(project).tolist(), c[project].tolist(), strict=False):
        notes[i].append(text[k])
    return F, one, unobserved


def object_stats(k: np.ndarray, flag: np.ndarray) -> dict[str, float]:
    """Mean, median and spread of one object's unflagged stiffness values (N/m and natural log)."""
    k = np.asarray(k, dtype=float)
    used = k[~np.asarray(flag, dtype=bool) & np.isfinite(k) & (k > 0)]
    n_used = int(used.size)
    out = {
        "n_pushes": int(k.size),
        "n_used": n_used,
        "n_flagged": int(k.size - n_used),
        "k_mean_N_per_m": float(used.mean()) if n_used else math.nan,
        "k_std_N_per_m": float(used.std(ddof=1)) if n_used > 1 else math.nan,
        "k_median_N_per_m": float(np.median(used)) if n_used else math.nan,
        "log_k_mean": float(np.log(used).mean()) if n_used else math.nan,
        "log_k_std": float(np.log(used).std(ddof=1)) if n_used > 1 else math.nan,
    }
    return out


def groups_by_size(values: np.ndarray, group: np.ndarray, n_groups: int) -> Iterator[tuple[np.ndarray, np.ndarray]]:
    """Every group's values as one row, the groups of one size together: (group numbers, (m, size) rows).

    A row holds its group's values in their order, contiguous, so numpy reduces it along the row
    exactly as it reduces that group alone (the same pairwise sums, bit for bit): ten thousand
    objects' statistics in a few calls instead of a few calls each.
    """
    order = np.argsort(group, kind="stable")
    counts = np.bincount(group, minlength=n_groups)
    starts = np.cumsum(counts) - counts
    v = values[order]
    for size in np.unique(counts[counts > 0]).tolist():
        ids = np.flatnonzero(counts == size)
        yield ids, v[starts[ids][:, None] + np.arange(size)]


def object_stats_many(k: np.ndarray, flag: np.ndarray, group: np.ndarray, n_groups: int) -> dict[str, np.ndarray]:
    """:func:`object_stats` of every group (objects numbered 0 .. n_groups - 1) at once, one array per key."""
    k = np.asarray(k, dtype=float)
    good = ~np.asarray(flag, dtype=bool) & np.isfinite(k) & (k > 0)
    n = np.bincount(group, minlength=n_groups)
    used = np.bincount(group[good], minlength=n_groups)
    out = {"n_pushes": n, "n_used": used, "n_flagged": n - used}
    for key in ("k_mean_N_per_m", "k_std_N_per_m", "k_median_N_per_m", "log_k_mean", "log_k_std"):
        out[key] = np.full(n_groups, math.nan)
    for ids, rows in groups_by_size(k[good], group[good], n_groups):
        logs = np.log(rows)
        out["k_mean_N_per_m"][ids] = rows.mean(axis=1)
        out["k_median_N_per_m"][ids] = np.median(rows, axis=1)
        out["log_k_mean"][ids] = logs.mean(axis=1)
        if rows.shape[1] > 1:
            out["k_std_N_per_m"][ids] = rows.std(axis=1, ddof=1)
            out["log_k_std"][ids] = logs.std(axis=1, ddof=1)
    return out
