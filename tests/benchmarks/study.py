"""One rig seed at one level of the rig's harshness: every headline sensing figure, raw.

The building block of ``sensitivity.py`` (the sweep) and ``baseline_estimator.py`` (the held-out
baseline), assembled from the accuracy benchmarks:

* ``sensing_accuracy.measure``: the straight (takuma2014) and bent (takuma2014-bent) protocols,
  108 trials each, both forms fitted on the 90 fit trials and checked on the 18 validation ones,
  taken as ``labcli acquire`` takes them (tests/benchmarks/acquired.py: every window after the
  protocol's earliest equilibrium, 15 s, the chambers supplied again past the drift limit);
* ``classify_accuracy.trials_and_pushes`` / ``classify_rows``: the six demo objects pushed ten
  times each on the straight arm with phi given, classified by the protocol's bands with the
  paper's form (the README demo's) and the posture form.  The trials and pushes are taken the same
  way (the demo's runs, tests/benchmarks/classify_heldout.py), the push run on the rig opened
  anew.  They differ from the acquired runs in waiting exactly 15 s where the settling rule waits
  until the readings are still (15-26 s) and in skipping the guard's checks; the steel can's k / k_true (posture form, kind rig, held-out
  seeds 11-30) is 0.89 here against the demo path's 0.88 (with drive.py's 6 s it was 1.77);
* ``phi_bent.run`` (optional): the same objects pushed on the bent arm with phi left blank, the
  trials and pushes taken the same way.

A level is a set of the rig's keyword arguments (:func:`rig_kw`): the literature's rig
(sim/nonideal.py, ``realism="literature"``) with some scales changed, or the kind rig.
Everything returned is plain data (lists, floats), so that results cache as JSON lines.
"""

from __future__ import annotations

import math
import sys
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

QUANTITIES = ("theta1", "theta2", "Fx", "Fy")
PROTOCOLS = {"straight": "takuma2014", "bent": "takuma2014-bent"}
FORMS = ("posture", "paper")


def rig_kw(level: dict[str, Any]) -> dict[str, Any]:
    """SimRig keyword arguments of a level: ``{"realism": ..., "noise": X, SCALE: X, ...}``."""
    from labcli.papers.takuma2014.sim.nonideal import NonIdeal

    level = dict(level)
    realism = level.pop("realism", "literature")
    noise = float(level.pop("noise", 1.0))
    return {"noise": noise, "nonideal": NonIdeal(realism=realism, **{k: float(v) for k, v in level.items()})}


def _finite(x: Any) -> list[float]:
    return [float(v) for v in np.asarray(x, dtype=float).ravel()]


def sensing(seed: int, kw: dict[str, Any], friction_terms: bool = False) -> dict[str, Any]:
    """Validation errors of both forms on both protocols, and the posture form's interval hits;
    with ``friction_terms`` the posture form is fitted with the sleeves' friction terms, as
    ``labcli fit`` fits it by default."""
    from sensing_accuracy import measure

    out: dict[str, Any] = {}
    for short, protocol in PROTOCOLS.items():
        m = measure(protocol, seed, rig_kw=kw, friction_terms=friction_terms)
        for form in FORMS:
            fitted_as = "friction" if friction_terms and form == "posture" else form
            for q in QUANTITIES:
                d = m[fitted_as][q]
                out[f"{short}/{form}/{q}/err_ok"] = _finite(d["err_ok"])
                out[f"{short}/{form}/{q}/err_all"] = _finite(d["err_all"])
                if form == "posture":
                    out[f"{short}/{form}/{q}/inside"] = [bool(v) for v in np.asarray(d["inside"]).ravel()]
    return out


def objects(seed: int, kw: dict[str, Any], pushes: int, friction_terms: bool = False) -> dict[str, Any]:
    """k / k_true, category, right or not and confidence of each demo object, per form."""
    from classify_accuracy import classify_rows, trials_and_pushes

    from labcli.core.protocol import load_protocol
    from labcli.papers.takuma2014.models.posture import PostureModel, limits_from_protocol
    from labcli.papers.takuma2014.models.takuma import TakumaModel

    force = load_protocol("takuma2014")
    trials, table = trials_and_pushes(seed, pushes, rig_kw=kw)
    models = {
        "paper": TakumaModel(geometry=force.settings.rig, protocol=force.name),
        "posture": PostureModel(
            geometry=force.settings.rig, limits=limits_from_protocol(force), friction=friction_terms
        ),
    }
    out: dict[str, Any] = {}
    from labcli.errors import ModelError

    for form, model in models.items():
        try:
            rows = classify_rows(trials, table, model.fit(trials))
        except ModelError:
            continue  # this form cannot be fitted at this level: its objects stay unmeasured
        for row in rows:
            key = f"objects/{form}/{row['object']}"
            out[f"{key}/k_over_true"] = float(row["ratio"])
            out[f"{key}/category"] = row["category"] or ""
            out[f"{key}/correct"] = bool(row["correct"])
            out[f"{key}/confidence"] = float(row["confidence"])
    return out


def phi_blank(seed: int, kw: dict[str, Any]) -> dict[str, Any]:
    """Pushes with phi blank on the bent arm: pushes used, pushes, objects in their category."""
    from phi_bent import run

    used, n, right = run(seed, "pressure-only", rig_kw=kw)
    return {"phi_blank/used": int(used), "phi_blank/pushes": int(n), "phi_blank/right": int(right)}


def measure_level(
    level: dict[str, Any], seed: int, pushes: int = 10, with_phi_blank: bool = False, friction_terms: bool = False
) -> dict[str, Any]:
    """Everything above for one level and one seed (the posture form with the friction terms where
    ``friction_terms``: labcli fit's default)."""
    kw = rig_kw(level)
    out = {**sensing(seed, kw, friction_terms), **objects(seed, kw, pushes, friction_terms)}
    if with_phi_blank:
        out.update(phi_blank(seed, kw))
    return out


def rms(values: list[float]) -> float:
    x = np.asarray(values, dtype=float)
    return float(np.sqrt(np.mean(x**2))) if x.size else math.nan


def per_seed(raw: dict[str, Any]) -> dict[str, float]:
    """One seed's figures: RMSE (reported and all), trials reported, coverage; the objects' as they are."""
    out: dict[str, float] = {}
    for key, value in raw.items():
        if key.endswith("/err_ok"):
            base = key[: -len("/err_ok")]
            out[f"{base}/rmse"] = rms(value)
            out[f"{base}/reported"] = float(len(value))
        elif key.endswith("/err_all"):
            out[f"{key[: -len('/err_all')]}/rmse_all"] = rms(value)
        elif key.endswith("/inside"):
            out[f"{key[: -len('/inside')]}/coverage"] = float(np.mean(value)) if value else math.nan
        elif isinstance(value, (bool, int, float)):
            out[key] = float(value)
    return out
