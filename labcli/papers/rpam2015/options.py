"""What the rPAM paper's analyses may be asked, declared as data (:mod:`labcli.core.options`), and
the commands whose default protocol it ships.

One frozen dataclass per command: the commands add these options to their command line
(``labcli fit stretch.h5 --plot fig6.png``), the core refuses any other a person types for
an rPAM run, and the analysis receives the filled-in object (:mod:`.analyses`).  Imports
nothing heavy: the paper's declaration reads it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ...core.options import BadValue, choice, integer, number, path, text

RPAM_PROTOCOL = "rpam2015"
DEFAULT_PROTOCOLS = {"optimize": RPAM_PROTOCOL}  # labcli optimize without --protocol

FORCE_READINGS = ("derived", "paper")  # actuator.FORCE_READINGS (a test holds them equal)
SEED_MAX = 2**32 - 1  # the search's random generator takes seeds 0 to 2**32 - 1


def parse_kpa(text: str) -> float:
    """A gauge pressure in kPa: a muscle cannot be driven below atmosphere."""
    value = float(text)
    if math.isnan(value):
        raise BadValue("must be a number of kPa")
    if not 0 <= value < math.inf:
        raise BadValue(f"{value:g} is not a gauge pressure; give 0 kPa or more.")
    return value


def parse_seed(text: str) -> int:
    value = int(text)
    if not 0 <= value <= SEED_MAX:
        raise BadValue(f"{value} is outside the seed's range; give a whole number from 0 to {SEED_MAX}.")
    return value


def overrides(help: str) -> Any:
    """``--set KEY=VALUE``, repeatable: protocol values changed for this analysis."""
    return text((), help=help, form="KEY=VALUE", repeat=True, flag="--set")


def parse_stiffness(text: str) -> float:
    """A joint stiffness in N m/rad: a joint with none holds nothing (nan compares as neither)."""
    value = float(text)
    if not 0 < value < math.inf:
        raise BadValue(f"{value:g} is not a stiffness a joint can hold with; give a number of N m/rad above 0.")
    return value


def force_reading() -> Any:
    """``--force derived|paper``: the reading of the actuator force (Eqs. 1-3)."""
    return choice(
        FORCE_READINGS,
        help="The reading of the actuator force (Eqs. 1-3): derived (the cage-held wall's energy and the gas's "
        "virtual work) or paper (the lumen's free body: cage term + P A0/lambda + Eq. 3).",
        default_text="the protocol's actuator.force_reading",
    )


_SET_HELP = (
    "Override a protocol value for this analysis, e.g. --set actuator.A0_m2=2.2e-4 "
    "(repeatable; the run file keeps its own)."
)


@dataclass(frozen=True)
class FitOptions:
    """``labcli fit`` on a stretch-test run (Eq. 7's stretch correction, Fig. 6)."""

    plot: Path | None = path(help="Write the stretch test's figure (Fig. 6) to this .png, .pdf or .svg file.")
    overrides: tuple[str, ...] = overrides(_SET_HELP)
    force: str | None = force_reading()


@dataclass(frozen=True)
class ValidateOptions:
    """``labcli validate`` on a joint-map run (Fig. 8)."""

    model: Path | None = path(
        help="Stretch fit from `labcli fit` on a stretch-test run.", default_text="the protocol's own correction"
    )
    plot: Path | None = path(help="Write Fig. 8 (the joint map against the model) to this .png, .pdf or .svg file.")
    overrides: tuple[str, ...] = overrides(_SET_HELP)
    force: str | None = force_reading()


@dataclass(frozen=True)
class OptimizeOptions:
    """``labcli optimize``: the link lengths of Section IV."""

    seed: int | None = integer(help="Seed of the search.", parse=parse_seed, default_text="the protocol's")
    pa: float | None = number(
        help="Pressure of actuator a.", units="kPa", parse=parse_kpa, form="KPA", default_text="the protocol's, 96"
    )
    pb: float | None = number(
        help="Pressure of actuator b.", units="kPa", parse=parse_kpa, form="KPA", default_text="the protocol's, 41"
    )
    overrides: tuple[str, ...] = overrides("Override any protocol value, e.g. --set actuator.L0_m=0.08 (repeatable).")
    force: str | None = force_reading()
    min_stiffness: float | None = number(
        help="Least joint stiffness at the balance.",
        units="N m/rad",
        parse=parse_stiffness,
        form="NM_PER_RAD",
        default_text="the protocol's optimize.min_stiffness_Nm_per_rad, 0.07",
    )
    actuator: Path | None = path(
        help="Design with the lab's own actuator: the stretch fit `labcli fit` wrote for a stretch-test run "
        "(its Ogden moduli, free length, radius and stretch correction).",
        default_text="the protocol's [actuator], [ogden] and [stretch_correction]",
    )


OPTIONS = {"fit": FitOptions, "validate": ValidateOptions, "optimize": OptimizeOptions}
