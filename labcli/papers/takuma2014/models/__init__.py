"""Models fitted to run data: the paper's pressure-to-contact regression (Eqs. 34-37).

``takuma`` holds the model (fit, predict, JSON), ``metrics`` the accuracy measures of the
validation step, ``synthetic`` trial tables that obey the paper's equations exactly.
"""

from __future__ import annotations

from .takuma import COEFFICIENT_NAMES, PAPER_COEFFICIENTS, TakumaModel, fit

__all__ = ["COEFFICIENT_NAMES", "PAPER_COEFFICIENTS", "TakumaModel", "fit"]
