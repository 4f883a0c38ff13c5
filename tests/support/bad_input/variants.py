"""Bad-input cases found by trying new variants of the campaign's families (files, values, streams,
limits, kills) as a new user would: each was a misleading outcome before it became one sentence.

A plan file holding only its header ran nothing and said "Stopped at your request" with exit 0
(trials), or ran the simulated rig's demonstration objects in its place (pushes).  A trial table
with 2200 columns of its own (a logger's every channel) was refused, after the run file was begun,
as "a run file is damaged and HDF5 cannot read part of it": their names overflow the header of the
run file's trial table.
"""

from __future__ import annotations

from pathlib import Path

from support.bad_input import PLAN_HEADER, SIM, Case

ORDER = 80

PUSH_PLAN_HEADER = "push,object,R_mm,d_mm,phi_deg,category,stiffness_N_per_m\n"


def wide_trial_table(world: Path) -> bytes:
    """The world's trial table with 2200 columns of its own (e0 ... e2199), each cell 1."""
    lines = (world / "trials.csv").read_text().splitlines()
    extra = [f"e{i}" for i in range(2200)]
    rows = [lines[0] + "," + ",".join(extra)] + [line + "," + ",".join("1" for _ in extra) for line in lines[1:]]
    return ("\n".join(rows) + "\n").encode()


CASES: list[Case] = [
    Case(
        "plan-header-only",
        "plan CSV",
        "a plan holding only its header",
        ["acquire", "new.h5", "--port", SIM, "--unattended", "--plan", "plan.csv"],
        [
            "plan.csv holds no trials, only its header; add a row per trial (trial, set, mass_g, "
            "direction_deg), or leave --plan out."
        ],
        files={"plan.csv": PLAN_HEADER.encode()},
    ),
    Case(
        "push-plan-header-only",
        "plan CSV",
        "a push plan holding only its header",
        ["acquire", "new.h5", "--port", SIM, "--unattended", "--protocol", "takuma2014-stiffness", "--plan", "pp.csv"],
        [
            "pp.csv holds no pushes, only its header; add a row per push (push, object, R_mm, d_mm, "
            "phi_deg), or leave --plan out."
        ],
        files={"pp.csv": PUSH_PLAN_HEADER.encode()},
    ),
    Case(
        "trial-table-too-wide",
        "trial CSV",
        "more columns of its own than a run file's table can name (import)",
        ["import", "wide.csv", "-o", "new.h5", "--protocol", "takuma2014"],
        [
            "wide.csv has 2200 columns labcli does not know, more than a run file's trial table can name "
            "(2106 at the longest name's 28 bytes; 60000 bytes of names in all); drop some or shorten their "
            "names, or keep them in a table beside the run."
        ],
        files={"wide.csv": wide_trial_table},
    ),
]
