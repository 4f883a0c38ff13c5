"""Analysis of rPAM runs: the stretch test (Figs. 5-6, Eq. 7) and the joint map (Fig. 8).

Two calls, one per experiment of the rPAM joint paper:

* :func:`analyse_stretch` turns a stretch-test table into the empirical stretch force of
  every point, ``F_stretch = m g - F_cons - F_int`` (Eq. 7 with ``F_ext = m g``; the
  gas's and the wall's forces are :mod:`labcli.papers.rpam2015.models.rpam`'s, derived
  from one potential in :mod:`labcli.papers.rpam2015.models.rpam_force`), and fits the cubic
  ``F_stretch(lambda) = c0 + c1 lambda + c2 lambda^2 + c3 lambda^3`` by least squares with
  standard errors, 95 % intervals, R^2 and RMSE (:class:`StretchCorrection`).
* the same call fits the lab's own actuator to the same points
  (:func:`~.rpam_actuator_fit.fit_actuator`): the Ogden moduli of Eq. 3 with the cubic, and
  the free length and radius when the data support them, each with its standard error
  (``StretchFit.actuator_fit``; ``labcli optimize --actuator`` designs with it).
* :func:`analyse_joint_map` compares a measured map of joint angles over (Pa, Pb) with
  the model's angles without and with the correction (Eq. 6 solved on the valid branch
  for every point at once), and flags where the model runs onto the toggle angle.

Input tables are pandas DataFrames or any mapping of column name -> sequence.  SI inside;
the column names carry the units (``docs/table-formats.md`` style):

=================  ===========================================================
stretch table      ``mass_g`` (or ``payload_kg``), ``P_A`` (MPa gauge; or
                   ``P_MPa``), ``L_m`` (actuator length, m; or ``lambda``)
joint-map table    ``P_A``, ``P_B`` (MPa gauge), ``alpha_deg`` (measured angle)
=================  ===========================================================

Rows with a missing value (NaN) are left out of the fit and listed in the result
(``skipped_rows``); impossible values (negative mass or pressure, non-positive length)
are a :class:`~labcli.errors.ModelError` naming the row (a measured pressure may read a
little below 0 through noise; below -5 kPa is taken as a sensor fault).

JSON documents (``to_dict`` / ``to_json``; ``from_dict`` / ``from_json`` read them back;
NaN is written as ``null``):

``StretchCorrection.to_dict()``::

    {"kind": "rpam-stretch-correction", "degree": 3,
     "coefficients_N": [c0, c1, c2, c3], "std_errors_N": [...4],
     "ci95_N": [[lo, hi] x 4], "covariance_N2": [[...4] x 4],
     "r2": float, "rmse_N": float, "n_points": int, "dof": int,
     "lambda_range": [min, max]}          # stretches the fit saw

``StretchFit.to_dict()``::

    {"kind": "rpam-stretch-fit", "protocol": path, "L0_m": float,
     "default_coefficients_N": [...4],     # the protocol's [stretch_correction]
     "default_lambda_range": [lo, hi],     # ... and the stretches it holds for
     "model": <StretchCorrection.to_dict()>,
     "skipped_rows": [int, ...],
     "actuator_fit": <ActuatorFit.to_dict()> | null,   # the lab's actuator, below
     "actuator_note": str,                 # why there is none ("" when there is)
     "points": {"row", "mass_kg", "P_MPa", "L_m", "lambda", "F_ext_N", "F_cons_N",
                "F_int_N", "F_stretch_N", "fitted_N", "residual_N": [...]}}

``JointMapResult.to_dict()``::

    {"kind": "rpam-joint-map", "protocol": path,
     "geometry": {"L1_m", "L2_m", "L3_m"}, "toggle_deg": float,
     "actuator": <Actuator.to_dict()>,          # correction included
     "correction": {"coefficients_N": [...4], "lambda_range": [lo, hi],
                    "source": "protocol" | "fit" | "given"},
     "summary": {"without": S, "with": S},
     "skipped_rows": [int, ...],
     "points": {"row", "P_A_MPa", "P_B_MPa", "measured_deg",
                "without_deg", "with_deg",            # null where the model toggles
                "without_toggle", "with_toggle": [bool, ...]}}

    S = {"rmse_deg", "max_abs_error_deg", "max_error_at_kPa": [Pa, Pb],
         "n_compared", "n_toggle", "n_on_stop", "rmse_all_deg"}

``rmse_deg`` and ``max_abs_error_deg`` are over the ``n_compared`` points where both the
model and the joint balance.  The others are ``n_toggle`` points where the model runs onto
the toggle, and ``n_on_stop`` points where the model balances but the joint was measured
on its stop (within :data:`STOP_BAND_DEG` of the toggle angle).  Those are the paper's
toggle (Section V): past the unstable balance that follows the stable one, the torque
drives the joint onto its stop, so a joint that comes from the stop stays there while the
model, released at 0, finds the stable balance.  ``rmse_all_deg`` counts every point, a
model toggle at the toggle angle on the side the pressures drive the joint to.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ....core.jsontext import MAX_DEPTH, JSONDepthError, loads_bounded
from ....core.protocol import check_document
from ....errors import ModelError
from ..actuator import Actuator
from ..protocol import PROTOCOL_KINDS, checked_actuator, load_rpam
from ..settings import RpamSettings
from . import rpam
from .rpam_actuator_fit import ActuatorFit, fit_actuator

DEGREE = 3
# A joint measured this close to its toggle angle rests on its stop, not at a balance: the
# swivel plates stop about 1 deg short of the toggle, plus the potentiometer's offset.
STOP_BAND_DEG = 2.0
_MIN_POINTS = DEGREE + 2  # a cubic plus at least one degree of freedom for its uncertainty
# A vented actuator reads a little below 0 through sensor noise; far below is a fault.
_NEGATIVE_P_MPA = 0.005
_NEGATIVE_P_TEXT = (
    "the rPAM works with gauge pressures of 0 MPa or more, so a reading below -5 kPa "
    "points to a pressure sensor or its calibration"
)


# --------------------------------------------------------------------------- tables and records


def _protocol(protocol: Any) -> tuple[str, RpamSettings]:
    """(how messages name it, its settings) of an rPAM protocol given as a shipped name or a
    path, a loaded protocol, a protocol document (plain data), or a ``(name, protocol)`` pair."""
    label = None
    if isinstance(protocol, tuple) and len(protocol) == 2:
        label, protocol = str(protocol[0]), protocol[1]
    if isinstance(protocol, Mapping):
        protocol = check_document(dict(protocol), source=label or "<protocol>", kinds=tuple(PROTOCOL_KINDS))
    elif isinstance(protocol, (str, Path)):
        protocol = load_rpam(protocol)
    return label or protocol.source_label, protocol.settings


def _columns(table: Any) -> list[str]:
    cols = getattr(table, "columns", None)
    if cols is not None:
        return [str(c) for c in cols]
    if isinstance(table, Mapping):
        return [str(c) for c in table.keys()]
    raise ModelError(f"Expected a table (a DataFrame or a mapping of columns), got {type(table).__name__}.")


def _column(table: Any, what: str, options: Sequence[tuple[str, float]], cols: list[str]) -> np.ndarray:
    """The first column of ``options`` (name, factor to SI) present in the table, as floats."""
    for name, factor in options:
        if name in cols:
            try:
                values = np.asarray(table[name], dtype=float).ravel()
            except (TypeError, ValueError):
                raise ModelError(f"Column '{name}' of the {what} table must hold numbers.") from None
            return values * factor
    names = " or ".join(f"'{n}'" for n, _ in options)
    raise ModelError(f"The {what} table needs a column {names}; it has {', '.join(cols) or 'no columns'}.")


def _row_ids(table: Any, n: int) -> np.ndarray:
    for key in ("point", "trial", "row"):
        if key in _columns(table):
            try:
                return np.asarray(table[key], dtype=np.int64).ravel()
            except (TypeError, ValueError):
                break
    return np.arange(n, dtype=np.int64)


def _nan_to_none(x: Any) -> Any:
    if isinstance(x, float) and not math.isfinite(x):
        return None
    if isinstance(x, (list, tuple)):
        return [_nan_to_none(v) for v in x]
    if isinstance(x, dict):
        return {k: _nan_to_none(v) for k, v in x.items()}
    return x


def _none_to_nan(x: Any) -> Any:
    if x is None:
        return float("nan")
    if isinstance(x, list):
        return [_none_to_nan(v) for v in x]
    return x


def _floats(a: Any) -> list[float]:
    return [float(v) for v in np.ravel(a)]


# --------------------------------------------------------------------------- the cubic


@dataclass
class StretchCorrection:
    """Least-squares cubic ``F_stretch(lambda)`` (N) with its uncertainty; plain data.

    ``StretchCorrection().fit(lam, force_N)`` returns the fitted model; :meth:`predict` and
    :meth:`band` are pure.  ``coefficients_N`` are c0..c3 of ``c0 + c1 l + c2 l^2 + c3 l^3``.
    """

    degree: int = DEGREE
    coefficients_N: tuple[float, ...] = ()
    std_errors_N: tuple[float, ...] = ()
    ci95_N: tuple[tuple[float, float], ...] = ()
    covariance_N2: tuple[tuple[float, ...], ...] = ()
    r2: float = float("nan")
    rmse_N: float = float("nan")
    n_points: int = 0
    dof: int = 0
    lambda_range: tuple[float, float] = (float("nan"), float("nan"))

    @property
    def fitted(self) -> bool:
        return len(self.coefficients_N) == self.degree + 1

    def fit(self, lam: Any, force_N: Any) -> StretchCorrection:
        """Fit the cubic through ``(lambda, F_stretch)``; returns ``self``."""
        from scipy import stats

        if self.degree != DEGREE:
            raise ModelError(f"The stretch correction of Eq. 7 is a cubic (degree 3), not degree {self.degree}.")
        lam = np.asarray(lam, dtype=float).ravel()
        force = np.asarray(force_N, dtype=float).ravel()
        if lam.shape != force.shape:
            raise ModelError(f"Got {lam.size} stretches but {force.size} forces; give one force per stretch.")
        keep = np.isfinite(lam) & np.isfinite(force)
        lam, force = lam[keep], force[keep]
        distinct = np.unique(lam).size
        if lam.size < _MIN_POINTS or distinct < DEGREE + 1:
            raise ModelError(
                f"The stretch correction is a cubic and needs at least {_MIN_POINTS} points at "
                f"{DEGREE + 1} or more distinct stretches; the stretch test gave {lam.size} points at "
                f"{distinct} distinct stretches."
            )
        # Solve in a centred, scaled variable (the monomials of lambda in 1..3 are nearly
        # collinear), then map coefficients and covariance back to powers of lambda.
        centre, half = 0.5 * (lam.max() + lam.min()), 0.5 * (lam.max() - lam.min())
        u = (lam - centre) / half
        U = np.vander(u, DEGREE + 1, increasing=True)
        q, r = np.linalg.qr(U)
        if np.min(np.abs(np.diag(r))) < 1e-10 * np.max(np.abs(np.diag(r))):
            raise ModelError("The stretch-test points do not determine a cubic (the stretches are degenerate).")
        b = np.linalg.solve(r, q.T @ force)
        fitted = U @ b
        resid = force - fitted
        dof = lam.size - (DEGREE + 1)
        s2 = float(resid @ resid) / dof
        rinv = np.linalg.inv(r)
        cov_u = s2 * (rinv @ rinv.T)
        # lambda^k from u: lambda = centre + half u  =>  u^j = sum_k T[j, k] lambda^k.
        T = np.zeros((DEGREE + 1, DEGREE + 1))
        for j in range(DEGREE + 1):
            poly = np.polynomial.polynomial.polypow([-centre / half, 1.0 / half], j)
            T[j, : poly.size] = poly
        coef = T.T @ b
        cov = T.T @ cov_u @ T
        se = np.sqrt(np.clip(np.diag(cov), 0.0, None))
        tq = float(stats.t.ppf(0.975, dof))
        ss_tot = float(((force - force.mean()) ** 2).sum())
        self.coefficients_N = tuple(_floats(coef))
        self.std_errors_N = tuple(_floats(se))
        self.ci95_N = tuple((float(c - tq * s), float(c + tq * s)) for c, s in zip(coef, se, strict=False))
        self.covariance_N2 = tuple(tuple(_floats(row)) for row in cov)
        self.r2 = 1.0 - float(resid @ resid) / ss_tot if ss_tot > 0 else float("nan")
        self.rmse_N = math.sqrt(float(resid @ resid) / lam.size)
        self.n_points = int(lam.size)
        self.dof = int(dof)
        self.lambda_range = (float(lam.min()), float(lam.max()))
        return self

    def _check(self) -> None:
        if not self.fitted:
            raise ModelError("The stretch correction has not been fitted; fit it to a stretch test first.")

    def predict(self, lam: Any) -> np.ndarray:
        """``F_stretch`` (N) at stretches ``lam`` (the polynomial; no clamping)."""
        self._check()
        return np.polynomial.polynomial.polyval(np.asarray(lam, dtype=float), self.coefficients_N)

    def band(self, lam: Any, level: float = 0.95) -> tuple[np.ndarray, np.ndarray]:
        """Confidence band of the fitted mean at ``lam``: ``(low, high)`` in N."""
        from scipy import stats

        self._check()
        lam = np.asarray(lam, dtype=float)
        X = np.stack([lam**k for k in range(self.degree + 1)], axis=-1)
        var = np.einsum("...i,ij,...j->...", X, np.asarray(self.covariance_N2), X)
        half = float(stats.t.ppf(0.5 + level / 2, self.dof)) * np.sqrt(np.clip(var, 0.0, None))
        mid = self.predict(lam)
        return mid - half, mid + half

    def to_dict(self) -> dict[str, Any]:
        return _nan_to_none(
            {
                "kind": "rpam-stretch-correction",
                "degree": self.degree,
                "coefficients_N": list(self.coefficients_N),
                "std_errors_N": list(self.std_errors_N),
                "ci95_N": [list(p) for p in self.ci95_N],
                "covariance_N2": [list(r) for r in self.covariance_N2],
                "r2": self.r2,
                "rmse_N": self.rmse_N,
                "n_points": self.n_points,
                "dof": self.dof,
                "lambda_range": list(self.lambda_range),
            }
        )

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> StretchCorrection:
        if d.get("kind") != "rpam-stretch-correction":
            raise ModelError(
                f"Expected a stretch correction (kind 'rpam-stretch-correction'), got kind {d.get('kind')!r}."
            )
        try:
            d = _none_to_nan(dict(d))
            return cls(
                degree=int(d["degree"]),
                coefficients_N=tuple(float(v) for v in d["coefficients_N"]),
                std_errors_N=tuple(float(v) for v in d["std_errors_N"]),
                ci95_N=tuple((float(a), float(b)) for a, b in d["ci95_N"]),
                covariance_N2=tuple(tuple(float(v) for v in _none_to_nan(r)) for r in d["covariance_N2"]),
                r2=float(_none_to_nan(d["r2"])),
                rmse_N=float(_none_to_nan(d["rmse_N"])),
                n_points=int(d["n_points"]),
                dof=int(d["dof"]),
                lambda_range=tuple(float(v) for v in _none_to_nan(d["lambda_range"])),  # type: ignore[arg-type]
            )
        except (KeyError, TypeError, ValueError) as e:
            raise ModelError(f"The stretch correction record is incomplete or malformed ({e!s}).") from None

    def to_json(self) -> str:
        return json.dumps(self.to_dict(), indent=2)

    @classmethod
    def from_json(cls, text: str) -> StretchCorrection:
        return cls.from_dict(_loads(text, "stretch correction"))


def _loads(text: str, what: str) -> dict[str, Any]:
    try:
        d = loads_bounded(text)
    except json.JSONDecodeError as e:
        raise ModelError(f"The {what} record is not valid JSON ({e.msg} at line {e.lineno}).") from None
    except JSONDepthError as e:
        raise ModelError(
            f"The {what} record nests {e.depth} levels deep, beyond the {MAX_DEPTH} it can have."
        ) from None
    if not isinstance(d, dict):
        raise ModelError(f"The {what} record must be a JSON object.")
    return d


# --------------------------------------------------------------------------- stretch test


@dataclass
class StretchFit:
    """A stretch test analysed: per-point forces and the fitted correction (plain data)."""

    model: StretchCorrection
    points: dict[str, list[Any]]
    protocol: str
    L0_m: float
    default_coefficients_N: tuple[float, ...]
    default_lambda_range: tuple[float, float] = (1.0, 2.2)
    skipped_rows: list[int] = field(default_factory=list)
    force_reading: str = "derived"
    # The lab's actuator fitted to the same points (Ogden moduli, cubic, L0 and radius when the
    # data support them); None, with the reason in actuator_note, when the points are too few.
    actuator_fit: ActuatorFit | None = None
    actuator_note: str = ""

    def apply_to(self, act: Actuator) -> Actuator:
        """``act`` with this fit's coefficients and the stretch range it was fitted on."""
        return act.with_stretch_correction(self.model.coefficients_N, self.model.lambda_range)

    def overrides(self) -> list[str]:
        """``key=value`` assignments for :func:`labcli.papers.rpam2015.models.rpam.apply_overrides` (or ``--set``)."""
        c = ", ".join(repr(v) for v in self.model.coefficients_N)
        lo, hi = self.model.lambda_range
        return [f"stretch_correction.coefficients_N=[{c}]", f"stretch_correction.lambda_range=[{lo!r}, {hi!r}]"]

    def to_dict(self) -> dict[str, Any]:
        return _nan_to_none(
            {
                "kind": "rpam-stretch-fit",
                "protocol": self.protocol,
                "force_reading": self.force_reading,
                "L0_m": self.L0_m,
                "default_coefficients_N": list(self.default_coefficients_N),
                "default_lambda_range": list(self.default_lambda_range),
                "model": self.model.to_dict(),
                "skipped_rows": list(self.skipped_rows),
                "actuator_fit": self.actuator_fit.to_dict() if self.actuator_fit is not None else None,
                "actuator_note": self.actuator_note,
                "points": {k: list(v) for k, v in self.points.items()},
            }
        )

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> StretchFit:
        if d.get("kind") != "rpam-stretch-fit":
            raise ModelError(f"Expected a stretch-test analysis (kind 'rpam-stretch-fit'), got kind {d.get('kind')!r}.")
        try:
            return cls(
                model=StretchCorrection.from_dict(d["model"]),
                points={k: _none_to_nan(list(v)) for k, v in d["points"].items()},
                protocol=str(d["protocol"]),
                L0_m=float(d["L0_m"]),
                default_coefficients_N=tuple(float(v) for v in d["default_coefficients_N"]),
                default_lambda_range=tuple(float(v) for v in d["default_lambda_range"]),  # type: ignore[arg-type]
                skipped_rows=[int(v) for v in d.get("skipped_rows", [])],
                # Fits written before the paper's reading existed were all derived.
                force_reading=str(d.get("force_reading", "derived")),
                # ... and before the actuator was fitted, had none.
                actuator_fit=ActuatorFit.from_dict(d["actuator_fit"]) if d.get("actuator_fit") else None,
                actuator_note=str(d.get("actuator_note", "")),
            )
        except (KeyError, TypeError, ValueError, AttributeError) as e:
            raise ModelError(f"The stretch-test analysis record is incomplete or malformed ({e!s}).") from None

    def to_json(self) -> str:
        return json.dumps(self.to_dict(), indent=2)

    @classmethod
    def from_json(cls, text: str) -> StretchFit:
        return cls.from_dict(_loads(text, "stretch-test analysis"))


def stretch_forces(mass_kg: Any, P_MPa: Any, L_m: Any, act: Actuator) -> dict[str, np.ndarray]:
    """Eq. 7 per point: ``F_ext = m g``, ``F_cons``, ``F_int`` and ``F_stretch = F_ext - F_cons - F_int`` (N)."""
    mass, P, L = (np.asarray(v, dtype=float) for v in (mass_kg, P_MPa, L_m))
    lam = L / act.L0_m
    F_ext = mass * rpam.G_N_PER_KG
    F_cons = rpam.constraint_force(P, L, act)
    F_int = rpam.wall_force(P, L, act)
    return {
        "lambda": lam,
        "F_ext_N": F_ext,
        "F_cons_N": F_cons,
        "F_int_N": F_int,
        "F_stretch_N": F_ext - F_cons - F_int,
    }


def _bad_row(what: str, rows: np.ndarray, mask: np.ndarray, column: str, need: str, values: np.ndarray) -> None:
    if mask.any():
        i = int(np.flatnonzero(mask)[0])
        raise ModelError(f"Row {int(rows[i])} of the {what} table has {column} = {values[i]:g}; {need}.")


def analyse_stretch(table: Any, protocol: Any = "rpam2015", force: str | None = None) -> StretchFit:
    """Analyse a stretch test: per-point ``F_stretch`` (Eq. 7) and the fitted cubic (Fig. 6).

    ``table`` has ``mass_g`` (or ``payload_kg``), ``P_A`` (or ``P_MPa``) in MPa and ``L_m``
    (or ``lambda``); ``protocol`` gives the actuator (a shipped name, a path, a raw dict);
    ``force`` reads its force ``"derived"`` or ``"paper"`` (default: the protocol's).  The
    correction is what the reading leaves unexplained, so it belongs to that reading.
    """
    path, settings = _protocol(protocol)
    act = checked_actuator(settings, path).with_force_reading(force)
    cols = _columns(table)
    mass = _column(table, "stretch", (("mass_g", 1e-3), ("payload_kg", 1.0), ("mass_kg", 1.0)), cols)
    P = _column(table, "stretch", (("P_A", 1.0), ("P_MPa", 1.0)), cols)
    if "L_m" in cols:
        L = _column(table, "stretch", (("L_m", 1.0),), cols)
    else:
        L = _column(table, "stretch", (("L_m", 1.0), ("lambda", act.L0_m)), cols)
    n = mass.size
    if not (P.size == n and L.size == n):
        raise ModelError("The stretch table's columns differ in length.")
    if n == 0:
        raise ModelError("The stretch table is empty; run the stretch test (payloads x pressures) first.")
    rows = _row_ids(table, n)
    ok = np.isfinite(mass) & np.isfinite(P) & np.isfinite(L)
    _bad_row("stretch", rows, ok & (mass < 0), "payload", "a payload cannot be negative", mass)
    _bad_row("stretch", rows, ok & (P < -_NEGATIVE_P_MPA), "pressure", _NEGATIVE_P_TEXT, P)
    _bad_row("stretch", rows, ok & (L <= 0), "length", "an actuator length must be positive (m)", L)
    if not ok.any():
        raise ModelError(f"Every one of the {n} rows of the stretch table misses a payload, pressure or length.")
    f = stretch_forces(mass[ok], P[ok], L[ok], act)
    model = StretchCorrection().fit(f["lambda"], f["F_stretch_N"])
    actuator_fit, actuator_note = None, ""
    try:
        actuator_fit = fit_actuator(mass[ok], P[ok], L[ok], act)
    except ModelError as e:
        actuator_note = str(e)
    fitted = model.predict(f["lambda"])
    points: dict[str, list[Any]] = {
        "row": [int(v) for v in rows[ok]],
        "mass_kg": _floats(mass[ok]),
        "P_MPa": _floats(P[ok]),
        "L_m": _floats(L[ok]),
        **{k: _floats(v) for k, v in f.items()},
        "fitted_N": _floats(fitted),
        "residual_N": _floats(f["F_stretch_N"] - fitted),
    }
    return StretchFit(
        model=model,
        points=points,
        protocol=path,
        L0_m=act.L0_m,
        default_coefficients_N=act.stretch_coefficients_N,
        default_lambda_range=act.stretch_lambda_range,
        skipped_rows=[int(v) for v in rows[~ok]],
        force_reading=act.force_reading,
        actuator_fit=actuator_fit,
        actuator_note=actuator_note,
    )


# --------------------------------------------------------------------------- joint map


@dataclass
class JointMapResult:
    """Measured joint angles against the model without and with the stretch correction."""

    protocol: str
    geometry: rpam.JointGeometry
    actuator: Actuator
    correction_source: str
    rows: np.ndarray
    Pa_MPa: np.ndarray
    Pb_MPa: np.ndarray
    measured_deg: np.ndarray
    model_deg: dict[str, np.ndarray]  # "without" / "with": NaN where the model toggles
    toggle: dict[str, np.ndarray]  # bool per point
    summary: dict[str, dict[str, Any]]
    skipped_rows: list[int] = field(default_factory=list)

    @property
    def toggle_deg(self) -> float:
        return math.degrees(float(rpam.toggle_angle(self.geometry)))

    def grid(self, tol_MPa: float = 0.002) -> tuple[np.ndarray, np.ndarray, dict[str, np.ndarray]] | None:
        """The points as a Pa x Pb grid, or None when they do not fill one.

        Measured pressures scatter round their set points, so values within ``tol_MPa`` of
        each other (2 kPa) count as one grid line.  Returns ``(Pa (m,), Pb (k,), {"measured",
        "without", "with": (k, m)})`` in MPa and deg, rows indexing Pb and columns Pa;
        repeated points are averaged (a toggle at any repeat makes the cell NaN).
        """
        pa, i = _grid_lines(self.Pa_MPa, tol_MPa)
        pb, j = _grid_lines(self.Pb_MPa, tol_MPa)
        count = np.zeros((pb.size, pa.size))
        np.add.at(count, (j, i), 1)
        if pa.size < 2 or pb.size < 2 or np.any(count == 0):
            return None
        out = {}
        for name, v in (
            ("measured", self.measured_deg),
            ("without", self.model_deg["without"]),
            ("with", self.model_deg["with"]),
        ):
            acc = np.zeros((pb.size, pa.size))
            np.add.at(acc, (j, i), v)
            out[name] = acc / count
        return pa, pb, out

    def to_dict(self) -> dict[str, Any]:
        return _nan_to_none(
            {
                "kind": "rpam-joint-map",
                "protocol": self.protocol,
                "force_reading": self.actuator.force_reading,
                "geometry": self.geometry.to_dict(),
                "toggle_deg": self.toggle_deg,
                "actuator": self.actuator.to_dict(),
                "correction": {
                    "coefficients_N": list(self.actuator.stretch_coefficients_N),
                    "lambda_range": list(self.actuator.stretch_lambda_range),
                    "source": self.correction_source,
                },
                "summary": self.summary,
                "skipped_rows": list(self.skipped_rows),
                "points": {
                    "row": [int(v) for v in self.rows],
                    "P_A_MPa": _floats(self.Pa_MPa),
                    "P_B_MPa": _floats(self.Pb_MPa),
                    "measured_deg": _floats(self.measured_deg),
                    "without_deg": _floats(self.model_deg["without"]),
                    "with_deg": _floats(self.model_deg["with"]),
                    "without_toggle": [bool(v) for v in self.toggle["without"]],
                    "with_toggle": [bool(v) for v in self.toggle["with"]],
                },
            }
        )

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> JointMapResult:
        if d.get("kind") != "rpam-joint-map":
            raise ModelError(f"Expected a joint-map analysis (kind 'rpam-joint-map'), got kind {d.get('kind')!r}.")
        try:
            p = d["points"]
            act = Actuator.from_dict(d["actuator"])
            arr = lambda k: np.asarray(_none_to_nan(list(p[k])), dtype=float)  # noqa: E731
            return cls(
                protocol=str(d["protocol"]),
                geometry=rpam.JointGeometry(**{k: float(v) for k, v in d["geometry"].items()}),
                actuator=act,
                correction_source=str(d["correction"]["source"]),
                rows=np.asarray(p["row"], dtype=np.int64),
                Pa_MPa=arr("P_A_MPa"),
                Pb_MPa=arr("P_B_MPa"),
                measured_deg=arr("measured_deg"),
                model_deg={"without": arr("without_deg"), "with": arr("with_deg")},
                toggle={"without": np.asarray(p["without_toggle"], bool), "with": np.asarray(p["with_toggle"], bool)},
                summary={k: {kk: _none_to_nan(vv) for kk, vv in v.items()} for k, v in d["summary"].items()},
                skipped_rows=[int(v) for v in d.get("skipped_rows", [])],
            )
        except (KeyError, TypeError, ValueError, AttributeError) as e:
            raise ModelError(f"The joint-map analysis record is incomplete or malformed ({e!s}).") from None

    def to_json(self) -> str:
        return json.dumps(self.to_dict(), indent=2)

    @classmethod
    def from_json(cls, text: str) -> JointMapResult:
        return cls.from_dict(_loads(text, "joint-map analysis"))


def _grid_lines(values: np.ndarray, tol: float) -> tuple[np.ndarray, np.ndarray]:
    """Cluster sorted values with gaps above ``tol``: (cluster means, cluster index per value)."""
    order = np.argsort(values)
    v = values[order]
    label_sorted = np.concatenate([[0], np.cumsum(np.diff(v) > tol)]) if v.size else np.zeros(0, int)
    labels = np.empty(values.size, dtype=np.int64)
    labels[order] = label_sorted
    n = int(label_sorted[-1]) + 1 if v.size else 0
    means = np.bincount(labels, weights=values, minlength=n) / np.bincount(labels, minlength=n)
    return means, labels


def correction_actuator(act: Actuator, correction: Any) -> tuple[Actuator, str]:
    """``act`` with ``correction`` applied, and where it came from ("protocol", "fit", "given").

    ``correction``: None (the protocol's own), a :class:`StretchFit`, a fitted
    :class:`StretchCorrection`, a dict of either, or four coefficients c0..c3 (N).
    """
    if correction is None:
        return act, "protocol"
    if isinstance(correction, Mapping):
        kind = correction.get("kind")
        correction = (
            StretchFit.from_dict(correction) if kind == "rpam-stretch-fit" else StretchCorrection.from_dict(correction)
        )
    if isinstance(correction, StretchFit):
        return correction.apply_to(act), "fit"
    if isinstance(correction, StretchCorrection):
        correction._check()
        return act.with_stretch_correction(correction.coefficients_N, correction.lambda_range), "fit"
    try:
        coef = tuple(float(v) for v in correction)
    except (TypeError, ValueError):
        coef = ()
    if len(coef) != DEGREE + 1 or not all(math.isfinite(c) for c in coef):
        raise ModelError("A stretch correction is four finite coefficients c0..c3 in N, a stretch fit, or None.")
    return act.with_stretch_correction(coef), "given"


def _summary(
    Pa: np.ndarray,
    Pb: np.ndarray,
    measured: np.ndarray,
    model: np.ndarray,
    toggle: np.ndarray,
    limit: np.ndarray,
    toggle_deg: float,
) -> dict[str, Any]:
    on_stop = np.isfinite(model) & (np.abs(measured) >= toggle_deg - STOP_BAND_DEG)
    both = np.isfinite(model) & np.isfinite(measured) & ~on_stop
    err = model[both] - measured[both]
    out: dict[str, Any] = {
        "n_compared": int(both.sum()),
        "n_toggle": int(toggle.sum()),
        "n_on_stop": int(on_stop.sum()),
    }
    if err.size:
        k = int(np.argmax(np.abs(err)))
        out.update(
            rmse_deg=float(np.sqrt(np.mean(err**2))),
            max_abs_error_deg=float(abs(err[k])),
            max_error_at_kPa=[float(Pa[both][k] * 1e3), float(Pb[both][k] * 1e3)],
        )
    else:
        out.update(rmse_deg=float("nan"), max_abs_error_deg=float("nan"), max_error_at_kPa=[float("nan")] * 2)
    filled = np.where(toggle, limit, model)
    have = np.isfinite(filled) & np.isfinite(measured)
    out["rmse_all_deg"] = float(np.sqrt(np.mean((filled[have] - measured[have]) ** 2))) if have.any() else float("nan")
    return out


def model_angles(
    Pa_MPa: Any, Pb_MPa: Any, geom: rpam.JointGeometry, act: Actuator, *, stretch: bool
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Model angles (deg, NaN at the toggle), toggle flags and the toggle-side limit (deg)."""
    eq = rpam.solve_equilibrium(Pa_MPa, Pb_MPa, geom, act, stretch=stretch)
    toggle = eq.status == rpam.TOGGLE
    side = np.sign(rpam.joint_torque(0.0, Pa_MPa, Pb_MPa, geom, act, stretch=stretch))
    return eq.alpha_deg, toggle, side * np.degrees(eq.toggle_rad)


def analyse_joint_map(
    table: Any, protocol: Any = "rpam2015", correction: Any = None, force: str | None = None
) -> JointMapResult:
    """Compare a measured joint map (Fig. 8 c) with the model without and with ``F_stretch``.

    ``table`` has ``P_A``, ``P_B`` (MPa) and ``alpha_deg``; ``correction`` as in
    :func:`correction_actuator` (None: the protocol's ``[stretch_correction]``); ``force``
    reads the actuator's force ``"derived"`` or ``"paper"`` (default: the stretch fit's
    reading when ``correction`` is one, else the protocol's).  A stretch fit made under the
    other reading is refused: its correction is what that reading left unexplained.
    """
    path, settings = _protocol(protocol)
    geom = settings.geometry
    if isinstance(correction, Mapping) and correction.get("kind") == "rpam-stretch-fit":
        correction = StretchFit.from_dict(correction)
    if isinstance(correction, StretchFit):
        if force is not None and force != correction.force_reading:
            raise ModelError(
                f"The stretch fit was made with the {correction.force_reading} force reading, so its correction "
                f"belongs to it; compare with --force {correction.force_reading}, or fit the stretch test again "
                f"with --force {force}."
            )
        force = correction.force_reading
    base = checked_actuator(settings, path).with_force_reading(force)
    act, source = correction_actuator(base, correction)
    cols = _columns(table)
    Pa = _column(table, "joint-map", (("P_A", 1.0), ("Pa_MPa", 1.0)), cols)
    Pb = _column(table, "joint-map", (("P_B", 1.0), ("Pb_MPa", 1.0)), cols)
    meas = _column(table, "joint-map", (("alpha_deg", 1.0), ("angle_deg", 1.0)), cols)
    n = Pa.size
    if not (Pb.size == n and meas.size == n):
        raise ModelError("The joint-map table's columns differ in length.")
    if n == 0:
        raise ModelError("The joint-map table is empty; measure the joint over a Pa x Pb grid first.")
    rows = _row_ids(table, n)
    ok = np.isfinite(Pa) & np.isfinite(Pb) & np.isfinite(meas)
    _bad_row("joint-map", rows, ok & (Pa < -_NEGATIVE_P_MPA), "P_A", _NEGATIVE_P_TEXT, Pa)
    _bad_row("joint-map", rows, ok & (Pb < -_NEGATIVE_P_MPA), "P_B", _NEGATIVE_P_TEXT, Pb)
    if not ok.any():
        raise ModelError(f"Every one of the {n} rows of the joint-map table misses a pressure or an angle.")
    Pa, Pb, meas, kept = Pa[ok], Pb[ok], meas[ok], rows[ok]
    model, toggles, summary = {}, {}, {}
    toggle_deg = math.degrees(float(rpam.toggle_angle(geom)))
    for name, stretch in (("without", False), ("with", True)):
        a, t, limit = model_angles(Pa, Pb, geom, act, stretch=stretch)
        model[name], toggles[name] = a, t
        summary[name] = _summary(Pa, Pb, meas, a, t, limit, toggle_deg)
    return JointMapResult(
        protocol=path,
        geometry=geom,
        actuator=act,
        correction_source=source,
        rows=kept,
        Pa_MPa=Pa,
        Pb_MPa=Pb,
        measured_deg=meas,
        model_deg=model,
        toggle=toggles,
        summary=summary,
        skipped_rows=[int(v) for v in rows[~ok]],
    )
