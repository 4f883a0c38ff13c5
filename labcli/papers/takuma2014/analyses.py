"""The McKibben paper's analyses, as ``labcli fit``, ``validate`` and ``classify`` run them.

Each is a plain function: the input path, the options object the paper declares for the
command (:mod:`.options`), the command's own keywords; a result object back, :class:`~labcli.errors.LabcliError` with one sentence for anything a person can
fix.  :mod:`.report` prints the results; ``to_dict`` gives their ``--json`` form.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from ...core import idranges
from ...core.figures import source_line
from ...core.heap import kept_heap
from ...core.jsontext import dumps_indented
from ...core.modelfile import check_fit_paths, default_model_path, model_destination, model_text, save_model
from ...core.provenance import rig_warning, same_data
from ...core.report import captures_warning, ids_text, print_warnings
from ...errors import ConfigError, ModelError
from . import report
from .captures import record_ids
from .figures import figure7, figure9
from .models import leak
from .models.classify import classify_file, flag_summary, object_items, push_items, report_header, write_report_json
from .models.inputs import load_trial_source
from .models.metrics import evaluate, evaluation_to_dict
from .models.posture import FORM as POSTURE
from .models.posture import (
    RELIEVED_BASELINES,
    PostureModel,
    force_model_from_json,
    limits_from_protocol,
    load_force_model,
)
from .models.takuma import ANGLE_COLUMNS, EQUATIONS, FORCE_COLUMNS, TERMS, TakumaModel, cap
from .options import FORMS, ClassifyOptions, FitOptions, ValidateOptions

MAX_AMPLIFICATION = 100.0  # the paper form's cut when --max-amplification is not given


@dataclass
class FitResult:
    """A force model fitted on a run's fit trials, where it went, the paper's values."""

    model: TakumaModel | PostureModel
    model_path: Path
    run: Path
    recorded: bool  # also recorded in the run file under /models/<protocol>
    paper: dict[str, float]
    captures: int = 1  # captures a fitted row averages (acquisition.captures_per_load)
    records: tuple[int, int] = (0, 0)  # with several captures a load: (captures read, rows they make)

    def to_dict(self) -> dict[str, Any]:
        out = {
            "model_path": str(self.model_path),
            "recorded_in_run": self.recorded,
            "model": self.model.to_dict(),
            "paper_coefficients": self.paper,
        }
        return out if self.captures == 1 else {**out, "captures_per_load": self.captures}


def fit(
    run: Path,
    options: FitOptions,
    *,
    output: Path | None = None,
    protocol: str | None = None,
    record: bool | None = None,
    leak_correct: bool = False,
) -> FitResult:
    """Fit a force model (``options.form``: posture-aware, or the paper's Eqs. 34-37) to a run's fit trials; save it.

    ``leak_correct``: move each trial's P0 along the run's leak to its loaded window first
    (models/leak.py; off by default, where it measured worse on the simulated rig).  The model
    file records which, and for a run file the trials' median baseline-to-capture gap.
    """
    form = options.form
    if form not in FORMS:
        raise ConfigError(f"Unknown model form '{form}'; use {' or '.join(FORMS)}.")
    if form == POSTURE and options.max_amplification is not None:
        raise ConfigError(
            "--max-amplification is the paper form's cut near theta2 = 0; the posture form "
            "flags by standard error ([sensing] in the protocol), so add --form paper or leave it out."
        )
    if options.friction_terms and form != POSTURE:
        raise ConfigError("--friction-terms are the posture form's; leave out --form paper or --friction-terms.")
    if options.friction_terms and options.no_friction_terms:
        raise ConfigError("--friction-terms and --no-friction-terms ask for opposite fits; give one of them.")
    # Before the inputs are read: an output that is one of them is refused whatever else is wrong.
    check_fit_paths(run, Path(output) if output is not None else default_model_path(run), protocol)
    with kept_heap():  # the table's columns, designs and factors: arrays of 8-100 MB made and dropped
        return _fit(run, form, options, output, protocol, record, leak_correct)


def _fit(
    run: Path,
    form: str,
    options: FitOptions,
    output: Path | None,
    protocol: str | None,
    record: bool | None,
    leak_correct: bool,
) -> FitResult:
    src = load_trial_source(run, protocol)
    out_path, keep = model_destination(run, output, record, src.is_run)
    if leak_correct:
        refuse_leak_on_captures(src, "fit --leak-correct")
        src = replace(src, table=leak.corrected(src.table, run, "fit --leak-correct"))
    with np.errstate(all="ignore"):  # an overflow is refused below, in a sentence
        model = _fit_form(
            form,
            src,
            str(run),
            options.max_amplification or MAX_AMPLIFICATION,
            friction_terms=not options.no_friction_terms,
        )
    if isinstance(model, TakumaModel):
        refuse_non_finite(model, src.table, str(run))
    stamp_fitted(model, src, run, leak_correct)
    recorded = save_model(model.to_json(), out_path, run=run if keep else None, name=model.protocol)
    paper = dict(src.protocol.settings.paper_coefficients or {})
    records = (int(src.table.attrs.get("records", 0)), len(src.table))
    return FitResult(model, out_path, run, recorded, paper, src.captures, records)


def stamp_fitted(model: Any, src: Any, run: Path, leak_correct: bool = False) -> None:
    """What a fitted model records of its trials besides its coefficients, as `labcli fit` writes it
    (the demo's and the sample runs' models too): the data it was fitted on, how its P0 were read,
    the captures a row averages and the fit trials' baseline-to-capture time (the leak's reach)."""
    model.fitted_on = src.identity
    model.p0_leak_corrected = leak_correct
    model.captures_per_load = src.captures
    fit_records = _fit_ids(src.table) if src.captures == 1 else record_ids(_fit_ids(src.table), src.captures)
    model.baseline_gap_s = leak.baseline_gap(run, fit_records) if src.is_run else None


def _fit_ids(table: Any) -> Any:
    return table.loc[in_set(table, "fit"), "trial"] if "set" in table.columns else table["trial"]


def in_set(table: Any, name: str) -> np.ndarray:
    """Which rows' ``set`` is exactly ``name`` (as ``table["set"].astype(str) == name``), each distinct
    value compared once: 0.1 s a comparison of 10^6 cells as strings."""
    import pandas as pd

    codes, values = pd.factorize(table["set"])  # a missing value is code -1: never a set's name
    hit = np.array([str(v) == name for v in values] + [False], dtype=bool)
    return hit[codes]


def refuse_leak_on_captures(src: Any, what: str) -> None:
    """ConfigError: the leak correction moves each record's P0 by its own windows' times, and a row of a
    run of several captures a load is the mean of several records."""
    if src.captures > 1:
        raise ConfigError(
            f"{what} moves each trial's P0 by its own windows' times, but {src.path} averages "
            f"{src.captures} captures into each load's row (acquisition.captures_per_load); leave it out."
        )


def leak_handled(model: Any, src: Any, run: Path) -> Any:
    """The trial source as the model wants it: P0 moved along the leak when it was fitted so (models/leak.py)."""
    if not getattr(model, "p0_leak_corrected", False):
        return src
    refuse_leak_on_captures(src, "A model fitted on leak-corrected baselines")
    return replace(src, table=leak.corrected(src.table, run, "A model fitted on leak-corrected baselines"))


# The column each equation is fitted to, named in the refusal of a fit that overflowed.
TARGET_COLUMNS = {
    "theta1": ANGLE_COLUMNS[0],
    "theta2": ANGLE_COLUMNS[1],
    "Fx": FORCE_COLUMNS[0],
    "Fy": FORCE_COLUMNS[1],
}


def refuse_non_finite(model: TakumaModel, table: Any, source: str) -> None:
    """ModelError when a fitted coefficient or its uncertainty is not finite (never print inf, never write null).

    The tables refuse absurd values on reading; this is the second line of defence, for
    values finite one by one whose squares or products overflow (Fx_N = 1e308).
    """
    for eq in EQUATIONS:
        bad = [
            k
            for k in TERMS[eq]
            if not all(math.isfinite(v) for v in (model.coefficients[k], model.standard_errors[k], *model.ci95[k]))
        ]
        if bad:
            col = TARGET_COLUMNS[eq]
            values = np.abs(np.asarray(table[col], dtype=float))
            largest = float(np.nanmax(values)) if np.isfinite(values).any() else math.nan
            raise ModelError(
                f"The {eq} fit on {source} gives no finite value for {', '.join(bad)}: "
                f"its numbers overflow (largest |{col}| is {largest:g} {col.rsplit('_', 1)[1]}); "
                f"check the table for values beyond what the rig measures."
            )


def friction_of(protocol: Any, asked: bool = False) -> bool | str:
    """The friction terms the posture form is offered on a run of ``protocol`` where ``asked``
    (``labcli fit``'s default; ``--no-friction-terms`` leaves them out, on every run, so that a
    relieved run too gives the plain form the board computes): the relieved ones where its
    baselines were each approached from the vented chambers (``acquisition.friction_relief_vent_s``,
    every run of several captures a load by default), those read from the history of loads
    otherwise.  A relieved run's baselines repeat, and each trial's P0 is then the mean of
    RELIEVED_BASELINES of them (a run of several captures a load: its row's own, already the mean
    of its captures').

    The default since the run-time estimator and the board keep the motion into each baseline
    they read: on runs taken as acquired (15 s waits, the chambers supplied again) they lower
    Fx, offline and live (docs/fit-and-validate.md)."""
    if not asked:
        return False
    air = getattr(protocol, "air", None)
    return "relieved" if getattr(air, "friction_relief_vent_s", 0.0) > 0 else True


def _fit_form(
    form: str,
    src: Any,
    source: str,
    max_amplification: float = MAX_AMPLIFICATION,
    *,
    record_trials: bool = True,
    friction_terms: bool = True,
) -> TakumaModel | PostureModel:
    rig, name = src.protocol.settings.rig, src.protocol.name
    if form == POSTURE:
        friction = friction_of(src.protocol, friction_terms)
        return PostureModel(
            geometry=rig,
            protocol=name,
            limits=limits_from_protocol(src.protocol),
            friction=friction,
            # A row of several captures holds the mean of its own baselines already: the form the
            # multi-capture protocol was chosen with on seeds 1-10 (tests/benchmarks/multi_capture.py).
            baseline_mean=RELIEVED_BASELINES if friction == "relieved" and getattr(src, "captures", 1) == 1 else 1,
        ).fit(src.table, source=source, record_trials=record_trials)
    model = TakumaModel(geometry=rig, protocol=name, max_amplification=max_amplification)
    return model.fit(src.table, source=source, record_trials=record_trials)


def _captures_read(result: FitResult) -> str:
    """How many captures a fitted row averages: N, or fewer where a capture was skipped at the rig."""
    read, rows = result.records
    n = result.captures
    if read in (0, rows * n):
        return f"{n} captures (acquisition.captures_per_load)"
    return (
        f"captures, {n} a load (acquisition.captures_per_load) or fewer where one was skipped "
        f"({read} of {rows * n} read)"
    )


def show_fit(result: FitResult, *, as_json: bool = False) -> None:
    if as_json:
        print(dumps_indented(result.to_dict()))
        return
    recorded = f" and recorded in {result.run} under /models/{result.model.protocol}" if result.recorded else ""
    if result.captures > 1:
        print(
            f"Each trial is the mean of its load's {_captures_read(result)}: "
            f"the standard errors are those of such a mean, too narrow for a single capture."
        )
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
    model_label: str = ""  # where the model came from: a file, or run.h5:/models/<name>
    warnings: list[str] = field(default_factory=list)

    def to_dict(self) -> dict[str, Any]:
        out = evaluation_to_dict(self.evaluation)
        out.update(
            run=str(self.run),
            model=self.model_label or str(self.model_path),
            plot=str(self.plot) if self.plot else None,
            warnings=list(self.warnings),
        )
        return out


def model_for_run(
    run: Path, model_path: Path | None, is_run: bool, name: str
) -> tuple[TakumaModel | PostureModel, str]:
    """The model to apply to ``run`` and where it came from (a label for the report).

    One precedence (:data:`labcli.core.modelfile.MODEL_PRECEDENCE`): ``--model`` when given;
    else the model a run file records in force under ``/models/<name>``; else the sidecar
    ``RUN.model.json``.
    """
    text, label = model_text(run, model_path, is_run, name)
    if text is None:
        return load_force_model(Path(label)), label
    return force_model_from_json(text, name=f"the model {label}"), label


def overlap(model: TakumaModel | PostureModel, src: Any) -> list[int]:
    """The validation trials of ``src`` that ``model`` was fitted on (same data only)."""
    if model.fitted_on:
        same = same_data(model.fitted_on, src.identity)
    else:  # a model written before models recorded their run: the run's name is all there is
        same = bool(model.source) and Path(model.source).name == src.path.name
    if not same:
        return []
    ft = model.fitted_trials  # ranges per equation (paper form), or one list of them (posture form)
    if isinstance(ft, idranges.Ranges):
        fitted = ft  # sorted and merged already (as written, or checked so on reading)
    else:
        fitted = idranges.merge([r for rs in (ft.values() if isinstance(ft, dict) else [ft]) for r in rs])
    table = src.table
    val = np.asarray(table.loc[in_set(table, "validation"), "trial"], dtype=np.int64)
    return sorted(val[idranges.contains(fitted, val)].tolist())


def validate(run: Path, options: ValidateOptions, *, protocol: str | None = None) -> ValidationResult:
    """Accuracy of a fitted model on the validation trials of a run file or trial CSV (Figure 7).

    Refuses when validation trials were used in the fit (unless ``options.allow_overlap``); warns
    when the model was fitted on another rig or under other protocol settings.
    """
    with kept_heap():  # the table's columns and the predictions: arrays of 8-100 MB made and dropped
        return _validate(run, options, protocol)


def _validate(run: Path, options: ValidateOptions, protocol: str | None) -> ValidationResult:
    model_path, mode, plot = options.model, options.mode, options.plot
    src = load_trial_source(run, protocol)
    model, label = model_for_run(run, model_path, src.is_run, src.protocol.name)
    model.check_compatible(
        src.protocol.name,
        src.protocol.settings.rig,
        model_name=f"the model {label}" if ":/models/" in label else f"the model file {label}",
        run_name=str(run),
    )
    warnings = [
        w
        for w in [
            rig_warning(cap(label), model.fitted_on, str(run), src.identity),
            captures_warning(f"the model {label}", model.captures_per_load, f"the rows of {run}", src.captures),
        ]
        if w
    ]
    src = leak_handled(model, src, run)
    shared = overlap(model, src)
    if shared:
        n_val = int(in_set(src.table, "validation").sum())
        what = f"{len(shared)} of the {n_val} validation trials of {run} ({ids_text(shared)}) were used to fit {label}"
        if not options.allow_overlap:
            raise ModelError(
                f"{what}, so the validation would test the model on its own data; refit after the "
                f"split (`labcli fit {run}`), or pass --allow-overlap to validate anyway."
            )
        warnings.append(f"{what}; their errors measure the fit, not a prediction (--allow-overlap).")
    ev = evaluate(model, src.table, mode=mode, source=str(run))
    ev["forms"] = side_by_side(model, ev, src, mode, str(run))
    if plot is not None:
        figure7(
            ev,
            plot,
            run=str(run),
            protocol=src.protocol.name,
            form=getattr(model, "form", "paper"),
            source=source_line(run, src.protocol.name, label),
        )
    return ValidationResult(ev, Path(model_path or default_model_path(run)), run, plot, label, warnings)


def side_by_side(model: Any, ev: dict[str, Any], src: Any, mode: str, source: str) -> dict[str, Any]:
    """Both forms' validation metrics: the given model's, and the other form fitted on the same fit trials.

    Empty of the other form when the run cannot fit it (no fit trials, a collinear design): the
    side-by-side table then shows the one form.
    """
    forms = {ev["form"]: ev["metrics"]}
    other = "paper" if ev["form"] == POSTURE else POSTURE
    try:
        # Fitted only to be measured: its trial list (a random split's 10^5 ranges) is not written.
        fitted = _fit_form(other, src, source, record_trials=False)
        forms[other] = evaluate(fitted, src.table, mode=mode, source=source)["metrics"]
    except ModelError:
        pass
    return {f: forms[f] for f in FORMS if f in forms}


def show_validation(result: ValidationResult, *, as_json: bool = False) -> None:
    print_warnings(result.warnings)
    if as_json:
        print(json.dumps(result.to_dict(), indent=2, allow_nan=False))
        return
    report.print_validation(result.evaluation, result.model_label or str(result.model_path), result.run, result.plot)


@dataclass
class ClassificationResult:
    """Every push's stiffness and every object's category (Section 4), and the figure written."""

    report: Any  # models.classify.ClassifyReport
    plot: Path | None
    list_pushes: bool = False  # list every push in the report, however many

    def to_dict(self) -> dict[str, Any]:
        data = self.report.to_dict()
        data["plot"] = str(self.plot) if self.plot else None
        return data


def classify(pushes: Path, options: ClassifyOptions, *, protocol: str | None = None) -> ClassificationResult:
    """Stiffness and category of each object pushed in a push run or push CSV (Figure 9)."""
    o = options
    # An object with every push flagged is reported without a category (and a sentence why), the others classified.
    result = classify_file(
        pushes,
        o.model,
        reference=o.reference,
        protocol=protocol,
        method=o.method,
        angles=o.angles,
        allow_unusable=True,
    )
    if o.plot is not None:
        prot = getattr(getattr(result, "protocol", None), "name", None) or protocol
        figure9(result.result, o.plot, source=source_line(pushes, prot, o.model))
    return ClassificationResult(result, o.plot, o.pushes)


# The human report lists every push up to this many; beyond, a summary per object (--pushes lists them).
PUSH_LIST_LIMIT = 60


def show_classification(result: ClassificationResult, *, as_json: bool = False) -> None:
    """Print the classification: JSON streamed push by push, or the report (pushes listed when few)."""
    import sys

    print_warnings(result.report.warnings)
    if as_json:
        write_report_json(result.report, sys.stdout, {"plot": str(result.plot) if result.plot else None})
        return
    rep = result.report
    data = {**report_header(rep), "objects": object_items(rep)}
    listed = result.list_pushes or data["n_pushes"] <= PUSH_LIST_LIMIT
    report.print_classification(
        data, result.plot, list(push_items(rep)) if listed else None, flag_summary(rep.result.pushes)
    )
