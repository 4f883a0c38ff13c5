"""Bad-input cases of the exchange tables: numbers beyond any rig, half-given pairs, ranges named.

Every number read from a table is finite and inside the physical range of its quantity
(``labcli.core.bounds``); the message names the file, the row, the column, the unit and
the range.
"""

from __future__ import annotations

from support.bad_input import (
    PLAN_HEADER,
    PUSH_HEADER,
    PUSH_ROW,
    SIM,
    TABLE_HEAD,
    TRIAL_HEADER,
    Case,
    set_cell,
    trial_csv,
)

ORDER = 30

GOOD_CELLS = "0.2,0.2,0.2,0.2,0.21,0.19,0.2,0.2,1.0,2.0,0.5,-0.5"

CASES: list[Case] = [
    Case(
        "trial-force-1e308",
        "trial CSV",
        "a force of 1e308 N (fit)",
        ["fit", "bad.csv"],
        [
            "bad.csv " + TABLE_HEAD,
            "bad.csv:row 3, column Fx_N: 1e+308 N is outside the range of a force at the tip, -1000 to 1000 N.",
        ],
        files={"bad.csv": trial_csv(set_cell(3, "Fx_N", "1e308"))},
    ),
    Case(
        "trial-angle-1e308",
        "trial CSV",
        "a joint angle of 1e308 deg (import)",
        ["import", "bad.csv", "-o", "new.h5", "--protocol", "takuma2014"],
        [
            "bad.csv " + TABLE_HEAD,
            "bad.csv:row 2, column theta1_deg: 1e+308 deg is outside the range of a joint angle, -180 to 180 deg.",
        ],
        files={"bad.csv": trial_csv(set_cell(2, "theta1_deg", "1e308"))},
    ),
    Case(
        "trial-infinite-force",
        "trial CSV",
        "a force written as inf (validate)",
        ["validate", "bad.csv", "--model", "run.model.json"],
        ["bad.csv " + TABLE_HEAD, "bad.csv:row 4, column Fy_N: 'inf' is not a number."],
        files={"bad.csv": trial_csv(set_cell(4, "Fy_N", "inf"))},
    ),
    Case(
        "trial-mass-too-large",
        "trial CSV",
        "a pulley load of two tonnes (import)",
        ["import", "bad.csv", "-o", "new.h5", "--protocol", "takuma2014"],
        [
            "bad.csv " + TABLE_HEAD,
            "bad.csv:row 2, column mass_g: 2000000 g is outside the range of a load, 0 to 100000 g.",
        ],
        files={"bad.csv": (TRIAL_HEADER + ",mass_g,direction_deg\n1,fit," + GOOD_CELLS + ",2e6,90\n").encode()},
    ),
    Case(
        "trial-rest-posture-half",
        "trial CSV",
        "rest posture with one angle left empty (import)",
        ["import", "bad.csv", "-o", "new.h5", "--protocol", "takuma2014"],
        [
            "bad.csv " + TABLE_HEAD,
            "bad.csv:row 3, column theta2_0_deg: is empty but theta1_0_deg is given; give both or neither.",
        ],
        files={
            "bad.csv": (
                TRIAL_HEADER + ",theta1_0_deg,theta2_0_deg\n1,fit," + GOOD_CELLS + ",1.5,-0.5\n"
                "2,fit," + GOOD_CELLS + ",1.5,\n"
            ).encode()
        },
    ),
    Case(
        "push-radius-in-mm",
        "push CSV",
        "an object radius typed in millimetres (import)",
        ["import", "bad.csv", "-o", "new.h5", "--protocol", "takuma2014-stiffness"],
        [
            "bad.csv " + TABLE_HEAD,
            "bad.csv:row 3, column R_m: 33 m is outside the range of a length on the bench, 0 to 1 m.",
        ],
        files={"bad.csv": f"{PUSH_HEADER}\n1,{PUSH_ROW}\n2,{PUSH_ROW.replace('0.033', '33')}\n".encode()},
    ),
    Case(
        "push-direction-1e300",
        "push CSV",
        "a push direction of 1e300 deg (classify)",
        ["classify", "bad.csv", "--model", "run.model.json"],
        [
            "bad.csv " + TABLE_HEAD,
            "bad.csv:row 2, column phi_deg: 1e+300 deg is outside the range of a direction, -720 to 720 deg.",
        ],
        files={"bad.csv": f"{PUSH_HEADER}\n1,{PUSH_ROW.replace(',,', ',1e300,')}\n".encode()},
    ),
    Case(
        "plan-direction-huge",
        "plan CSV",
        "a plan direction of -5.2e11 deg",
        ["acquire", "new.h5", "--port", SIM, "--unattended", "--plan", "plan.csv"],
        [
            "plan.csv " + TABLE_HEAD,
            "plan.csv:row 3, column direction_deg: -520000000000 deg is outside the "
            "range of a direction, -720 to 720 deg.",
        ],
        files={"plan.csv": (PLAN_HEADER + "1,fit,500,-60\n2,fit,300,-5.2e11\n").encode()},
    ),
    Case(
        "point-below-vacuum",
        "point CSV",
        "an rPAM pressure below vacuum (import)",
        ["import", "bad.csv", "-o", "new.h5", "--protocol", "rpam2015", "--experiment", "stretch"],
        [
            "bad.csv " + TABLE_HEAD,
            "bad.csv:row 2, column P_A: -0.5 MPa is outside the range of a gauge pressure, -0.101325 to 1 MPa.",
        ],
        files={"bad.csv": b"point,mass_g,P_A,P_B,L_m\n1,100,-0.5,0,0.08\n"},
    ),
]
