"""Accuracy, not time: what a lab's actuator spread does to the rPAM joint's angle alpha.

For each reading of the actuator force, at the K_min where its optimum is quoted (derived 0.07,
paper 0.2 N m/rad), the optimum's links are fixed (``labcli optimize --seed 1``) and the joint
built with them is balanced at the optimiser's pressures (96 / 41 kPa) with actuators that
differ from the protocol's:

* one at a time, each parameter moved by +-1 standard deviation of a lab's spread on both
  actuators: each Ogden modulus 10 % (silicone batch and cure), the free length L0 0.5 mm, the
  rest radius 0.1 mm (moulding), each link 0.2 mm (machining and the swivel pins' play);
* the spread as a lab builds it: per seed (held-out seeds 11-30) two actuators drawn
  independently with all those deviations at once, and links drawn once; alpha's mean, standard
  deviation, range, and how many such joints run onto the toggle or come within 1 deg of it;
* re-optimised: the optimum itself when all three moduli are 10 % stiffer or softer (what a
  fitted actuator, ``labcli optimize --actuator``, would move it by).

The baseline is the nominal joint's alpha in the same run.  A joint with no balance below
the toggle counts as "toggles" and stays out of alpha's statistics.

    nice python tests/benchmarks/rpam_sensitivity.py [--seeds 11-30] [--figures FILE.json]
"""

from __future__ import annotations

import json
import math
import re
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

KMIN = {"derived": 0.07, "paper": 0.2}
PA, PB = 0.096, 0.041
# One standard deviation of a lab's spread (relative for the moduli, metres for the dimensions).
SPREAD = {"mu_rel": 0.10, "L0_m": 0.5e-3, "radius_m": 0.1e-3, "link_m": 0.2e-3}
MARGIN_DEG = 1.0


def balance_deg(geom: Any, act_a: Any, act_b: Any) -> tuple[float, float]:
    """(alpha, toggle) in degrees of the joint released at 0 with actuators a and b; alpha NaN when
    it runs onto the toggle."""
    from scipy.optimize import brentq

    from labcli.papers.rpam2015.models import rpam

    toggle = float(rpam.toggle_angle(geom))

    def tau(alpha: Any) -> Any:
        La, Lb = rpam.actuator_lengths(alpha, geom)
        ma, mb = rpam.moment_arms(alpha, geom)
        return rpam.push_force(PA, La, act_a) * ma - rpam.push_force(PB, Lb, act_b) * mb

    grid = np.linspace(0.0, toggle - 1e-6, 600)
    t = np.asarray(tau(grid))
    k = np.flatnonzero((t[:-1] > 0) & (t[1:] <= 0))
    if t[0] <= 0 or k.size == 0:
        return math.nan, math.degrees(toggle)
    i = int(k[0])
    return math.degrees(brentq(lambda a: float(tau(a)), grid[i], grid[i + 1], xtol=1e-12)), math.degrees(toggle)


def perturbed(act: Any, d: dict[str, float]) -> Any:
    from labcli.papers.rpam2015.models.rpam_actuator_fit import resized

    mu = tuple(m * (1 + d.get(f"mu_{i + 1}", 0.0)) for i, m in enumerate(act.ogden_mu_MPa))
    out = replace(act, ogden_mu_MPa=mu)
    if d.get("L0_m") or d.get("radius_m"):
        out = resized(out, act.L0_m + d.get("L0_m", 0.0), act.rest_radius_m + d.get("radius_m", 0.0))
    return out


def links(geom: Any, d: dict[str, float]) -> Any:
    from labcli.papers.rpam2015.models import rpam

    return rpam.JointGeometry(
        geom.L1_m + d.get("L1_m", 0.0), geom.L2_m + d.get("L2_m", 0.0), geom.L3_m + d.get("L3_m", 0.0)
    )


def study(reading: str, seeds: list[int]) -> dict[str, Any]:
    from labcli.errors import ModelError
    from labcli.papers.rpam2015.models import rpam
    from labcli.papers.rpam2015.models.rpam_optimize import optimize_protocol
    from labcli.papers.rpam2015.protocol import actuator_of

    act = actuator_of("rpam2015").with_force_reading(reading)
    best = optimize_protocol("rpam2015", seed=1, force=reading, min_stiffness=KMIN[reading])
    geom = rpam.JointGeometry(best.geometry.L1_m, best.geometry.L2_m, best.geometry.L3_m)
    nominal, toggle = balance_deg(geom, act, act)
    fig: dict[str, Any] = {"optimum alpha_deg": best.alpha_deg, "nominal alpha_deg": nominal, "toggle_deg": toggle}
    steps = {
        **{f"mu_{i}": SPREAD["mu_rel"] for i in (1, 2, 3)},
        "L0_m": SPREAD["L0_m"],
        "radius_m": SPREAD["radius_m"],
        **{f"{k}_link": SPREAD["link_m"] for k in ("L1", "L2", "L3")},
    }
    for name, step in steps.items():
        up_down = []
        for sign in (1, -1):
            if name.endswith("_link"):
                g = links(geom, {name.replace("_link", "_m"): sign * step})
                a, _ = balance_deg(g, act, act)
            else:
                p = perturbed(act, {name: sign * step})
                a, _ = balance_deg(geom, p, p)
            up_down.append(a)
        fig[f"oat.{name}.+1sd alpha_deg"] = up_down[0] - nominal
        fig[f"oat.{name}.-1sd alpha_deg"] = up_down[1] - nominal
    alphas, toggles, close = [], 0, 0
    for seed in seeds:
        rng = np.random.default_rng([seed, 26])

        def draw() -> Any:
            d = {f"mu_{i}": SPREAD["mu_rel"] * float(rng.standard_normal()) for i in (1, 2, 3)}
            d["L0_m"] = SPREAD["L0_m"] * float(rng.standard_normal())
            d["radius_m"] = SPREAD["radius_m"] * float(rng.standard_normal())
            return perturbed(act, d)

        a_act, b_act = draw(), draw()
        g = links(geom, {f"L{i}_m": SPREAD["link_m"] * float(rng.standard_normal()) for i in (1, 2, 3)})
        a, t = balance_deg(g, a_act, b_act)
        if math.isnan(a):
            toggles += 1
            continue
        alphas.append(a)
        close += t - a < MARGIN_DEG
    arr = np.asarray(alphas)
    fig.update(
        {
            "spread.n": len(seeds),
            "spread.toggles": toggles,
            "spread.within 1 deg of the toggle": close,
            "spread.mean alpha_deg": float(arr.mean()) if arr.size else math.nan,
            "spread.sd alpha_deg": float(arr.std(ddof=1)) if arr.size > 1 else math.nan,
            "spread.min alpha_deg": float(arr.min()) if arr.size else math.nan,
            "spread.max alpha_deg": float(arr.max()) if arr.size else math.nan,
        }
    )
    for label, factor in (("stiffer", 1 + SPREAD["mu_rel"]), ("softer", 1 - SPREAD["mu_rel"])):
        mu = ",".join(f"{m * factor:.6g}" for m in act.ogden_mu_MPa)
        try:
            r = optimize_protocol(
                "rpam2015", seed=1, force=reading, min_stiffness=KMIN[reading], overrides=(f"ogden.mu_MPa=[{mu}]",)
            )
        except ModelError as e:
            # An optimum on a fold (too sensitive to build on a 0.1 mm grid) still names its angle.
            m = re.search(r"alpha = ([\d.]+) deg\) is too sensitive", str(e))
            if not m:
                raise
            fig[f"reoptimised.{label}.alpha_deg"] = float(m.group(1))
            fig[f"reoptimised.{label}.buildable"] = False
            continue
        fig[f"reoptimised.{label}.alpha_deg"] = r.alpha_deg
        fig[f"reoptimised.{label}.buildable"] = True
        for k in ("L1_m", "L2_m", "L3_m"):
            fig[f"reoptimised.{label}.{k}"] = getattr(r.geometry, k)
    return fig


def _json_value(v: Any) -> Any:
    if isinstance(v, float):
        return round(v, 6) if math.isfinite(v) else None
    return v


def main() -> None:
    from rig_options import add_seeds_option, bench_parser

    ap = bench_parser(__doc__)
    add_seeds_option(ap, "11-30", what="seeds of the lab actuators drawn (held out: 11-30)")
    ap.add_argument("--figures", help="also write the figures to this JSON file ({name: value})")
    args = ap.parse_args()
    seeds = args.seeds
    figures: dict[str, Any] = {}
    for reading in KMIN:
        fig = study(reading, seeds)
        print(f"{reading} reading, K_min {KMIN[reading]} N m/rad: optimum {fig['optimum alpha_deg']:.2f} deg")
        for k, v in fig.items():
            print(f"  {k:45s} {v:.4g}" if isinstance(v, float) else f"  {k:45s} {v}")
        # NaN (a joint that runs onto its toggle) is written as null.
        figures.update({f"{reading}.{k}": _json_value(v) for k, v in fig.items()})
    if args.figures:
        Path(args.figures).write_text(json.dumps(figures, indent=1, allow_nan=False) + "\n")


if __name__ == "__main__":
    main()
