"""The McKibben experiment's analyses, as ``labcli fit``, ``validate`` and ``classify`` run them.

Each is a plain function: plain arguments (paths, options as typed), a result object
back, :class:`~labcli.errors.LabcliError` with one sentence for anything a person can
fix.  :mod:`.report` prints the results; ``to_dict`` gives their ``--json`` form.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ...core.modelfile import default_model_path, save_model
from ...errors import ConfigError, ModelError
from . import report
from .figures import figure7, figure9
from .models.classify import classify_file
from .models.inputs import load_trial_source
from .models.metrics import evaluate, evaluation_to_dict
from .models.posture import FORM as POSTURE, PostureModel, limits_from_protocol, load_force_model
from .models.takuma import TakumaModel

FORMS = (POSTURE, "paper")  # labcli fit --form; the first is the default

# Options of the rPAM analyses that mean nothing to a force run (``--set``, ``--plot`` of fit).
SET_REFUSED = ("--set changes rPAM model constants (e.g. --set actuator.L0_m=0.08); a force "
               "run's model is fitted from its trials, so leave --set out.")


@dataclass
class FitResult:
    """A force model fitted on a run's fit trials, where it went, the paper's values."""

    model: TakumaModel | PostureModel
    model_path: Path
    run: Path
    recorded: bool  # also recorded in the run file under /models/<protocol>
    paper: dict[str, float]

    def to_dict(self) -> dict[str, Any]:
        return {"model_path": str(self.model_path), "recorded_in_run": self.recorded,
                "model": self.model.to_dict(), "paper_coefficients": self.paper}


def fit(run: Path, *, output: Path | None = None, protocol: str | None = None, max_amplification: float = 100.0,
        form: str = POSTURE, plot: Path | None = None, overrides: tuple[str, ...] = (),
        typed: frozenset[str] = frozenset()) -> FitResult:
    """Fit a force model (``form``: posture-aware, or the paper's Eqs. 34-37) to a run's fit trials; save it."""
    if overrides:
        raise ConfigError(SET_REFUSED)
    if plot is not None:
        raise ConfigError("--plot draws the stretch test (Fig. 6) of an rPAM stretch-test run; "
                          "for a force run draw Figure 7 with labcli validate --plot.")
    if form not in FORMS:
        raise ConfigError(f"Unknown model form '{form}'; use {' or '.join(FORMS)}.")
    if form == POSTURE and "max_amplification" in typed:
        raise ConfigError("--max-amplification is the paper form's cut near theta2 = 0; the posture form "
                          "flags by standard error ([sensing] in the protocol), so add --form paper or leave it out.")
    src = load_trial_source(run, protocol)
    model = _fit_form(form, src, str(run), max_amplification)
    out_path = output or default_model_path(run)
    recorded = save_model(model.to_json(), out_path, run=run if src.is_run else None, name=model.protocol)
    return FitResult(model, out_path, run, recorded, dict(src.protocol.settings.paper_coefficients or {}))


def _fit_form(form: str, src: Any, source: str, max_amplification: float = 100.0) -> TakumaModel | PostureModel:
    rig, name = src.protocol.settings.rig, src.protocol.name
    if form == POSTURE:
        return PostureModel(geometry=rig, protocol=name, limits=limits_from_protocol(src.protocol)).fit(
            src.table, source=source)
    return TakumaModel(geometry=rig, protocol=name, max_amplification=max_amplification).fit(src.table, source=source)


def show_fit(result: FitResult, *, as_json: bool = False) -> None:
    if as_json:
        print(json.dumps(result.to_dict(), indent=2))
        return
    recorded = f" and recorded in {result.run} under /models/{result.model.protocol}" if result.recorded else ""
    if isinstance(result.model, PostureModel):
        report.print_posture_fit(result.model, result.model_path, recorded)
    else:
        report.print_fit(result.model, result.paper, result.model_path, recorded)


@dataclass
class ValidationResult:
    """A model checked on the validation trials (the metrics and every trial's values)."""

    evaluation: dict[str, Any]
    model_path: Path
    run: Path
    plot: Path | None

    def to_dict(self) -> dict[str, Any]:
        out = evaluation_to_dict(self.evaluation)
        out.update(run=str(self.run), model=str(self.model_path), plot=str(self.plot) if self.plot else None)
        return out


def validate(run: Path, *, model_path: Path | None = None, mode: str = "pressure-only", plot: Path | None = None,
             protocol: str | None = None, overrides: tuple[str, ...] = (),
             typed: frozenset[str] = frozenset()) -> ValidationResult:
    """Accuracy of a fitted model on the validation trials of a run file or trial CSV (Figure 7)."""
    if overrides:
        raise ConfigError(SET_REFUSED)
    src = load_trial_source(run, protocol)
    mpath = model_path or default_model_path(run)
    model = load_force_model(mpath)
    model.check_compatible(src.protocol.name, src.protocol.settings.rig,
                           model_name=f"the model file {mpath}", run_name=str(run))
    ev = evaluate(model, src.table, mode=mode, source=str(run))
    ev["forms"] = side_by_side(model, ev, src, mode, str(run))
    if plot is not None:
        figure7(ev, plot)
    return ValidationResult(ev, mpath, run, plot)


def side_by_side(model: Any, ev: dict[str, Any], src: Any, mode: str, source: str) -> dict[str, Any]:
    """Both forms' validation metrics: the given model's, and the other form fitted on the same fit trials.

    Empty of the other form when the run cannot fit it (no fit trials, a collinear design): the
    side-by-side table then shows the one form.
    """
    forms = {ev["form"]: ev["metrics"]}
    other = "paper" if ev["form"] == POSTURE else POSTURE
    try:
        forms[other] = evaluate(_fit_form(other, src, source), src.table, mode=mode, source=source)["metrics"]
    except ModelError:
        pass
    return {f: forms[f] for f in FORMS if f in forms}


def show_validation(result: ValidationResult, *, as_json: bool = False) -> None:
    if as_json:
        print(json.dumps(result.to_dict(), indent=2, allow_nan=False))
        return
    report.print_validation(result.evaluation, result.model_path, result.run, result.plot)


@dataclass
class ClassificationResult:
    """Every push's stiffness and every object's category (Section 4), and the figure written."""

    report: Any  # models.classify.ClassifyReport
    plot: Path | None

    def to_dict(self) -> dict[str, Any]:
        data = self.report.to_dict()
        data["plot"] = str(self.plot) if self.plot else None
        return data


def classify(pushes: Path, *, model_path: Path, reference: Path | None = None, method: str = "auto",
             angles: str = "pressure-only", plot: Path | None = None, protocol: str | None = None,
             typed: frozenset[str] = frozenset()) -> ClassificationResult:
    """Stiffness and category of each object pushed in a push run or push CSV (Figure 9)."""
    result = classify_file(pushes, model_path, reference=reference, protocol=protocol, method=method, angles=angles)
    if plot is not None:
        figure9(result.result, plot)
    return ClassificationResult(result, plot)


def show_classification(result: ClassificationResult, *, as_json: bool = False) -> None:
    if as_json:
        print(json.dumps(result.to_dict(), indent=2, allow_nan=False))
        return
    report.print_classification(result.report.to_dict(), result.plot)
