"""Bad-input cases of the session at the rig: standard input, option values, protocol bounds, rigs that misbehave.

The rigs that misbehave are :class:`support.firmware.FakeFirmware` on a pseudo-terminal
(``PTY`` in the arguments), named as the protocol's rig where the case must reach the
stream, or the simulated rig with an option that leaves it without a supply.
"""

from __future__ import annotations

from support.bad_input import SIM, Case, toml_edit

ORDER = 10

ACQUIRE_P = ["acquire", "new.h5", "--port", SIM, "--unattended", "--protocol", "p.toml"]
RIG = "mckibben-2dof"  # the device takuma2014 expects


def _rad_unit(world) -> bytes:
    text = (world / "good.toml").read_text()
    i = text.index('unit = "deg"')  # the first angle channel, POT1
    return (text[:i] + 'unit = "rad"' + text[i + len('unit = "deg"') :]).encode()


CASES: list[Case] = [
    # ---- standard input
    Case(
        "stdin-eof",
        "standard input",
        "input ends at the first prompt (`</dev/null`; a 1.0 board: the air supply's)",
        ["acquire", "new.h5", "--port", SIM + "&fw=1.0"],
        [
            "No input (standard input ended) during the setup, before anything was written to new.h5; run the "
            "command where someone at the rig can answer its prompts."
        ],
    ),
    Case(
        "stdin-dev-zero",
        "standard input",
        "input that floods bytes with no line end (`</dev/zero`; a 1.0 board: the air supply's)",
        ["acquire", "new.h5", "--port", SIM + "&fw=1.0"],
        [
            "No input (standard input sent more than 4096 characters with no line end, as a device such as "
            "/dev/zero does) during the setup, before anything was written to new.h5; run the command where "
            "someone at the rig can answer its prompts."
        ],
        stdin="/dev/zero",
        timeout=60,
    ),
    # ---- option values
    Case(
        "option-nan-seconds",
        "CLI argument",
        "NaN duration (monitor)",
        ["monitor", "--port", "sim://", "--seconds", "nan"],
        ["Invalid value for '--seconds': 'nan' is not a finite number."],
        code=2,
        usage="monitor [OPTIONS]",
    ),
    Case(
        "option-inf-rate",
        "CLI argument",
        "infinite rate (acquire)",
        ["acquire", "new.h5", "--port", SIM, "--unattended", "--rate", "inf"],
        ["Invalid value for '--rate': 'inf' is not a finite number."],
        code=2,
        usage="acquire [OPTIONS] RUN.h5",
    ),
    # ---- protocol bounds and loader limits
    Case(
        "toml-capture-unbounded",
        "protocol TOML",
        "capture window of 1e9 s",
        ACQUIRE_P,
        ["p.toml: key 'settling.capture_s' must be at most 60 s, not 1000000000.0."],
        files={"p.toml": toml_edit("capture_s = 1.0", "capture_s = 1e9")},
    ),
    Case(
        "toml-400-digits",
        "protocol TOML",
        "a 400-digit number",
        ACQUIRE_P,
        ["p.toml: key 'rig.h1_m' holds an integer of 400 digits; TOML integers are 64-bit (at most 19 digits)."],
        files={"p.toml": toml_edit("h1_m = 0.355", "h1_m = " + "9" * 400)},
    ),
    Case(
        "toml-deep-arrays",
        "protocol TOML",
        "arrays nested 5,000 deep",
        ACQUIRE_P,
        ["p.toml: arrays or tables nested thousands of levels deep; a protocol file nests at most 16 levels."],
        files={
            "p.toml": toml_edit(
                'plan = "takuma2014-plan.csv"', 'plan = "takuma2014-plan.csv"\ndeep = ' + "[" * 5000 + "]" * 5000
            )
        },
    ),
    Case(
        "toml-plan-folder",
        "protocol TOML",
        'trials.plan names a folder (".")',
        ACQUIRE_P,
        [
            "p.toml: key 'trials.plan' names ., a folder, not a plan file; give the name of the plan CSV "
            "(e.g. takuma2014-plan.csv)."
        ],
        files={"p.toml": toml_edit('plan = "takuma2014-plan.csv"', 'plan = "."')},
    ),
    Case(
        "toml-angle-in-rad",
        "protocol TOML",
        "angle channel unit rad on a calibration in degrees",
        ACQUIRE_P,
        [
            "p.toml: key 'channels.POT1.unit' is rad, but its range -5156.62 to 5156.62 deg goes beyond "
            "a full turn; check the unit (deg or rad)."
        ],
        files={"p.toml": _rad_unit},
    ),
    # ---- rigs that misbehave
    Case(
        "rig-no-supply",
        "rig",
        "no air supply (`sim://?supply=0`): refused before any trial",
        ["acquire", "new.h5", "--port", SIM + "&supply=0", "--unattended"],
        [
            "After the air supply P_L1 reads -0.002 MPa, P_R1 reads -0.001 MPa, P_L2 reads 0.002 MPa, P_R2 reads "
            "0.003 MPa, below the 0.1 MPa the protocol asks for (acquisition.supply_min_MPa): check the compressor, "
            "the regulator and that the valves are open; nothing was written to new.h5."
        ],
    ),
    Case(
        "rig-repeated-channel",
        "rig",
        "a channel named twice in the ID reply (monitor)",
        ["monitor", "--port", "PTY", "--seconds", "1"],
        [
            "The device on PTY names channel P_L1 more than once in its ID line "
            "('ID,fake-rig,0.9,P_L1,P_L1,P_L2,P_R2,POT1,POT2'), so its values cannot be told apart. Check that its "
            "firmware gives each channel its own name."
        ],
        firmware={"channels": ("P_L1", "P_L1", "P_L2", "P_R2", "POT1", "POT2")},
    ),
    Case(
        "rig-clock-back",
        "rig",
        "timestamps that run backwards (a board reset mid-stream)",
        ["acquire", "new.h5", "--port", "PTY"],
        [
            "The rig on PTY sent a timestamp that does not follow the one before (t_us 0 after 245000), as a clock "
            "that went back or a board that restarted does during the setup, before anything was written to new.h5. "
            "Check the cable and power, then run the same command again."
        ],
        firmware={"device": RIG, "clock_back_at": 50},
    ),
]
