"""Which estimate each quantity takes: the posture form's, the paper's Eqs. 34-37, or a blend of both.

The posture form (models/posture.py) goes through the joint torques; the paper's form regresses
each quantity directly (Eq. 34 for theta1 on the outside pair alone, Eq. 36 for Fx on the
pressure drops weighted by j* at the deflection).  Where the arm rests straight the paper's
direct regressions can predict better: Eq. 36 fits Fx's own error with 6 coefficients where the
torque route fits two torques on up to 14 terms, and Eq. 34 leaves out the inside pair, whose
pressures carry theta1 only through friction.  Neither form contains the other, so the choice is
made per quantity on the fit trials alone: both forms are fitted without one contiguous block of
fit trials (a plan groups its trials by pulley position, so a block is a direction the fit has
not seen) and predict that block from pressures only, as a validation trial is predicted.  The
validation trials never enter the choice.

The two forms' errors are far from equal (friction errs one way in the torques and another in
Eq. 36's direct fit), so the estimate is the stacked one (Breiman's stacking, two members):
w x_posture + (1 - w) x_paper with the weight w in [0, 1] that minimises the held-out squared
error over the fit trials both forms report,

    w = sum e_pa (e_pa - e_po) / sum (e_po - e_pa)^2,   clipped to [0, 1].

w = 1 is the posture route, w = 0 the paper's, anything between a blend.  The paper's form takes
part only when it reports every held-out trial the posture form reports, and only while its
held-out RMSE is within the quantity's standard-error limit (beyond it every one of its trials
would be flagged); where the posture form reports none, the paper's route is taken if it
reports any.

A quantity on the paper's route gets the paper's value and flags, and a standard error from the
same cross-validation: sqrt(s_cv^2 + x^T C x), with s_cv^2 the mean squared held-out error (which
already holds the angle estimate's error, as the force is computed from estimated angles) and
x^T C x the coefficients' share (Eqs. 34-37's covariance at the trial's terms; for an angle the
sine's variance over cos^2 theta).  A blend's variance is that of the weighted sum,
w^2 s_po^2 + (1 - w)^2 s_pa^2 + 2 w (1 - w) rho s_po s_pa, with each form's own standard error
and rho the correlation of their held-out errors; on a trial the paper's form does not report,
the blend is the posture form's estimate.  Either is flagged, as on the posture route, when its
standard error exceeds the protocol's limit.

The posture form's own standard errors come from its fit's residuals, which a direction the fit
never loaded does not show: on the literature's rig the straight arm's Fx erred by 0.77 N held
out a direction at a time where its standard errors said 0.71 (tuning seeds 1-10).  The same
folds measure it: each held-out trial lies some angle d from the nearest load direction its fold
was fitted on (the table's ``direction_deg``), and the variance the standard errors lack grows
as c d^2 (the fit's error is smooth in the direction, so it grows linearly away from a direction
it saw).  c is the value with mean e^2 / (s^2 + c d^2) = 1 over the held-out trials the posture
form reports (e its held-out error, s its fold's standard error), and a new load is given the
term at the farthest a load can lie from the fit plan's directions, half the widest gap between
neighbouring directions (:func:`held_out_variances`).  It widens the intervals only: the
estimates and their flags are those of the trial's own standard error (``labcli sense``'s release
reading, forces within ``release_force_se`` standard errors of zero, takes the widened ones: the
sensing figures are measured with it).  Chosen on tuning seeds
1-10 over the folds' own excess at every load (c d^2 at the folds' distance): that one covered the
literature bent arm's Fx 98 % and, entering the flags, left 60 of its 180 trials under the 1 N
limit (159 before); the kind rig's bent Fy 100 %.

Units: pressures MPa, angles rad, forces N.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from typing import Any

import numpy as np

from .takuma import TakumaModel, force_design, pressure_ratio_features

QUANTITIES = ("theta1", "theta2", "Fx", "Fy")
POSTURE, PAPER, BLEND = "posture", "paper", "blend"
VALUE_KEYS = {"theta1": "theta1_rad", "theta2": "theta2_rad", "Fx": "Fx_N", "Fy": "Fy_N"}
CV_FOLDS = 10
DIRECTIONS = "directions"  # held_out_errors' key of each held-out trial's distance in direction
# A stacking weight this close to 0 or 1 is taken as the one form alone: it would move no
# estimate by more than 1 % of the two forms' difference, and a blend needs the paper's part.
SNAP = 0.01


# The route choice compares two held-out errors; past this many fit trials more of them do not
# change it (the errors' relative precision is already about 1 %), while refitting both forms ten
# times over a lab archive's 10^6 trials took eight times the fit itself (tests/benchmarks/bench_tables.py).
ROUTE_SAMPLE = 20_000


def route_sample(fit_index: np.ndarray) -> np.ndarray:
    """The fit trials the route choice uses: all of them, or ROUTE_SAMPLE evenly spread in recorded
    order (so each contiguous block is still a stretch of the plan's pulley positions)."""
    n = len(fit_index)
    if n <= ROUTE_SAMPLE:
        return fit_index
    return fit_index[np.unique(np.linspace(0, n - 1, ROUTE_SAMPLE).round().astype(np.int64))]


def _blocks(n: int) -> list[np.ndarray]:
    edges = np.linspace(0, n, min(CV_FOLDS, n) + 1).astype(int)
    return [np.arange(lo, hi) for lo, hi in zip(edges[:-1], edges[1:], strict=False) if hi > lo]


def held_out_errors(
    fit_rows: Any,
    fit_posture: Callable[[Any], Any],
    fit_paper: Callable[[Any], TakumaModel],
    paper_folds: Callable[[Any, list[np.ndarray]], list[TakumaModel] | None] | None = None,
) -> dict[str, dict[str, np.ndarray]]:
    """Per form and quantity: held-out errors (rad, N) of the fit trials and whether each was reported.

    ``fit_rows`` are the table's fit trials in recorded order; each contiguous block is left out
    in turn, both forms are fitted on the rest (``fit_posture``, ``fit_paper``) and predict the
    block pressure-only.  ``paper_folds(fit_rows, blocks)``, when given and not None, gives the
    paper form's fold fits all at once (models/paper_folds.py: from each block's R factor) in
    place of ``fit_paper`` on each fold's rows.  Returns ``{form: {q: err}}``,
    ``{form + "_ok": {q: bool}}``, the posture form's standard errors ``{"posture_se": {q: se}}``
    and the load directions (:func:`direction_distances`) under ``DIRECTIONS``.
    """
    n = len(fit_rows)
    out: dict[str, dict[str, np.ndarray]] = {
        key: {q: np.full(n, np.nan) if not key.endswith("_ok") else np.zeros(n, bool) for q in QUANTITIES}
        for key in (POSTURE, PAPER, POSTURE + "_ok", PAPER + "_ok", POSTURE + "_se")
    }
    truth = {
        "theta1": np.deg2rad(np.asarray(fit_rows["theta1_deg"], dtype=float)),
        "theta2": np.deg2rad(np.asarray(fit_rows["theta2_deg"], dtype=float)),
        "Fx": np.asarray(fit_rows["Fx_N"], dtype=float),
        "Fy": np.asarray(fit_rows["Fy_N"], dtype=float),
    }
    blocks = _blocks(n)
    papers = paper_folds(fit_rows, blocks) if paper_folds is not None else None
    for f, block in enumerate(blocks):
        train = fit_rows.iloc[np.setdiff1d(np.arange(n), block)]
        test = fit_rows.iloc[block]
        for form, fitter in ((POSTURE, fit_posture), (PAPER, fit_paper)):
            model = papers[f] if form == PAPER and papers is not None else fitter(train)
            pred = model.predict_table(test)
            for q in QUANTITIES:
                out[form][q][block] = np.asarray(pred[VALUE_KEYS[q]], dtype=float) - truth[q][block]
                out[form + "_ok"][q][block] = np.asarray(pred["ok"][q], dtype=bool)
                if form == POSTURE:
                    out[POSTURE + "_se"][q][block] = np.asarray(pred["se"][q], dtype=float)
    out[DIRECTIONS] = direction_distances(fit_rows, blocks)
    return out


def _angle_between(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """|a - b| on the circle (rad), in [0, pi]."""
    return np.abs(np.angle(np.exp(1j * (np.asarray(a, dtype=float) - np.asarray(b, dtype=float)))))


def direction_distances(fit_rows: Any, blocks: list[np.ndarray]) -> dict[str, np.ndarray]:
    """Each fit trial's angle (rad) to the nearest load direction of the trials its fold was fitted
    on (``"held_out"``), and the fit trials' load directions (``"fitted"``); without a
    ``direction_deg`` column every distance is 1 and no direction is known (the term is then the
    held-out folds' own).  Trials without a load (or direction) take no part (NaN)."""
    n = len(fit_rows)
    if "direction_deg" not in getattr(fit_rows, "columns", ()):
        return {"held_out": np.ones(n), "fitted": np.empty(0)}
    mass = np.asarray(fit_rows["mass_g"], dtype=float) if "mass_g" in fit_rows.columns else np.ones(n)
    phi = np.radians(np.asarray(fit_rows["direction_deg"], dtype=float))
    loaded = np.isfinite(phi) & (mass > 0)
    phi = np.where(loaded, phi, np.nan)
    out = np.full(n, np.nan)
    for block in blocks:
        rest = np.setdiff1d(np.arange(n), block)
        seen = np.unique(phi[rest][loaded[rest]])
        if seen.size:
            out[block] = np.min(_angle_between(phi[block][:, None], seen[None, :]), axis=1)
    return {"held_out": out, "fitted": np.unique(phi[loaded])}


def widest_half_gap(directions: np.ndarray) -> float:
    """Half the widest gap (rad) between neighbouring load directions around the circle: the
    farthest a load can lie from all of them (1 where none are known: the folds' own distance)."""
    phi = np.unique(np.mod(np.asarray(directions, dtype=float), 2 * np.pi))
    if phi.size == 0:
        return 1.0
    gaps = np.diff(np.append(phi, phi[0] + 2 * np.pi))
    return 0.5 * float(np.max(gaps))


def held_out_variances(cv: Mapping[str, Mapping[str, np.ndarray]]) -> dict[str, float]:
    """Per quantity the variance (rad^2, N^2) the posture form's standard errors lack at the farthest
    a load can lie from the fit plan's directions (module docstring): c d_max^2 with c the value
    that makes mean e^2 / (s^2 + c d^2) = 1 over the held-out trials the posture form reports.
    Quantities whose held-out errors their standard errors already cover get none."""
    d2 = np.asarray(cv[DIRECTIONS]["held_out"], dtype=float) ** 2
    reach = widest_half_gap(cv[DIRECTIONS]["fitted"]) ** 2
    out = {}
    for q in QUANTITIES:
        e, s = cv[POSTURE][q], cv[POSTURE + "_se"][q]
        keep = cv[POSTURE + "_ok"][q] & np.isfinite(e) & np.isfinite(s) & (s > 0) & np.isfinite(d2)
        z2, r = e[keep] ** 2 / s[keep] ** 2, d2[keep] / s[keep] ** 2
        if z2.size < 2 or not np.mean(z2) > 1.0 or not np.any(r > 0):
            continue
        # mean z^2 / (1 + c r) falls with c, from above 1 at c = 0 to below 1 where c r >= z^2 - 1 for all.
        lo, hi = 0.0, float(np.max(z2 / np.where(r > 0, r, np.inf)))
        for _ in range(60):
            mid = 0.5 * (lo + hi)
            lo, hi = (mid, hi) if np.mean(z2 / (1.0 + mid * r)) > 1.0 else (lo, mid)
        out[q] = 0.5 * (lo + hi) * reach
    return out


def stacking_weight(e_posture: np.ndarray, e_paper: np.ndarray) -> float:
    """The posture form's weight w in [0, 1] minimising sum (w e_po + (1 - w) e_pa)^2 (held-out errors)."""
    d = np.asarray(e_posture, dtype=float) - np.asarray(e_paper, dtype=float)
    dd = float(np.sum(d * d))
    if not dd > 0:
        return 1.0  # the same errors: the posture form alone
    return float(np.clip(-np.sum(np.asarray(e_paper, dtype=float) * d) / dd, 0.0, 1.0))


def error_correlation(e_posture: np.ndarray, e_paper: np.ndarray) -> float:
    """The correlation of two forms' held-out errors about zero (their mean is part of the error)."""
    a, b = np.asarray(e_posture, dtype=float), np.asarray(e_paper, dtype=float)
    norm = math.sqrt(float(np.sum(a * a)) * float(np.sum(b * b)))
    return float(np.clip(np.sum(a * b) / norm, -1.0, 1.0)) if norm > 0 else 0.0


def choose_routes(
    cv: Mapping[str, Mapping[str, np.ndarray]], limits: Mapping[str, float]
) -> tuple[dict[str, str], dict[str, Any], dict[str, dict[str, float]]]:
    """The route per quantity, the cross-validation's figures, and each blend's weight and correlation.

    Returns ``routes`` (``posture``, ``paper`` or ``blend`` per quantity), ``stats`` (held-out RMSE
    of each form and of the stacked estimate over the trials both report, and how many each
    reports) and ``blends`` (``{q: {"posture_weight": w, "error_correlation": rho}}`` for the
    blended quantities).  The paper's trials count as reported only while its held-out RMSE is
    within the quantity's standard-error limit (``limits``, rad or N).
    """
    routes, stats, blends = {}, {}, {}
    for q in QUANTITIES:
        ok_po, ok_pa = cv[POSTURE + "_ok"][q], cv[PAPER + "_ok"][q] & np.isfinite(cv[PAPER][q])
        if ok_pa.any() and not np.sqrt(np.mean(cv[PAPER][q][ok_pa] ** 2)) <= limits.get(q, np.inf):
            ok_pa = np.zeros_like(ok_pa)
        both = ok_po & ok_pa & np.isfinite(cv[POSTURE][q])
        e_po, e_pa = cv[POSTURE][q][both], cv[PAPER][q][both]
        covers = not np.any(ok_po & ~ok_pa)  # the paper's form reports every trial the posture form does
        w = stacking_weight(e_po, e_pa) if both.any() and covers else 1.0
        if not both.any() and ok_pa.any() and not ok_po.any():
            w = 0.0
        routes[q] = POSTURE if w >= 1.0 - SNAP else PAPER if w <= SNAP else BLEND
        if routes[q] == BLEND:
            blends[q] = {"posture_weight": w, "error_correlation": error_correlation(e_po, e_pa)}
        rmse = (lambda e: float(np.sqrt(np.mean(e**2)))) if both.any() else (lambda e: None)
        stats[q] = {
            "n_both": int(both.sum()),
            "rmse_posture": rmse(e_po),
            "rmse_paper": rmse(e_pa),
            "rmse_stacked": rmse(w * e_po + (1.0 - w) * e_pa),
            "posture_weight": w,
            "reported_posture": int(ok_po.sum()),
            "reported_paper": int(ok_pa.sum()),
        }
    return routes, stats, blends


def blend_estimate(
    w: float, rho: float, v_po: np.ndarray, s_po: np.ndarray, v_pa: np.ndarray, s_pa: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """The stacked estimate w v_po + (1 - w) v_pa and its standard error (module docstring)."""
    var = (w * s_po) ** 2 + ((1.0 - w) * s_pa) ** 2 + 2.0 * w * (1.0 - w) * rho * s_po * s_pa
    return w * v_po + (1.0 - w) * v_pa, np.sqrt(np.maximum(var, 0.0))


def paper_residual_variances(cv: Mapping[str, Mapping[str, np.ndarray]], routes: Mapping[str, str]) -> dict[str, float]:
    """Mean squared held-out error (rad^2, N^2) of the paper's form over the trials it reports, for
    the quantities that take it (paper route or blend)."""
    out = {}
    for q, route in routes.items():
        if route != POSTURE:
            err = cv[PAPER][q][cv[PAPER + "_ok"][q] & np.isfinite(cv[PAPER][q])]
            out[q] = float(np.mean(err**2))
    return out


def paper_standard_errors(
    paper: TakumaModel,
    pred: Mapping[str, Any],
    P0: np.ndarray,
    P: np.ndarray,
    theta_force: np.ndarray,
    variances: Mapping[str, float],
) -> dict[str, np.ndarray]:
    """Standard errors (rad, N) of the paper's form for the quantities in ``variances``: held-out
    residual plus the coefficients' share."""
    u = pressure_ratio_features(P0, P)
    g = paper.geometry
    forces = [q for q in ("Fx", "Fy") if q in variances]  # a force design only where one is asked for
    with np.errstate(divide="ignore", invalid="ignore"):
        designs = dict(zip(forces, force_design(P0, P, theta_force, g["h2"], g["h3"], forces), strict=False))
    designs.update(theta1=u[:, :2], theta2=u)
    out = {}
    for q, var in variances.items():
        X = np.nan_to_num(designs[q], nan=0.0, posinf=1e300, neginf=-1e300)
        C = np.asarray(paper.covariance[q], dtype=float)
        with np.errstate(over="ignore", invalid="ignore"):
            coef = np.einsum("ni,ij,nj->n", X, C, X)
        if q.startswith("theta"):
            coef = coef / np.maximum(np.cos(np.asarray(pred[VALUE_KEYS[q]], dtype=float)) ** 2, 1e-12)
        se = np.sqrt(var + np.where(np.isfinite(coef), np.maximum(coef, 0.0), np.inf))
        out[q] = se
    return out
