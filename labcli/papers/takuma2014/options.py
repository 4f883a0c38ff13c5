"""What the McKibben paper's analyses may be asked, declared as data (:mod:`labcli.core.options`),
and the commands whose default protocol it ships.

One frozen dataclass per command: the commands add these options to their command line
(``labcli fit --form paper``), the core refuses any other a person types for a force or
push run, and the analysis receives the filled-in object (:mod:`.analyses`).  Imports
nothing heavy: the paper's declaration reads it.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ...core.options import choice, number, path, switch

# The shipped protocols labcli reads with when nothing names one: a trial table, a new run, the
# monitor's calibration and the demo take the force protocol; a push table the stiffness protocol.
TRIAL_PROTOCOL = "takuma2014"
PUSH_PROTOCOL = "takuma2014-stiffness"
DEFAULT_PROTOCOLS = {
    "acquire": TRIAL_PROTOCOL,
    "monitor": TRIAL_PROTOCOL,
    "demo": TRIAL_PROTOCOL,
    "fit": TRIAL_PROTOCOL,
    "validate": TRIAL_PROTOCOL,
    "classify": PUSH_PROTOCOL,
    "predict": TRIAL_PROTOCOL,
    "split": TRIAL_PROTOCOL,
}

FORMS = ("posture", "paper")  # labcli fit --form; the first is the default (models.posture.FORM)
ANGLES = ("pressure-only", "measured-angles")

_ANGLES_HELP = "Angles for the force equations: from the pressures (Eqs. 34-35) or the potentiometers."


@dataclass(frozen=True)
class FitOptions:
    """``labcli fit`` on a force run or trial table."""

    form: str = choice(
        FORMS,
        FORMS[0],
        help="posture: torques at the arm's rest posture plus deflection, forces by (J^T)^-1, with "
        "standard errors; paper: Eqs. 34-37 exactly as printed, beside the paper's coefficients.",
    )
    max_amplification: float | None = number(
        help="With --form paper: leave a posture out of the Fx (Fy) fit when that force's error "
        "amplification near theta2 = 0 exceeds this.",
        minimum=1,
        above=True,
        default_text="100",
    )
    friction_terms: bool = switch(
        help="With the posture form: offer its torque fit the sleeves' friction terms, each trial's read from "
        "its motion under the load and into its baseline (the default; lower Fx on runs taken with 15 s waits)."
    )
    no_friction_terms: bool = switch(
        help="With the posture form: fit it without the sleeves' friction terms (a relieved run's too), as it "
        "was fitted before they were the default; the form export-model carries to the board."
    )


@dataclass(frozen=True)
class ValidateOptions:
    """``labcli validate`` on a force run or trial table (Figure 7)."""

    model: Path | None = path(
        help="Model JSON from `labcli fit`.",
        default_text="the model RUN records, else RUN.model.json beside it",
    )
    mode: str = choice(ANGLES, ANGLES[0], help=_ANGLES_HELP)
    plot: Path | None = path(help="Write Figure 7 (observed vs calculated) to this .png, .pdf or .svg file.")
    allow_overlap: bool = switch(
        help="Validate even when validation trials were used to fit the model (a warning says how many)."
    )


@dataclass(frozen=True)
class ClassifyOptions:
    """``labcli classify`` on a push run or push table (Section 4, Figure 9)."""

    model: Path = path(help="Model JSON from `labcli fit` on a force run of the same rig.", required=True)
    reference: Path | None = path(help="Push run or CSV whose labelled pushes (category column) are reference objects.")
    method: str = choice(
        ("auto", "reference", "bands"),
        "auto",
        help="Categories from labelled reference objects, from the protocol's stiffness bands, "
        "or reference objects when any push is labelled, else bands.",
    )
    angles: str = choice(
        ANGLES, ANGLES[0], help="Joint angles from the pressures (Eqs. 34-35, the paper) or from the potentiometers."
    )
    plot: Path | None = path(help="Write Figure 9 (stiffness per object) to this .png, .pdf or .svg file.")
    pushes: bool = switch(help="List every push in the report [default: only when there are 60 or fewer].")


RANGE_MARGIN = 0.10  # labcli predict / sense --range-margin (sensing.py's out-of-range flags)


def _range_margin() -> Any:
    return number(
        RANGE_MARGIN,
        help="How far an input or an estimate may lie beyond the span the fit trials covered, as a share of "
        "that span, before it is flagged out-of-range.",
        minimum=0,
        maximum=10,
    )


@dataclass(frozen=True)
class PredictOptions:
    """``labcli predict`` on a table of new pressures or a run file (the model file is the core's
    ``--model``)."""

    range_margin: float = _range_margin()


@dataclass(frozen=True)
class SensingOptions:
    """``labcli sense`` with one of this paper's model files (the core's own options aside)."""

    range_margin: float = _range_margin()


OPTIONS = {"fit": FitOptions, "validate": ValidateOptions, "classify": ClassifyOptions, "predict": PredictOptions}
