"""The seam between the estimator and a paper's fitted model.

The estimator (:mod:`.estimator`) knows nothing of McKibben muscles: it tracks pressures,
finds loads in them and asks a :class:`SensingModel` what a pair of pressure vectors means.
A paper provides the model (``Paper.sensing_model``, found through the registry by
:func:`load_model`), built from the model file its ``fit`` wrote and applied exactly as its
``validate`` applies it.

A model declares, as plain data:

* ``quantities``, their SI ``units`` and their ``kinds``: a ``"state"`` quantity describes
  the rig as it is now (a joint angle: it follows the pressures through the muscles' lag),
  a ``"load"`` quantity the cause (a force: constant from the moment a weight hangs, so it is
  estimated from the pressures the rig is settling to);
* ``actuators`` and ``joints``: the channel roles it reads (a protocol's
  ``[channels.NAME]`` tables name them), pressures first, then the rest posture;
* ``p0_leak_corrected`` and ``baseline_gap_s``: how the trials it was fitted on measured
  their baseline pressure P0 (see :mod:`.estimator`, "Baseline").

A model may also read the history of loads (:class:`HistoryModel`, ``uses_history`` true): the
joints' motion into the baseline from the previous load's posture (``motion_in``, rad, one per
joint), which a friction that opposes the last motion needs.  The estimator keeps it: the rest
posture now less the previous load's, that load's rest plus the deflections the model's
``deflections`` reads from its last pressures before it came off.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Protocol, runtime_checkable

import numpy as np

from ..core.options import OptionRefused, Typed, bind, names
from ..errors import ModelError

STATE = "state"
LOAD = "load"

# Flags a model (or the estimator) attaches to an estimate; per quantity they read "NAME:q".
UNOBSERVABLE = "unobservable"  # the pressures do not determine this component (its SE is over the model's limit)
OUT_OF_RANGE = "out-of-range"  # inputs or estimate beyond what the model was fitted on
BAD_INPUT = "bad-input"  # a pressure missing, not positive, or outside its sensor's span
TRANSIENT = "transient"  # the rig has not settled since the last change: the SE includes the lag and heat
BASELINE = "no-baseline"  # the baseline is still being learnt (first seconds, or after a change it could not follow)


@dataclass(frozen=True)
class Prediction:
    """What a model says about ``n`` rows of inputs: values and standard errors (n, q) in SI,
    and per row the flags (``"unobservable:Fy"``, ``"out-of-range:Fx"``, ``"bad-input"``)."""

    values: np.ndarray
    se: np.ndarray
    flags: list[tuple[str, ...]]


@runtime_checkable
class SensingModel(Protocol):
    """A fitted model the estimator can apply (a paper's adapter around its model file)."""

    quantities: tuple[str, ...]  # e.g. ("theta1", "theta2", "Fx", "Fy")
    units: tuple[str, ...]  # SI: "rad", "N"
    kinds: tuple[str, ...]  # STATE or LOAD per quantity
    actuators: tuple[str, ...]  # pressure channel roles, in the order of predict's columns
    joints: tuple[int, ...]  # rest-posture channel roles (angles), in the order of predict's columns
    protocol: str  # the protocol the model was fitted under (its calibration converts the rig's counts)
    p0_leak_corrected: bool
    baseline_gap_s: float | None  # median baseline-to-capture time of the fit trials (None: not known)

    def predict(self, P0: np.ndarray, P: np.ndarray, rest: np.ndarray) -> Prediction:
        """Rows of baseline pressures ``P0`` and pressures ``P`` (n, len(actuators)), MPa, and rest
        postures ``rest`` (n, len(joints)), rad: the estimate of each row."""


class HistoryModel(Protocol):
    """What a model that reads the history of loads offers beside :class:`SensingModel`'s (the
    module docstring): ``predict`` takes ``motion_in`` (n, len(joints)) rad, None where unknown."""

    uses_history: bool

    def deflections(self, P0: np.ndarray, P: np.ndarray) -> np.ndarray:
        """The joints' deflections (n, len(joints)) rad from the rest posture that the history reads."""

    def predict(
        self, P0: np.ndarray, P: np.ndarray, rest: np.ndarray, motion_in: np.ndarray | None = None
    ) -> Prediction: ...


def uses_history(model: Any) -> bool:
    """Does ``model`` read the joints' motion into each baseline (:class:`HistoryModel`)?"""
    return bool(getattr(model, "uses_history", False)) and hasattr(model, "deflections")


@runtime_checkable
class SensingPaper(Protocol):
    """A paper whose model files the estimator can use (the optional part of ``Paper``)."""

    name: str
    # What `labcli sense` may be asked of its models beside the core's own options: a dataclass of
    # labcli.core.options fields (None: nothing), built into the command line like analysis_options.
    sensing_options: type | None

    def sensing_model(self, text: str, name: str, options: Any = None) -> SensingModel | None:
        """The model in ``text`` (a model file's JSON; ``name`` names it in sentences), or None
        when the text is not one of this paper's models; ``options`` an object of
        :attr:`sensing_options` (None: its defaults)."""


def load_model(path: str | Path, typed: Typed | None = None) -> SensingModel:
    """The sensing model of a model file, from whichever installed paper wrote it (ModelError),
    with the paper's declared options a person ``typed`` (:func:`model_from_text`)."""
    from ..core.files import read_input

    p = Path(path)
    try:
        text = read_input(p, "a model file", label=f"The model file {p}", error=ModelError).decode("utf-8")
    except FileNotFoundError:
        raise ModelError(f"The model file {p} does not exist; write one with `labcli fit`.") from None
    except IsADirectoryError:
        raise ModelError(f"The model file {p} is a folder; pass the .json file `labcli fit` wrote.") from None
    except UnicodeDecodeError:
        raise ModelError(f"The model file {p} is not UTF-8 text; pass the .json file `labcli fit` wrote.") from None
    except OSError as e:
        raise ModelError(f"The model file {p} cannot be read ({e.strerror or e}).") from None
    return model_from_text(text, f"the model file {p}", typed)


def sensing_papers() -> list[SensingPaper]:
    """The installed papers whose model files the estimator can use."""
    from ..core import registry

    return [p for p in registry.papers() if isinstance(p, SensingPaper)]


def model_from_text(text: str, name: str = "the model", typed: Typed | None = None) -> SensingModel:
    """The sensing model of a model file's JSON text (a file's, or one a run records).

    ``typed``: options the model's paper declares in ``sensing_options``; one it does not
    declare is refused in one sentence (OptionRefused) naming the papers that do.
    """
    typed = typed or Typed()
    papers = sensing_papers()

    def owners(option: str) -> list[str]:
        holders = [p.name for p in papers if p.sensing_options is not None and option in names(p.sensing_options)]
        return [" and ".join(holders) + " models"] if holders else []

    for paper in papers:
        try:
            options = bind(paper.sensing_options, typed, owners=owners, subject=f"{name} is a model of {paper.name}")
        except OptionRefused:
            if paper.sensing_model(text, name) is not None:  # its model: the refusal is the answer
                raise
            continue
        model = paper.sensing_model(text, name, options)
        if model is not None:
            return model
    raise ModelError(
        f"{name[:1].upper()}{name[1:]} is not a model any installed paper can estimate with; "
        "pass the .json file `labcli fit` wrote."
    )


REQUIRED = (
    "quantities",
    "units",
    "kinds",
    "actuators",
    "joints",
    "protocol",
    "p0_leak_corrected",
    "baseline_gap_s",
    "predict",
)


def check_model(model: Any) -> SensingModel:
    """``model`` if it offers what the estimator needs, else ModelError naming what is missing."""
    missing = [a for a in REQUIRED if not hasattr(model, a)]
    if missing:
        raise ModelError(f"{type(model).__name__} is not a sensing model (it lacks {', '.join(sorted(missing))}).")
    n = len(model.quantities)
    if not (len(model.units) == len(model.kinds) == n and all(k in (STATE, LOAD) for k in model.kinds)):
        raise ModelError("A sensing model needs one unit and one kind ('state' or 'load') per quantity.")
    return model


def flag_names(flags: Sequence[str]) -> Mapping[str, tuple[str, ...]]:
    """``("unobservable:Fy", "transient")`` -> ``{"unobservable": ("Fy",), "transient": ()}``."""
    out: dict[str, list[str]] = {}
    for f in flags:
        name, _, q = f.partition(":")
        out.setdefault(name, [])
        if q:
            out[name].append(q)
    return {k: tuple(v) for k, v in out.items()}
