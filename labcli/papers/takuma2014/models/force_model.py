"""The seam every form of the force model offers: the paper's Eqs. 34-37 (:class:`.takuma.TakumaModel`)
and the posture-aware form (:class:`.posture.PostureModel`).

What validation, classification and the demo ask of a fitted model, and nothing more, so a
third form plugs in by offering these methods (:func:`.metrics.evaluate` takes any of them).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, Protocol, runtime_checkable


@runtime_checkable
class ForceModel(Protocol):
    """A fitted force model: angles (rad) and tip force (N) from the four pressures (MPa)."""

    @property
    def is_fitted(self) -> bool:
        """Whether every coefficient the form needs has a value."""

    def predict_table(self, table: Any, mode: str = "pressure-only") -> dict[str, Any]:
        """Predict the rows of a trial table: ``{"theta", "F", "flags", ...}`` arrays (rad, N)."""

    def check_compatible(
        self, protocol: str, geometry: Mapping[str, Any], model_name: str = "the model", run_name: str = "the run"
    ) -> None:
        """ModelError (one sentence) when the model was fitted on another rig than this run's."""

    def to_dict(self) -> dict[str, Any]:
        """The model as plain JSON data (what a model file holds)."""
