"""The pressure-to-contact regression of Takuma, Takamine & Masuda (2014), Eqs. 34-37.

Four equations, eighteen coefficients, no intercepts (the paper has none)::

    sin(theta1) = b_t1L1 u_L1 + b_t1R1 u_R1                                   (Eq. 34)
    sin(theta2) = b_t2L1 u_L1 + b_t2R1 u_R1 + b_t2L2 u_L2 + b_t2R2 u_R2       (Eq. 35)
    Fx = b_Fx1 j*11 c1 dP_L1 + b_Fx2 j*11 c1 dP_R1
       + b_Fx3 j*11 (c1 - c2) dP_L2 + b_Fx4 j*11 (c1 - c2) dP_R2
       + b_Fx5 j*12 c2 dP_L2 + b_Fx6 j*12 c2 dP_R2                            (Eq. 36)
    Fy = the same with j*21, j*22 and b_Fy1..b_Fy6                             (Eq. 37)

with ``u_ij = P_ij0 / P_ij - 1``, ``dP_ij = P_ij0 - P_ij`` (MPa gauge, as the paper's sensors
read), ``c_k = cos(theta_k)`` and ``j*_kl`` the elements of ``(J^-1)^T`` for the Jacobian printed
in the paper's Section 2.2.2::

    J = [[-h2 c1 - h3 c12, -h3 c12],
         [-h2 s1 - h3 s12, -h3 s12]]          det J = h2 h3 sin(theta2)

Sign reading: every coefficient multiplies its term with a plus sign (Eq. 31's form), and the
paper's listed beta_theta2R2 = -2.972 is taken as printed in Section 3.3; the minus that Eq. 35
prints before that term is a misprint.  Measured: the paper's coefficients on the simulated rig's
pressures give theta2 at +1.3 to +1.6 times the truth in this reading and -0.7 times in the other
(``python -m labcli.papers.takuma2014.sim.paper_scale``), and the geometry (Eqs. 6-7, 13)
puts L2 and R2 on opposite sides of the joint, so their coefficients must have opposite signs.

Units: pressures MPa, lengths m, angles rad, forces N.  Angle coefficients are dimensionless
(sine per unit pressure ratio); force coefficients are N m / MPa (j* is in 1/m).

Near-singular posture: ``det J`` vanishes at theta2 = 0, where a force along the straight arm
makes no torque and the j* blow up.  Only the component along the arm is lost, so the policy is
per component: the amplification of Fx (resp. Fy) is ``||row 1 (resp. 2) of (J^-1)^T|| ||J||``
(dimensionless, at most cond(J)), the factor by which a relative torque error grows into that
force.  A trial whose amplification exceeds ``max_amplification`` (default 100) is left out of
that component's fit with the reason, and in prediction that component is flagged
``singular-jacobian`` (ok False) and kept out of the accuracy metrics.  Its value is still the
model's own answer; only at theta2 = 0 exactly, where that is infinite, a stand-in is computed
with theta2 moved to the whole-Jacobian bound (cond J = max_amplification, 2.86 deg for the
paper's h2, h3), so every returned number is finite.  On an upright arm Fx stays well
determined (amplification of a few tens) while Fy is lost below |theta2| of about 3 deg.
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, NoReturn, cast

import numpy as np

from ....core import idranges
from ....core.arrays import rows_all, rows_any, stack_columns
from ....core.jsontext import MAX_DEPTH, JSONDepthError, PlainList, dumps_indented, json_kind, loads_bounded
from ....core.nogc import paused_gc
from ....core.version import __version__
from ....errors import ModelError
from .geometry import force_amplification, jacobian_cond, jstar
from .student_t import t_975

SCHEMA = "labcli-takuma-model"
SCHEMA_VERSION = 1

EQUATIONS: tuple[str, ...] = ("theta1", "theta2", "Fx", "Fy")
TERMS: dict[str, tuple[str, ...]] = {
    "theta1": ("beta_theta1_L1", "beta_theta1_R1"),
    "theta2": ("beta_theta2_L1", "beta_theta2_R1", "beta_theta2_L2", "beta_theta2_R2"),
    "Fx": tuple(f"beta_Fx{i}" for i in range(1, 7)),
    "Fy": tuple(f"beta_Fy{i}" for i in range(1, 7)),
}
COEFFICIENT_NAMES: tuple[str, ...] = tuple(n for eq in EQUATIONS for n in TERMS[eq])

# Section 3.3 of the paper as listed, plus-sign reading (Eq. 35's minus before beta_theta2R2 is a misprint).
PAPER_COEFFICIENTS: dict[str, float] = {
    "beta_theta1_L1": 0.136,
    "beta_theta1_R1": -1.587,
    "beta_theta2_L1": 1.359,
    "beta_theta2_R1": 1.094,
    "beta_theta2_L2": 0.766,
    "beta_theta2_R2": -2.972,
    "beta_Fx1": -75.906,
    "beta_Fx2": -5.538,
    "beta_Fx3": -2201.033,
    "beta_Fx4": -131.738,
    "beta_Fx5": 1.545,
    "beta_Fx6": -21.865,
    "beta_Fy1": 1.309,
    "beta_Fy2": -75.973,
    "beta_Fy3": -642.995,
    "beta_Fy4": -393.750,
    "beta_Fy5": 1.196,
    "beta_Fy6": -21.697,
}
SIGN_NOTE = (
    "plus-sign reading: every coefficient multiplies its term with +, the paper's "
    "beta_theta2R2 = -2.972 as listed (the minus Eq. 35 prints before it is a misprint: "
    "fed the rig's pressures, -2.972 gives theta2 x1.4 of the truth, +2.972 gives x-0.7)"
)

BASELINE_COLUMNS = ("P_L10", "P_R10", "P_L20", "P_R20")
LOADED_COLUMNS = ("P_L1", "P_R1", "P_L2", "P_R2")
ANGLE_COLUMNS = ("theta1_deg", "theta2_deg")
FORCE_COLUMNS = ("Fx_N", "Fy_N")

UNITS = {
    "pressure": "MPa (gauge)",
    "length": "m",
    "angle": "rad",
    "force": "N",
    "angle_coefficients": "1 (sine per unit pressure ratio)",
    "force_coefficients": "N m / MPa",
}
GEOMETRY_KEYS = ("h1", "h2", "h3", "r1", "r2")
# A coefficient maps MPa to rad or N: a fit on a bench rig gives at most a few 1e4 (the shipped
# runs' largest is about 1e4 N/MPa^2); one beyond 1e6 is a damaged or hand-edited file, whose
# estimates would overflow.
MAX_COEFFICIENT = 1e6

DEFAULT_MAX_AMPLIFICATION = 100.0
DEFAULT_MAX_DESIGN_COND = 1e8
LABEL_PLAYS = ("fit", "loads", "none")  # TakumaModel.label_play: how the pots' play is taken
# Fewer fit trials than this: the play is not estimated (its column would eat a tenth of the data).
MIN_PLAY_TRIALS = 20
MAX_PLAY_TRIALS = 20_000
# Above this (column-scaled) condition number the fit is kept but marked ill-conditioned.
WARN_DESIGN_COND = 1e4


def check_label_play(label_play: str) -> None:
    """Refuse, in one sentence, a way of taking the potentiometers' play that is not one of LABEL_PLAYS."""
    if label_play not in LABEL_PLAYS:
        raise ModelError(f"Unknown label play {label_play!r}; use one of {', '.join(LABEL_PLAYS)}.")


FLAG_TEXT = {
    "bad-pressure": "a pressure is missing or not positive",
    "theta1-clipped": "Eq. 34 gave |sin(theta1)| > 1 (clipped)",
    "theta2-clipped": "Eq. 35 gave |sin(theta2)| > 1 (clipped)",
    "missing-angle": "the measured angle is missing",
    "singular-jacobian": "theta2 too close to 0 for this force component (Jacobian near singular)",
    # The posture-aware form (models/posture.py) flags by uncertainty instead.
    "uncertain": "standard error over the protocol's [sensing] limit",
}


# --------------------------------------------------------------------------- features


def _measured_angles(theta: Any, n: int, flags: list[list[str]], bad_p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The measured angles ``theta`` ((n, 2), rad) the force equations take in the measured-angles
    mode, 0 where missing (flagged), and which rows they make trustworthy."""
    if theta is None:
        raise ModelError("The measured-angles mode needs the measured joint angles.")
    th_meas = np.atleast_2d(np.asarray(theta, dtype=float))
    if th_meas.shape != (n, 2):
        raise ModelError(f"Measured angles must be an (n, 2) array; got {th_meas.shape}.")
    known = rows_all(np.isfinite(th_meas))
    for i in np.flatnonzero(~known):
        flags[i].append("missing-angle")
    return np.where(known[:, None], th_meas, 0.0), known & ~bad_p


# A tall design's R is built from the R's of row blocks this long (the R of their stacked R's is
# the whole's, up to the signs of its rows): LAPACK's Householder passes then run over a block
# that stays in cache, where over 10^5 rows of 16 columns each pass went to memory (3x slower).
QR_ROWS = 8192


def qr_r(a: np.ndarray) -> np.ndarray:
    """The R factor of ``a`` (numpy's ``qr(mode="r")``, an array despite what its stubs say), up to the
    signs of its rows; a tall ``a`` of 4 to 64 columns goes by row blocks of :data:`QR_ROWS`."""
    if a.ndim == 2 and a.shape[0] > 2 * QR_ROWS and 4 <= a.shape[1] <= 64:
        return qr_r(np.vstack([np.linalg.qr(a[lo : lo + QR_ROWS], mode="r") for lo in range(0, len(a), QR_ROWS)]))
    return cast(np.ndarray, np.linalg.qr(a, mode="r"))


def pressure_ratio_features(P0: np.ndarray, P: np.ndarray) -> np.ndarray:
    """``u_ij = P_ij0 / P_ij - 1`` for (n, 4) arrays in the order L1, R1, L2, R2."""
    P0 = np.asarray(P0, dtype=float)
    P = np.asarray(P, dtype=float)
    return P0 / P - 1.0


def pressure_arrays(P0: Any, P: Any) -> tuple[np.ndarray, np.ndarray]:
    """Baseline and loaded pressures as (n, 4) float arrays (ModelError for any other shape)."""
    P0 = np.atleast_2d(np.asarray(P0, dtype=float))
    P = np.atleast_2d(np.asarray(P, dtype=float))
    if P0.shape != P.shape or P0.shape[1] != 4:
        raise ModelError(f"Pressures must be (n, 4) arrays in the order L1, R1, L2, R2; got {P0.shape} and {P.shape}.")
    return P0, P


def theta2_threshold(h2: float, h3: float, max_cond: float) -> float:
    """Smallest |theta2| (rad) at which cond(J) <= max_cond."""
    if not max_cond > 1.0:
        raise ModelError(f"The force amplification bound must exceed 1, got {max_cond:g}.")
    lo, hi = 0.0, math.pi / 2
    if jacobian_cond(np.array(hi), h2, h3) > max_cond:
        return hi
    for _ in range(80):  # bisection: cond(J) falls monotonically on (0, pi/2]
        mid = 0.5 * (lo + hi)
        if jacobian_cond(np.array(mid), h2, h3) > max_cond:
            lo = mid
        else:
            hi = mid
    return hi


def force_design(
    P0: np.ndarray,
    P: np.ndarray,
    theta: np.ndarray,
    h2: float,
    h3: float,
    equations: Sequence[str] = ("Fx", "Fy"),
    js: np.ndarray | None = None,
) -> tuple[np.ndarray, ...]:
    """Design matrices (n, 6) of Eqs. 36 and 37 (those of ``equations``), columns beta_F*1..6.

    ``js``: ``jstar(theta, h2, h3)`` when the caller has it already (the fit needs it three times).
    """
    dP = np.asarray(P0, dtype=float) - np.asarray(P, dtype=float)
    theta = np.atleast_2d(np.asarray(theta, dtype=float))
    c1, c2 = np.cos(theta[:, 0]), np.cos(theta[:, 1])
    js = jstar(theta, h2, h3) if js is None else js

    def rows(ja: np.ndarray, jb: np.ndarray) -> np.ndarray:
        # Written into one array: six (n,) temporaries and a stacked copy were 2x the design.  Column
        # by column (Fortran order): each product lands contiguous, and the least squares' blocks
        # are copied into LAPACK's own order from it.
        X = np.empty((len(dP), 6), order="F")
        outer, inner, lower = ja * c1, ja * (c1 - c2), jb * c2  # each weight serves two pressure drops
        for k, (weight, drop) in enumerate(((outer, 0), (outer, 1), (inner, 2), (inner, 3), (lower, 2), (lower, 3))):
            np.multiply(weight, dP[:, drop], out=X[:, k])
        return X

    row = {"Fx": 0, "Fy": 1}
    return tuple(rows(js[:, row[eq], 0], js[:, row[eq], 1]) for eq in equations)


# --------------------------------------------------------------------------- tables and least squares


def normalise_geometry(geometry: Mapping[str, Any]) -> dict[str, float]:
    """Geometry dict in m with keys h1, h2, h3, r1, r2 (h2, h3 required; ``_m`` suffix accepted)."""
    out: dict[str, float] = {}
    for key in GEOMETRY_KEYS:
        for name in (key, f"{key}_m"):
            if name in geometry and geometry[name] is not None:
                out[key] = float(geometry[name])
                break
    for key in ("h2", "h3"):
        if key not in out or not (math.isfinite(out[key]) and out[key] > 0):
            raise ModelError(
                f"The rig geometry needs a positive length '{key}' in m "
                f"(got {dict(geometry)!r}); check the protocol's [rig] table."
            )
    return out


def _table_arrays(table: Any, rows: np.ndarray | None = None) -> dict[str, np.ndarray]:
    """Trial ids and (n, k) arrays of pressures, angles (rad) and forces; ``rows`` a boolean mask (default all),
    taken column by column so the table itself is never copied."""
    missing = [c for c in ("trial",) + BASELINE_COLUMNS + LOADED_COLUMNS if c not in table.columns]
    if missing:
        raise ModelError(
            f"The trial table lacks the column(s) {', '.join(missing)}; "
            "see the trial-table format (P_L10..P_R20, P_L1..P_R2 in MPa)."
        )
    n = len(table) if rows is None else int(np.count_nonzero(rows))

    def values(c: str, dtype: Any = float) -> np.ndarray:
        v = np.asarray(table[c], dtype=dtype)
        return v if rows is None else v[rows]

    def col(names: Sequence[str]) -> np.ndarray:
        cols = [values(c) if c in table.columns else np.full(n, np.nan) for c in names]
        return stack_columns(cols) if cols else np.empty((n, 0))

    return {
        "trial": values("trial", None).astype(int),
        "P0": col(BASELINE_COLUMNS),
        "P": col(LOADED_COLUMNS),
        "theta": np.deg2rad(col(ANGLE_COLUMNS)),
        "F": col(FORCE_COLUMNS),
    }


def set_mask(table: Any, name: str, source: str = "the trial table") -> np.ndarray:
    """Which rows of the trial table have ``set`` ``name``, a boolean array (ModelError if none do)."""
    if "set" in table.columns:
        import pandas as pd

        # Few distinct set names: normalise each once, not every row (code -1 is a missing value).
        codes, values = pd.factorize(table["set"])
        hit = np.array([str(v).strip().lower() == name for v in values] + [False], dtype=bool)
        mask = hit[codes]
    else:
        mask = np.zeros(len(table), dtype=bool)
    if not mask.any():
        hint = "assign trials with `labcli split` (or fill the `set` column)"
        raise ModelError(f"{cap(source)} has no {name} trials (no row with set = '{name}'); {hint}.")
    return mask


def select_set(table: Any, name: str, source: str = "the trial table") -> Any:
    """Rows of the trial table whose ``set`` is ``name`` (ModelError if there are none)."""
    return table[set_mask(table, name, source)]


@dataclass
class _LstsqResult:
    beta: np.ndarray
    cov: np.ndarray
    fitted: np.ndarray
    cond: float
    sigma: float
    dof: int


# Rows per block of the least squares' QR: 2 MB of [X y] at a time, whatever the table's size.
QR_BLOCK = 32_768


def _lstsq(X: np.ndarray, y: np.ndarray, names: Sequence[str], equation: str, max_cond: float) -> _LstsqResult:
    n, p = X.shape
    # Each column's norm by itself: numpy's norm along the rows of a C-ordered (n, 2-6) array
    # steps a row at a time.
    scale = np.sqrt(np.array([X[:, k] @ X[:, k] for k in range(p)]))
    zero = [names[k] for k in range(p) if not scale[k] > 0]
    if zero:
        raise ModelError(
            f"The {equation} fit cannot determine {', '.join(zero)}: its term is zero "
            "in every usable fit trial; record fit trials that load every actuator."
        )
    # Column scaling makes the condition number measure collinearity, not units.  [X y] = Q R
    # (Householder QR), so X's singular values and directions are those of R's first p
    # columns and U^T y = U_R^T (Q^T y).  R is built from the R's of row blocks (the R of
    # their stacked R's is [X y]'s, up to signs), so no (n, p) array besides the design itself.
    parts: list[np.ndarray] = []
    for lo in range(0, n, QR_BLOCK):
        hi = min(n, lo + QR_BLOCK)
        Z = np.empty((hi - lo, p + 1), order="F")  # LAPACK's own order: no further copy
        np.divide(X[lo:hi], scale, out=Z[:, :p])
        Z[:, p] = y[lo:hi]
        parts.append(qr_r(Z))
    R = parts[0] if len(parts) == 1 else qr_r(np.vstack(parts))
    del Z, parts
    U, s, Vt = np.linalg.svd(R[:p, :p])
    cond = float(s[0] / s[-1]) if s[-1] > 0 else math.inf
    if not cond <= max_cond:
        worst = names[int(np.argmax(np.abs(Vt[-1])))]
        raise ModelError(
            f"The {equation} design matrix is collinear (condition number "
            f"{cond:.3g} > {max_cond:.3g}, weakest direction mostly {worst}); "
            "record fit trials with more varied force directions and postures."
        )
    bs = Vt.T @ ((U.T @ R[:p, p]) / s)
    beta = bs / scale
    fitted = X @ beta
    resid = y - fitted
    dof = n - p
    sigma = math.sqrt(float(resid @ resid) / dof)
    cov_s = (Vt.T / s**2) @ Vt
    cov = sigma**2 * cov_s / np.outer(scale, scale)
    return _LstsqResult(beta, cov, fitted, cond, sigma, dof)


def _r2(obs: np.ndarray, calc: np.ndarray) -> float | None:
    ss_tot = float(np.sum((obs - obs.mean()) ** 2))
    if ss_tot <= 0:
        return None
    return 1.0 - float(np.sum((obs - calc) ** 2)) / ss_tot


def _rmse(obs: np.ndarray, calc: np.ndarray) -> float:
    return float(np.sqrt(np.mean((obs - calc) ** 2)))


def _equation_stats(eq: str, res: Any, y: np.ndarray, theta: np.ndarray, n: int, tq: float) -> dict[str, Any]:
    """How well one equation fits: in its own space (sin theta, N) and natively (deg, N)."""
    st: dict[str, Any] = {
        "n": n,
        "dof": res.dof,
        "design_cond": res.cond,
        "ill_conditioned": bool(res.cond > WARN_DESIGN_COND),
        "sigma": res.sigma,
        "t_975": tq,
        "r2": _r2(y, res.fitted),
        "rmse": _rmse(y, res.fitted),
    }
    if eq.startswith("theta"):
        st["space"] = f"sin({eq})"
        obs_deg = np.degrees(theta[:, 0 if eq == "theta1" else 1])
        calc_deg = np.degrees(np.arcsin(np.clip(res.fitted, -1.0, 1.0)))
        st["r2_native"], st["rmse_native"] = _r2(obs_deg, calc_deg), _rmse(obs_deg, calc_deg)
        st["native_unit"] = "deg"
    else:
        st["space"] = f"{eq} (N)"
        st["r2_native"], st["rmse_native"], st["native_unit"] = st["r2"], st["rmse"], "N"
    return st


def cap(text: str) -> str:
    """Sentence case for a name that may open a message ("the model" -> "The model").

    Only a leading article is capitalised: a file name is shown exactly as typed
    (``unsplit.h5`` stays ``unsplit.h5``), because it is what the person must find.
    """
    head, sep, rest = text.partition(" ")
    if sep and head in ("the", "a", "an"):
        return head.capitalize() + sep + rest
    return text


def _clean(value: Any, copies: dict[int, PlainList] | None = None) -> Any:
    """Plain JSON types: numpy scalars to Python, non-finite floats to None.

    A :class:`PlainList` met several times (one equation's trial ranges shared by the others) is
    copied once, so the copies stay one list and the writer encodes it once
    (:func:`~labcli.core.jsontext.dumps_indented`: 10^5 pairs each on a random split).
    """
    copies = {} if copies is None else copies
    if isinstance(value, dict):
        return {str(k): _clean(v, copies) for k, v in value.items()}
    if isinstance(value, PlainList):  # trial ranges: plain already, however many
        if id(value) not in copies:  # ``value`` lives as long as the call: its id is its own
            copies[id(value)] = type(value)(value)
        return copies[id(value)]
    if isinstance(value, (list, tuple)):
        if all(type(v) is int for v in value):  # trial ids: already plain, however many
            return list(value)
        return [_clean(v, copies) for v in value]
    if isinstance(value, np.ndarray):
        return _clean(value.tolist(), copies)
    if isinstance(value, (np.integer,)):
        return int(value)
    if isinstance(value, (float, np.floating)):
        value = float(value)
        return value if math.isfinite(value) else None
    return value


# --------------------------------------------------------------------------- the model


@dataclass
class TakumaModel:
    """Eqs. 34-37 with their 18 coefficients; parameters are plain data that serialise to JSON.

    Example::

        model = TakumaModel(geometry=protocol.settings.rig, protocol="takuma2014").fit(table)
        out = model.predict(P0, P)            # pressure-only: angles, then forces
        text = model.to_json(); TakumaModel.from_json(text) == model
    """

    geometry: dict[str, float]
    protocol: str = "takuma2014"
    max_amplification: float = DEFAULT_MAX_AMPLIFICATION
    max_design_cond: float = DEFAULT_MAX_DESIGN_COND
    coefficients: dict[str, float] = field(default_factory=dict)
    standard_errors: dict[str, float] = field(default_factory=dict)
    ci95: dict[str, list[float]] = field(default_factory=dict)
    covariance: dict[str, list[list[float]]] = field(default_factory=dict)
    fit_stats: dict[str, dict[str, Any]] = field(default_factory=dict)
    fitted_trials: dict[str, list[list[int]]] = field(default_factory=dict)  # per equation, [first, last] ranges
    excluded_trials: dict[str, list[dict[str, Any]]] = field(default_factory=dict)
    source: str = ""
    labcli_version: str = ""
    fitted_on: dict[str, Any] = field(default_factory=dict)  # the fit run's identity (core.provenance)
    # The fit trials' span, and how their P0 was taken (models/calibrated.py, models/leak.py).
    calibrated_range: dict[str, list[list[float]]] = field(default_factory=dict)
    p0_leak_corrected: bool = False
    baseline_gap_s: float | None = None
    captures_per_load: int = 1  # captures each fit row averaged (models/calibrated.py)
    # The potentiometers' play fitted with Eqs. 34-35 (models/labels.py): "fit" estimates it by least
    # squares, "loads" by two-stage least squares on the trials' loads (free of the pressure
    # readings' errors, which shorten a least-squares width; opt-in, as its width still varies from
    # seed to seed: tests/benchmarks/steel_deformation.py), "none" takes the readings as they are.
    # ``play`` holds what the fit estimated.
    label_play: str = "fit"
    play: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        self.geometry = normalise_geometry(self.geometry)
        check_label_play(self.label_play)

    # ---------------------------------------------------------------- fitting
    @property
    def is_fitted(self) -> bool:
        return set(self.coefficients) == set(COEFFICIENT_NAMES)

    @property
    def theta2_threshold_rad(self) -> float:
        """|theta2| below which cond(J) exceeds max_amplification (stand-in posture at theta2 = 0)."""
        return theta2_threshold(self.geometry["h2"], self.geometry["h3"], self.max_amplification)

    def fit(
        self,
        table: Any,
        source: str = "the trial table",
        *,
        record_trials: bool = True,
        calibrated: Mapping[str, list[list[float]]] | None = None,
        fit_rows: np.ndarray | None = None,
    ) -> TakumaModel:
        """Least squares on the table's ``set == 'fit'`` rows; returns self, fitted.

        ``record_trials=False`` leaves ``fitted_trials`` empty (a fit made only to predict, as
        the posture form's route choice makes ten).  ``calibrated``: the fit rows'
        ``calibrated_range`` when the caller has it from the same table and rows (the posture
        form's, for the paper's part it fits on its own trials: a pass over 10^6 rows saved);
        ``fit_rows``, likewise, the table's :func:`set_mask` of its fit trials.
        """
        fit_rows = set_mask(table, "fit", source) if fit_rows is None else fit_rows
        table, stuck = self._unplayed(table, fit_rows)
        a = _table_arrays(table, fit_rows)
        trial, P0, P, theta, F = a["trial"], a["P0"], a["P"], a["theta"], a["F"]
        h2, h3 = self.geometry["h2"], self.geometry["h3"]
        theta_known = np.nan_to_num(theta, nan=1.0)  # a stand-in where an angle is missing: such trials are left out
        with np.errstate(divide="ignore", invalid="ignore"):
            js = jstar(theta_known, h2, h3)  # (J^-1)^T once, for the exclusions and both force designs
        reasons = self._exclusions(trial, P0, P, theta, F, js)
        for eq, ids in stuck.items():
            for t in ids:
                reasons[eq].setdefault(t, "the potentiometer's reading did not leave its play")
        with np.errstate(divide="ignore", invalid="ignore"):
            u = pressure_ratio_features(P0, P)

        def design(eq: str) -> np.ndarray:
            # One force design at a time, built when its equation comes: each is (n, 6), and at
            # 10^6 trials holding both beside the least squares' own copy was 40 MB of the peak.
            if eq.startswith("theta"):
                return u[:, :2] if eq == "theta1" else u
            with np.errstate(divide="ignore", invalid="ignore"):
                return force_design(P0, P, theta_known, h2, h3, (eq,), js)[0]

        targets = {
            "theta1": np.sin(theta[:, 0]),
            "theta2": np.sin(theta[:, 1]),
            "Fx": F[:, 0],
            "Fy": F[:, 1],
        }

        coefs: dict[str, float] = {}
        ses: dict[str, float] = {}
        ci: dict[str, list[float]] = {}
        covs: dict[str, list[list[float]]] = {}
        stats_out: dict[str, dict[str, Any]] = {}
        excluded: dict[str, list[dict[str, Any]]] = {}
        used: dict[str, np.ndarray] = {}
        for eq in EQUATIONS:
            names = TERMS[eq]
            use = ~np.isin(trial, np.fromiter(reasons[eq], dtype=trial.dtype, count=len(reasons[eq])))
            n = _enough_trials(eq, int(use.sum()), len(names), reasons[eq], source)
            X, y = (design(eq), targets[eq]) if use.all() else (design(eq)[use], targets[eq][use])
            res = _lstsq(X, y, names, eq, self.max_design_cond)
            tq = t_975(res.dof)
            se = np.sqrt(np.maximum(np.diag(res.cov), 0.0))
            for k, name in enumerate(names):
                coefs[name] = float(res.beta[k])
                ses[name] = float(se[k])
                ci[name] = [float(res.beta[k] - tq * se[k]), float(res.beta[k] + tq * se[k])]
            covs[eq] = res.cov.tolist()
            stats_out[eq] = _equation_stats(eq, res, y, theta if use.all() else theta[use], n, tq)
            used[eq] = use
            excluded[eq] = [{"trial": t, "reason": r} for t, r in sorted(reasons[eq].items())]
            del X, y, res  # before the next equation's design is built

        self.coefficients, self.standard_errors, self.ci95 = coefs, ses, ci
        self.covariance, self.fit_stats = covs, _clean(stats_out)
        self.fitted_trials = _fitted_ranges(trial, used) if record_trials else {}
        self.excluded_trials = excluded
        self.source = str(source)
        self.labcli_version = __version__
        self.calibrated_range = _calibrated(table, fit_rows, calibrated)
        return self

    def _unplayed(self, table: Any, fit_rows: np.ndarray) -> tuple[Any, dict[str, list[int]]]:
        """The table with its angle labels corrected for the potentiometers' play (fitted here with
        Eqs. 34-35's designs, models/labels.py), and per angle equation the trials left out as read
        inside the play.  ``label_play="none"``, or too few fit trials, leaves the labels as read."""
        from .labels import fit_play, load_instruments, ratio_error_var, shaft_returns

        self.play = {}
        n_fit = int(np.count_nonzero(fit_rows))
        if self.label_play == "none" or n_fit < MIN_PLAY_TRIALS:
            return table, {}
        if n_fit > MAX_PLAY_TRIALS:
            # The shaft's states are a pass in trial order per joint; an archive this size is many
            # runs joined, not one sequence of loads, and its labels are taken as read.
            self.play = {"skipped": f"{n_fit} fit trials, more than the {MAX_PLAY_TRIALS} of one run's sequence"}
            return table, {}
        a = _table_arrays(table)
        if not np.all(np.isfinite(a["P0"]) & np.isfinite(a["P"]) & (a["P"] > 0)):
            return table, {}
        u = pressure_ratio_features(a["P0"], a["P"])
        order = np.argsort(a["trial"], kind="stable")
        out = table.copy()
        stuck: dict[str, list[int]] = {}
        widths, ses, trailing, holds = [], [], [], []
        fit_rows = np.asarray(fit_rows, bool)
        # "loads": the width on the loads as instruments (models/labels.py; fit_play leaves out a
        # trial without a finite load, so one such trial does not turn the fit back to "fit").
        loads = load_instruments(a["F"]) if self.label_play == "loads" else None
        error_var = ratio_error_var(u[fit_rows])  # the readings' repeatability, from the run itself
        returns = shaft_returns(table, order)  # where the shafts went between a load and the next rest
        for k, eq in enumerate(("theta1", "theta2")):
            design = u[:, :2] if eq == "theta1" else u
            res, corrected = fit_play(
                design,
                a["theta"][:, k],
                order,
                fit_rows,
                a["trial"],
                loads,
                error_var[: design.shape[1]],
                returns[:, k],
            )
            out[ANGLE_COLUMNS[k]] = np.degrees(corrected)
            stuck[eq] = list(res.stuck)
            widths.append(math.degrees(res.play_rad))
            ses.append(math.degrees(res.se_rad))
            trailing.append(res.trailing)
            holds.append(res.holds)
        self.play = {"play_deg": widths, "se_deg": ses, "trailing_trials": trailing, "inside_play": stuck}
        # Always written: a file without it predates the fit's decision, which its validation then
        # takes from the table as it did when it was written (labels.fitted_play).
        self.play["friction_holds"] = holds
        return out, stuck

    def _exclusions(
        self, trial: np.ndarray, P0: np.ndarray, P: np.ndarray, theta: np.ndarray, F: np.ndarray, js: np.ndarray
    ) -> dict[str, dict[int, str]]:
        """Per equation, the fit trials it leaves out and why (a sentence per trial); ``js`` is (J^-1)^T at
        the trials' angles (any stand-in where one is missing: such a trial is left out by that alone)."""
        h2, h3 = self.geometry["h2"], self.geometry["h3"]
        reasons: dict[str, dict[int, str]] = {eq: {} for eq in EQUATIONS}
        bad_p = ~(rows_all(np.isfinite(P0)) & rows_all(np.isfinite(P)) & rows_all(P0 > 0) & rows_all(P > 0))
        for eq in EQUATIONS:
            for t in trial[bad_p]:
                reasons[eq][int(t)] = "a pressure is missing or not positive"
        for k, eq in enumerate(("theta1", "theta2")):
            for t in trial[~np.isfinite(theta[:, k]) & ~bad_p]:
                reasons[eq][int(t)] = f"{ANGLE_COLUMNS[k]} is missing"
        angles_known = rows_all(np.isfinite(theta))
        theta2_threshold(h2, h3, self.max_amplification)  # a bound <= 1 is refused here
        amp = force_amplification(np.where(angles_known[:, None], theta, 0.0), h2, h3, js)
        for k, eq in enumerate(("Fx", "Fy")):
            # A sentence per excluded trial only; the usable ones are settled by one mask.
            usable = angles_known & np.isfinite(F[:, k]) & (amp[:, k] <= self.max_amplification)
            for i in np.flatnonzero(~bad_p & ~usable):
                t = trial[i]
                if not angles_known[i]:
                    reasons[eq][int(t)] = "a measured angle is missing"
                elif not np.isfinite(F[i, k]):
                    reasons[eq][int(t)] = f"{FORCE_COLUMNS[k]} is missing"
                elif not amp[i, k] <= self.max_amplification:
                    reasons[eq][int(t)] = (
                        f"singular Jacobian: |theta2| = {abs(math.degrees(theta[i, 1])):.2f} deg, "
                        f"{eq} amplification {amp[i, k]:.3g} > {self.max_amplification:g}"
                    )
        return reasons

    # ---------------------------------------------------------------- prediction
    def _require_fitted(self) -> None:
        if not self.is_fitted:
            raise ModelError("The model has no coefficients yet; fit it on a run first (`labcli fit RUN.h5`).")

    def predict(self, P0: Any, P: Any, mode: str = "pressure-only", theta: Any = None) -> dict[str, Any]:
        """Angles (rad) and forces (N) from pressures (MPa, (n, 4) in the order L1, R1, L2, R2).

        ``mode="pressure-only"`` takes the angles of Eqs. 34-35 into Eqs. 36-37;
        ``mode="measured-angles"`` uses ``theta`` ((n, 2), rad) there instead.  Every returned
        number is finite; ``ok`` marks which are trustworthy and ``flags`` says why not.
        """
        self._require_fitted()
        if mode not in ("pressure-only", "measured-angles"):
            raise ModelError(f"Unknown prediction mode '{mode}'; use pressure-only or measured-angles.")
        P0, P = pressure_arrays(P0, P)
        n = len(P)
        h2, h3 = self.geometry["h2"], self.geometry["h3"]
        with paused_gc():  # a list per trial: 10^6 of them, no cycles
            flags: list[list[str]] = [[] for _ in range(n)]
        bad_p = ~(rows_all(np.isfinite(P0)) & rows_all(np.isfinite(P)) & rows_all(P0 > 0) & rows_all(P > 0))
        # Bad rows get a neutral surrogate (no load) so the arithmetic stays finite.
        P0s = np.where(bad_p[:, None], 1.0, P0)
        Ps = np.where(bad_p[:, None], 1.0, P)
        u = pressure_ratio_features(P0s, Ps)
        b = self.coefficients
        s = stack_columns(
            [u[:, :2] @ np.array([b[k] for k in TERMS["theta1"]]), u @ np.array([b[k] for k in TERMS["theta2"]])]
        )
        clipped = np.abs(s) > 1.0
        th = np.arcsin(np.clip(s, -1.0, 1.0))
        ok_t = ~clipped & ~bad_p[:, None]
        for i in np.flatnonzero(bad_p | rows_any(clipped)):
            if bad_p[i]:
                flags[i].append("bad-pressure")
            for k in range(2):
                if clipped[i, k] and not bad_p[i]:
                    flags[i].append(f"theta{k + 1}-clipped")

        if mode == "pressure-only":
            th_force, ok_source = th, ok_t[:, 0] & ok_t[:, 1]
        else:
            th_force, ok_source = _measured_angles(theta, n, flags, bad_p)

        with np.errstate(divide="ignore", invalid="ignore"):
            js = jstar(th_force, h2, h3)
        amp = force_amplification(th_force, h2, h3, js)
        singular = ~(amp <= self.max_amplification)  # (n, 2): Fx, Fy
        for i in np.flatnonzero(rows_any(singular) & ok_source):
            flags[i].append("singular-jacobian")
        bx, by = (np.array([b[k] for k in TERMS[eq]]) for eq in ("Fx", "Fy"))
        with np.errstate(divide="ignore", invalid="ignore"):
            Xfx, Xfy = force_design(P0s, Ps, th_force, h2, h3, js=js)
            F = stack_columns([Xfx @ bx, Xfy @ by])
        bad = ~np.isfinite(F)
        if bad.any():
            # theta2 = 0 exactly: a finite stand-in from the edge of the trusted region.
            thr = self.theta2_threshold_rad
            t2 = np.where(th_force[:, 1] < 0, -thr, thr)
            Sx, Sy = force_design(P0s, Ps, stack_columns([th_force[:, 0], t2]), h2, h3)
            F = np.where(bad, stack_columns([Sx @ bx, Sy @ by]), F)
        ok_f = ok_source[:, None] & ~singular
        return {
            "theta1_rad": th[:, 0],
            "theta2_rad": th[:, 1],
            "Fx_N": F[:, 0],
            "Fy_N": F[:, 1],
            "ok": {"theta1": ok_t[:, 0], "theta2": ok_t[:, 1], "Fx": ok_f[:, 0], "Fy": ok_f[:, 1]},
            "flags": flags,
            "amplification": amp,
            "jacobian_cond": jacobian_cond(th_force[:, 1], h2, h3),
            "mode": mode,
        }

    def predict_table(self, table: Any, mode: str = "pressure-only") -> dict[str, Any]:
        """``predict`` on a trial table (measured angles taken from theta1_deg, theta2_deg)."""
        a = _table_arrays(table)
        out = self.predict(a["P0"], a["P"], mode=mode, theta=a["theta"] if mode == "measured-angles" else None)
        out["trial"] = a["trial"]
        return out

    # ---------------------------------------------------------------- compatibility
    def check_compatible(
        self, protocol: str, geometry: Mapping[str, Any], model_name: str = "the model", run_name: str = "the run"
    ) -> None:
        """ModelError unless the run has this model's protocol name and rig geometry."""
        if protocol != self.protocol:
            raise ModelError(
                f"{cap(model_name)} was fitted for protocol '{self.protocol}' but {run_name} "
                f"uses protocol '{protocol}'; fit a model on a run of this protocol."
            )
        other = normalise_geometry(geometry)
        for key in GEOMETRY_KEYS:
            if (
                key in self.geometry
                and key in other
                and not math.isclose(self.geometry[key], other[key], rel_tol=1e-9, abs_tol=1e-12)
            ):
                raise ModelError(
                    f"{cap(model_name)} was fitted for {key} = {self.geometry[key]:g} m but "
                    f"{run_name} has {key} = {other[key]:g} m; fit a model for this rig."
                )

    # ---------------------------------------------------------------- JSON
    def to_dict(self) -> dict[str, Any]:
        from .calibrated import captures_dict

        return _clean(
            {
                "schema": SCHEMA,
                "version": SCHEMA_VERSION,
                "units": UNITS,
                "sign_convention": SIGN_NOTE,
                "equations": {eq: list(TERMS[eq]) for eq in EQUATIONS},
                "protocol": self.protocol,
                "geometry": self.geometry,
                "settings": {
                    "max_amplification": self.max_amplification,
                    "max_design_cond": self.max_design_cond,
                    "theta2_threshold_deg": math.degrees(self.theta2_threshold_rad),
                },
                "coefficients": self.coefficients,
                "standard_errors": self.standard_errors,
                "ci95": self.ci95,
                "covariance": self.covariance,
                "fit_stats": self.fit_stats,
                "fitted_trials": self.fitted_trials,
                "excluded_trials": self.excluded_trials,
                "source": self.source,
                "labcli_version": self.labcli_version,
                "fitted_on": self.fitted_on,
                "form": "paper",
                "calibrated_range": self.calibrated_range,
                "baseline": {"p0_leak_corrected": self.p0_leak_corrected, "gap_s": self.baseline_gap_s},
                "labels": {"play": self.label_play, **self.play},
                **captures_dict(self.captures_per_load),
            }
        )

    def to_json(self) -> str:
        """The model as JSON (schema ``labcli-takuma-model``); floats round-trip exactly."""
        return dumps_indented(self.to_dict(), allow_nan=False) + "\n"

    @classmethod
    def from_dict(cls, d: Mapping[str, Any], name: str = "the model") -> TakumaModel:
        if not isinstance(d, Mapping):
            raise ModelError(
                f"{cap(name)} is not a labcli Takuma model (it holds {json_kind(d)}, not an "
                f"object with schema {SCHEMA!r}); pass a file written by `labcli fit`."
            )
        if d.get("schema") != SCHEMA:
            raise ModelError(
                f"{cap(name)} is not a labcli Takuma model (schema {d.get('schema')!r}, "
                f"expected {SCHEMA!r}); pass a file written by `labcli fit`."
            )
        if d.get("version") != SCHEMA_VERSION:
            raise ModelError(
                f"{cap(name)} has model version {d.get('version')!r}; this labcli reads version {SCHEMA_VERSION}."
            )
        if d.get("form", "paper") != "paper":
            raise ModelError(
                f"{cap(name)} holds the {d.get('form')!r} form, not the paper's Eqs. 34-37; "
                "this step needs a model from `labcli fit --form paper`."
            )
        from .calibrated import check_baseline, check_captures, check_range

        model = cls(**_model_fields(d, cap(name)))
        model.calibrated_range = check_range(d.get("calibrated_range"), name)
        model.p0_leak_corrected, model.baseline_gap_s = check_baseline(d.get("baseline"), name)
        model.captures_per_load = check_captures(d.get("captures_per_load"), name)
        model.label_play, model.play = labels_from_dict(d.get("labels"), name)
        unknown = [k for k in model.coefficients if k not in COEFFICIENT_NAMES]
        if unknown:
            what = "an unknown coefficient" if len(unknown) == 1 else "unknown coefficients"
            raise ModelError(
                f"{cap(name)} has {what}, {', '.join(unknown)} (Eqs. 34-37 have "
                f"{COEFFICIENT_NAMES[0]} to {COEFFICIENT_NAMES[-1]}); refit with `labcli fit`."
            )
        missing = [k for k in COEFFICIENT_NAMES if k not in model.coefficients]
        if missing:
            raise ModelError(f"{cap(name)} lacks the coefficient(s) {', '.join(missing)}; refit with `labcli fit`.")
        return model

    @classmethod
    def from_json(cls, text: str, name: str = "the model") -> TakumaModel:
        try:
            d = loads_bounded(text)
        except json.JSONDecodeError as e:
            raise ModelError(f"{cap(name)} is not valid JSON (line {e.lineno}, column {e.colno}: {e.msg}).") from None
        except JSONDepthError as e:
            raise ModelError(
                f"{cap(name)} nests {e.depth} levels deep, beyond the {MAX_DEPTH} a model file "
                "can have; pass the .json file `labcli fit` wrote."
            ) from None
        return cls.from_dict(d, name)

    @classmethod
    def load(cls, path: Any) -> TakumaModel:
        """Read a model JSON file (ModelError if missing or not a model)."""
        from ....core.files import read_input

        p = Path(path)
        try:
            text = read_input(p, "a model file", label=f"The model file {p}", error=ModelError).decode("utf-8")
        except FileNotFoundError:
            raise ModelError(f"The model file {p} does not exist; write one with `labcli fit`.") from None
        except IsADirectoryError:
            raise ModelError(f"The model file {p} is a folder; pass the .json file `labcli fit` wrote.") from None
        except UnicodeDecodeError as e:
            raise ModelError(
                f"The model file {p} is not UTF-8 text (bad byte at offset {e.start}); "
                "pass the .json file `labcli fit` wrote."
            ) from None
        except OSError as e:
            raise ModelError(f"The model file {p} cannot be read ({e.strerror or e}).") from None
        return cls.from_json(text, name=f"The model file {p}")

    def save(self, path: Any) -> None:
        Path(path).write_text(self.to_json(), encoding="utf-8")


def labels_from_dict(value: Any, name: str) -> tuple[str, dict[str, Any]]:
    """A model file's ``labels``: how its angle labels were taken (absent in older files: as read)."""
    if value is None:
        return "none", {}
    if not isinstance(value, Mapping) or value.get("play") not in LABEL_PLAYS:
        raise ModelError(
            f"{cap(name)} has a bad 'labels' entry (expected play 'fit', 'loads' or 'none'); refit with `labcli fit`."
        )
    holds = value.get("friction_holds", [False, False])
    if not (isinstance(holds, list) and len(holds) == 2 and all(isinstance(h, bool) for h in holds)):
        raise ModelError(
            f"{cap(name)}: key 'labels.friction_holds' must list two booleans (theta1, theta2); refit with `labcli fit`."
        )
    rest = {k: v for k, v in value.items() if k != "play"}
    return str(value["play"]), rest


# --------------------------------------------------------------------------- reading a model file
# A model file is typed by hand now and then, or comes from another program: every field is
# checked by name, so a damaged file gives one sentence naming the key, never a traceback.


def _bounded(name: str, x: float, bad: Callable[[str, str], NoReturn]) -> float:
    """A coefficient within :data:`MAX_COEFFICIENT` (``bad`` says otherwise)."""
    if not abs(x) <= MAX_COEFFICIENT:
        bad(f"coefficients.{name}", f"is {x:g}, beyond the {MAX_COEFFICIENT:g} a fitted coefficient can reach")
    return x


def _model_fields(d: Mapping[str, Any], where: str) -> dict[str, Any]:
    """Constructor arguments of TakumaModel from a model dict, each checked by key."""

    def bad(key: str, what: str) -> NoReturn:
        raise ModelError(f"{where}: key '{key}' {what}; refit with `labcli fit`.")

    def obj(key: str, v: Any) -> Mapping[str, Any]:
        if not isinstance(v, Mapping):
            bad(key, f"must be an object, not {json_kind(v)}")
        return v

    def num(key: str, v: Any, *, finite: bool = True, allow_null: bool = False) -> float:
        if v is None and allow_null:
            return math.nan  # written for a non-finite statistic (to_dict stores those as null)
        if isinstance(v, bool) or not isinstance(v, (int, float)) or (finite and not math.isfinite(v)):
            bad(key, f"must be a {'finite ' if finite else ''}number, not {json_kind(v)}")
        return float(v)

    def seq(key: str, v: Any) -> list[Any]:
        if not isinstance(v, list):
            bad(key, f"must be a list, not {json_kind(v)}")
        return v

    for key in ("protocol", "geometry", "coefficients"):
        if key not in d:
            raise ModelError(f"{where} lacks the key '{key}'; refit with `labcli fit`.")
    if not isinstance(d["protocol"], str):
        bad("protocol", f"must be a string, not {json_kind(d['protocol'])}")
    geometry = {k: num(f"geometry.{k}", v) for k, v in obj("geometry", d["geometry"]).items()}
    for key in ("h2", "h3"):
        value = geometry.get(key, geometry.get(f"{key}_m"))
        if value is None:
            raise ModelError(f"{where} lacks the key 'geometry.{key}'; refit with `labcli fit`.")
        if not value > 0:
            bad(f"geometry.{key}", f"must be a length greater than 0 m, not {value:g}")
    settings = obj("settings", d.get("settings", {}))
    max_amp = num("settings.max_amplification", settings.get("max_amplification", DEFAULT_MAX_AMPLIFICATION))
    if not max_amp > 1:
        bad("settings.max_amplification", f"must exceed 1, not {max_amp:g}")
    max_cond = num("settings.max_design_cond", settings.get("max_design_cond", DEFAULT_MAX_DESIGN_COND))
    if not max_cond > 1:
        bad("settings.max_design_cond", f"must exceed 1, not {max_cond:g}")
    stats = obj("fit_stats", d.get("fit_stats", {}))
    for k, v in stats.items():
        obj(f"fit_stats.{k}", v)
    fitted: dict[str, list[int]] = {}
    for k, v in obj("fitted_trials", d.get("fitted_trials", {})).items():
        fitted[k] = idranges.parse(v, f"fitted_trials.{k}", bad)
    excluded = {
        k: list(seq(f"excluded_trials.{k}", v)) for k, v in obj("excluded_trials", d.get("excluded_trials", {})).items()
    }
    coefs = obj("coefficients", d["coefficients"])
    return dict(
        geometry=geometry,
        protocol=d["protocol"],
        max_amplification=max_amp,
        max_design_cond=max_cond,
        coefficients={k: _bounded(k, num(f"coefficients.{k}", v), bad) for k, v in coefs.items()},
        standard_errors={
            k: num(f"standard_errors.{k}", v, finite=False, allow_null=True)
            for k, v in obj("standard_errors", d.get("standard_errors", {})).items()
        },
        ci95={
            k: [num(f"ci95.{k}", x, finite=False, allow_null=True) for x in seq(f"ci95.{k}", v)]
            for k, v in obj("ci95", d.get("ci95", {})).items()
        },
        covariance={
            k: [
                [num(f"covariance.{k}", x, finite=False, allow_null=True) for x in seq(f"covariance.{k}", r)]
                for r in seq(f"covariance.{k}", v)
            ]
            for k, v in obj("covariance", d.get("covariance", {})).items()
        },
        fit_stats={k: dict(v) for k, v in stats.items()},
        fitted_trials=fitted,
        excluded_trials=excluded,
        source=str(d.get("source", "")),
        labcli_version=str(d.get("labcli_version", "")),
        fitted_on=dict(obj("fitted_on", d.get("fitted_on", {}))),
    )


def _fitted_ranges(trial: np.ndarray, used: dict[str, np.ndarray]) -> dict[str, list[list[int]]]:
    """Per equation, the trials it was fitted on as ranges; listed once for the equations that use
    every fit trial (on a random split of 10^6 trials, 10^5 pairs each)."""
    every: list[list[int]] | None = None
    out: dict[str, list[list[int]]] = {}
    for eq, use in used.items():
        if use.all():
            every = idranges.to_ranges(trial) if every is None else every
            out[eq] = every
        else:
            out[eq] = idranges.to_ranges(trial[use])
    return out


def fit(
    table: Any,
    geometry: Mapping[str, Any],
    *,
    protocol: str = "takuma2014",
    max_amplification: float = DEFAULT_MAX_AMPLIFICATION,
    max_design_cond: float = DEFAULT_MAX_DESIGN_COND,
    source: str = "the trial table",
) -> TakumaModel:
    """Fit Eqs. 34-37 to the table's fit trials and return the model."""
    return TakumaModel(
        geometry=dict(geometry), protocol=protocol, max_amplification=max_amplification, max_design_cond=max_design_cond
    ).fit(table, source=source)


def _enough_trials(eq: str, n: int, p: int, reasons: Mapping[int, str], source: str) -> int:
    """``n``, the equation's usable fit trials, or the one sentence saying they are too few for its ``p`` coefficients."""
    if n < p + 1:
        why = sorted(set(reasons.values()))
        detail = f" ({len(reasons)} excluded: {'; '.join(why)})" if why else ""
        raise ModelError(
            f"The {eq} equation needs at least {p + 1} usable fit trials for "
            f"its {p} coefficients, but {source} has {n}{detail}; "
            "record more fit trials."
        )
    return n


def _calibrated(
    table: Any, fit_rows: np.ndarray, calibrated: Mapping[str, list[list[float]]] | None
) -> dict[str, list[list[float]]]:
    """The fit rows' calibrated range: the caller's, when it has it from the same table and rows."""
    from .calibrated import calibrated_range

    if calibrated is None:
        return calibrated_range(table, fit_rows)  # the play's correction keeps the rows
    return {k: [list(p) for p in v] for k, v in calibrated.items()}
