"""One set of bounds for what is stored and what is exported.

A rig whose readings leave the bench's physics (``sim://?leak=1e300`` drains the muscles below
vacuum) used to have its trials stored, pass ``inspect --verify`` and then be refused by
``export``.  The store now asks the exchange table's own reader
(:func:`labcli.core.tables.frame_problems`) before writing a record, so such a trial is refused
in one sentence at ``acquire``, the run keeps what came before, and the run verifies and exports.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from support.procs import labcli

from labcli.core.tables import frame_problems
from labcli.papers.takuma2014.tables import TRIAL

PLAN = "trial,set,mass_g,direction_deg\n1,fit,300,-60\n2,fit,500,30\n3,validation,400,120\n"


def test_acquire_refuses_a_trial_beyond_the_table_and_the_run_still_exports(tmp_path: Path) -> None:
    (tmp_path / "plan.csv").write_text(PLAN)
    port = "sim://?seed=1&clock=virtual&leak=1e300"
    r = labcli("acquire", "r.h5", "--port", port, "--unattended", "--plan", "plan.csv", cwd=tmp_path)
    assert "Traceback" not in r.stderr
    assert r.returncode == 1
    # The pressure is the rig's below-vacuum reading (about -0.103 MPa: all air leaked out).
    assert re.fullmatch(
        r"Error: trial 1 was not stored: column P_L10: -0\.10[0-9]+ MPa is not a positive gauge "
        r"pressure, which a trial table cannot hold \(the rig or its link is not measuring\)\.",
        r.stderr.splitlines()[-1],
    ), r.stderr
    v = labcli("inspect", "r.h5", "--verify", cwd=tmp_path)
    assert v.returncode == 0, v.stderr
    assert "0 trials" in v.stdout
    e = labcli("export", "r.h5", "-o", "out.csv", cwd=tmp_path)
    assert e.returncode == 0, e.stderr


def _trial_row(**cells: float) -> pd.DataFrame:
    row = {"trial": 1, "set": "fit", "theta1_deg": 1.0, "theta2_deg": 2.0, "Fx_N": 0.5, "Fy_N": -0.5}
    for name in ("P_L10", "P_R10", "P_L20", "P_R20", "P_L1", "P_R1", "P_L2", "P_R2"):
        row[name] = 0.3
    row.update(cells)
    return pd.DataFrame([row])


@pytest.mark.parametrize(
    ("cells", "column", "why"),
    [
        ({}, None, None),
        ({"P_L1": 1.5}, "P_L1", "1.5 MPa is outside the sensor span 0 to 1 MPa"),
        ({"P_R20": -0.01}, "P_R20", "-0.01 MPa is not a positive gauge pressure"),
        ({"Fx_N": 1e300}, "Fx_N", "1e+300 N is outside the range of a force at the tip, -1000 to 1000 N"),
        ({"theta2_deg": np.inf}, "theta2_deg", None),
    ],
)
def test_frame_problems_is_the_table_readers_verdict(cells: dict, column: str | None, why: str | None) -> None:
    problems = frame_problems(_trial_row(**cells), TRIAL)
    if column is None:
        assert problems == []
        return
    assert [(i, c) for i, c, _ in problems] == [(0, column)]
    if why is not None:
        assert problems[0][2] == why


def test_a_window_at_the_adc_rail_ends_acquire_in_one_sentence_and_stores_nothing_from_it(tmp_path: Path) -> None:
    # thermal=1e300 drives the loaded pressures of trial 1 to the sensor's top (4095 counts, 1 MPa):
    # inside every bound, but a rail, not a reading.
    (tmp_path / "plan.csv").write_text(PLAN)
    port = "sim://?seed=1&clock=virtual&thermal=1e300"
    r = labcli("acquire", "r.h5", "--port", port, "--unattended", "--plan", "plan.csv", cwd=tmp_path)
    assert "Traceback" not in r.stderr
    assert r.returncode == 1
    assert r.stderr.splitlines()[-1] == (
        f"Error: The rig on {port} sent counts at an end of its ADC's range (0 or 4095) on P_L1, P_L2 for most "
        "of a window (a sensor at its rail, not a reading) during trial 1; that trial was not stored and the 0 "
        f"completed trials in r.h5 are unchanged. Check the cable and power, then resume with: labcli acquire "
        f"r.h5 --port '{port}' --resume --unattended"
    )
    v = labcli("inspect", "r.h5", "--verify", cwd=tmp_path)
    assert v.returncode == 0, v.stderr
    assert "0 trials" in v.stdout
