"""Baseline: what a user writes to classify pushed objects from a push CSV, pandas and numpy alone.

    python classify_groupby.py PUSHES.csv MODEL.json H2_M H3_M BANDS_JSON

The force model is a labcli model file of the paper's form (Eqs. 34-37's coefficients under
"coefficients"), evaluated vectorised: angles from the pressure ratios, forces from the pressure
drops at those angles.  Each push's stiffness is Section 4's k = |F| / delta_x with the object's
centre pushed by d along phi from (R, h2 + h3); pushes with no deformation or no force are left
out.  Per object (pandas groupby): pushes, pushes used, mean, sd and median of k, mean and sd of
ln k, and the band (BANDS_JSON: {category: [low, high]} in N/m, high null = open) holding the
median.  Every push and every object is written as JSON to stdout.  No labcli import: the
benchmarks time this beside ``labcli classify --json`` as the independent baseline.
"""

import json
import sys

import numpy as np
import pandas as pd


def forces(df, b, h2, h3):
    P0 = df[["P_L10", "P_R10", "P_L20", "P_R20"]].to_numpy()
    P = df[["P_L1", "P_R1", "P_L2", "P_R2"]].to_numpy()
    u, dP = P0 / P - 1, P0 - P
    t1 = np.arcsin(np.clip(u[:, :2] @ [b["beta_theta1_L1"], b["beta_theta1_R1"]], -1, 1))
    t2 = np.arcsin(np.clip(u @ [b[f"beta_theta2_{a}"] for a in ("L1", "R1", "L2", "R2")], -1, 1))
    c1, c2, s1, c12, s12 = np.cos(t1), np.cos(t2), np.sin(t1), np.cos(t1 + t2), np.sin(t1 + t2)
    det = h2 * h3 * np.sin(t2)
    jstar = {"Fx": (-h3 * s12 / det, (h2 * s1 + h3 * s12) / det), "Fy": (h3 * c12 / det, (-h2 * c1 - h3 * c12) / det)}
    out = {"theta1": t1, "theta2": t2}
    for q, (ja, jb) in jstar.items():
        terms = [
            ja * c1 * dP[:, 0],
            ja * c1 * dP[:, 1],
            ja * (c1 - c2) * dP[:, 2],
            ja * (c1 - c2) * dP[:, 3],
            jb * c2 * dP[:, 2],
            jb * c2 * dP[:, 3],
        ]
        out[q] = sum(b[f"beta_{q}{i + 1}"] * t for i, t in enumerate(terms))
    return out


def main():
    pushes, model, h2, h3, bands = sys.argv[1], sys.argv[2], float(sys.argv[3]), float(sys.argv[4]), sys.argv[5]
    df = pd.read_csv(pushes)
    with open(model) as f:
        b = json.load(f)["coefficients"]
    est = forces(df, b, h2, h3)
    t1, t12 = est["theta1"], est["theta1"] + est["theta2"]
    cx, cy = -h2 * np.sin(t1) - h3 * np.sin(t12), h2 * np.cos(t1) + h3 * np.cos(t12)
    phi = np.radians(df["phi_deg"].to_numpy())
    ox, oy = df["R_m"] - df["d_m"] * np.cos(phi), h2 + h3 - df["d_m"] * np.sin(phi)
    df["Fx_N"], df["Fy_N"] = est["Fx"], est["Fy"]
    df["delta_x_m"] = df["R_m"] - np.hypot(cx - ox, cy - oy)
    force = np.hypot(est["Fx"], est["Fy"])
    df["k_N_per_m"] = np.where(df["delta_x_m"] > 0, force / df["delta_x_m"], np.nan)
    df["log_k"] = np.log(df["k_N_per_m"])
    g = df.groupby("object", sort=False)
    objects = pd.DataFrame(
        {
            "n": g.size(),
            "n_used": g["k_N_per_m"].count(),
            "k_mean_N_per_m": g["k_N_per_m"].mean(),
            "k_sd_N_per_m": g["k_N_per_m"].std(),
            "k_median_N_per_m": g["k_N_per_m"].median(),
            "log_k_mean": g["log_k"].mean(),
            "log_k_sd": g["log_k"].std(),
        }
    )
    objects["category"] = ""
    for name, (lo, hi) in json.loads(bands).items():
        inside = (objects["k_median_N_per_m"] >= lo) & (objects["k_median_N_per_m"] < (np.inf if hi is None else hi))
        objects.loc[inside, "category"] = name
    sys.stdout.write('{"objects": ' + objects.reset_index().to_json(orient="records"))
    sys.stdout.write(', "pushes": ' + df.to_json(orient="records", lines=False) + "}\n")


if __name__ == "__main__":
    main()
