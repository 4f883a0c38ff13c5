"""Material categories from object stiffness (the classification of Section 4, Figure 9).

Two methods, and every result says which one was used:

``reference``
    Fitted on labelled reference objects (pushes whose ``category`` is given).
    Each class c gets the mean mu_c of ln k over its unflagged reference
    pushes (log because stiffness spans decades and its scatter is
    multiplicative), and all classes share one spread sigma, the pooled
    within-class standard deviation of ln k (floored at ``min_std_log_k``).
    An object with stiffness samples k_1..k_n is scored by m = mean(ln k_i)
    under each class's normal N(mu_c, sigma^2): the category is the nearest
    class mean in ln k, and the confidence is its relative likelihood
    L_best / sum_c L_c (the posterior with equal priors).  One shared,
    push-level sigma on purpose: objects of one class differ from each other
    by more than their push noise, a class's own spread sees that only if it
    has several reference objects, and sigma / sqrt(n) would make a single
    object's repeat pushes look like proof.  Label at least two reference
    objects per category so the spread holds object-to-object variation.
    ``z`` = (m - mu_best) / sigma tells how typical the object is of the class
    it was put in.  Each class's own spread is kept (``std_log_k``) for the
    report.

``bands``
    Fixed stiffness bands in N/m, e.g. ``{"soft": [0, 800], "medium": [800,
    3000], "hard": [3000, inf]}`` (lower bound inclusive, upper exclusive).
    The category is the band holding the object's median stiffness; the
    confidence is the fraction of its pushes whose own stiffness lies in that
    band.  Medians outside every band give the category "" and confidence 0.
    The median, not the mean: a push whose phi was solved wrong (phi moves by
    about R/d times the force direction's error) gives a wild stiffness, and on
    the bent arm one such push lifted a soft object's mean into the medium band.
    Chosen on rig seeds 1-10; on the held-out seeds 11-30, pushes on the bent arm
    with phi left blank put all six objects in their category on 12 of 20 seeds by
    the mean, 20 of 20 by the median (tests/benchmarks/heldout_choices.py median).

Either way each object also gets its evidence: the distance to every class (z above;
for bands, how far ln of its median lies outside each band in its own spread of ln k), and
"uncertain" when it lies outside every class or between two close ones (see Z_OUTSIDE,
CLOSE_RATIO, BAND_CLOSE_Z).  The classifier adds "in-sample" for an object that was its
class's only reference.

Parameters are plain data: :meth:`CategoryModel.to_dict` / ``to_json`` and
``from_dict`` / ``from_json`` round-trip them (an open upper bound is written
as ``null``).
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ....errors import ConfigError, ModelError

METHODS = ("reference", "bands")


@dataclass
class CategoryPrediction:
    """One row per object: ``category`` ("" if none), ``confidence`` in [0, 1],
    ``z`` (reference method; NaN for bands), ``method``, ``note`` (why "" or
    anything the reader should know)."""

    category: list[str]
    confidence: np.ndarray
    z: np.ndarray
    method: str
    note: list[str]
    evidence: list[str] = field(default_factory=list)  # "uncertain" or ""
    distances: list[dict[str, float]] = field(default_factory=list)  # per object: z to each class


# When a category is not trusted.  Reference method: the object's mean ln k lies more than
# Z_OUTSIDE class spreads from every class mean, or the runner-up class is less than
# CLOSE_RATIO times less likely than the best.  Bands: the median lies outside every band, or
# within BAND_CLOSE_Z of its own spread of ln k from another band.
Z_OUTSIDE = 3.0
CLOSE_RATIO = 10.0
BAND_CLOSE_Z = 1.0


def _bound(value: Any, name: str, which: str) -> float:
    if value is None or (isinstance(value, str) and value.strip().lower() in ("inf", "+inf", "infinity")):
        return math.inf
    try:
        number = float(value)
    except (TypeError, ValueError):
        number = math.nan
    if math.isnan(number):
        raise ConfigError(f"The {which} bound of stiffness band {name!r} must be a number in N/m, got {value!r}.")
    return number


def parse_bands(bands: Mapping[str, Any]) -> dict[str, tuple[float, float]]:
    """Validate stiffness bands {name: [lower, upper]} in N/m; ``inf``/``null`` allowed as upper."""
    if not isinstance(bands, Mapping) or not bands:
        raise ConfigError("Stiffness bands must be a non-empty table of name = [lower, upper] in N/m.")
    out: dict[str, tuple[float, float]] = {}
    for name, pair in bands.items():
        if not isinstance(pair, (list, tuple)) or len(pair) != 2:
            raise ConfigError(f"Stiffness band {name!r} must be [lower, upper] in N/m, got {pair!r}.")
        lo, hi = _bound(pair[0], name, "lower"), _bound(pair[1], name, "upper")
        if not (0 <= lo < hi):
            raise ConfigError(
                f"Stiffness band {name!r} must satisfy 0 <= lower < upper (N/m), got [{pair[0]}, {pair[1]}]."
            )
        out[str(name)] = (lo, hi)
    ordered = sorted(out.items(), key=lambda item: item[1][0])
    for (a, (_, a_hi)), (b, (b_lo, _)) in zip(ordered, ordered[1:], strict=False):
        if b_lo < a_hi:
            raise ConfigError(
                f"Stiffness bands {a!r} and {b!r} overlap; make each band's lower bound the previous upper bound or more."
            )
    return out


@dataclass
class CategoryModel:
    """Assigns material categories to objects from their stiffness samples.

    ``CategoryModel("reference").fit(k, labels)`` or
    ``CategoryModel.from_bands({...})``; then ``predict([k_obj1, k_obj2, ...])``.
    """

    method: str = "reference"
    classes: dict[str, dict[str, float]] = field(default_factory=dict)
    bands: dict[str, tuple[float, float]] = field(default_factory=dict)
    min_std_log_k: float = 0.05
    std_log_k: float = math.nan

    def __post_init__(self) -> None:
        if self.method not in METHODS:
            raise ConfigError(f"Unknown category method {self.method!r}; use 'reference' or 'bands'.")

    @classmethod
    def from_bands(cls, bands: Mapping[str, Any]) -> CategoryModel:
        return cls(method="bands", bands=parse_bands(bands))

    def fit(self, k: Sequence[float] | np.ndarray, labels: Sequence[str]) -> CategoryModel:
        """Fit class statistics from reference pushes' stiffness ``k`` (N/m, already unflagged) and labels."""
        if self.method != "reference":
            raise ModelError("Only the reference method is fitted; stiffness bands are given, not fitted.")
        k = np.asarray(k, dtype=float).reshape(-1)
        labels = [
            "" if lab is None or (isinstance(lab, float) and math.isnan(lab)) else str(lab).strip() for lab in labels
        ]
        if len(labels) != k.size:
            raise ModelError(f"Got {k.size} stiffness values but {len(labels)} category labels.")
        names = sorted({lab for lab in labels if lab})
        if not names:
            raise ModelError(
                "No reference objects: no push has a category, so the reference method cannot be fitted; "
                "label the reference objects' pushes in the category column or give stiffness bands in the protocol."
            )
        lab = np.array(labels, dtype=object)
        stats: dict[str, dict[str, float]] = {}
        for name in names:
            values = k[(lab == name)]
            good = values[np.isfinite(values) & (values > 0)]
            if good.size == 0:
                raise ModelError(
                    f"Category {name!r} has no usable reference push ({values.size} given, all flagged or without "
                    "a finite positive stiffness); push its reference objects again or drop the category."
                )
            logs = np.log(good)
            stats[name] = {
                "mean_log_k": float(logs.mean()),
                "std_log_k": float(logs.std(ddof=1)) if good.size > 1 else math.nan,
                "n": int(good.size),
            }
        if len(names) < 2:
            raise ModelError(
                f"Only one category ({names[0]!r}) has reference pushes; the reference method needs at least two "
                "categories to choose between."
            )
        multi = [s for s in stats.values() if s["n"] > 1]
        if not multi:
            raise ModelError(
                "Every category has a single reference push, so no class spread can be measured; push each "
                "reference object at least twice."
            )
        pooled = math.sqrt(sum((s["n"] - 1) * s["std_log_k"] ** 2 for s in multi) / sum(s["n"] - 1 for s in multi))
        self.classes = stats
        self.std_log_k = max(pooled, self.min_std_log_k)
        return self

    def predict(
        self, samples: Sequence[Sequence[float] | np.ndarray], names: Sequence[str] | None = None
    ) -> CategoryPrediction:
        """Categorise objects, each given by its unflagged stiffness samples (N/m)."""
        if self.method == "reference" and not self.classes:
            raise ModelError("The category model has no classes; fit it on reference pushes before classifying.")
        names = list(names) if names is not None else [f"#{i}" for i in range(len(samples))]
        cats: list[str] = []
        conf = np.zeros(len(samples))
        zs = np.full(len(samples), np.nan)
        notes: list[str] = []
        evidence: list[str] = []
        distances: list[dict[str, float]] = []
        for i, raw in enumerate(samples):
            k = np.asarray(raw, dtype=float).reshape(-1)
            k = k[np.isfinite(k) & (k > 0)]
            if k.size == 0:
                raise ModelError(
                    f"Object {names[i]!r} has no usable push (all flagged or without a finite positive stiffness), "
                    "so it cannot be categorised; see the reasons in the push table."
                )
            if self.method == "reference":
                cat, c, z = self._score_reference(k)
                cats.append(cat)
                conf[i], zs[i] = c, z
                dist = self._reference_distances(k)
                notes.append("" if abs(z) <= Z_OUTSIDE else f"mean ln k is {abs(z):.1f} class spreads from {cat!r}")
                ranked = sorted(abs(v) for v in dist.values())
                # likelihood ratio of best to runner-up: exp((z2^2 - z1^2) / 2)
                close = len(ranked) > 1 and 0.5 * (ranked[1] ** 2 - ranked[0] ** 2) < math.log(CLOSE_RATIO)
                if close:
                    notes[-1] = "; ".join(t for t in (notes[-1], "two classes are close") if t)
                evidence.append("uncertain" if abs(z) > Z_OUTSIDE or close else "")
            else:
                cat, c, note = self._score_bands(k)
                cats.append(cat)
                conf[i] = c
                dist = self._band_distances(k)
                near = [n for n, v in dist.items() if n != cat and v < BAND_CLOSE_Z]
                if cat and near:
                    note = f"within one spread of band {near[0]!r}"
                notes.append(note)
                evidence.append("uncertain" if not cat or near else "")
            distances.append(dist)
        return CategoryPrediction(
            category=cats, confidence=conf, z=zs, method=self.method, note=notes, evidence=evidence, distances=distances
        )

    def predict_groups(
        self, k: np.ndarray, group: np.ndarray, n_groups: int, names: Sequence[str] | None = None
    ) -> CategoryPrediction:
        """:meth:`predict` of every group of ``k`` (objects numbered 0 .. n_groups - 1) at once.

        The same numbers and words as ``predict([k[group == g] for g in range(n_groups)])``: the
        bands are scored whole-array (:func:`~.stiffness.groups_by_size` keeps each object's
        sums numpy's own), the reference method object by object.
        """
        from .stiffness import groups_by_size

        k, group = np.asarray(k, dtype=float).reshape(-1), np.asarray(group).reshape(-1)
        keep = np.isfinite(k) & (k > 0)
        if self.method != "bands" or not np.all(np.bincount(group[keep], minlength=n_groups) > 0):
            order = np.argsort(group, kind="stable")
            cuts = np.cumsum(np.bincount(group, minlength=n_groups))[:-1]
            return self.predict(np.split(k[order], cuts), names)
        median, spread, inside = np.empty(n_groups), np.empty(n_groups), np.full((n_groups, len(self.bands)), 0.0)
        for ids, rows in groups_by_size(k[keep], group[keep], n_groups):
            median[ids] = np.median(rows, axis=1)
            spread[ids] = np.log(rows).std(axis=1, ddof=1) if rows.shape[1] > 1 else 0.0
            for b, (lo, hi) in enumerate(self.bands.values()):
                inside[ids, b] = np.mean((rows >= lo) & (rows < hi), axis=1)
        return self._bands_prediction(median, np.maximum(spread, self.min_std_log_k), inside)

    def _bands_prediction(self, median: np.ndarray, spread: np.ndarray, inside: np.ndarray) -> CategoryPrediction:
        """The bands' verdicts from each object's median, spread of ln k and share of pushes in each band."""
        bands = list(self.bands.items())
        m = np.log(median)
        dist = np.zeros((len(median), len(bands)))
        for b, (_, (lo, hi)) in enumerate(bands):
            below = math.log(lo) - m if lo > 0 else np.full(len(m), -math.inf)
            above = m - math.log(hi) if math.isfinite(hi) else np.full(len(m), -math.inf)
            dist[:, b] = np.maximum(np.maximum(below, above), 0.0) / spread
        holding = np.column_stack([(lo <= median) & (median < hi) for _, (lo, hi) in bands])
        first = np.where(holding.any(axis=1), np.argmax(holding, axis=1), -1)
        names = [name for name, _ in bands]
        cats, notes, evidence = [], [], []
        for i, b in enumerate(first.tolist()):
            cat = names[b] if b >= 0 else ""
            near = [n for j, n in enumerate(names) if n != cat and dist[i, j] < BAND_CLOSE_Z]
            note = "" if cat else f"median stiffness {float(median[i]):.0f} N/m lies outside every band"
            cats.append(cat)
            notes.append(f"within one spread of band {near[0]!r}" if cat and near else note)
            evidence.append("uncertain" if not cat or near else "")
        conf = np.where(first >= 0, inside[np.arange(len(first)), np.maximum(first, 0)], 0.0)
        distances = [dict(zip(names, row, strict=True)) for row in dist.tolist()]
        return CategoryPrediction(
            category=cats,
            confidence=conf,
            z=np.full(len(median), np.nan),
            method=self.method,
            note=notes,
            evidence=evidence,
            distances=distances,
        )

    def _reference_distances(self, k: np.ndarray) -> dict[str, float]:
        """z of the object's mean ln k from each class mean, in class spreads (signed)."""
        m = float(np.log(k).mean())
        return {c: (m - s["mean_log_k"]) / self.std_log_k for c, s in self.classes.items()}

    def _band_distances(self, k: np.ndarray) -> dict[str, float]:
        """How far ln(median k) lies outside each band, in the object's own spread of ln k (0 inside)."""
        logs = np.log(k)
        m = float(np.log(np.median(k)))
        spread = max(float(logs.std(ddof=1)) if k.size > 1 else 0.0, self.min_std_log_k)
        out = {}
        for name, (lo, hi) in self.bands.items():
            below = (math.log(lo) - m) if lo > 0 else -math.inf
            above = m - math.log(hi) if math.isfinite(hi) else -math.inf
            out[name] = max(below, above, 0.0) / spread
        return out

    def _score_reference(self, k: np.ndarray) -> tuple[str, float, float]:
        m = float(np.log(k).mean())
        names = list(self.classes)
        mu = np.array([self.classes[c]["mean_log_k"] for c in names])
        loglik = -0.5 * ((m - mu) / self.std_log_k) ** 2
        post = np.exp(loglik - loglik.max())
        post /= post.sum()
        best = int(np.argmax(post))
        return names[best], float(post[best]), float((m - mu[best]) / self.std_log_k)

    def _score_bands(self, k: np.ndarray) -> tuple[str, float, str]:
        median = float(np.median(k))
        for name, (lo, hi) in self.bands.items():
            if lo <= median < hi:
                inside = float(np.mean((k >= lo) & (k < hi)))
                return name, inside, ""
        return "", 0.0, f"median stiffness {median:.0f} N/m lies outside every band"

    def to_dict(self) -> dict[str, Any]:
        if self.method == "bands":
            return {
                "method": "bands",
                "bands": {n: [lo, None if math.isinf(hi) else hi] for n, (lo, hi) in self.bands.items()},
            }
        return {
            "method": "reference",
            "min_std_log_k": self.min_std_log_k,
            "std_log_k": self.std_log_k,
            "classes": {
                n: {**s, "std_log_k": None if math.isnan(s["std_log_k"]) else s["std_log_k"]}
                for n, s in self.classes.items()
            },
        }

    def to_json(self) -> str:
        return json.dumps(self.to_dict(), indent=2, sort_keys=True)

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> CategoryModel:
        method = data.get("method")
        if method == "bands":
            return cls.from_bands(data.get("bands") or {})
        if method == "reference":
            try:
                classes = {
                    str(n): {
                        "mean_log_k": float(s["mean_log_k"]),
                        "std_log_k": math.nan if s.get("std_log_k") is None else float(s["std_log_k"]),
                        "n": int(s["n"]),
                    }
                    for n, s in (data.get("classes") or {}).items()
                }
                spread = float(data["std_log_k"])
            except (KeyError, TypeError, ValueError, AttributeError):
                raise ConfigError(
                    "The reference category parameters need classes with mean_log_k and n, and std_log_k."
                ) from None
            return cls(
                method="reference",
                classes=classes,
                min_std_log_k=float(data.get("min_std_log_k", 0.05)),
                std_log_k=spread,
            )
        raise ConfigError(f"Unknown category method {method!r} in the category parameters; use 'reference' or 'bands'.")

    @classmethod
    def from_json(cls, text: str) -> CategoryModel:
        return cls.from_dict(json.loads(text))
