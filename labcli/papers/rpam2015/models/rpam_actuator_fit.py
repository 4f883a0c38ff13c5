"""The lab's own actuator from its stretch test: Ogden moduli, free length and radius, with errors.

A stretch test (Figs. 5-6) hangs the actuator under payloads m at pressures P and reads its
length L.  Each point is one equation of the force balance (Eqs. 1, 7),

    F_ext(P, L; theta) = m g,

with ``F_ext`` the actuator's force in its reading (:mod:`.rpam_force`) plus Eq. 7's cubic.
:func:`fit_actuator` fits by nonlinear least squares (scipy's ``least_squares``, trust region
with the moduli kept positive) the parameters ``theta`` of the lab's actuator:

* the Ogden moduli ``mu_i`` (MPa) of Eq. 3, the exponents ``alpha_i`` held at the protocol's
  (moduli and exponents together are not identifiable from one stretch test: the exponents
  shape the same curve the moduli scale);
* the cubic ``c0..c3`` (N) of Eq. 7 with them, since the correction is what the model leaves
  unexplained and changes with the moduli;
* the actuator's free length ``L0`` and rest radius ``r`` (the thread cage's radius at L0)
  when the data support them.  Resizing keeps the protocol's number of thread turns and wall
  thickness, so the thread length ``b = sqrt(L0^2 + (2 pi n r)^2)`` and the wall section follow.

Standard errors are from the Jacobian at the optimum, ``cov = s^2 (J^T J)^-1`` with ``s^2``
the residual variance (RSS / degrees of freedom), as for any least-squares fit whose errors are
the load's scatter (friction on the stand, Fig. 6).

What the data determine.  The pressure's share of the force, ``P (3 L^2 - b^2) / (4 pi n^2)``
(plus ``P A0 / lambda`` in the paper's reading), fixes the cage, so the radius is usually
well determined; the free length moves every stretch at once.  Each geometric parameter is
added only when it lowers the residual sum of squares significantly (an F-test at
:data:`GEOMETRY_P_VALUE`, one parameter at a time); otherwise it stays at the protocol's value
and the result says why (``geometry[name]["note"]``).  The moduli are always fitted, but the
wall's force is a function of the stretch alone wherever the cage holds the wall, as the cubic
is, so a stretch test separates them only through the shape of Eq. 3 and through the vented
and low-pressure points (where the wall is free, not cage-held, in the derived reading).  A
modulus whose standard error exceeds half its value is reported as not determined by the data
(``determined``): the initial shear modulus, the sum, is typically determined far better than
the single terms.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from ....errors import ModelError
from ..actuator import Actuator
from . import rpam

# A free length or radius is fitted when the data give it to this fraction of its value (a
# caliper measures either to about 1 %: a stretch test that does worse adds nothing).
GEOMETRY_RELATIVE_SE = 0.02
GEOMETRY = ("L0_m", "radius_m")
# A modulus is determined when its standard error is under this fraction of its value.
DETERMINED_RELATIVE_SE = 0.5
_MU_FLOOR_MPA = 1e-9  # the moduli stay positive (Eq. 3's convention for a stable wall)
_LABELS = {"L0_m": "free length", "radius_m": "rest radius"}
_WHY_UNDETERMINED = {
    "derived": "where the cage holds the wall its force depends on the stretch alone",
    "paper": "the paper's wall force, Eq. 3, depends on the stretch alone",
}


def resized(act: Actuator, L0_m: float | None = None, radius_m: float | None = None) -> Actuator:
    """``act`` with another free length and rest radius, same thread turns and wall thickness.

    The thread length becomes ``sqrt(L0^2 + (2 pi n r)^2)`` (n turns round radius r over L0)
    and the wall section ``pi (r^2 - (r - t)^2)`` for the protocol's wall thickness t.
    """
    if L0_m is None and radius_m is None:
        return act
    r0 = act.rest_radius_m
    thickness = r0 - math.sqrt(max(r0**2 - act.A0_m2 / math.pi, 0.0))
    L0 = act.L0_m if L0_m is None else float(L0_m)
    r = r0 if radius_m is None else float(radius_m)
    if not (L0 > 0 and r > thickness):
        raise ModelError(f"An actuator of free length {L0:g} m and radius {r:g} m cannot hold its wall.")
    b = math.hypot(L0, 2 * math.pi * act.n_turns * r)
    return replace(act, L0_m=L0, thread_length_m=b, A0_m2=math.pi * (r**2 - (r - thickness) ** 2))


@dataclass
class ActuatorFit:
    """The lab's actuator fitted to a stretch test; plain data (``to_dict`` / ``from_dict``).

    ``names``/``values``/``std_errors``/``covariance``: every fitted parameter (``mu_1``..
    ``mu_k`` in MPa, ``c0``..``c3`` in N, and ``L0_m``, ``radius_m`` in m when fitted);
    ``protocol_values``: the same names' values in the protocol the fit started from;
    ``geometry``: per geometric parameter, whether it was fitted, its value and standard error
    with every parameter free, and a sentence; ``actuator``: the fitted actuator, ready
    for the model and the optimiser.
    """

    actuator: Actuator
    names: tuple[str, ...]
    values: tuple[float, ...]
    std_errors: tuple[float, ...]
    covariance: tuple[tuple[float, ...], ...]
    protocol_values: dict[str, float]
    geometry: dict[str, dict[str, Any]]
    rmse_N: float
    n_points: int
    dof: int
    force_reading: str
    notes: list[str] = field(default_factory=list)

    def value(self, name: str) -> float:
        return self.values[self.names.index(name)]

    def std_error(self, name: str) -> float:
        return self.std_errors[self.names.index(name)]

    @property
    def moduli(self) -> list[str]:
        return [n for n in self.names if n.startswith("mu_")]

    @property
    def determined(self) -> dict[str, bool]:
        """Per modulus: is its standard error under half its value?"""
        return {n: self.std_error(n) < DETERMINED_RELATIVE_SE * abs(self.value(n)) for n in self.moduli}

    def to_dict(self) -> dict[str, Any]:
        return {
            "kind": "rpam-actuator-fit",
            "force_reading": self.force_reading,
            "parameters": {
                n: {"value": v, "std_error": s, "protocol": self.protocol_values.get(n)}
                for n, v, s in zip(self.names, self.values, self.std_errors, strict=True)
            },
            "names": list(self.names),
            "covariance": [list(r) for r in self.covariance],
            "determined": self.determined,
            "geometry": self.geometry,
            "rmse_N": self.rmse_N,
            "n_points": self.n_points,
            "dof": self.dof,
            "notes": list(self.notes),
            "actuator": self.actuator.to_dict(),
        }

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> ActuatorFit:
        if d.get("kind") != "rpam-actuator-fit":
            raise ModelError(f"Expected a fitted actuator (kind 'rpam-actuator-fit'), got kind {d.get('kind')!r}.")
        try:
            names = tuple(str(n) for n in d["names"])
            params = d["parameters"]
            return cls(
                actuator=Actuator.from_dict(d["actuator"]),
                names=names,
                values=tuple(float(params[n]["value"]) for n in names),
                std_errors=tuple(float(params[n]["std_error"]) for n in names),
                covariance=tuple(tuple(float(v) for v in row) for row in d["covariance"]),
                protocol_values={
                    n: float(params[n]["protocol"]) for n in names if params[n].get("protocol") is not None
                },
                geometry={str(k): dict(v) for k, v in d["geometry"].items()},
                rmse_N=float(d["rmse_N"]),
                n_points=int(d["n_points"]),
                dof=int(d["dof"]),
                force_reading=str(d["force_reading"]),
                notes=[str(v) for v in d.get("notes", [])],
            )
        except (KeyError, TypeError, ValueError, AttributeError, IndexError) as e:
            raise ModelError(f"The fitted actuator record is incomplete or malformed ({e!s}).") from None


@dataclass
class _Solution:
    names: tuple[str, ...]
    x: np.ndarray
    cov: np.ndarray
    rss: float
    dof: int
    actuator: Actuator


class _Problem:
    """The residuals ``F_ext(P, L; theta) - m g`` (N) for a chosen set of free parameters."""

    def __init__(self, mass_kg: np.ndarray, P: np.ndarray, L: np.ndarray, act: Actuator) -> None:
        self.load = mass_kg * rpam.G_N_PER_KG
        self.P, self.L, self.act = P, L, act
        self.k = len(act.ogden_mu_MPa)

    def names(self, geometry: Sequence[str]) -> tuple[str, ...]:
        return (*(f"mu_{i + 1}" for i in range(self.k)), "c0", "c1", "c2", "c3", *geometry)

    def start(self, geometry: Sequence[str]) -> tuple[np.ndarray, np.ndarray]:
        """(starting point, typical scale) of each parameter."""
        a = self.act
        geo = {"L0_m": a.L0_m, "radius_m": a.rest_radius_m}
        x0 = np.r_[a.ogden_mu_MPa, a.stretch_coefficients_N, [geo[g] for g in geometry]]
        scale = np.r_[a.ogden_mu_MPa, np.maximum(np.abs(a.stretch_coefficients_N), 1.0), [1e-3] * len(geometry)]
        return x0.astype(float), scale.astype(float)

    def actuator(self, x: np.ndarray, geometry: Sequence[str]) -> Actuator:
        k = self.k
        geo = dict(zip(geometry, x[k + 4 :], strict=True))
        act = resized(self.act, geo.get("L0_m"), geo.get("radius_m"))
        lam = self.L / act.L0_m
        return replace(
            act,
            ogden_mu_MPa=tuple(float(v) for v in x[:k]),
            stretch_coefficients_N=tuple(float(v) for v in x[k : k + 4]),
            # The fit's own stretches: the cubic is never clamped inside them.
            stretch_lambda_range=(float(lam.min()), float(lam.max())),
        )

    def residuals(self, x: np.ndarray, geometry: Sequence[str]) -> np.ndarray:
        try:
            act = self.actuator(x, geometry)
        except ModelError:
            return np.full(self.L.shape, 1e6)
        r = rpam.external_force(self.P, self.L, act) - self.load
        return np.where(np.isfinite(r), r, 1e6)

    def solve(self, geometry: Sequence[str]) -> _Solution:
        from scipy.optimize import least_squares

        names = self.names(geometry)
        x0, scale = self.start(geometry)
        lower = np.r_[[_MU_FLOOR_MPA] * self.k, [-np.inf] * (4 + len(geometry))]
        res = least_squares(
            self.residuals,
            x0,
            args=(geometry,),
            x_scale=scale,
            bounds=(lower, np.inf),
            jac="3-point",
            xtol=1e-12,
            ftol=1e-12,
            gtol=1e-12,
            max_nfev=400,
        )
        dof = self.L.size - len(names)
        rss = float(res.fun @ res.fun)
        J = np.asarray(res.jac, dtype=float) * scale  # in scaled units: better conditioned
        cov_scaled = (rss / dof) * np.linalg.pinv(J.T @ J)
        cov = cov_scaled * np.outer(scale, scale)
        return _Solution(names, np.asarray(res.x, float), cov, rss, dof, self.actuator(res.x, geometry))


def fit_actuator(mass_kg: Any, P_MPa: Any, L_m: Any, act: Actuator) -> ActuatorFit:
    """Fit the Ogden moduli and Eq. 7's cubic (and L0, r when supported) to stretch-test points.

    ``mass_kg``, ``P_MPa`` and ``L_m`` are the points (finite, checked by the caller);
    ``act`` is the protocol's actuator in the reading to fit under, and the starting point.
    """
    mass, P, L = (np.asarray(v, dtype=float).ravel() for v in (mass_kg, P_MPa, L_m))
    problem = _Problem(mass, P, L, act)
    need = len(problem.names(GEOMETRY)) + 2
    if L.size < need:
        raise ModelError(
            f"Fitting the actuator (its {problem.k} Ogden moduli, the cubic and its free length and radius) "
            f"needs at least {need} stretch-test points; the test gave {L.size}."
        )
    protocol_geo = {"L0_m": act.L0_m, "radius_m": act.rest_radius_m}
    # Every parameter free first: leaving out a dimension the data do determine biases the
    # moduli and the cubic by more than their errors.  A dimension the data leave loose
    # (standard error above GEOMETRY_RELATIVE_SE of its value) is held at the protocol's.
    full = problem.solve(GEOMETRY)
    loose = {}
    for name in GEOMETRY:
        i = full.names.index(name)
        value, se = float(full.x[i]), float(math.sqrt(max(full.cov[i, i], 0.0)))
        if not se < GEOMETRY_RELATIVE_SE * abs(value):
            loose[name] = (value, se)
    best = problem.solve(tuple(n for n in GEOMETRY if n not in loose)) if loose else full
    geometry: dict[str, dict[str, Any]] = {}
    for name in GEOMETRY:
        label, protocol = _LABELS[name], protocol_geo[name]
        if name in loose:
            value, se = loose[name]
            note = (
                f"The data do not support fitting the {label}: its standard error, {se * 1e3:.2g} mm, is above "
                f"{GEOMETRY_RELATIVE_SE:.0%} of it (stretches or pressures too few or too alike), so it stays at "
                f"the protocol's {protocol * 1e3:.2f} mm."
            )
        else:
            i = best.names.index(name)
            value, se = float(best.x[i]), float(math.sqrt(max(best.cov[i, i], 0.0)))
            note = f"The {label} is fitted: {value * 1e3:.2f} +- {se * 1e3:.2f} mm (the protocol's {protocol * 1e3:.2f} mm)."
        geometry[name] = {
            "fitted": name not in loose,
            "value": value,
            "std_error": se,
            "protocol": protocol,
            "note": note,
        }
    se_all = np.sqrt(np.clip(np.diag(best.cov), 0.0, None))
    protocol_values = dict(zip(problem.names(GEOMETRY), problem.start(GEOMETRY)[0].tolist(), strict=True))
    out = ActuatorFit(
        actuator=best.actuator,
        names=best.names,
        values=tuple(float(v) for v in best.x),
        std_errors=tuple(float(v) for v in se_all),
        covariance=tuple(tuple(float(v) for v in row) for row in best.cov),
        protocol_values={n: float(protocol_values[n]) for n in best.names},
        geometry=geometry,
        rmse_N=math.sqrt(best.rss / L.size),
        n_points=int(L.size),
        dof=int(best.dof),
        force_reading=act.force_reading,
    )
    undetermined = [n for n, ok in out.determined.items() if not ok]
    if undetermined:
        out.notes.append(
            f"The stretch test does not determine {', '.join(undetermined)} (standard error above half the value): "
            f"{_WHY_UNDETERMINED[act.force_reading]}, as the stretch correction does, so the two trade against "
            "each other; the sum of the moduli, the initial shear modulus, is "
            f"{sum(out.value(n) for n in out.moduli):.4g} +- {_sum_se(out):.2g} MPa."
        )
    at_floor = [n for n in out.moduli if out.value(n) <= 10 * _MU_FLOOR_MPA]
    if at_floor:
        out.notes.append(
            f"{', '.join(at_floor)} reached 0 MPa, the least a stable wall allows, where a standard error means "
            "little: the data ask for less of that term than any."
        )
    return out


def _sum_se(fit: ActuatorFit) -> float:
    idx = [fit.names.index(n) for n in fit.moduli]
    cov = np.asarray(fit.covariance)[np.ix_(idx, idx)]
    return float(math.sqrt(max(float(cov.sum()), 0.0)))
