"""Pushes online: each push's object stiffness and category as soon as the push has settled.

A :class:`PushClassifier` is the estimator's settled-load hook (:class:`labcli.sensing.SettledHook`)
for a push session: given the pushes in the order they will come (each its object, radius, push
distance and, when known, direction: what a push plan or the experimenter says), every ``settled``
event of the estimator becomes one ``push`` event carrying Section 4's answer for that push from
the live estimate: the stiffness by Eqs. 38-42 (:func:`.models.stiffness.estimate_pushes`, with the
protocol's ``[stiffness]`` settings, the near-singular Fy projected as ``classify`` does) and the
category of its stiffness band (``[stiffness_bands_N_per_m]``, :class:`.models.categories.CategoryModel`),
with the object's running median over its pushes so far (the category ``classify`` would give the
object on the pushes seen).
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ...errors import ConfigError
from ...sensing.results import Estimate
from .models.categories import CategoryModel
from .models.stiffness import StiffnessParams, estimate_pushes


@dataclass(frozen=True)
class PlannedPush:
    """One push as planned: the object's name and radius (m), the push distance (m), its direction (rad, NaN: unknown)."""

    object: str
    radius_m: float
    distance_m: float
    phi_rad: float = math.nan


@dataclass
class PushClassifier:
    """The settled-load hook of a push session (module docstring)."""

    pushes: list[PlannedPush]
    h2: float
    h3: float
    bands: Mapping[str, Any]
    params: StiffnessParams = field(default_factory=StiffnessParams)
    kind: str = "push"
    done: int = 0
    stiffness: dict[str, list[float]] = field(default_factory=dict)  # per object, the pushes' k so far (N/m)

    def __post_init__(self) -> None:
        self._bands = CategoryModel.from_bands(self.bands)

    @classmethod
    def from_protocol(cls, protocol: Any, model: Any, pushes: Iterable[PlannedPush]) -> PushClassifier:
        """With a push protocol's bands and ``[stiffness]`` settings and the model's geometry."""
        from .models.classify import stiffness_settings

        sections = getattr(protocol, "sections", None) or {}
        bands = sections.get("stiffness_bands_N_per_m")
        if not bands:
            raise ConfigError(
                f"The protocol {getattr(protocol, 'name', '')} has no [stiffness_bands_N_per_m] table, which "
                "online pushes need to name a category; use a push protocol such as takuma2014-stiffness."
            )
        params, _ = stiffness_settings(protocol)
        return cls(list(pushes), model.geometry["h2"], model.geometry["h3"], dict(bands), params)

    def __call__(self, estimate: Estimate, rest: np.ndarray) -> dict[str, Any] | None:
        """The push's stiffness and category from its settled estimate (None once every push is done)."""
        if self.done >= len(self.pushes):
            return None
        plan = self.pushes[self.done]
        self.done += 1
        v, flags = estimate.values, set(estimate.flags)
        force_ok = np.array([[f"unobservable:{q}" not in flags for q in ("Fx", "Fy")]])
        # A component the model does not report is its "uncertain" flag, as classify reads the model.
        model_flags = [["uncertain"] if not force_ok.all() else []]
        est = estimate_pushes(
            [v["theta1"]], [v["theta2"]], [v["Fx"]], [v["Fy"]], plan.radius_m, plan.distance_m, plan.phi_rad,
            h2=self.h2, h3=self.h3, theta0=np.asarray(rest, dtype=float), params=self.params,
            model_flags=model_flags, force_ok=force_ok,
        )  # fmt: skip
        k = float(est.k[0])
        usable = not bool(est.flag[0]) and math.isfinite(k) and k > 0
        out: dict[str, Any] = {
            "push": self.done,
            "object": plan.object,
            "k_N_per_m": round(k, 3) if math.isfinite(k) else None,
            "delta_x_mm": round(float(est.delta_x[0]) * 1e3, 4),
            "flag": str(est.reason[0]),
            "category": "",
            "object_category": "",
        }
        if usable:
            out["category"] = self._bands.predict([[k]]).category[0]
            self.stiffness.setdefault(plan.object, []).append(k)
        ks = self.stiffness.get(plan.object)
        if ks:
            out["object_category"] = self._bands.predict([ks]).category[0]
            out["object_k_median_N_per_m"] = round(float(np.median(ks)), 3)
        return out
