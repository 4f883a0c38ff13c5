"""Bad-input cases of numbers without physics: model coefficients no fit gives, a run holding a
reading no exchange table may hold (written before the store checked the table's bounds).

What ``acquire`` does with such a reading (it refuses to store the trial, after the run file was
begun) is tested in tests/cli/test_bounds_shared.py, since a run file is then left behind on
purpose: the trials before it are whole.
"""

from __future__ import annotations

import tempfile
from pathlib import Path

from support.bad_input import SIM, Case, model_edit

ORDER = 70

BEYOND = "beyond the 1e+06 a fitted coefficient can reach; refit with `labcli fit`."


def coefficient(name: str, value: float):
    return model_edit(lambda d: d["coefficients"].update({name: value}))


def run_beyond_the_table(world: Path) -> bytes:
    """A run whose trial 2 holds a baseline of -0.05 MPa: inside the run file's wide bounds, outside the table's.

    Written through the bulk append of the library (what ``labcli import`` uses after its table
    reader has checked the rows), which is how a run of an earlier release could come to hold it.
    """
    import numpy as np

    from labcli.core.protocol import load_protocol
    from labcli.core.store import RunFile

    with tempfile.TemporaryDirectory() as d:
        path = Path(d) / "old.h5"
        with RunFile.create(path, protocol=load_protocol("takuma2014"), imported=True) as rf:
            p0 = np.array([[0.3] * 4, [-0.05, 0.3, 0.3, 0.3]])
            rf.records.append(
                {"trial": np.array([1, 2]), "P0": p0, "P": np.full((2, 4), 0.35), "theta": np.zeros((2, 2))}
                | {"F": np.ones((2, 2))}
            )
        return path.read_bytes()


CASES: list[Case] = [
    Case(
        "model-coefficient-1e300-validate",
        "model JSON",
        "a coefficient of 1e300 (validate)",
        ["validate", "run.h5", "--model", "m.json"],
        ["The model file m.json: key 'coefficients.beta_Fx3' is 1e+300, " + BEYOND],
        files={"m.json": coefficient("beta_Fx3", 1e300)},
    ),
    Case(
        "model-coefficient-1e300-predict",
        "model JSON",
        "a coefficient of -1e300 (predict)",
        ["predict", "trials.csv", "--model", "m.json"],
        ["The model file m.json: key 'coefficients.beta_theta1_L1' is -1e+300, " + BEYOND],
        files={"m.json": coefficient("beta_theta1_L1", -1e300)},
    ),
    Case(
        "model-coefficient-1e300-sense",
        "model JSON",
        "a coefficient of 1e300 (sense)",
        ["sense", "--port", SIM, "--seconds", "1", "--jsonl", "--model", "m.json"],
        ["The model file m.json: key 'coefficients.beta_Fy4' is 1e+300, " + BEYOND],
        files={"m.json": coefficient("beta_Fy4", 1e300)},
    ),
    Case(
        "model-coefficient-infinite",
        "model JSON",
        "a coefficient written as Infinity (validate)",
        ["validate", "run.h5", "--model", "m.json"],
        [
            "The model file m.json: key 'coefficients.beta_Fx1' must be a finite number, not the number inf; refit "
            "with `labcli fit`."
        ],
        files={"m.json": coefficient("beta_Fx1", float("inf"))},
    ),
    Case(
        "run-reading-beyond-the-table",
        "run file",
        "a run holding a baseline of -0.05 MPa (export)",
        ["export", "old.h5", "-o", "out.csv"],
        [
            "old.h5: trial 2, column P_L10: -0.05 MPa is not a positive gauge pressure, which a trial table "
            "cannot hold, so the run cannot be exported; that reading is not physical: record the trial again."
        ],
        files={"old.h5": run_beyond_the_table},
    ),
]
