"""Baseline: what a user writes to fit Eqs. 34-37 (or check them) on a trial CSV, pandas and numpy alone.

    python paper_lstsq.py fit TRIALS.csv H2_M H3_M            # the four regressions; coefficients as JSON
    python paper_lstsq.py validate TRIALS.csv H2_M H3_M       # fitted on set == fit, checked on set == validation

No labcli import: the benchmarks time this beside ``labcli fit`` and ``labcli validate`` as the
independent baseline.  The equations are the paper's as the toolkit reads them (docs/errata.md):
sin(theta1) on u_L1, u_R1; sin(theta2) on the four u = P0/P - 1; Fx and Fy on the pressure
drops weighted by (J^-1)^T at the deflection and the joints' cosines.  validate predicts the
angles from the pressures, then the forces at those angles, and prints RMSE, MAE, max |error|,
bias and R^2 per quantity.
"""

import json
import sys

import numpy as np
import pandas as pd

P0 = ["P_L10", "P_R10", "P_L20", "P_R20"]
P1 = ["P_L1", "P_R1", "P_L2", "P_R2"]


def force_designs(P0, P, t1, t2, h2, h3):
    """Eqs. 36 and 37's six columns each, at the angles t1, t2 (rad)."""
    dP = P0 - P
    c1, c2 = np.cos(t1), np.cos(t2)
    s1, c12, s12 = np.sin(t1), np.cos(t1 + t2), np.sin(t1 + t2)
    a, b, c, d = -h2 * c1 - h3 * c12, -h3 * c12, -h2 * s1 - h3 * s12, -h3 * s12  # J
    det = h2 * h3 * np.sin(t2)
    jstar = [[d / det, -c / det], [-b / det, a / det]]  # (J^-1)^T
    out = []
    for row in jstar:
        ja, jb = row
        out.append(
            np.column_stack(
                [
                    ja * c1 * dP[:, 0],
                    ja * c1 * dP[:, 1],
                    ja * (c1 - c2) * dP[:, 2],
                    ja * (c1 - c2) * dP[:, 3],
                    jb * c2 * dP[:, 2],
                    jb * c2 * dP[:, 3],
                ]
            )
        )
    return out


def fit(df, h2, h3):
    P0v, Pv = df[P0].to_numpy(), df[P1].to_numpy()
    t1, t2 = np.radians(df["theta1_deg"].to_numpy()), np.radians(df["theta2_deg"].to_numpy())
    u = P0v / Pv - 1
    Xx, Xy = force_designs(P0v, Pv, t1, t2, h2, h3)
    return {
        "theta1": np.linalg.lstsq(u[:, :2], np.sin(t1), rcond=None)[0],
        "theta2": np.linalg.lstsq(u, np.sin(t2), rcond=None)[0],
        "Fx": np.linalg.lstsq(Xx, df["Fx_N"].to_numpy(), rcond=None)[0],
        "Fy": np.linalg.lstsq(Xy, df["Fy_N"].to_numpy(), rcond=None)[0],
    }


def metrics(obs, calc):
    err = calc - obs
    ss = np.sum((obs - obs.mean()) ** 2)
    return {
        "rmse": float(np.sqrt(np.mean(err**2))),
        "mae": float(np.mean(np.abs(err))),
        "max_abs": float(np.max(np.abs(err))),
        "bias": float(np.mean(err)),
        "r2": float(1 - np.sum(err**2) / ss),
    }


def validate(df, beta, h2, h3):
    P0v, Pv = df[P0].to_numpy(), df[P1].to_numpy()
    u = P0v / Pv - 1
    t1 = np.arcsin(np.clip(u[:, :2] @ beta["theta1"], -1, 1))
    t2 = np.arcsin(np.clip(u @ beta["theta2"], -1, 1))
    Xx, Xy = force_designs(P0v, Pv, t1, t2, h2, h3)
    calc = {
        "theta1_deg": np.degrees(t1),
        "theta2_deg": np.degrees(t2),
        "Fx_N": Xx @ beta["Fx"],
        "Fy_N": Xy @ beta["Fy"],
    }
    return {q: metrics(df[q].to_numpy(), v) for q, v in calc.items()}


def main():
    what, path, h2, h3 = sys.argv[1], sys.argv[2], float(sys.argv[3]), float(sys.argv[4])
    df = pd.read_csv(path)
    beta = fit(df[df["set"] == "fit"], h2, h3)
    if what == "fit":
        print(json.dumps({q: b.tolist() for q, b in beta.items()}, indent=2))
    else:
        print(json.dumps(validate(df[df["set"] == "validation"], beta, h2, h3), indent=2))


if __name__ == "__main__":
    main()
