"""The rPAM paper's analyses, as ``labcli fit``, ``validate`` and ``optimize`` run them.

* :func:`fit`: the cubic stretch correction ``F_stretch(lambda)`` of Eq. 7, with its
  uncertainty, fitted to a stretch-test run (kind ``rpam-stretch``);
* :func:`validate`: a joint-map run (kind ``rpam-joint``) against the model without and
  with that correction (Fig. 8);
* :func:`optimize`: the link lengths that maximise the joint's travel (Section IV).

Each is a plain function: the input, the options object the paper declares for the command
(:mod:`.options`), the command's own keywords; a result back, :class:`~labcli.errors.LabcliError`
with one sentence for anything a person can fix.  :mod:`.report` prints the results.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ...core.figures import source_line
from ...core.files import read_input
from ...core.jsontext import loads_bounded
from ...core.modelfile import check_fit_paths, model_destination, save_model
from ...core.protocol import Protocol
from ...core.store import RunFile
from ...errors import ConfigError
from . import report
from .actuator import Actuator
from .figures import figure8, figure_stretch
from .models.rpam_fit import StretchCorrection, StretchFit, analyse_joint_map, analyse_stretch
from .models.rpam_optimize import optimize_protocol
from .options import FitOptions, OptimizeOptions, ValidateOptions
from .protocol import checked_actuator, stored_protocol, with_overrides


def _read_run(path: Path, protocol: str | None, overrides: tuple[str, ...] = ()) -> tuple[str, Any, Protocol, str, str]:
    """(kind, point table, its protocol, protocol name, where) of an rPAM run.

    ``overrides`` (``--set key=value``) change the run's stored protocol for this analysis only;
    ``where`` names the protocol in messages, with the overrides when there are any.
    """
    with RunFile.open(path) as run:
        kind = run.kind
        name = str(run.attrs.get("protocol", ""))
        text = run.protocol_text
        table = run.records.table()
    if protocol is not None and protocol != name:
        raise ConfigError(
            f"{path} was recorded with protocol '{name}'; --protocol applies to "
            "trial CSV files only, so leave it out for a run file."
        )
    label = f"{path} (protocol)"
    proto = with_overrides(stored_protocol(text, path), overrides, label, shown=overrides)
    where = f"{label} with --set {' '.join(overrides)}" if overrides else label
    return kind, table, proto, name, where


# --------------------------------------------------------------------------- fit


@dataclass
class StretchFitResult:
    """The stretch correction fitted to a stretch-test run, and where it was written."""

    fit: StretchFit
    model_path: Path
    run: Path
    model_name: str
    plot: Path | None
    recorded: bool = True  # also recorded in the run file under /models/<model_name>

    def to_dict(self) -> dict[str, Any]:
        return {
            "model_path": str(self.model_path),
            "recorded_in_run": self.recorded,
            "model_name": self.model_name,
            "plot": str(self.plot) if self.plot else None,
            "fit": self.fit.to_dict(),
        }


def fit(
    run: Path,
    options: FitOptions,
    *,
    output: Path | None = None,
    protocol: str | None = None,
    record: bool | None = None,
) -> StretchFitResult:
    """Fit the stretch correction to a stretch-test run; write the fit and record it in the run."""
    plot, overrides, force = options.plot, options.overrides, options.force
    out, keep = model_destination(run, output, record, True)
    check_fit_paths(run, out, protocol)
    kind, table, proto, name, where = _read_run(run, protocol, overrides)
    if kind != "rpam-stretch":
        raise ConfigError(
            f"{run} is a joint-map run (kind {kind}); labcli fit fits the stretch correction to a stretch-test "
            "run (labcli acquire --experiment stretch), and labcli validate compares a joint map with the model."
        )
    stretch = analyse_stretch(table, (where, proto), force=force)
    if plot is not None:
        figure_stretch(stretch, plot, source=source_line(run, name or proto_name(proto), out))
    model_name = f"{name or 'rpam'}-stretch"
    save_model(stretch.to_json(), out, run=run, name=model_name, record=keep)
    return StretchFitResult(stretch, out, run, model_name, plot, keep)


def show_fit(result: StretchFitResult, *, as_json: bool = False) -> None:
    if as_json:
        print(json.dumps(result.to_dict(), indent=2, allow_nan=False))
        return
    report.print_stretch_fit(
        result.fit, result.model_path, result.run, result.model_name, result.plot, recorded=result.recorded
    )


# --------------------------------------------------------------------------- validate


@dataclass
class JointMapValidation:
    """A joint-map run against the model (Fig. 8), and the files involved."""

    result: Any  # models.rpam_fit.JointMapResult
    run: Path
    model_path: Path | None
    plot: Path | None

    def to_dict(self) -> dict[str, Any]:
        out = self.result.to_dict()
        out.update(
            run=str(self.run),
            model=str(self.model_path) if self.model_path else None,
            plot=str(self.plot) if self.plot else None,
        )
        return out


def load_stretch_model(path: Path) -> Any:
    """A stretch fit (``labcli fit`` on a stretch-test run) or a bare stretch correction, from JSON."""
    if not path.is_file():
        raise ConfigError(
            f"Model file {path} does not exist; fit the stretch test first with "
            "labcli fit STRETCH.h5, which writes STRETCH.model.json."
        )
    try:
        text = read_input(path, "a model file", label=f"Model file {path}").decode("utf-8")
        d = loads_bounded(text)
    except (OSError, UnicodeDecodeError, ValueError):  # ValueError: bad JSON, or nested too deep
        raise ConfigError(
            f"Model file {path} is not a JSON stretch fit; give the file labcli fit wrote for a stretch-test run."
        ) from None
    kind = d.get("kind") if isinstance(d, dict) else None
    if kind == "rpam-stretch-fit":
        return StretchFit.from_dict(d)
    if kind == "rpam-stretch-correction":
        return StretchCorrection.from_dict(d)
    raise ConfigError(
        f"Model file {path} is not a stretch fit (kind {kind!r}); a joint map is compared with "
        "the stretch correction labcli fit writes for a stretch-test run."
    )


def validate(run: Path, options: ValidateOptions, *, protocol: str | None = None) -> JointMapValidation:
    """Compare a joint-map run with the model without and with the stretch correction (Fig. 8).

    The correction is the fit in ``options.model`` or, without one, the protocol's own
    ``[stretch_correction]``; a protocol whose correction is zero needs a fit.
    """
    model_path, plot, force = options.model, options.plot, options.force
    kind, table, proto, _, where = _read_run(run, protocol, options.overrides)
    if kind != "rpam-joint":
        raise ConfigError(
            f"{run} is a stretch-test run (kind {kind}); labcli validate compares a joint-map run with the model: "
            f"fit this one with labcli fit {run} and pass the model it writes to labcli validate JOINT.h5 --model."
        )
    correction = None
    if model_path is not None:
        correction = load_stretch_model(model_path)
    else:
        act = checked_actuator(proto.settings, where)
        if not any(act.stretch_coefficients_N):
            raise ConfigError(
                f"{run}'s protocol has no stretch correction (its coefficients are all 0 N), so the model with "
                "and without it would agree; fit one to a stretch-test run with labcli fit STRETCH.h5 and pass "
                "it with --model STRETCH.model.json."
            )
    result = analyse_joint_map(table, (where, proto), correction, force=force)
    if plot is not None:
        model = model_path if model_path is not None else "the protocol's stretch correction"
        figure8(result, plot, source=source_line(run, proto_name(proto), model))
    return JointMapValidation(result, run, model_path, plot)


def show_validation(result: JointMapValidation, *, as_json: bool = False) -> None:
    if as_json:
        print(json.dumps(result.to_dict(), indent=2, allow_nan=False))
        return
    report.print_joint_map(result.result, result.run, result.model_path, result.plot)


# --------------------------------------------------------------------------- optimize


def optimize(protocol: str, options: OptimizeOptions, *, progress: bool = True) -> Any:
    """Maximise the joint angle over L1, L2, L3 (g1-g7, K_min, the toggle margin); a live line
    on stderr while it runs."""
    o = options
    fitted = (str(o.actuator), load_fitted_actuator(o.actuator)) if o.actuator is not None else None
    kw = dict(
        overrides=o.overrides,
        seed=o.seed,
        Pa_kPa=o.pa,
        Pb_kPa=o.pb,
        force=o.force,
        min_stiffness=o.min_stiffness,
        actuator=fitted,
    )
    if not progress:
        return optimize_protocol(protocol, **kw)  # type: ignore[arg-type]
    with report.optimize_progress() as show:
        return optimize_protocol(protocol, progress=show, **kw)  # type: ignore[arg-type]


def load_fitted_actuator(path: Path) -> Actuator:
    """The lab's actuator fitted in a stretch fit (``labcli fit`` on a stretch-test run), for
    ``labcli optimize --actuator``; :class:`ConfigError` in one sentence for any other file."""
    if not path.exists():
        raise ConfigError(
            f"Actuator file {path} does not exist; fit the stretch test first with labcli fit STRETCH.h5, "
            "which writes STRETCH.model.json."
        )
    try:
        d = loads_bounded(read_input(path, "a model file", label=f"Actuator file {path}").decode("utf-8"))
    except (OSError, UnicodeDecodeError, ValueError):  # ValueError: bad JSON, or nested too deep
        raise ConfigError(
            f"Actuator file {path} is not a JSON stretch fit; give the file labcli fit wrote for an rPAM "
            "stretch-test run."
        ) from None
    kind = d.get("kind", d.get("schema")) if isinstance(d, dict) else None
    if kind != "rpam-stretch-fit":
        what = _OTHER_MODELS.get(str(kind), f"a file of kind {kind!r}")
        raise ConfigError(
            f"Actuator file {path} is {what}, not a stretch fit of the rPAM paper; --actuator takes the file "
            "labcli fit writes for an rPAM stretch-test run."
        )
    fit = StretchFit.from_dict(d)
    if fit.actuator_fit is None:
        why = fit.actuator_note.rstrip(".") if fit.actuator_note else "written before labcli fit fitted one"
        raise ConfigError(
            f"Actuator file {path} holds a stretch correction but no fitted actuator ({why}); fit the stretch-test "
            "run again with labcli fit."
        )
    return fit.actuator_fit.actuator


# What a model file of another kind is, for the sentence that refuses it as --actuator.
_OTHER_MODELS = {
    "labcli-takuma-model": "a force model of the McKibben paper (takuma2014)",
    "rpam-joint-map": "a joint-map analysis",
    "rpam-stretch-correction": "a bare stretch correction without the actuator it was fitted with",
}


def show_optimum(result: Any, *, as_json: bool = False) -> None:
    d = result.to_dict()
    if as_json:
        print(json.dumps(d, indent=2))
        return
    report.print_optimum(d)


def proto_name(proto: Any) -> str:
    """A protocol's name for a figure's foot ("" when it has none)."""
    return str(getattr(proto, "name", "") or "")
