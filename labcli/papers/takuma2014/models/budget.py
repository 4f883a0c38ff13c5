"""Standard errors of the paper form's estimates from an error budget (Section 4's k_o = |F| / delta_x).

Eqs. 34-37 give numbers without standard errors.  A push's stiffness needs one (a steel can
read a third low has all its pushes agreeing, so their spread says nothing of the calibration's
error, which every push of the object shares).  The budget, per push and per quantity, with each
term in quadrature:

* **angle noise and model error**: the angle equation's residual standard deviation on the fit
  trials (``fit_stats[eq]["sigma"]``, in sin(theta), i.e. rad at these angles);
* **play**: the standard error of the play the fit estimated (``play["se_deg"]``,
  models/labels.py); the correction shifts every label by up to the play, so an error in it
  is an error in every deflection's scale;
* **scale**: the potentiometers' gain, :data:`POT_SCALE_SD` of the deflection (1 % rms, the
  tolerance of a conductive-plastic pot's resistance ratio such as the COPAL JC22E's);
* **thermal tail**: what is left of a fast load's pressure excess when the window is captured:
  a nearly adiabatic compression overshoots the isothermal change by ``kappa - 1`` of it, and
  ``exp(-settle / THERMAL_TAU_S)`` of that remains, with ``settle`` the protocol's earliest
  acceptance (three windows and the hold); counted as that share of the deflection;
* **force**: the force equation's residual standard deviation (N).

The deformation's error follows from the angles' through the contact point (``dx_theta_gain``
in models/stiffness.py), and ``classify`` turns both into each object's standard error of ln k
and its category's confidence (models/classify.py).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np

POT_SCALE_SD = 0.01  # relative rms error of a potentiometer's gain
THERMAL_TAU_S = 3.0  # the air's thermal relaxation in chambers of this size (s)
KAPPA_EXCESS = 0.4  # kappa - 1 for air: the adiabatic overshoot as a share of the isothermal change
DEFAULT_SETTLE_S = 5.0  # the earliest acceptance when the protocol's settling is not known


def tail_share(settle_s: float | None) -> float:
    """Share of a fast load's thermal excess left after ``settle_s``."""
    return KAPPA_EXCESS * math.exp(-(settle_s if settle_s and settle_s > 0 else DEFAULT_SETTLE_S) / THERMAL_TAU_S)


def paper_form_errors(model: Any, pred: Mapping[str, Any], settle_s: float | None) -> dict[str, np.ndarray] | None:
    """Per push: standard errors of theta1, theta2 (rad), Fx, Fy (N) of the paper form's ``pred``
    (None when the model carries no fit statistics, e.g. a model file of the paper's coefficients)."""
    stats = getattr(model, "fit_stats", None) or {}
    if not all(isinstance(stats.get(q), Mapping) and stats[q].get("sigma") is not None for q in ("theta1", "theta2")):
        return None
    play = getattr(model, "play", None) or {}
    play_se = [math.radians(float(v)) for v in play.get("se_deg", [0.0, 0.0])]
    tail = tail_share(settle_s)
    out: dict[str, np.ndarray] = {}
    for k, q in enumerate(("theta1", "theta2")):
        theta = np.abs(np.asarray(pred[f"{q}_rad"], dtype=float))
        sigma = float(stats[q]["sigma"])
        out[q] = np.sqrt(sigma**2 + play_se[k] ** 2 + (POT_SCALE_SD * theta) ** 2 + (tail * theta) ** 2)
    for q in ("Fx", "Fy"):
        n = len(out["theta1"])
        sigma_f = stats.get(q, {}).get("sigma") if isinstance(stats.get(q), Mapping) else None
        out[q] = np.full(n, float(sigma_f) if sigma_f is not None else math.nan)
    return out
