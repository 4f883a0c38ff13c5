"""Bad-input cases of the analyses: model files with numbers or nesting no parser should meet,
a model with a coefficient the equations do not have, an optimiser seed
out of the generator's range, an option another paper declares."""

from __future__ import annotations

import re
from collections.abc import Callable
from pathlib import Path

from support.bad_input import Case, model_edit

ORDER = 40


def coefficient_text(digits: int) -> Callable[[Path], bytes]:
    """The run's model with beta_Fx1 written as an integer of ``digits`` digits."""

    def make(world: Path) -> bytes:
        text = (world / "run.model.json").read_text()
        return re.sub(r'"beta_Fx1": [^,\n]+', '"beta_Fx1": ' + "1" * digits, text, count=1).encode()

    return make


CASES: list[Case] = [
    Case(
        "model-400-digits",
        "model JSON",
        "400-digit integer coefficient",
        ["validate", "run.h5", "--model", "m.json"],
        [
            "The model file m.json: key 'coefficients.beta_Fx1' must be a finite number, not a 400-digit number "
            "(beyond the largest float, about 1.8e308); refit with `labcli fit`."
        ],
        files={"m.json": coefficient_text(400)},
    ),
    Case(
        "model-5000-digits",
        "model JSON",
        "5000-digit integer coefficient (classify)",
        ["classify", "push.h5", "--model", "m.json"],
        [
            "The model file m.json: key 'coefficients.beta_Fx1' must be a finite number, not a 5000-digit number "
            "(beyond the largest float, about 1.8e308); refit with `labcli fit`."
        ],
        files={"m.json": coefficient_text(5000)},
    ),
    Case(
        "model-float-overflow",
        "model JSON",
        "coefficient 1e400",
        ["validate", "run.h5", "--model", "m.json"],
        [
            "The model file m.json: key 'geometry.h2' must be a finite number, not the number 1e400 "
            "(beyond the largest float, about 1.8e308); refit with `labcli fit`."
        ],
        files={
            "m.json": lambda w: re.sub(
                r'"h2": [^,\n]+', '"h2": 1e400', (w / "run.model.json").read_text(), count=1
            ).encode()
        },
    ),
    Case(
        "model-nested-deep",
        "model JSON",
        "JSON nested 100,000 deep",
        ["validate", "run.h5", "--model", "m.json"],
        [
            "The model file m.json nests 100000 levels deep, beyond the 64 a model file can have; "
            "pass the .json file `labcli fit` wrote."
        ],
        files={"m.json": b"[" * 100_000 + b"]" * 100_000},
    ),
    Case(
        "model-extra-coefficient",
        "model JSON",
        "extra coefficient beta_Fy7",
        ["validate", "run.h5", "--model", "m.json"],
        [
            "The model file m.json has an unknown coefficient, beta_Fy7 (Eqs. 34-37 have beta_theta1_L1 to "
            "beta_Fy6); refit with `labcli fit`."
        ],
        files={"m.json": model_edit(lambda d: d["coefficients"].update(beta_Fy7=1.0))},
    ),
    Case(
        "model-fitted-range-backwards",
        "model JSON",
        "fitted trial range [5, 1]",
        ["validate", "run.h5", "--model", "m.json"],
        [
            "The model file m.json: key 'fitted_trials.Fx' must list whole trial numbers, or [first, last] ranges "
            "of them; refit with `labcli fit`."
        ],
        files={"m.json": model_edit(lambda d: d["fitted_trials"].update(Fx=[[5, 1]]))},
    ),
    Case(
        "arg-optimize-negative-seed",
        "CLI argument",
        "--seed -1 (optimize)",
        ["optimize", "--seed", "-1"],
        ["Invalid value for '--seed': -1 is outside the seed's range; give a whole number from 0 to 4294967295."],
        code=2,
        usage="optimize [OPTIONS]",
    ),
    Case(
        "arg-optimize-huge-seed",
        "CLI argument",
        "--seed beyond 2**32 - 1 (optimize)",
        ["optimize", "--seed", "4294967296"],
        [
            "Invalid value for '--seed': 4294967296 is outside the seed's range; give a whole number from 0 to "
            "4294967295."
        ],
        code=2,
        usage="optimize [OPTIONS]",
    ),
    Case(
        "actuator-other-paper",
        "model JSON",
        "a McKibben force model as the rPAM actuator (optimize --actuator)",
        ["optimize", "--actuator", "run.model.json"],
        [
            "Actuator file run.model.json is a force model of the McKibben paper (takuma2014), not a stretch fit "
            "of the rPAM paper; --actuator takes the file labcli fit writes for an rPAM stretch-test run."
        ],
    ),
    Case(
        "actuator-other-kind",
        "model JSON",
        "a joint-map analysis as the rPAM actuator (optimize --actuator)",
        ["optimize", "--actuator", "joint.json"],
        [
            "Actuator file joint.json is a joint-map analysis, not a stretch fit of the rPAM paper; --actuator "
            "takes the file labcli fit writes for an rPAM stretch-test run."
        ],
        files={"joint.json": b'{"kind": "rpam-joint-map"}'},
    ),
    Case(
        "actuator-missing",
        "model JSON",
        "a missing actuator file (optimize --actuator)",
        ["optimize", "--actuator", "stretch.model.json"],
        [
            "Actuator file stretch.model.json does not exist; fit the stretch test first with labcli fit "
            "STRETCH.h5, which writes STRETCH.model.json."
        ],
    ),
    Case(
        "arg-other-papers-option-run",
        "CLI argument",
        "an option another paper declares, on a force run (fit --set)",
        ["fit", "run.h5", "--set", "actuator.L0_m=0.08"],
        ["--set is an option of rpam2015 runs; run.h5 is a run of kind force (takuma2014)."],
    ),
    Case(
        "arg-other-papers-option-table",
        "CLI argument",
        "an option another paper declares, on a trial table (fit --plot)",
        ["fit", "trials.csv", "--plot", "fig6.png"],
        ["--plot is an option of rpam2015 runs; labcli fit reads trials.csv with takuma2014."],
    ),
]
