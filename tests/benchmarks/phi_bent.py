"""Accuracy, not time: pushes with the direction phi blank on the arm resting bent (issue target:
at least 80 % of pushes used, the six objects 6/6 in their category).

Per rig seed: the bent protocol's 90 fit trials fit the posture-aware form; the six simulated
objects are pushed ten times each on the same bent rig (supply 0.15/0.15/0.45/0.15 MPa) with phi
left blank; each push's rest posture comes from its baseline potentiometers.  Trials and pushes are
taken as ``labcli acquire`` takes them (tests/benchmarks/acquired.py: each window after the
protocol's earliest equilibrium, 15 s, the chambers supplied again past the drift limit).  classify solves
phi from the force direction (Eqs. 39-41 as docs/errata.md reads them) and categorises by the
stiffness protocol's bands.  The force model's standard-error limits are lifted here, because
the stiffness estimate has its own flags.

``--rig second`` runs the same study on tests/support/second_rig.py, a forward model written from the
paper's Eqs. 2-7 without the simulated rig's code (ideal braided muscles closed at rest, exact
geometry a few per cent off the protocol's, potentiometer scale errors, 0.5 kPa pressure noise).

``--second KEY=VALUE`` (repeatable) changes a field of the second rig (``p_noise_kPa=0``, ``h2=0.130``,
``pot_scale=1,1``), and ``--realism literature`` runs the simulated rig at the literature's levels
(``kind``, the default, is passed to the rig explicitly, so the figures do not follow the rig's own
default); ``--effect NAME=SCALE`` (repeatable) scales one of its effects (``repeat=0``,
``friction=0.25``): which of the differences makes the direction wrong.  ``--friction-terms`` fits the posture
form with the sleeves' friction terms (``labcli fit --friction-terms``; classify then reads each
push's motion into its baseline from the push before it).  ``--settle S`` and
``--repressurise KPA`` change the trials' and pushes' timing (``--settle 8 --repressurise 0``: the
timing these figures were once measured with).  Each seed also prints how far the estimated force's
direction is from the true one (median over the pushes) and, on the simulated rig, its mean signed
error (a bias the pushes share; the true direction is the radial one, from the pushed object's true
centre to the contact point its potentiometers give), on the second rig the Fy error, beside the
Cramer-Rao floor of Fy's standard error from one push's readings (``second_rig.force_floor``).

    python tests/benchmarks/phi_bent.py [--seeds 1-3] [--angles pressure-only|measured-angles]
                                        [--rig project|second] [--second KEY=VALUE ...]
                                        [--realism kind|literature] [--effect NAME=SCALE ...]
                                        [--settle S] [--repressurise KPA] [--friction-terms]
                                        [--figures FILE.json]
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
from acquired import Windows, acquired_air, add_air_options
from rig_options import add_rig_options, bench_parser, seeds_text
from sensing_accuracy import BENT_SUPPLY_MPA, trials

# The stiffness settings, as --max-phi-se sets them (None: the protocol's defaults).
PARAMS: dict | None = None
SECOND: dict = {}  # the second rig's fields changed by --second
DIRECTION: list[tuple[float, float]] = []  # per seed of the second rig: median direction error (deg), Fy RMSE (N)
# Per seed of the simulated rig: the force direction's median absolute and mean signed error (deg).
BIAS: list[tuple[float, float]] = []
AIR: dict = {}  # the trials' and pushes' timing, as --settle and --repressurise set it (empty: as acquired)
FORM: dict = {}  # the posture form's options: {"friction": True} with --friction-terms
CONFIDENT_WRONG: list[int] = []  # per seed: objects in a wrong category with confidence >= 0.9


def run(seed: int, angles: str, rig_kw: dict | None = None) -> tuple[int, int, int]:
    """Pushes used, pushes, objects in their category on seed ``seed``'s bent rig (``rig_kw``: more
    keyword arguments of the rig, as a sweep sets them)."""
    from labcli.core.protocol import load_protocol
    from labcli.papers.takuma2014.models.classify import classify_pushes
    from labcli.papers.takuma2014.models.posture import PostureModel
    from labcli.papers.takuma2014.sim.drive import simulate_pushes
    from labcli.papers.takuma2014.sim.rig import SimRig

    proto, table = trials("takuma2014-bent", seed, rig_kw=rig_kw, **AIR)
    model = PostureModel(
        geometry=proto.settings.rig,
        protocol="takuma2014-stiffness",
        limits={q: np.inf for q in ("theta1", "theta2", "Fx", "Fy")},
        **FORM,
    ).fit(table)
    sp = load_protocol("takuma2014-stiffness")
    # The push run on the rig opened anew, taken as the trials are (as acquired: acquired.py).
    rig = Windows(SimRig(seed=seed, **{"supply_MPa": BENT_SUPPLY_MPA, **(rig_kw or {})}))
    pushes = simulate_pushes(rig, calibration=sp.calibration, phi_known=False, **acquired_air(sp, **AIR))
    rig.rest_columns(pushes, sp.calibration)
    truth = dict(
        zip(pushes["object"], [sp.settings.push.category_of(k) for k in pushes["true_stiffness_N_per_m"]], strict=False)
    )
    bands = {k: list(v) for k, v in sp.settings.push.stiffness_bands_N_per_m.items()}
    res = classify_pushes(pushes, model, bands=bands, method="bands", angles=angles, allow_unusable=True, params=PARAMS)
    ps, objs = (res.pushes, res.objects) if "push" in res.pushes.columns else (res.objects, res.pushes)
    used = int(objs["n_used"].sum())
    right = int(sum(truth[o] == c for o, c in zip(objs["object"], objs["category"], strict=False)))
    CONFIDENT_WRONG.append(confident_wrong(objs, truth))
    off = direction_error(pushes, ps, proto.settings.rig)
    BIAS.append((float(np.nanmedian(np.abs(off))), float(np.nanmean(off))))
    return used, len(ps), right


def confident_wrong(objs, truth: dict) -> int:
    """Objects given a category that is not theirs with a confidence of 0.9 or more."""
    cats, conf = objs["category"].fillna("").astype(str), objs["confidence"].to_numpy(float)
    return int(sum(bool(c) and c != truth[o] and p >= 0.9 for o, c, p in zip(objs["object"], cats, conf, strict=True)))


def direction_error(pushes, ps, rig: dict) -> np.ndarray:
    """Each push's estimated force direction less the true radial one (deg): from the object's true
    centre (its true phi, Eq. 39 from the rest posture's contact point) to the contact point its
    potentiometers give."""
    from labcli.papers.takuma2014.models.geometry import contact_point
    from labcli.papers.takuma2014.models.stiffness import object_centre

    h2, h3 = float(rig["h2_m"]), float(rig["h3_m"])
    rest = np.radians(pushes[["theta1_0_deg", "theta2_0_deg"]].to_numpy(float))
    moved = rest + np.radians(pushes[["theta1_deg", "theta2_deg"]].to_numpy(float))
    C0 = contact_point(rest[:, 0], rest[:, 1], h2, h3)
    C = contact_point(moved[:, 0], moved[:, 1], h2, h3)
    phi = np.radians(pushes["true_phi_deg"].to_numpy(float))
    radial = C - object_centre(pushes["R_m"].to_numpy(float), pushes["d_m"].to_numpy(float), phi, h2, h3, C0)
    est = np.arctan2(ps["Fy_N"].to_numpy(float), ps["Fx_N"].to_numpy(float))
    return np.degrees(np.angle(np.exp(1j * (est - np.arctan2(radial[:, 1], radial[:, 0])))))


def run_second(seed: int, angles: str) -> tuple[int, int, int]:
    """As :func:`run`, on the second forward model's bent arm (the bent plan, the six objects)."""
    import sys

    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
    from support.second_rig import harsher, push_table, weight_trials

    from labcli.core.protocol import load_protocol
    from labcli.papers.takuma2014.models.classify import classify_pushes
    from labcli.papers.takuma2014.models.posture import PostureModel
    from labcli.papers.takuma2014.protocol import load_plan

    rig = harsher(None, **SECOND)
    proto = load_protocol("takuma2014-bent")
    table = weight_trials(load_plan(proto), seed, rig)
    model = PostureModel(
        geometry=proto.settings.rig,
        protocol="takuma2014-stiffness",
        limits={q: np.inf for q in ("theta1", "theta2", "Fx", "Fy")},
        **FORM,
    ).fit(table)
    pushes = push_table(seed + 1000, rig)
    truth = dict(zip(pushes["object"], pushes["true_category"], strict=False))
    bands = {k: list(v) for k, v in load_protocol("takuma2014-stiffness").settings.push.stiffness_bands_N_per_m.items()}
    res = classify_pushes(pushes, model, bands=bands, method="bands", angles=angles, allow_unusable=True, params=PARAMS)
    ps, objs = (res.pushes, res.objects) if "push" in res.pushes.columns else (res.objects, res.pushes)
    right = int(sum(truth[o] == c for o, c in zip(objs["object"], objs["category"], strict=False)))
    est = np.arctan2(ps["Fy_N"].to_numpy(float), ps["Fx_N"].to_numpy(float))
    true = np.arctan2(pushes["true_Fy_N"].to_numpy(float), pushes["true_Fx_N"].to_numpy(float))
    off = np.degrees(np.abs(np.angle(np.exp(1j * (est - true)))))
    fy = ps["Fy_N"].to_numpy(float) - pushes["true_Fy_N"].to_numpy(float)
    DIRECTION.append((float(np.nanmedian(off)), float(np.sqrt(np.nanmean(fy**2)))))
    return int(objs["n_used"].sum()), len(ps), right


def main() -> None:
    ap = bench_parser(__doc__)
    add_rig_options(ap, realism="kind", seeds="1-3")
    ap.add_argument("--angles", default="pressure-only", choices=["pressure-only", "measured-angles"])
    ap.add_argument("--rig", default="project", choices=["project", "second"])
    ap.add_argument("--max-phi-se", type=float, help="max_phi_se_deg of the stiffness settings (deg)")
    ap.add_argument("--second", action="append", default=[], metavar="KEY=VALUE", help="a second rig's field")
    ap.add_argument("--effect", action="append", default=[], metavar="NAME=SCALE", help="one effect's scale")
    ap.add_argument("--friction-terms", action="store_true", help="the posture form with the sleeves' friction terms")
    add_air_options(ap)
    ap.add_argument("--figures", help="also write the figures to this JSON file ({name: value})")
    args = ap.parse_args()
    global PARAMS
    if args.max_phi_se is not None:
        PARAMS = {"max_phi_se_deg": args.max_phi_se}
    for item in args.second:
        key, _, value = item.partition("=")
        numbers = tuple(float(v) for v in value.split(","))
        SECOND[key] = numbers if len(numbers) > 1 else numbers[0]
    from labcli.papers.takuma2014.sim.nonideal import NonIdeal

    effects = {name: float(value) for name, _, value in (e.partition("=") for e in args.effect)}
    rig_kw = {"nonideal": NonIdeal(realism=args.realism, **effects)}
    FORM.update({"friction": True} if args.friction_terms else {})
    AIR.update({k: v for k, v in (("settle_s", args.settle), ("repressurise_kPa", args.repressurise)) if v is not None})
    rows = []
    for seed in args.seeds:
        used, n, right = run_second(seed, args.angles) if args.rig == "second" else run(seed, args.angles, rig_kw)
        rows.append((used, n, right))
        aside = ""
        if args.rig == "second":
            aside = (
                f"; force direction off by {DIRECTION[-1][0]:.1f} deg (median), Fy error {DIRECTION[-1][1]:.2f} N rms"
            )
        else:
            aside = (
                f"; force direction off by {BIAS[-1][0]:.1f} deg (median), {BIAS[-1][1]:+.1f} deg on average; "
                f"{CONFIDENT_WRONG[-1]} wrong at confidence >= 0.9"
            )
        print(
            f"seed {seed}: {used}/{n} pushes used ({100 * used / n:.0f} %), {right}/6 objects in category "
            f"(target >= 80 %, 6/6){aside}"
        )
    if args.rig == "second":
        import sys

        sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
        from support.second_rig import force_floor, harsher

        floor = force_floor(harsher(None, **SECOND))
        print(
            f"Cramer-Rao floor of one push's force from its pressures: Fx {floor[0]:.2f} N, Fy {floor[1]:.2f} N "
            f"(median force direction error {np.median([d for d, _ in DIRECTION]):.1f} deg over the seeds)"
        )
    if args.figures:
        figures = {
            "seeds": seeds_text(args.seeds),
            "angles": args.angles,
            "rig": args.rig,
            "pushes per seed": rows[0][1],
            "pushes used min": min(u for u, _, _ in rows),
            "pushes used max": max(u for u, _, _ in rows),
            "pushes used pct min": min(100 * u / n for u, n, _ in rows),
            "pushes used pct max": max(100 * u / n for u, n, _ in rows),
            "objects right min": min(r for _, _, r in rows),
            "seeds with every object right": sum(r == 6 for _, _, r in rows),
        }
        if args.rig == "second":
            figures["direction error median deg"] = float(np.median([d for d, _ in DIRECTION]))
            figures["Fy error rms N"] = float(np.sqrt(np.mean([f**2 for _, f in DIRECTION])))
            figures["Fy floor N"], figures["Fx floor N"] = float(floor[1]), float(floor[0])
            figures["second"] = " ".join(args.second)
        else:
            figures["direction error median deg"] = float(np.median([d for d, _ in BIAS]))
            figures["direction bias deg"] = float(np.mean([b for _, b in BIAS]))
            figures["wrong at confidence 0.9"] = int(sum(CONFIDENT_WRONG))
            figures["friction terms"] = bool(args.friction_terms)
            figures["realism"] = args.realism
            figures["effects"] = " ".join(args.effect)
            figures["timing"] = " ".join(f"{k}={v:g}" for k, v in AIR.items())
        Path(args.figures).write_text(json.dumps(figures, indent=1) + "\n")


if __name__ == "__main__":
    main()
