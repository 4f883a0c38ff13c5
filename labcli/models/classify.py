"""Classify pushed objects: push table + fitted force model -> stiffness and category.

:func:`classify_pushes` is the whole of the ``classify`` command's work in one
call: it asks the force model for (theta1, theta2, Fx, Fy) from each push's
pressures (``predict(P0, P, mode="pressure-only")``), estimates each push's
object stiffness (:mod:`labcli.models.stiffness`), summarises each object over
its unflagged pushes, and assigns categories (:mod:`labcli.models.categories`)
either from labelled reference objects or from stiffness bands.

Reference objects are categorised leave-one-object-out (class statistics
refitted without the object), so their rows show how well the method would
have done on them; an object that is the only reference of its class is
categorised in-sample and says so.
"""

from __future__ import annotations

import math
from collections import Counter
from dataclasses import dataclass
from typing import Any, Mapping

import numpy as np

from ..errors import ConfigError, ModelError
from .categories import CategoryModel
from .stiffness import PushEstimates, StiffnessParams, estimate_pushes, object_stats

P0_COLUMNS = ("P_L10", "P_R10", "P_L20", "P_R20")
THETA0_COLUMNS = ("theta10_deg", "theta20_deg")  # optional: absolute baseline posture
THETA_COLUMNS = ("theta1_deg", "theta2_deg")  # optional: measured deflections
P_COLUMNS = ("P_L1", "P_R1", "P_L2", "P_R2")
REQUIRED = ("push", "object", "R_m", "d_m") + P0_COLUMNS + P_COLUMNS
TRUE_K = "true_stiffness_N_per_m"


@dataclass
class ClassifyResult:
    """``pushes``: the push table's id columns plus the per-push estimates;
    ``objects``: one row per object (stiffness statistics, category,
    confidence, method); ``model``: the fitted or given :class:`CategoryModel`;
    ``params``: the flag thresholds used."""

    pushes: Any
    objects: Any
    model: CategoryModel
    params: StiffnessParams

    @property
    def method(self) -> str:
        return self.model.method

    def to_dict(self) -> dict[str, Any]:
        """Plain data for recording next to the run (categories and thresholds)."""
        return {"categories": self.model.to_dict(), "stiffness": self.params.to_dict()}


def _column(df: Any, name: str) -> np.ndarray:
    values = np.asarray(df[name], dtype=float)
    bad = np.flatnonzero(~np.isfinite(values))
    if bad.size:
        raise ConfigError(f"Push {df['push'].iloc[bad[0]]}: column {name!r} is empty or not a number; check the push table.")
    return values


def _labels(df: Any) -> np.ndarray:
    if "category" not in df.columns:
        return np.full(len(df), "", dtype=object)
    return np.array(
        ["" if v is None or (isinstance(v, float) and math.isnan(v)) else str(v).strip() for v in df["category"]],
        dtype=object,
    )


def _prediction(pred: Mapping[str, Any], name: str) -> Any:
    # TakumaModel.predict names its outputs with units (theta1_rad, Fx_N).
    for key in (name, f"{name}_rad", f"{name}_N"):
        if key in pred:
            return pred[key]
    raise ModelError(f"The force model's prediction has no {name!r}; it must give theta1, theta2 (rad) and Fx, Fy (N).")


def _length(model: Any, key: str, value: float | None) -> float:
    if value is None:
        geometry = getattr(model, "geometry", None) or {}
        value = geometry.get(key, geometry.get(f"{key}_m"))
    try:
        length = float(value)
    except (TypeError, ValueError):
        length = math.nan
    if not (math.isfinite(length) and length > 0):
        raise ConfigError(f"The rig length {key} must be a positive number of metres (got {value!r}); check the protocol's [rig] table.")
    return length


def classify_pushes(
    table: Any,
    model: Any,
    *,
    h2: float | None = None,
    h3: float | None = None,
    params: StiffnessParams | Mapping[str, Any] | None = None,
    bands: Mapping[str, Any] | None = None,
    method: str = "auto",
    angles: str = "pressure-only",
    allow_unusable: bool = False,
) -> ClassifyResult:
    """Stiffness per push, statistics and category per object, from a push table.

    ``table``: push table DataFrame (``push, object, R_m, d_m, phi_deg`` (NaN =
    unknown), ``P_L10..P_R20``, ``P_L1..P_R2`` in MPa, optional ``category``);
    ``model``: anything with ``predict(P0, P, mode="pressure-only")`` returning
    ``theta1_rad, theta2_rad, Fx_N, Fy_N`` (or the same without units) and
    optionally ``flags`` (per push: list of strings, string or bool);
    ``h2, h3``: rig geometry in m (default: the model's ``geometry``); ``method``: ``"reference"``, ``"bands"`` or
    ``"auto"`` (reference objects if any push has a category, else bands);
    ``angles``: ``"pressure-only"`` (the paper: everything from pressures) or
    ``"measured-angles"`` (deflections from the table's ``theta1_deg,
    theta2_deg``, for the contact point and the force).  Optional columns
    ``theta10_deg, theta20_deg`` give the absolute baseline posture.
    Raises :class:`ModelError` if an object has no usable push, unless
    ``allow_unusable`` (its row then has no category and says why).
    """
    import pandas as pd

    if not isinstance(params, StiffnessParams):
        params = StiffnessParams.from_dict(params)
    h2, h3 = (_length(model, key, value) for key, value in (("h2", h2), ("h3", h3)))
    missing = [c for c in REQUIRED if c not in table.columns]
    if missing:
        raise ConfigError(f"The push table lacks column {missing[0]!r}; a push table needs {', '.join(REQUIRED)}.")
    if len(table) == 0:
        raise ModelError("The push table has no pushes to classify.")
    if method not in ("auto", "reference", "bands"):
        raise ConfigError(f"Unknown category method {method!r}; use 'auto', 'reference' or 'bands'.")

    table = table.reset_index(drop=True)
    P0 = np.column_stack([_column(table, c) for c in P0_COLUMNS])
    P = np.column_stack([_column(table, c) for c in P_COLUMNS])
    phi = np.radians(np.asarray(table["phi_deg"], dtype=float)) if "phi_deg" in table.columns else None
    theta0 = None
    if all(c in table.columns for c in THETA0_COLUMNS):
        theta0 = np.radians(np.column_stack([_column(table, c) for c in THETA0_COLUMNS]))
    if angles == "pressure-only":
        pred = model.predict(P0, P, mode="pressure-only")
        theta = np.column_stack([_prediction(pred, "theta1"), _prediction(pred, "theta2")])
    elif angles == "measured-angles":
        missing = [c for c in THETA_COLUMNS if c not in table.columns]
        if missing:
            raise ConfigError(f"The push table lacks column {missing[0]!r}, which measured angles need.")
        theta = np.radians(np.column_stack([_column(table, c) for c in THETA_COLUMNS]))
        pred = model.predict(P0, P, mode="measured-angles", theta=theta)
    else:
        raise ConfigError(f"Unknown angle source {angles!r}; use 'pressure-only' or 'measured-angles'.")
    est: PushEstimates = estimate_pushes(
        theta[:, 0], theta[:, 1], _prediction(pred, "Fx"), _prediction(pred, "Fy"),
        _column(table, "R_m"), _column(table, "d_m"), phi,
        h2=h2, h3=h3, theta0=theta0, params=params,
        model_flags=pred.get("flags"), model_reasons=pred.get("reasons"),
        push_ids=list(table["push"]),
    )

    labels = _labels(table)
    objects = [str(o) for o in pd.unique(table["object"].astype(str))]
    obj_col = table["object"].astype(str).to_numpy()
    known: dict[str, str] = {}
    for name in objects:
        cats = sorted(set(labels[obj_col == name]))
        named = [c for c in cats if c]
        if len(named) > 1 or (named and "" in cats):
            raise ConfigError(
                f"Object {name!r} has pushes with different categories ({', '.join(repr(c) for c in cats)}); "
                "give every push of a reference object the same category."
            )
        known[name] = named[0] if named else ""

    use = ~est.flag & np.isfinite(est.k)
    if method == "auto":
        method = "reference" if any(known.values()) else "bands"
    if method == "bands":
        if not bands:
            raise ModelError(
                "No reference objects and no stiffness bands: label some objects' pushes with a category "
                "or give [stiffness_bands_N_per_m] in the protocol."
            )
        cat_model = CategoryModel.from_bands(bands)
    else:
        # Flagged reference pushes go in as NaN so that a category whose pushes
        # are all flagged is named as such rather than reported missing.
        ref = labels != ""
        cat_model = CategoryModel("reference").fit(np.where(use, est.k, np.nan)[ref], list(labels[ref]))

    rows = []
    for name in objects:
        sel = obj_col == name
        stats = object_stats(est.k[sel], est.flag[sel] | ~np.isfinite(est.k[sel]))
        row: dict[str, Any] = {"object": name, "known_category": known[name], **stats}
        if TRUE_K in table.columns:
            row["true_k_N_per_m"] = float(np.nanmean(np.asarray(table[TRUE_K], dtype=float)[sel]))
        samples = est.k[sel & use]
        if samples.size == 0:
            counts = Counter(r for r in est.reason[sel] if r)
            top = counts.most_common(1)[0][0] if counts else "no finite stiffness"
            if not allow_unusable:
                raise ModelError(
                    f"Object {name!r} has no usable push: all {int(sel.sum())} are flagged (most often: {top})."
                )
            row.update(category="", confidence=0.0, z=math.nan, method=cat_model.method, note=f"no usable push ({top})")
            rows.append(row)
            continue
        scorer, note = cat_model, ""
        if cat_model.method == "reference" and known[name]:
            others = use & (labels != "") & ~sel
            note = "in-sample (only reference of its category)"
            if known[name] in set(labels[others]):
                try:
                    scorer = CategoryModel("reference", min_std_log_k=cat_model.min_std_log_k).fit(
                        est.k[others], list(labels[others])
                    )
                    note = ""
                except ModelError:
                    pass  # too few references left without this object: keep the in-sample answer
        p = scorer.predict([samples], names=[name])
        row.update(
            category=p.category[0],
            confidence=float(p.confidence[0]),
            z=float(p.z[0]),
            method=p.method,
            note="; ".join(t for t in (note, p.note[0]) if t),
        )
        rows.append(row)

    push_cols = [c for c in ("push", "object", "category", TRUE_K) if c in table.columns]
    pushes = pd.concat([table[push_cols], est.to_frame()], axis=1)
    return ClassifyResult(pushes=pushes, objects=pd.DataFrame(rows), model=cat_model, params=params)
