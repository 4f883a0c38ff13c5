"""Trial tables that obey Eqs. 34-37 exactly, for checking the fit and the accuracy figures.

Each trial draws joint angles, a tip force and baseline pressures, then solves the four
equations for the four loaded pressures (the angle equations fix two combinations of the
pressure ratios, the force equations two combinations of the pressure drops).  Sensor noise is
at the reference rig's 12-bit level: an optional Gaussian of a few counts, then rounding to the
count grid, for the SMC PSE530 pressures (1-5 V for 0-1 MPa on a 5 V ADC) and for the
potentiometer angles (about 340 deg over the 12-bit range).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from .takuma import (
    ANGLE_COLUMNS as ANGLES,
)
from .takuma import (
    BASELINE_COLUMNS as BASELINE,
)
from .takuma import (
    LOADED_COLUMNS as LOADED,
)
from .takuma import (
    PAPER_COEFFICIENTS,
    TERMS,
    force_design,
    pressure_ratio_features,
)

PAPER_GEOMETRY: dict[str, float] = {"h1": 0.355, "h2": 0.130, "h3": 0.065, "r1": 0.075, "r2": 0.035}
PRESSURE_LSB_MPA = 5.0 / 4095.0 / 4.0  # one ADC count through V = 4 P + 1
ANGLE_LSB_DEG = 340.0 / 4095.0


def _quantise(x: np.ndarray, lsb: float) -> np.ndarray:
    return np.round(x / lsb) * lsb


def add_sensor_noise(table: Any, seed: int = 0, noise_counts: float = 0.0) -> Any:
    """A copy of the table read through 12-bit sensors: pressures and angles get a Gaussian of
    ``noise_counts`` ADC counts and are then rounded to the count grid (forces are untouched:
    they come from weights)."""
    rng = np.random.default_rng(seed)
    out = table.copy()
    for cols, lsb in (((*BASELINE, *LOADED), PRESSURE_LSB_MPA), (ANGLES, ANGLE_LSB_DEG)):
        for c in cols:
            x = out[c].to_numpy(dtype=float)
            out[c] = _quantise(x + rng.normal(0.0, noise_counts * lsb, x.shape), lsb)
    return out


def paper_trials(
    n: int,
    *,
    seed: int = 0,
    noise: bool = True,
    set_name: str = "fit",
    start_id: int = 1,
    noise_counts: float = 0.0,
    coefficients: Mapping[str, float] = PAPER_COEFFICIENTS,
    geometry: Mapping[str, float] = PAPER_GEOMETRY,
    theta1_deg: tuple[float, float] = (-8.0, 8.0),
    theta2_deg: tuple[float, float] = (5.0, 25.0),
    force_N: float = 5.0,
    baseline_MPa: tuple[float, float] = (0.28, 0.32),
    theta2_values_deg: Any = None,
) -> Any:
    """A trial-table DataFrame of ``n`` trials that satisfy Eqs. 34-37.

    ``theta2_deg`` is the range of |theta2| (its sign is random); ``theta2_values_deg`` pins
    theta2 per trial instead (e.g. near-singular postures; not exactly 0, where Eqs. 36-37
    have no finite value).  Draws whose pressures have no
    solution in (0.05, 0.95) MPa are redrawn, so the table always has ``n`` rows.
    """
    rng = np.random.default_rng(seed)
    b = {eq: np.array([coefficients[k] for k in TERMS[eq]]) for eq in TERMS}
    rows: list[tuple[Any, ...]] = []
    attempts = 0
    while len(rows) < n:
        attempts += 1
        if attempts > 200 * n:
            raise ValueError("no pressures solve Eqs. 34-37 for these ranges; narrow them")
        i = len(rows)
        t1 = np.radians(rng.uniform(*theta1_deg))
        if theta2_values_deg is not None:
            t2 = np.radians(float(theta2_values_deg[i]))
        else:
            t2 = np.radians(rng.choice([-1.0, 1.0]) * rng.uniform(*theta2_deg))
        F = rng.uniform(-force_N, force_N, 2)
        P0 = rng.uniform(*baseline_MPa, 4)
        P = _loaded_pressures(t1, t2, F, P0, b, geometry)
        if P is not None:
            rows.append((t1, t2, F, P0, P))
    df = _trial_frame(rows, start_id, set_name)
    return add_sensor_noise(df, seed + 1, noise_counts) if noise else df


def _loaded_pressures(
    t1: float, t2: float, F: np.ndarray, P0: np.ndarray, b: dict[str, np.ndarray], geometry: Mapping[str, float]
) -> np.ndarray | None:
    """The loaded pressures that satisfy Eqs. 34-37 for this posture, force and baseline; None when
    none lies in (0.05, 0.95) MPa."""
    from scipy.optimize import fsolve

    theta = np.array([[t1, t2]])
    # Forces are linear in dP once the angles are fixed: row vectors a, c with F = [a; c] dP.
    eye = np.eye(4)
    Xfx, Xfy = force_design(np.zeros((4, 4)), -eye, np.repeat(theta, 4, axis=0), geometry["h2"], geometry["h3"])
    A = np.vstack([Xfx @ b["Fx"], Xfy @ b["Fy"]])

    def equations(dP: np.ndarray) -> np.ndarray:
        u = pressure_ratio_features(P0[None, :], (P0 - dP)[None, :])[0]
        return np.array([u[:2] @ b["theta1"] - np.sin(t1), u @ b["theta2"] - np.sin(t2), *(A @ dP - F)])

    # Start from the linearised system (u ~ dP / P0), which is close for loads of this size.
    lin = np.vstack([np.r_[b["theta1"], 0.0, 0.0] / P0, b["theta2"] / P0, A])
    try:
        start = np.linalg.solve(lin, np.r_[np.sin(t1), np.sin(t2), F])
    except np.linalg.LinAlgError:
        return None
    if np.any(P0 - start < 0.0):
        return None
    # Success is judged by the residual below; full_output keeps fsolve quiet about slow progress.
    dP = fsolve(equations, start, xtol=1e-13, full_output=True)[0]
    P = P0 - dP
    if np.max(np.abs(equations(dP))) > 1e-12 or np.any(P < 0.05) or np.any(P > 0.95):
        return None
    return P


def _trial_frame(rows: list[tuple[Any, ...]], start_id: int, set_name: str) -> Any:
    """The trial table of the solved trials ``(t1, t2, F, P0, P)``, numbered from ``start_id``."""
    import pandas as pd

    t1 = np.array([r[0] for r in rows])
    t2 = np.array([r[1] for r in rows])
    F = np.array([r[2] for r in rows])
    P0 = np.array([r[3] for r in rows])
    P = np.array([r[4] for r in rows])
    th = np.degrees(np.column_stack([t1, t2]))
    return pd.DataFrame(
        {
            "trial": np.arange(start_id, start_id + len(rows)),
            "set": set_name,
            "P_L10": P0[:, 0],
            "P_R10": P0[:, 1],
            "P_L20": P0[:, 2],
            "P_R20": P0[:, 3],
            "P_L1": P[:, 0],
            "P_R1": P[:, 1],
            "P_L2": P[:, 2],
            "P_R2": P[:, 3],
            "theta1_deg": th[:, 0],
            "theta2_deg": th[:, 1],
            "Fx_N": F[:, 0],
            "Fy_N": F[:, 1],
        }
    )
