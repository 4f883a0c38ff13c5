"""Which estimate each quantity takes: the posture form's or the paper's Eqs. 34-37, by cross-validation.

The posture form (models/posture.py) goes through the joint torques; the paper's form regresses
each quantity directly (Eq. 34 for theta1 on the outside pair alone, Eq. 36 for Fx on the
pressure drops weighted by j* at the deflection).  Where the arm rests straight the paper's
direct regressions can predict better: Eq. 36 fits Fx's own error with 6 coefficients where the
torque route fits two torques with 14 each, and Eq. 34 leaves out the inside pair, whose
pressures carry theta1 only through friction.  Neither form contains the other, so the choice is
made per quantity on the fit trials alone: both forms are fitted without one contiguous block of
fit trials (a plan groups its trials by pulley position, so a block is a direction the fit has
not seen) and predict that block from pressures only, as a validation trial is predicted.  A
quantity takes the paper's route when, over the held-out fit trials, the paper's form reports
every trial the posture form reports and its squared error summed over the trials both report is
lower.  The validation trials never enter the choice.

A quantity on the paper's route gets the paper's value and flags, and a standard error from the
same cross-validation: sqrt(s_cv^2 + x^T C x), with s_cv^2 the mean squared held-out error (which
already holds the angle estimate's error, as the force is computed from estimated angles) and
x^T C x the coefficients' share (Eqs. 34-37's covariance at the trial's terms; for an angle the
sine's variance over cos^2 theta).  It is flagged, as on the posture route, when that standard
error exceeds the protocol's limit.

Units: pressures MPa, angles rad, forces N.
"""

from __future__ import annotations

from typing import Any, Callable, Mapping

import numpy as np

from .takuma import TakumaModel, force_design, pressure_ratio_features

QUANTITIES = ("theta1", "theta2", "Fx", "Fy")
POSTURE, PAPER = "posture", "paper"
VALUE_KEYS = {"theta1": "theta1_rad", "theta2": "theta2_rad", "Fx": "Fx_N", "Fy": "Fy_N"}
CV_FOLDS = 10


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
    return [np.arange(lo, hi) for lo, hi in zip(edges[:-1], edges[1:]) if hi > lo]


def held_out_errors(fit_rows: Any, fit_posture: Callable[[Any], Any],
                    fit_paper: Callable[[Any], TakumaModel]) -> dict[str, dict[str, np.ndarray]]:
    """Per form and quantity: held-out errors (rad, N) of the fit trials and whether each was reported.

    ``fit_rows`` are the table's fit trials in recorded order; each contiguous block is left out
    in turn, both forms are fitted on the rest (``fit_posture``, ``fit_paper``) and predict the
    block pressure-only.  Returns ``{form: {q: err}}`` and ``{form + "_ok": {q: bool}}``.
    """
    n = len(fit_rows)
    out: dict[str, dict[str, np.ndarray]] = {
        key: {q: np.full(n, np.nan) if not key.endswith("_ok") else np.zeros(n, bool) for q in QUANTITIES}
        for key in (POSTURE, PAPER, POSTURE + "_ok", PAPER + "_ok")}
    truth = {"theta1": np.deg2rad(np.asarray(fit_rows["theta1_deg"], dtype=float)),
             "theta2": np.deg2rad(np.asarray(fit_rows["theta2_deg"], dtype=float)),
             "Fx": np.asarray(fit_rows["Fx_N"], dtype=float), "Fy": np.asarray(fit_rows["Fy_N"], dtype=float)}
    for block in _blocks(n):
        train = fit_rows.iloc[np.setdiff1d(np.arange(n), block)]
        test = fit_rows.iloc[block]
        for form, fitter in ((POSTURE, fit_posture), (PAPER, fit_paper)):
            pred = fitter(train).predict_table(test)
            for q in QUANTITIES:
                out[form][q][block] = np.asarray(pred[VALUE_KEYS[q]], dtype=float) - truth[q][block]
                out[form + "_ok"][q][block] = np.asarray(pred["ok"][q], dtype=bool)
    return out


def choose_routes(cv: Mapping[str, Mapping[str, np.ndarray]],
                  limits: Mapping[str, float]) -> tuple[dict[str, str], dict[str, Any]]:
    """The route per quantity and the cross-validation's figures (RMSE over the trials both report).

    The paper's route is taken only when it reports every held-out trial the posture form
    reports, and either its summed squared error over the trials both report is lower or the
    posture form reports none.  The paper's trials count as reported only while its held-out
    RMSE is within the quantity's standard-error limit (``limits``, rad or N): beyond it every
    one of them would be flagged by that standard error.
    """
    routes, stats = {}, {}
    for q in QUANTITIES:
        ok_po, ok_pa = cv[POSTURE + "_ok"][q], cv[PAPER + "_ok"][q] & np.isfinite(cv[PAPER][q])
        if ok_pa.any() and not np.sqrt(np.mean(cv[PAPER][q][ok_pa] ** 2)) <= limits.get(q, np.inf):
            ok_pa = np.zeros_like(ok_pa)
        both = ok_po & ok_pa & np.isfinite(cv[POSTURE][q])
        sse = {f: float(np.sum(cv[f][q][both] ** 2)) for f in (POSTURE, PAPER)}
        better = sse[PAPER] < sse[POSTURE] if both.any() else bool(ok_pa.any()) and not ok_po.any()
        take_paper = better and not np.any(ok_po & ~ok_pa)
        routes[q] = PAPER if take_paper else POSTURE
        stats[q] = {"n_both": int(both.sum()),
                    **{f"rmse_{f}": (float(np.sqrt(sse[f] / both.sum())) if both.any() else None)
                       for f in (POSTURE, PAPER)},
                    "reported_posture": int(ok_po.sum()), "reported_paper": int(ok_pa.sum())}
    return routes, stats


def paper_residual_variances(cv: Mapping[str, Mapping[str, np.ndarray]], routes: Mapping[str, str]) -> dict[str, float]:
    """Mean squared held-out error (rad^2, N^2) of the paper's route over the trials it reports."""
    out = {}
    for q, route in routes.items():
        if route == PAPER:
            err = cv[PAPER][q][cv[PAPER + "_ok"][q] & np.isfinite(cv[PAPER][q])]
            out[q] = float(np.mean(err ** 2))
    return out


def paper_standard_errors(paper: TakumaModel, pred: Mapping[str, Any], P0: np.ndarray, P: np.ndarray,
                          theta_force: np.ndarray, variances: Mapping[str, float]) -> dict[str, np.ndarray]:
    """Standard errors (rad, N) of the paper-routed quantities: held-out residual plus the coefficients' share."""
    u = pressure_ratio_features(P0, P)
    g = paper.geometry
    with np.errstate(divide="ignore", invalid="ignore"):
        Xfx, Xfy = force_design(P0, P, theta_force, g["h2"], g["h3"])
    designs = {"theta1": u[:, :2], "theta2": u, "Fx": Xfx, "Fy": Xfy}
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
