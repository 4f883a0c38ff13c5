"""Bad-input cases found by trying new variants of the campaign's families (files, values, streams,
limits, kills) as a new user would: each was a misleading outcome before it became one sentence.

A plan file holding only its header ran nothing and said "Stopped at your request" with exit 0
(trials), or ran the simulated rig's demonstration objects in its place (pushes).
"""

from __future__ import annotations

from support.bad_input import PLAN_HEADER, SIM, Case

ORDER = 80

PUSH_PLAN_HEADER = "push,object,R_mm,d_mm,phi_deg,category,stiffness_N_per_m\n"

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
]
