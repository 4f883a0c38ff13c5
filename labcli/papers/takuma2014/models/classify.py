"""Classify pushed objects: push table + fitted force model -> stiffness and category.

:func:`classify_pushes` is the whole of the ``classify`` command's work in one
call: it asks the force model for (theta1, theta2, Fx, Fy) from each push's
pressures (``predict(P0, P, mode="pressure-only")``), estimates each push's
object stiffness (:mod:`labcli.papers.takuma2014.models.stiffness`), summarises each object over
its unflagged pushes, and assigns categories (:mod:`labcli.papers.takuma2014.models.categories`)
either from labelled reference objects or from stiffness bands.

Reference objects are categorised leave-one-object-out (class statistics
refitted without the object), so their rows show how well the method would
have done on them; an object that is the only reference of its class is
categorised in-sample and says so.

:func:`classify_file` is the same from files, as ``labcli classify`` and the
demo call it: a push run file or CSV, a model JSON (checked to be fitted on a
force run of the same rig), optionally a reference run whose labelled pushes
join as reference objects, bands from the protocol's
``[stiffness_bands_N_per_m]`` and flag settings from its ``[stiffness]`` table
when it has one (:func:`stiffness_settings`).  :func:`report_to_dict` gives
the JSON of the command, with mm, deg, N and N/m in the key names.
"""

from __future__ import annotations

import json
import math
from collections import Counter
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO, Any

import numpy as np

from ....core.files import RUN_FILE_SUFFIXES
from ....core.nogc import paused_gc
from ....core.protocol import load_protocol, loads_protocol, shipped_protocols
from ....core.provenance import rig_warning, run_identity, table_identity
from ....core.store import RunFile
from ....errors import ConfigError, ModelError
from ..options import PUSH_PROTOCOL
from ..records import load_pushes
from .categories import CategoryModel
from .posture import PostureModel, load_force_model
from .stiffness import PushEstimates, StiffnessParams, estimate_pushes, groups_by_size, object_stats_many
from .takuma import TakumaModel, cap

P0_COLUMNS = ("P_L10", "P_R10", "P_L20", "P_R20")
THETA0_COLUMNS = ("theta10_deg", "theta20_deg")  # optional: absolute baseline posture
# The same in the table format's spelling (docs/table-formats.md), read when the above is absent.
REST_COLUMNS = ("theta1_0_deg", "theta2_0_deg")
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
        raise ConfigError(
            f"Push {df['push'].iloc[bad[0]]}: column {name!r} is empty or not a number; check the push table."
        )
    return values


def _labels(df: Any) -> np.ndarray:
    if "category" not in df.columns:
        return np.full(len(df), "", dtype=object)
    import pandas as pd

    # Few distinct labels: clean each once (code -1 is an empty cell).
    codes, values = pd.factorize(df["category"])
    return np.array([str(v).strip() for v in values] + [""], dtype=object)[codes]


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
        length = float(value)  # type: ignore[arg-type]  # None: the TypeError below
    except (TypeError, ValueError):
        length = math.nan
    if not (math.isfinite(length) and length > 0):
        raise ConfigError(
            f"The rig length {key} must be a positive number of metres (got {value!r}); check the protocol's [rig] table."
        )
    return length


def _force_ok(pred: Mapping[str, Any]) -> np.ndarray | None:
    """Which force components the model trusts, (n, 2), when it says (None: it does not)."""
    ok = pred.get("ok")
    if isinstance(ok, Mapping) and "Fx" in ok and "Fy" in ok:
        return np.column_stack([np.asarray(ok["Fx"], dtype=bool), np.asarray(ok["Fy"], dtype=bool)])
    return None


def _force_se(pred: Mapping[str, Any]) -> np.ndarray | None:
    """The standard errors of Fx, Fy (n, 2) in N, when the prediction carries them."""
    se = pred.get("se")
    if not isinstance(se, Mapping) or "Fx" not in se or "Fy" not in se:
        return None
    return np.column_stack([np.asarray(se["Fx"], dtype=float), np.asarray(se["Fy"], dtype=float)])


def _estimate(
    table: Any,
    theta: np.ndarray,
    Fx: np.ndarray,
    Fy: np.ndarray,
    pred: Mapping[str, Any],
    force_ok: np.ndarray | None,
    **geometry: Any,
) -> PushEstimates:
    """Each push's deformation, force along its direction and stiffness (Eqs. 38-42)."""
    phi = np.radians(np.asarray(table["phi_deg"], dtype=float)) if "phi_deg" in table.columns else None
    return estimate_pushes(
        theta[:, 0],
        theta[:, 1],
        Fx,
        Fy,
        _column(table, "R_m"),
        _column(table, "d_m"),
        phi,
        model_flags=pred.get("flags"),
        model_reasons=pred.get("reasons"),
        force_ok=force_ok,
        push_ids=table["push"].tolist(),
        force_se=_force_se(pred),
        **geometry,
    )


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
    settle_s: float | None = None,
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
    ``allow_unusable`` (its row then has no category and says why).  ``settle_s``: the push
    protocol's earliest acceptance of equilibrium, the thermal tail's term in the paper form's
    error budget (models/budget.py).
    """
    import pandas as pd

    if not isinstance(params, StiffnessParams):
        params = StiffnessParams.from_dict(params)
    h2, h3 = (_length(model, key, value) for key, value in (("h2", h2), ("h3", h3)))
    _check_table(table, method)
    table = table.reset_index(drop=True)
    theta0 = _rest_posture(table)
    theta, pred = _posture_and_force(table, model, angles, theta0)
    Fx, Fy = (np.asarray(_prediction(pred, q), dtype=float) for q in ("Fx", "Fy"))
    force_ok = _force_ok(pred)
    pred = _with_budget(pred, model, settle_s)
    est = _estimate(table, theta, Fx, Fy, pred, force_ok, h2=h2, h3=h3, theta0=theta0, params=params)

    labels = _labels(table)
    # Each push's object as a number (in order of first appearance) and every object's rows in one
    # pass; a mask per object would cost objects x pushes.
    codes, uniques = pd.factorize(table["object"].astype(str).to_numpy())
    objects = [str(o) for o in uniques]
    members = pd.Series(np.arange(len(table))).groupby(codes, sort=False).indices
    known = _known_categories(objects, {name: members[g] for g, name in enumerate(objects)}, labels)
    use = ~est.flag & np.isfinite(est.k)
    if method == "auto":
        method = "reference" if any(known.values()) else "bands"
    cat_model = _category_model(method, bands, est.k, use, labels)
    true_k = np.asarray(table[TRUE_K], dtype=float) if TRUE_K in table.columns else None
    objs = _Objects(objects, codes, members, [known[name] for name in objects])
    rows = _object_rows(objs, est, use, labels, cat_model, true_k, allow_unusable)
    if cat_model.method == "bands":
        _band_confidence(rows, objs, est, use, cat_model, log_k_standard_errors(pred, est, force_ok))

    push_cols = [c for c in ("push", "object", "category", "source", TRUE_K) if c in table.columns]
    model_cols = pd.DataFrame(
        {
            "R_m": _column(table, "R_m"),
            "d_m": _column(table, "d_m"),
            "theta1_deg": np.degrees(theta[:, 0]),
            "theta2_deg": np.degrees(theta[:, 1]),
            "Fx_N": Fx,
            "Fy_N": Fy,
        }
    )
    pushes = pd.concat([table[push_cols], model_cols, est.to_frame()], axis=1)
    return ClassifyResult(pushes=pushes, objects=pd.DataFrame(rows), model=cat_model, params=params)


def _check_table(table: Any, method: str) -> None:
    missing = [c for c in REQUIRED if c not in table.columns]
    if missing:
        raise ConfigError(f"The push table lacks column {missing[0]!r}; a push table needs {', '.join(REQUIRED)}.")
    if len(table) == 0:
        raise ModelError("The push table has no pushes to classify.")
    if method not in ("auto", "reference", "bands"):
        raise ConfigError(f"Unknown category method {method!r}; use 'auto', 'reference' or 'bands'.")


def _rest_posture(table: Any) -> np.ndarray | None:
    """Each push's absolute baseline posture (rad), from either spelling of its columns, or None.

    The table format's rest columns are optional and may be empty (absent means 0, 0): None when
    every cell is empty, 0 in an empty cell otherwise.
    """
    if all(c in table.columns for c in THETA0_COLUMNS):
        return np.radians(np.column_stack([_column(table, c) for c in THETA0_COLUMNS]))
    if all(c in table.columns for c in REST_COLUMNS):
        import pandas as pd

        rest = np.column_stack([pd.to_numeric(table[c], errors="coerce").to_numpy(dtype=float) for c in REST_COLUMNS])
        if np.isnan(rest).all():
            return None
        return np.radians(np.where(np.isnan(rest), 0.0, rest))
    return None


def _posture_and_force(
    table: Any, model: Any, angles: str, theta0: np.ndarray | None = None
) -> tuple[np.ndarray, Mapping[str, Any]]:
    """The joint angles (rad, per push) and the model's prediction, from the pressures or the pots.

    The posture-aware form also takes the rest posture (its Jacobian is evaluated there) and, with
    friction terms, each push's motion into its baseline from the push before it (by push number):
    pushed from one side, the arm comes back into every baseline against the way the next push
    moves it, so the sleeves' friction turns round between baseline and push, push after push.
    """
    P0 = np.column_stack([_column(table, c) for c in P0_COLUMNS])
    P = np.column_stack([_column(table, c) for c in P_COLUMNS])
    theta = None
    if angles == "measured-angles":
        missing = [c for c in THETA_COLUMNS if c not in table.columns]
        if missing:
            raise ConfigError(f"The push table lacks column {missing[0]!r}, which measured angles need.")
        theta = np.radians(np.column_stack([_column(table, c) for c in THETA_COLUMNS]))
    elif angles != "pressure-only":
        raise ConfigError(f"Unknown angle source {angles!r}; use 'pressure-only' or 'measured-angles'.")
    rest: dict[str, Any] = {}
    if isinstance(model, PostureModel):
        th0 = np.zeros((len(P), 2)) if theta0 is None else theta0
        if theta0 is not None:
            rest["theta0"] = theta0
        moved = model.motion_in_of(_push_order(table), P0, P, th0, theta)
        if moved is not None:
            rest["motion_in"] = moved
    if theta is None:
        pred = model.predict(P0, P, mode="pressure-only", **rest)
        return np.column_stack([_prediction(pred, "theta1"), _prediction(pred, "theta2")]), pred
    return theta, model.predict(P0, P, mode="measured-angles", theta=theta, **rest)


def _push_order(table: Any) -> np.ndarray:
    """The pushes' order of acquisition: their numbers where every one is a number, else the rows'."""
    import pandas as pd

    if "push" not in table.columns:
        return np.arange(len(table), dtype=float)
    ids = pd.to_numeric(table["push"], errors="coerce").to_numpy(dtype=float)
    return ids if np.isfinite(ids).all() and len(np.unique(ids)) == len(ids) else np.arange(len(ids), dtype=float)


def _known_categories(objects: list[str], members: Mapping[str, np.ndarray], labels: np.ndarray) -> dict[str, str]:
    """Each object's category as its pushes give it ("" for an unknown object)."""
    known: dict[str, str] = {}
    for name in objects:
        cats = sorted(set(labels[members[name]]))
        named = [c for c in cats if c]
        if len(named) > 1 or (named and "" in cats):
            raise ConfigError(
                f"Object {name!r} has pushes with different categories ({', '.join(repr(c) for c in cats)}); "
                "give every push of a reference object the same category."
            )
        known[name] = named[0] if named else ""
    return known


def _category_model(
    method: str, bands: Mapping[str, Any] | None, k: np.ndarray, use: np.ndarray, labels: np.ndarray
) -> CategoryModel:
    if method == "bands":
        if not bands:
            raise ModelError(
                "No reference objects and no stiffness bands: label some objects' pushes with a category "
                "or give [stiffness_bands_N_per_m] in the protocol."
            )
        return CategoryModel.from_bands(bands)
    # Flagged reference pushes go in as NaN so that a category whose pushes
    # are all flagged is named as such rather than reported missing.
    ref = labels != ""
    return CategoryModel("reference").fit(np.where(use, k, np.nan)[ref], list(labels[ref]))


@dataclass(frozen=True)
class _Objects:
    """The pushed objects: names in order of first appearance, each push's object number, each
    object's push rows, and the category its pushes give ("" for an unknown object)."""

    names: list[str]
    codes: np.ndarray
    members: Mapping[int, np.ndarray]
    known: list[str]


def _object_rows(
    objs: _Objects,
    est: PushEstimates,
    use: np.ndarray,
    labels: np.ndarray,
    cat_model: CategoryModel,
    true_k: np.ndarray | None,
    allow_unusable: bool,
) -> list[dict[str, Any]]:
    """Every object's statistics over its unflagged pushes, its category and how sure that is.

    The statistics and the bands' verdicts come whole-array (:func:`object_stats_many`,
    :meth:`CategoryModel.predict_groups`: the numbers :func:`object_stats` and ``predict`` give
    one object at a time); a reference object is judged against the other references.
    """
    n = len(objs.names)
    stats = object_stats_many(est.k, est.flag | ~np.isfinite(est.k), objs.codes, n)
    n_use = np.bincount(objs.codes[use], minlength=n)
    scored = np.flatnonzero(stats["n_used"] > 0)
    verdicts = None
    if cat_model.method == "bands":
        number = np.full(n, -1)
        number[scored] = np.arange(len(scored))
        pick = use & (number[objs.codes] >= 0)
        verdicts = cat_model.predict_groups(est.k[pick], number[objs.codes[pick]], len(scored))
    mean_true = _group_nanmean(true_k, objs.codes, n) if true_k is not None else None
    rows = []
    for g, name in enumerate(objs.names):
        row: dict[str, Any] = {"object": name, "known_category": objs.known[g]}
        row.update({key: _plain(key, values[g]) for key, values in stats.items()})
        if mean_true is not None:
            row["true_k_N_per_m"] = float(mean_true[g])
        sel = objs.members[g]
        if n_use[g] == 0:
            row.update(_unusable(name, sel, est, cat_model, allow_unusable))
        elif stats["n_used"][g] == 0:
            cat_model.predict([est.k[sel[use[sel]]]], names=[name])  # raises: no finite positive stiffness
        elif verdicts is not None:
            row.update(_verdict(verdicts, int(np.searchsorted(scored, g))))
        else:
            row.update(_reference_verdict(name, sel, objs.known[g], est, use, labels, cat_model))
        rows.append(row)
    return rows


def _with_budget(pred: Mapping[str, Any], model: Any, settle_s: float | None) -> Mapping[str, Any]:
    """The prediction with standard errors: the model's own, or the paper form's error budget."""
    if isinstance(pred.get("se"), Mapping) or not isinstance(model, TakumaModel):
        return pred
    from .budget import paper_form_errors

    se = paper_form_errors(model, pred, settle_s)
    return pred if se is None else {**pred, "se": se}


def log_k_standard_errors(
    pred: Mapping[str, Any], est: PushEstimates, force_ok: np.ndarray | None
) -> np.ndarray | None:
    """Each push's standard error of ln k_o from the model's own standard errors (None when the
    model gives none, as the paper's Eqs. 34-37 do).

    k_o = |F| / delta_x, so (se ln k)^2 = (se |F| / |F|)^2 + (se delta_x / delta_x)^2, with
    se |F| = |(Fx se Fx, Fy se Fy)| / |F| (each component's error along the force).  The
    deformation's error is the angles' through d delta_x / d theta (``dx_theta_gain``); the
    angles' standard errors come from the calibration's held-out residuals, so they carry the
    labels' play, scale error and thermal tail as the fit saw them.  Where one force component is
    unobservable (a straight arm's Fy) the force was rebuilt from the other along the push, and
    its relative error is that component's.  A solved phi adds its own term to the deformation's:
    the force direction's standard error (``phi_se / |phi_gain|``) times ``dx_gain``, how far
    delta_x moves per radian the direction turns (at 40 deg of phi error a PET bottle's delta_x
    is barely known, whatever the angles' errors).
    """
    se = pred.get("se")
    if not isinstance(se, Mapping) or not all(q in se for q in ("theta1", "theta2", "Fx", "Fy")):
        return None
    t1, t2, fx, fy = (np.asarray(se[q], dtype=float) for q in ("theta1", "theta2", "Fx", "Fy"))
    F = est.F if est.F is not None else np.full((len(est), 2), np.nan)
    with np.errstate(divide="ignore", invalid="ignore"):
        # |F|'s error is each component's along F: (Fx se_x, Fy se_y) / |F|, not the errors' norm
        # (on an upright arm Fy's error is several newtons while Fy itself is a small share of |F|).
        rel_f = np.hypot(F[:, 0] * fx, F[:, 1] * fy) / est.force**2
        if force_ok is not None:
            rel_f = np.where(~force_ok[:, 1] & force_ok[:, 0], fx / np.abs(F[:, 0]), rel_f)
            rel_f = np.where(~force_ok[:, 0] & force_ok[:, 1], fy / np.abs(F[:, 1]), rel_f)
        rel_x = est.dx_theta_gain * np.hypot(t1, t2) / est.delta_x
        if getattr(est, "phi_se", None) is not None:
            turn = np.abs(est.dx_gain) * est.phi_se / np.abs(est.phi_gain)
            rel_x = np.hypot(rel_x, np.where(np.isfinite(turn), turn, 0.0) / est.delta_x)
    return np.hypot(rel_f, rel_x)


def _band_confidence(
    rows: list[dict[str, Any]],
    objs: _Objects,
    est: PushEstimates,
    use: np.ndarray,
    cat_model: CategoryModel,
    se_log_k: np.ndarray | None,
) -> None:
    """A band's confidence from the object's stiffness and its standard error, where the model gives one.

    The pushes' spread says how repeatable the object's k is, not how right: the calibration's
    error is shared by every push of the object.  So an object's ln k carries the median of its
    pushes' standard errors (:func:`log_k_standard_errors`) whole, plus the pushes' spread over
    the square root of their number; the confidence is the probability, under a normal ln k, that
    its stiffness lies in the band it was put in.  A steel can read a third low sits in the band
    below with its pushes all agreeing, and is no longer reported there with confidence 1.
    """
    if se_log_k is None:
        return
    # Each object's used pushes as one row, objects of one size together (few numpy calls, not a few per object).
    n_obj = len(rows)
    codes = np.asarray(objs.codes)[use]
    count = np.bincount(codes, minlength=n_obj)
    median_k, spreads, shareds = (np.full(n_obj, math.nan) for _ in range(3))
    for ids, k_rows in groups_by_size(est.k[use], codes, n_obj):
        median_k[ids] = np.median(k_rows, axis=1)
        spreads[ids] = np.log(k_rows).std(axis=1, ddof=1) if k_rows.shape[1] > 1 else 0.0
    for ids, se_rows in groups_by_size(se_log_k[use], codes, n_obj):
        shareds[ids] = np.nanmedian(se_rows, axis=1)
    for g, row in enumerate(rows):
        band = cat_model.bands.get(row.get("category", ""))
        if band is None or not count[g]:
            continue
        spread, shared = float(spreads[g]), float(shareds[g])
        sd = math.hypot(shared if math.isfinite(shared) else 0.0, spread / math.sqrt(int(count[g])))
        m = math.log(float(median_k[g]))
        lo, hi = band
        upper = (
            1.0
            if not math.isfinite(hi)
            else _normal_cdf((math.log(hi) - m) / sd)
            if sd > 0
            else float(m < math.log(hi))
        )
        lower = 0.0 if lo <= 0 else _normal_cdf((math.log(lo) - m) / sd) if sd > 0 else float(m < math.log(lo))
        row["confidence"] = max(0.0, upper - lower)
        row["log_k_se"] = sd


def _normal_cdf(z: float) -> float:
    """The standard normal's CDF at ``z`` (scipy's ``norm.cdf``, without its per-call cost: one per object)."""
    return 0.5 * math.erfc(-z / math.sqrt(2.0))


def _plain(key: str, value: Any) -> int | float:
    return int(value) if key.startswith("n_") else float(value)


def _group_nanmean(values: np.ndarray, codes: np.ndarray, n: int) -> np.ndarray:
    """np.nanmean of each object's values (row by row: numpy's own sums for each object)."""
    out = np.full(n, math.nan)
    for ids, rows in groups_by_size(values, codes, n):
        out[ids] = np.nanmean(rows, axis=1)
    return out


UNUSABLE = "no usable push"  # an uncategorised object's note: "no usable push (its pushes' commonest flag)"


def _unusable(name: str, sel: np.ndarray, est: PushEstimates, cat_model: CategoryModel, allow: bool) -> dict[str, Any]:
    """An object whose pushes are all flagged: ModelError, or (``allow``) a row that says why."""
    counts = Counter(r for r in est.reason[sel] if r)
    top = counts.most_common(1)[0][0] if counts else "no finite stiffness"
    if not allow:
        raise ModelError(f"Object {name!r} has no usable push: all {len(sel)} are flagged (most often: {top}).")
    return {
        "category": "",
        "confidence": 0.0,
        "z": math.nan,
        "method": cat_model.method,
        "note": f"{UNUSABLE} ({top})",
        "evidence": "uncertain",
        "z_by_category": {},
    }


def _uncategorised(objects: Any) -> list[str]:
    """One sentence per object left without a category because every push of it is flagged (``allow_unusable``)."""
    prefix = f"{UNUSABLE} ("
    if not len(objects) or "note" not in objects.columns:
        return []
    rows = objects[(objects["category"] == "") & objects["note"].astype(str).str.startswith(prefix)]
    return [
        f"Object {name!r} has no category: all {n} of its pushes are flagged (most often: {note[len(prefix) : -1]})."
        for name, n, note in zip(rows["object"], rows["n_pushes"], rows["note"], strict=True)
    ]


def _verdict(p: Any, i: int, note: str = "", in_sample: bool = False) -> dict[str, Any]:
    """Object ``i`` of a :class:`CategoryPrediction` as the row's category fields."""
    return {
        "category": p.category[i],
        "confidence": float(p.confidence[i]),
        "z": float(p.z[i]),
        "method": p.method,
        "note": "; ".join(t for t in (note, p.note[i]) if t),
        # in-sample first: a class scored against its own only reference proves nothing
        "evidence": "in-sample" if in_sample else p.evidence[i],
        "z_by_category": p.distances[i],
    }


def _reference_verdict(
    name: str,
    sel: np.ndarray,
    known: str,
    est: PushEstimates,
    use: np.ndarray,
    labels: np.ndarray,
    cat_model: CategoryModel,
) -> dict[str, Any]:
    """A category from the reference objects; a reference object is judged against the other references."""
    scorer, note = cat_model, ""
    if known:
        # A reference object is judged against the other references, where there are some of its category.
        others = use & (labels != "")
        others[sel] = False
        note = "in-sample (only reference of its category)"
        if known in set(labels[others]):
            try:
                scorer = CategoryModel("reference", min_std_log_k=cat_model.min_std_log_k).fit(
                    est.k[others], list(labels[others])
                )
                note = ""
            except ModelError:
                pass  # too few references left without this object: keep the in-sample answer
    p = scorer.predict([est.k[sel[use[sel]]]], names=[name])
    return _verdict(p, 0, note, in_sample=note.startswith("in-sample"))


# --------------------------------------------------------------------------- from files

DEFAULT_PUSH_PROTOCOL = PUSH_PROTOCOL  # the paper declares it (labcli classify's default)
FORCE_PROTOCOL_KEY = "force_protocol"


@dataclass
class PushSource:
    """A push table with the protocol it was recorded under (a run file carries its own)."""

    path: Any
    table: Any
    protocol: Any
    is_run: bool
    identity: dict = field(default_factory=dict)  # core.provenance: the data, the rig, the protocol


def load_push_source(path: Any, protocol: str | None = None, *, measured_angles: bool = False) -> PushSource:
    """Pushes and protocol of a push run file (.h5) or a push CSV (``protocol`` names one for a CSV).

    With ``measured_angles`` the potentiometer deflections a run file stores per
    push are added as ``theta1_deg, theta2_deg`` when the table lacks them.
    """
    p = Path(path)
    if not p.exists():
        raise ConfigError(f"{p} does not exist; pass a push run file (.h5) or a push CSV.")
    if p.suffix.lower() not in RUN_FILE_SUFFIXES:
        proto = load_protocol(protocol or DEFAULT_PUSH_PROTOCOL)
        if proto.kind != "push":
            raise ConfigError(
                f"Protocol '{proto.name}' is of kind '{proto.kind}'; a push CSV needs a push protocol "
                f"such as {DEFAULT_PUSH_PROTOCOL}."
            )
        return PushSource(p, load_pushes(p), proto, False, table_identity(p, proto))

    with RunFile.open(p) as run:
        text = run.protocol_text
        name = str(run.attrs.get("protocol", ""))
        kind = run.kind
        if protocol is not None and protocol != name:
            raise ConfigError(
                f"{p} was recorded with protocol '{name}'; --protocol applies to push CSV files only, "
                "so leave it out for a run file."
            )
        if kind != "push":
            raise ConfigError(
                f"{p} is a {kind} run (protocol '{name}'), not a push run; classify reads the pushes of a "
                "stiffness run such as one recorded with protocol takuma2014-stiffness."
            )
        table = run.records.table()
        identity = run_identity(run, p)
        if measured_angles and not all(c in table.columns for c in THETA_COLUMNS):
            rows: list[Any] = []
            for pid in table["push"]:
                rec: dict[str, Any] = dict(run.records.read(int(pid)))
                rows.append(np.degrees(rec["theta_rad"]) if "theta_rad" in rec else (math.nan, math.nan))
            theta = np.asarray(rows, dtype=float).reshape(-1, 2)
            table["theta1_deg"], table["theta2_deg"] = theta[:, 0], theta[:, 1]
    proto = (
        loads_protocol(text, source=f"{p} (embedded protocol)")
        if text.strip()
        else load_protocol(name or DEFAULT_PUSH_PROTOCOL)
    )
    return PushSource(p, table, proto, True, identity)


def stiffness_settings(protocol: Any) -> tuple[StiffnessParams, str | None]:
    """Flag thresholds and the force protocol from a protocol's ``[stiffness]`` table, if it has one.

    Without the table the defaults of :class:`StiffnessParams` apply (they are
    the settings measured for the reference rig; see the module docstring of
    :mod:`labcli.papers.takuma2014.models.stiffness`) and any force protocol's model is accepted
    whose rig geometry matches.
    """
    sections = getattr(protocol, "sections", None) or {}
    raw = dict(sections.get("stiffness") or {})
    force_protocol = raw.pop(FORCE_PROTOCOL_KEY, None)
    where = f"[stiffness] of {getattr(protocol, 'source_label', getattr(protocol, 'name', 'the protocol'))}"
    if force_protocol is not None and not isinstance(force_protocol, str):
        raise ConfigError(f"Key {FORCE_PROTOCOL_KEY!r} in {where} must be a protocol name, got {force_protocol!r}.")
    return StiffnessParams.from_dict(raw, where=where), force_protocol


def check_force_model(
    model: Any, protocol: Any, *, model_name: str, run_name: str, force_protocol: str | None = None
) -> None:
    """ModelError unless ``model`` was fitted on a force run of the rig these pushes were made on."""
    if force_protocol is not None and model.protocol != force_protocol:
        raise ModelError(
            f"{cap(model_name)} was fitted for protocol '{model.protocol}' but pushes of protocol "
            f"'{protocol.name}' need a model of protocol '{force_protocol}'; fit one with `labcli fit` "
            f"on a {force_protocol} run."
        )
    if model.protocol in shipped_protocols():
        kind = load_protocol(model.protocol).kind
        if kind != "force":
            raise ModelError(
                f"{cap(model_name)} was fitted for protocol '{model.protocol}', of kind '{kind}', not on a "
                f"force run; fit a model with `labcli fit` on a force run of the rig of {run_name}."
            )
    model.check_compatible(model.protocol, protocol.settings.rig, model_name=model_name, run_name=run_name)


def _merge_reference(table: Any, ref: Any, ref_label: str) -> Any:
    """Append a reference run's labelled pushes, renaming objects whose names the run already uses."""
    import pandas as pd

    labels = _labels(ref)
    if not (labels != "").any():
        raise ModelError(
            f"The reference run {ref_label} has no labelled push (no push has a category); "
            "label its reference objects' pushes in the category column."
        )
    ref = ref[labels != ""].copy()
    taken = set(table["object"].astype(str))
    ref["object"] = [f"{o} (reference)" if o in taken else o for o in ref["object"].astype(str)]
    ref["source"] = "reference"
    out = table.copy()
    out["source"] = "run"
    return pd.concat([out, ref], ignore_index=True, sort=False)


@dataclass
class ClassifyReport:
    """Everything ``labcli classify`` shows: the result and where its inputs came from."""

    result: ClassifyResult
    pushes_path: Any
    model_path: Any
    reference_path: Any
    protocol: Any
    angles: str
    force_protocol: str | None = None
    warnings: list[str] = field(default_factory=list)  # one sentence each, printed before the report

    @property
    def method(self) -> str:
        return self.result.method

    def to_dict(self) -> dict[str, Any]:
        """Plain JSON-ready data: per push and per object, with units in the key names."""
        return report_to_dict(self)


@paused_gc()
def classify_file(
    pushes: Any,
    model: Any,
    *,
    reference: Any = None,
    protocol: str | None = None,
    method: str = "auto",
    angles: str = "pressure-only",
    allow_unusable: bool = False,
) -> ClassifyReport:
    """Classify the objects of a push run file or push CSV with a fitted force model.

    ``model`` is a model JSON path or a :class:`~labcli.papers.takuma2014.models.takuma.TakumaModel`;
    ``reference`` a push run or CSV whose labelled pushes serve as reference
    objects; ``protocol`` names the protocol of a CSV (default
    takuma2014-stiffness); ``method`` ``auto | reference | bands``; ``angles``
    ``pressure-only | measured-angles``.  Bands come from the protocol's
    ``[stiffness_bands_N_per_m]``, flag settings from its ``[stiffness]``.

    Cyclic collection waits until the report is built (:mod:`labcli.core.nogc`): the table's
    texts and the pushes' flag lists made Python walk every live object four times, a sixth of
    this function at 10^5 pushes, and found nothing to collect.
    """
    if method not in ("auto", "reference", "bands"):
        raise ConfigError(f"Unknown category method {method!r}; use 'auto', 'reference' or 'bands'.")
    src = load_push_source(pushes, protocol, measured_angles=angles == "measured-angles")
    params, force_protocol = stiffness_settings(src.protocol)
    if isinstance(model, (TakumaModel, PostureModel)):
        model_path, fmodel = None, model
    else:
        model_path = Path(model)
        fmodel = load_force_model(model_path)
    model_name = f"the model file {model_path}" if model_path is not None else "the model"
    check_force_model(
        fmodel, src.protocol, model_name=model_name, run_name=str(src.path), force_protocol=force_protocol
    )
    # Pushes are read under a push protocol, the model under a force one: the rig is compared, not the text.
    warnings = [
        w
        for w in [rig_warning(cap(model_name), fmodel.fitted_on, str(src.path), src.identity, protocol_text=False)]
        if w
    ]
    table = src.table
    ref_path = None
    if reference is not None:
        ref_path = Path(reference)
        ref = load_push_source(
            ref_path, protocol if not src.is_run else None, measured_angles=angles == "measured-angles"
        )
        check_force_model(
            fmodel, ref.protocol, model_name=model_name, run_name=str(ref_path), force_protocol=force_protocol
        )
        table = _merge_reference(table, ref.table, str(ref_path))
    if method == "reference" and not (_labels(table) != "").any():
        raise ModelError(
            f"The reference method needs labelled reference objects, but no push of {src.path} has a category "
            "and no reference run was given; give one with --reference or use the protocol's stiffness bands "
            "(--method bands)."
        )
    push = src.protocol.settings.push
    bands = push.stiffness_bands_N_per_m if push is not None else None
    try:
        result = classify_pushes(
            table,
            fmodel,
            params=params,
            bands=bands or None,
            method=method,
            angles=angles,
            allow_unusable=allow_unusable,
            settle_s=_earliest_settle(src.protocol),
        )
    except ModelError as e:
        if warnings:  # a model of another rig is the likeliest cause: say so with the failure
            raise ModelError(f"{e} {warnings[0]}") from None
        raise
    warnings += _uncategorised(result.objects)
    return ClassifyReport(result, src.path, model_path, ref_path, src.protocol, angles, force_protocol, warnings)


def _earliest_settle(protocol: Any) -> float | None:
    """Three windows and the hold: when the protocol's settling rule accepts equilibrium at the earliest (s)."""
    st = getattr(protocol, "settling", None)
    return None if st is None else 3.0 * float(st.window_s) + float(st.hold_s)


def _num(x: Any, scale: float = 1.0) -> float | None:
    try:
        v = float(x)
    except (TypeError, ValueError):
        return None
    return v * scale if math.isfinite(v) else None


PUSH_FIELDS: tuple[tuple[str, str, float], ...] = (
    # (output key, pushes-frame column, scale to the output unit)
    ("R_mm", "R_m", 1e3),
    ("d_mm", "d_m", 1e3),
    ("theta1_deg", "theta1_deg", 1.0),
    ("theta2_deg", "theta2_deg", 1.0),
    ("Fx_N", "Fx_N", 1.0),
    ("Fy_N", "Fy_N", 1.0),
    ("Fx_used_N", "Fx_used_N", 1.0),
    ("Fy_used_N", "Fy_used_N", 1.0),
    ("force_N", "force_N", 1.0),
    ("xc_mm", "xc_m", 1e3),
    ("yc_mm", "yc_m", 1e3),
    ("phi_deg", "phi_deg", 1.0),
    ("xo_mm", "xo_m", 1e3),
    ("yo_mm", "yo_m", 1e3),
    ("delta_x_mm", "delta_x_m", 1e3),
    ("k_N_per_m", "k_N_per_m", 1.0),
    ("direction_error_deg", "direction_error_deg", 1.0),
    ("phi_gain", "phi_gain", 1.0),
    ("phi_se_deg", "phi_se_deg", 1.0),
    ("dx_theta_gain_mm_per_deg", "dx_theta_gain_m_per_rad", 1e3 * math.pi / 180),
)


def _push_item(row: Mapping[str, Any]) -> dict[str, Any]:
    item: dict[str, Any] = {"push": int(row["push"]), "object": str(row["object"])}
    if "source" in row:
        item["source"] = str(row["source"])
    item["category_given"] = "" if not isinstance(row.get("category"), str) else row["category"]
    for key, col, scale in PUSH_FIELDS:
        item[key] = _num(row.get(col), scale)
    item["phi_solved"] = bool(row["phi_solved"])
    item["n_phi_solutions"] = int(row["n_phi_solutions"])
    item["flagged"] = bool(row["flag"])
    item["reason"] = str(row["reason"])
    item["note"] = str(row["note"])
    if TRUE_K in row:
        item["true_k_N_per_m"] = _num(row[TRUE_K])
    return item


def push_items(report: ClassifyReport, chunk: int = 10_000) -> Iterator[dict[str, Any]]:
    """Every push as plain data, a chunk of rows at a time (memory stays flat for any number of pushes)."""
    df = report.result.pushes
    for start in range(0, len(df), chunk):
        for row in df.iloc[start : start + chunk].to_dict("records"):
            yield _push_item(row)


def push_lines(report: ClassifyReport, chunk: int = 10_000) -> Iterator[list[str]]:
    """``json.dumps(item)`` of every :func:`push_items` item, the same text, a chunk of pushes at a time.

    Written column by column: each number's ``repr`` once, each distinct text's JSON once, then one
    %-format per push.  One ``json.dumps`` and twenty conversions per push were half of ``classify
    --json`` on 10^5 pushes.  A chunk with a number JSON cannot hold (a scaled value overflowing)
    goes item by item, which refuses it as before.
    """
    df = report.result.pushes
    fields = _line_fields(df)
    template = "{" + ", ".join(f"{json.dumps(key)}: {spec}" for key, spec, _ in fields) + "}"
    for start in range(0, len(df), chunk):
        stop = min(start + chunk, len(df))
        try:
            columns = [convert(start, stop) for _, _, convert in fields]
        except OverflowError:
            yield [json.dumps(item, allow_nan=False) for item in _chunk_items(df.iloc[start:stop])]
            continue
        yield [template % values for values in zip(*columns, strict=True)]


def push_text(report: ClassifyReport, chunk: int = 10_000) -> Iterator[str]:
    """``",\n    ".join`` of each chunk of :func:`push_lines`, the same text, made as one list of
    pieces (each key's text and each value's, a column at a time) joined once: a %-format per
    push was a tenth of writing the pushes."""
    df = report.result.pushes
    fields = _line_fields(df)
    width = 2 * len(fields)
    heads = [f"{', ' if j else ''}{json.dumps(key)}: " for j, (key, _, _) in enumerate(fields)]
    for start in range(0, len(df), chunk):
        stop = min(start + chunk, len(df))
        try:
            columns = [convert(start, stop) for _, _, convert in fields]
        except OverflowError:
            yield ",\n    ".join(json.dumps(item, allow_nan=False) for item in _chunk_items(df.iloc[start:stop]))
            continue
        pieces: list[Any] = [None] * (width * (stop - start))
        for j, ((_, spec, _), values) in enumerate(zip(fields, columns, strict=True)):
            pieces[2 * j :: width] = [heads[j]] * (stop - start)
            pieces[2 * j + 1 :: width] = list(map(str, values)) if spec == "%d" else values
        pieces[width::width] = ["},\n    {" + heads[0]] * (stop - start - 1)
        pieces[0] = "{" + heads[0]
        yield "".join(pieces) + "}"


# Columns of few distinct values (set per object or by the protocol's push directions): each distinct
# value's repr once.  And the force a push used, the estimate itself unless a component was rebuilt
# along the push: its text is the estimate's wherever the two are the same float.
_REPEATED = frozenset({"R_m", "d_m", "phi_deg", TRUE_K})
_TWINS = {"Fx_used_N": "Fx_N", "Fy_used_N": "Fy_N"}
Converter = Callable[[int, int], list[Any]]  # rows [start, stop) of a column, each formatted by its field's spec


def _line_fields(df: Any) -> list[tuple[str, str, Converter]]:
    """The keys of a push item in order, each with its %-spec and its values for rows [start, stop).

    Texts come as their JSON, ints as ints (``%d``), floats as their ``repr`` (json's own text of a
    float), a missing number as ``null``.  The columns are taken once, as arrays (views of the
    frame's own), and cut per chunk.  A float's ``repr`` is most of the cost (half a microsecond
    each, 2 x 10^6 of them at 10^5 pushes), so it is made once per distinct float where a column
    repeats its values (:data:`_REPEATED`, :data:`_TWINS`); "distinct" is bit for bit, which keeps
    -0.0 apart from 0.0.
    """
    made: dict[str, tuple[int, np.ndarray, list[str]]] = {}  # this chunk's floats and texts, by column

    def ints(col: str) -> Converter:
        values = df[col].to_numpy()
        return lambda a, b: list(map(int, values[a:b].tolist()))

    def flags(col: str) -> Converter:
        words = np.array(["false", "true"], dtype=object)
        values = df[col].to_numpy()
        return lambda a, b: words[np.asarray([bool(v) for v in values[a:b].tolist()], dtype=np.intp)].tolist()

    def texts(col: str, given: bool = False) -> Converter:
        if col not in df.columns:
            return lambda a, b: ['""'] * (b - a)
        codes, uniques = _factorize(df[col])
        words = np.array(
            [json.dumps((v if isinstance(v, str) else "") if given else str(v)) for v in uniques], dtype=object
        )
        return lambda a, b: words[codes[a:b]].tolist()

    def numbers(col: str, scale: float = 1.0) -> Converter:
        if col not in df.columns:
            return lambda a, b: ["null"] * (b - a)
        values = np.asarray(df[col], dtype=float)

        def convert(a: int, b: int) -> list[Any]:
            v = values[a:b]
            finite = np.isfinite(v)
            with np.errstate(over="ignore"):
                scaled = v * scale
            if not np.all(np.isfinite(scaled[finite])):
                raise OverflowError(col)
            bits = scaled.view(np.int64)
            out = _float_texts(scaled, bits, col, made.get(_TWINS.get(col, ""), (-1, bits, [])), a)
            for i in np.flatnonzero(~finite).tolist():
                out[i] = "null"
            made[col] = (a, bits, out)
            return out

        return convert

    fields = [("push", "%d", ints("push")), ("object", "%s", texts("object"))]
    if "source" in df.columns:
        fields.append(("source", "%s", texts("source")))
    fields.append(("category_given", "%s", texts("category", given=True)))
    fields += [(key, "%s", numbers(col, scale)) for key, col, scale in PUSH_FIELDS]
    fields += [("phi_solved", "%s", flags("phi_solved")), ("n_phi_solutions", "%d", ints("n_phi_solutions"))]
    fields += [("flagged", "%s", flags("flag")), ("reason", "%s", texts("reason")), ("note", "%s", texts("note"))]
    if TRUE_K in df.columns:
        fields.append(("true_k_N_per_m", "%s", numbers(TRUE_K)))
    return fields


def _float_texts(
    scaled: np.ndarray, bits: np.ndarray, col: str, twin: tuple[int, np.ndarray, list[str]], start: int
) -> list[str]:
    """``repr`` of each float of a chunk: once per distinct value in a column of few, the twin
    column's text where it holds the same float (``twin``: its chunk's start, floats' bits, texts)."""
    if col in _REPEATED:
        codes, uniques = _factorize(bits)
        words = np.array(list(map(repr, uniques.view(np.float64).tolist())), dtype=object)
        return words[codes].tolist()
    if twin[0] != start or len(twin[2]) != len(scaled):
        return list(map(repr, scaled.tolist()))
    out = np.array(twin[2], dtype=object)
    other = np.flatnonzero(bits != twin[1])
    out[other] = list(map(repr, scaled[other].tolist()))
    return out.tolist()


def _factorize(values: Any) -> tuple[np.ndarray, Any]:
    """Codes and distinct values (a missing value one of them), so each distinct text is converted once."""
    import pandas as pd

    return pd.factorize(values, use_na_sentinel=False)


def _chunk_items(part: Any) -> Iterator[dict[str, Any]]:
    for row in part.to_dict("records"):
        yield _push_item(row)


def object_items(report: ClassifyReport) -> list[dict[str, Any]]:
    """Every object's summary as plain data (one per object: small).

    Column by column (:func:`_object_columns`), then one dict per object: the items a row at a
    time made (tests/papers/takuma2014/test_classify_equivalence.py keeps that rule), at a
    fraction of the cost for an archive's 10^4 objects.
    """
    res = report.result
    df = res.objects
    if not len(df):
        return []
    columns = _object_columns(df, res.method)
    keys = list(columns)
    return [dict(zip(keys, values, strict=True)) for values in zip(*columns.values(), strict=True)]


def _object_columns(df: Any, method: str) -> dict[str, list[Any]]:
    n = len(df)

    def cells(col: str) -> list[Any]:
        return df[col].tolist() if col in df.columns else [None] * n

    def nums(col: str) -> list[float | None]:
        if col not in df.columns:
            return [None] * n
        values = df[col].to_numpy()
        if values.dtype.kind != "f":
            return [_num(v) for v in values.tolist()]
        out: list[float | None] = values.tolist()
        for i in np.flatnonzero(~np.isfinite(values)).tolist():
            out[i] = None
        return out

    def words(col: str, default: str = "") -> list[str]:
        return [str(v or default) for v in cells(col)]

    known = cells("known_category")
    role = ("reference" if method == "reference" else "given", "unknown")
    out: dict[str, list[Any]] = {
        "object": list(map(str, cells("object"))),
        # Under bands a known category is only compared with the bands' answer, not used to place them.
        "role": [role[0] if k else role[1] for k in known],
        "category_given": [str(k or "") for k in known],
        "n": list(map(int, cells("n_pushes"))),
        "n_used": list(map(int, cells("n_used"))),
        "n_flagged": list(map(int, cells("n_flagged"))),
        "k_mean_N_per_m": nums("k_mean_N_per_m"),
        "k_sd_N_per_m": nums("k_std_N_per_m"),
        "k_median_N_per_m": nums("k_median_N_per_m"),
        "log_k_mean": nums("log_k_mean"),
        "log_k_sd": nums("log_k_std"),
        "category": words("category"),
        "confidence": nums("confidence"),
        "z": nums("z"),
        "method": words("method", method),
        "note": words("note"),
        "evidence": words("evidence"),
        "z_by_category": [{str(c): _num(v) for c, v in dict(z or {}).items()} for z in cells("z_by_category")],
    }
    if "true_k_N_per_m" in df.columns:
        out["true_k_N_per_m"] = nums("true_k_N_per_m")
    if "log_k_se" in df.columns:
        out["log_k_se"] = nums("log_k_se")  # the standard error behind a band's confidence
    return out


def report_header(report: ClassifyReport) -> dict[str, Any]:
    """What the report says besides its pushes and objects: files, protocol, method, categories, settings."""
    res = report.result
    return {
        "pushes_file": str(report.pushes_path),
        "model_file": None if report.model_path is None else str(report.model_path),
        "reference_file": None if report.reference_path is None else str(report.reference_path),
        "protocol": report.protocol.name,
        "angles": report.angles,
        "method": res.method,
        "warnings": list(report.warnings),
        "categories": res.model.to_dict(),
        "stiffness_settings": res.params.to_dict(),
        "units": {"length": "mm", "angle": "deg", "force": "N", "stiffness": "N/m"},
        "n_pushes": int(len(res.pushes)),
    }


def flag_summary(pushes: Any) -> dict[str, Any]:
    """How many pushes are flagged (by reason) and how many carry each note, without listing them."""
    flagged = pushes["flag"].to_numpy(dtype=bool)
    reasons = pushes.loc[flagged, "reason"].astype(str).value_counts()
    notes = pushes.loc[~flagged & (pushes["note"].astype(str) != ""), "note"].astype(str).value_counts()
    return {
        "n_flagged": int(flagged.sum()),
        "reasons": {str(k): int(v) for k, v in reasons.items()},
        "notes": {str(k): int(v) for k, v in notes.items()},
    }


def report_to_dict(report: ClassifyReport) -> dict[str, Any]:
    """The report as plain data (JSON-ready; NaN becomes None; mm, deg, N, N/m in the key names)."""
    return {**report_header(report), "pushes": list(push_items(report)), "objects": object_items(report)}


def write_report_json(report: ClassifyReport, out: IO[str], extra: Mapping[str, Any] | None = None) -> None:
    """The JSON of :func:`report_to_dict`, streamed: one push per line, never all pushes in memory at once."""
    head = {**report_header(report), **(extra or {})}
    out.write("{\n")
    for key, value in head.items():
        out.write(f"  {json.dumps(key)}: {json.dumps(value, allow_nan=False)},\n")
    out.write('  "objects": ' + json.dumps(object_items(report), allow_nan=False) + ',\n  "pushes": [')
    sep = "\n    "
    for text in push_text(report):
        out.write(sep + text)
        sep = ",\n    "
    out.write("\n  ]\n}\n")
