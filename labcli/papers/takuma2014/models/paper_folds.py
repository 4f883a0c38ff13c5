"""The paper's Eqs. 34-37 fitted once per cross-validation fold, from each block's R factor.

The posture form's route choice (models/routes.py) fits the paper's form ten times, each time
without one contiguous block of the same fit trials.  Those fits share their rows: each
equation's design [X | y] is built once for all the trials, each block is reduced to the R
factor of its rows (at most p + 1 rows), and a fold's least squares is the one on the stacked R's
of the other blocks (Q is orthonormal: the same normal equations, the same singular values).  A
fold then costs a QR of 9 x 7 rows instead of a pass over 18,000 trials' pressures, angles,
exclusions and designs.

The answer is :meth:`TakumaModel.fit`'s on the fold's trials (``label_play="none"``, as the route
choice fits it), to rounding: the same column scaling (the training rows' column norms, read off
the stacked R), the same SVD, the same refusals (too few usable trials, a term zero in every
trial, a collinear design) as ModelError.  Only the coefficients are kept: the route choice
asks each fold's model for predictions alone.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ....errors import ModelError
from .geometry import jstar
from .takuma import (
    EQUATIONS,
    TERMS,
    TakumaModel,
    _table_arrays,
    force_design,
    pressure_ratio_features,
    qr_r,
    set_mask,
)


def fold_models(template: TakumaModel, rows: Any, blocks: list[np.ndarray], source: str) -> list[TakumaModel] | None:
    """Per block of ``rows`` (positions in the table ``rows``), the paper's form fitted on the other blocks.

    ``template`` gives the geometry, protocol and bounds.  None when the shortcut does not apply
    (labels corrected for the potentiometers' play, or a trial number on several rows, where an
    exclusion reaches past its own row): the caller then fits each fold from its rows.
    """
    if template.label_play != "none":
        return None
    fit = set_mask(rows, "fit", source)
    a = _table_arrays(rows)
    trial = a["trial"]
    if len(np.unique(trial)) != len(trial):
        return None
    probe = TakumaModel(geometry=template.geometry, protocol=template.protocol, label_play="none")
    probe.max_amplification, probe.max_design_cond = template.max_amplification, template.max_design_cond
    h2, h3 = probe.geometry["h2"], probe.geometry["h3"]
    theta_known = np.nan_to_num(a["theta"], nan=1.0)
    with np.errstate(divide="ignore", invalid="ignore"):
        js = jstar(theta_known, h2, h3)
        reasons = probe._exclusions(trial, a["P0"], a["P"], a["theta"], a["F"], js)
        u = pressure_ratio_features(a["P0"], a["P"])
        designs = {
            "theta1": (u[:, :2], np.sin(a["theta"][:, 0])),
            "theta2": (u, np.sin(a["theta"][:, 1])),
            "Fx": (force_design(a["P0"], a["P"], theta_known, h2, h3, ("Fx",), js)[0], a["F"][:, 0]),
            "Fy": (force_design(a["P0"], a["P"], theta_known, h2, h3, ("Fy",), js)[0], a["F"][:, 1]),
        }
    factors = {}
    for eq in EQUATIONS:
        use = fit & ~np.isin(trial, np.fromiter(reasons[eq], dtype=trial.dtype, count=len(reasons[eq])))
        X, y = designs[eq]
        factors[eq] = [_block_factor(X, y, use, block) for block in blocks]
    return [_fold_model(probe, factors, f, source) for f in range(len(blocks))]


def _block_factor(X: np.ndarray, y: np.ndarray, use: np.ndarray, block: np.ndarray) -> tuple[np.ndarray, int]:
    """The R of the block's usable rows of [X | y], and how many rows that is."""
    keep = block[use[block]]
    if not len(keep):
        return np.zeros((0, X.shape[1] + 1)), 0
    Z = np.empty((len(keep), X.shape[1] + 1), order="F")
    Z[:, :-1], Z[:, -1] = X[keep], y[keep]
    return qr_r(Z), len(keep)


def _fold_model(
    probe: TakumaModel, factors: dict[str, list[tuple[np.ndarray, int]]], f: int, source: str
) -> TakumaModel:
    coefs: dict[str, float] = {}
    for eq in EQUATIONS:
        names = TERMS[eq]
        parts = [r for i, (r, _) in enumerate(factors[eq]) if i != f and len(r)]
        n, p = sum(k for i, (_, k) in enumerate(factors[eq]) if i != f), len(names)
        if n < p + 1:
            raise ModelError(f"The {eq} equation needs at least {p + 1} usable fit trials, but {source} has {n}.")
        beta = _solve(qr_r(np.vstack(parts)), names, eq, probe.max_design_cond)
        coefs.update({name: float(b) for name, b in zip(names, beta, strict=True)})
    model = TakumaModel(geometry=probe.geometry, protocol=probe.protocol, label_play="none")
    model.max_amplification, model.max_design_cond = probe.max_amplification, probe.max_design_cond
    model.coefficients = coefs
    return model


def _solve(R: np.ndarray, names: tuple[str, ...], eq: str, max_cond: float) -> np.ndarray:
    """:func:`..takuma._lstsq`'s coefficients from the R of the training rows' [X | y]."""
    p = len(names)
    scale = np.linalg.norm(R[:, :p], axis=0)  # X's column norms: Q keeps lengths
    zero = [names[k] for k in range(p) if not scale[k] > 0]
    if zero:
        raise ModelError(f"The {eq} fit cannot determine {', '.join(zero)}: its term is zero in every usable trial.")
    U, s, Vt = np.linalg.svd(R[:p, :p] / scale)
    if not (s[-1] > 0 and s[0] / s[-1] <= max_cond):
        raise ModelError(f"The {eq} design matrix is collinear.")
    return (Vt.T @ ((U.T @ R[:p, p]) / s)) / scale
