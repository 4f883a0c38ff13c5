"""Bad-input cases of labcli 0.1: protocol files, plans, tables, run files, models, options, ports."""

from __future__ import annotations

from support.bad_input import (
    PLAN_HEADER,
    PUSH_HEADER,
    PUSH_ROW,
    SIM,
    SIM_URL_FORM,
    TABLE_HEAD,
    TRIAL_HEADER,
    Case,
    cut,
    drop_column,
    model_edit,
    other_schema,
    set_cell,
    toml_edit,
    trial_csv,
)

ORDER = 0

CASES: list[Case] = [
    # ---- protocol TOML
    Case(
        "toml-unknown-key",
        "protocol TOML",
        "unknown key",
        ["acquire", "new.h5", "--port", SIM, "--unattended", "--protocol", "p.toml"],
        [
            "p.toml: unknown key 'acquisition.rate_hzz'; the keys allowed there are rate_hz, supply_min_MPa, valves, "
            "end_valves, leak_max_kPa_per_min, hold_check_s, friction_relief_s, friction_relief_vent_s, friction_relief_vent, captures_per_load, repressurise_kPa."
        ],
        files={"p.toml": toml_edit("rate_hz = 200.0", "rate_hz = 200.0\nrate_hzz = 3")},
    ),
    Case(
        "toml-missing-key",
        "protocol TOML",
        "missing key",
        ["acquire", "new.h5", "--port", SIM, "--unattended", "--protocol", "p.toml"],
        ["p.toml: missing key 'rig.h1_m', expected a number in m."],
        files={"p.toml": toml_edit("h1_m = 0.355\n", "")},
    ),
    Case(
        "toml-wrong-type",
        "protocol TOML",
        "wrong type",
        ["acquire", "new.h5", "--port", SIM, "--unattended", "--protocol", "p.toml"],
        ["p.toml: key 'rig.h1_m' must be a number in m, not the string 'tall'."],
        files={"p.toml": toml_edit("h1_m = 0.355", 'h1_m = "tall"')},
    ),
    Case(
        "toml-bad-value",
        "protocol TOML",
        "value out of range",
        ["acquire", "new.h5", "--port", SIM, "--unattended", "--protocol", "p.toml"],
        ["p.toml: key 'rig.h1_m' must be greater than 0, not -0.355."],
        files={"p.toml": toml_edit("h1_m = 0.355", "h1_m = -0.355")},
    ),
    Case(
        "toml-syntax",
        "protocol TOML",
        "syntax error",
        ["monitor", "--port", "sim://", "--seconds", "1", "--protocol", "p.toml"],
        ["p.toml: TOML syntax error at line 34, column 14: expected newline or end of document after a statement."],
        files={"p.toml": toml_edit("h1_m = 0.355", "h1_m = 0.355 ]")},
    ),
    Case(
        "toml-not-utf8",
        "protocol TOML",
        "not UTF-8",
        ["acquire", "new.h5", "--port", SIM, "--protocol", "p.toml"],
        ["p.toml: not UTF-8 text (byte 9); save the file as UTF-8."],
        files={"p.toml": b'name = "x\xff"\n'},
    ),
    Case(
        "toml-no-such-name",
        "protocol TOML",
        "no shipped protocol of that name",
        ["import", "trials.csv", "-o", "new.h5", "--protocol", "takuma2041"],
        [
            "There is no shipped protocol named 'takuma2041'; shipped protocols are rpam2015, takuma2014, "
            "takuma2014-bent, takuma2014-stiffness, or give the path of a .toml file."
        ],
    ),
    Case(
        "toml-missing-file",
        "protocol TOML",
        "missing file",
        ["acquire", "new.h5", "--port", SIM, "--protocol", "nope.toml"],
        ["Protocol file nope.toml does not exist; check the path."],
    ),
    Case(
        "toml-wrong-kind",
        "protocol TOML",
        "force protocol given to the rPAM optimiser",
        ["optimize", "--protocol", "good.toml"],
        ["Protocol file good.toml has kind = 'force'; the rPAM model needs kind = \"rpam\"."],
    ),
    # ---- plan CSV
    Case(
        "plan-missing-column",
        "plan CSV",
        "missing column",
        ["acquire", "new.h5", "--port", SIM, "--unattended", "--plan", "plan.csv"],
        ["plan.csv " + TABLE_HEAD, "plan.csv:row 1, column mass_g: required column is missing from the header."],
        files={"plan.csv": b"trial,set,direction_deg\n1,fit,-60\n"},
    ),
    Case(
        "plan-negative-mass",
        "plan CSV",
        "negative mass",
        ["acquire", "new.h5", "--port", SIM, "--unattended", "--plan", "plan.csv"],
        ["plan.csv " + TABLE_HEAD, "plan.csv:row 3, column mass_g: -300 must be greater than 0."],
        files={"plan.csv": (PLAN_HEADER + "1,fit,500,-60\n2,fit,-300,30\n").encode()},
    ),
    Case(
        "plan-duplicate-id",
        "plan CSV",
        "duplicate trial id",
        ["acquire", "new.h5", "--port", SIM, "--unattended", "--plan", "plan.csv"],
        ["plan.csv " + TABLE_HEAD, "plan.csv:row 3, column trial: trial 1 is already used on row 2."],
        files={"plan.csv": (PLAN_HEADER + "1,fit,500,-60\n1,fit,300,30\n").encode()},
    ),
    Case(
        "plan-non-numeric",
        "plan CSV",
        "non-numeric mass",
        ["acquire", "new.h5", "--port", SIM, "--unattended", "--plan", "plan.csv"],
        ["plan.csv " + TABLE_HEAD, "plan.csv:row 3, column mass_g: 'heavy' is not a number."],
        files={"plan.csv": (PLAN_HEADER + "1,fit,500,-60\n2,fit,heavy,30\n").encode()},
    ),
    Case(
        "plan-beyond-limits",
        "plan CSV",
        "mass beyond the protocol's limits",
        ["acquire", "new.h5", "--port", SIM, "--unattended", "--plan", "plan.csv"],
        [
            "plan.csv " + TABLE_HEAD,
            "plan.csv:row 2, column mass_g: 5000 g is outside the protocol's range 1 to 2000 g.",
        ],
        files={"plan.csv": (PLAN_HEADER + "1,fit,5000,-60\n").encode()},
    ),
    Case(
        "plan-bad-set",
        "plan CSV",
        "set neither fit nor validation",
        ["acquire", "new.h5", "--port", SIM, "--unattended", "--plan", "plan.csv"],
        ["plan.csv " + TABLE_HEAD, "plan.csv:row 2, column set: 'train' must be fit or validation."],
        files={"plan.csv": (PLAN_HEADER + "1,train,500,-60\n").encode()},
    ),
    Case(
        "plan-missing-file",
        "plan CSV",
        "missing file",
        ["acquire", "new.h5", "--port", SIM, "--unattended", "--plan", "nope.csv"],
        ["nope.csv does not exist; check the path."],
    ),
    # ---- trial CSV
    Case(
        "trial-bad-cell",
        "trial CSV",
        "text in a pressure cell (import)",
        ["import", "bad.csv", "-o", "new.h5", "--protocol", "takuma2014"],
        ["bad.csv " + TABLE_HEAD, "bad.csv:row 3, column P_R1: 'abc' is not a number."],
        files={"bad.csv": trial_csv(set_cell(3, "P_R1", "abc"))},
    ),
    Case(
        "trial-missing-column",
        "trial CSV",
        "missing column (import)",
        ["import", "bad.csv", "-o", "new.h5", "--protocol", "takuma2014"],
        ["bad.csv " + TABLE_HEAD, "bad.csv:row 1, column theta2_deg: required column is missing from the header."],
        files={"bad.csv": trial_csv(drop_column("theta2_deg"))},
    ),
    Case(
        "trial-beyond-span",
        "trial CSV",
        "pressure beyond the sensor span (fit)",
        ["fit", "bad.csv"],
        ["bad.csv " + TABLE_HEAD, "bad.csv:row 4, column P_L1: 1.5 MPa is outside the sensor span 0 to 1 MPa."],
        files={"bad.csv": trial_csv(set_cell(4, "P_L1", "1.5"))},
    ),
    Case(
        "trial-not-utf8",
        "trial CSV",
        "binary file given as a table (import)",
        ["import", "acq.h5", "-o", "new.h5", "--protocol", "takuma2014"],
        ["acq.h5 is not UTF-8 text (bad byte at offset 0); save it as CSV UTF-8."],
    ),
    Case(
        "trial-push-protocol",
        "trial CSV",
        "trial CSV fitted under a push protocol",
        ["fit", "trials.csv", "--protocol", "takuma2014-stiffness"],
        [
            "--protocol takuma2014-stiffness is of kind 'push'; a trial CSV is read with a force protocol "
            "such as takuma2014."
        ],
    ),
    Case(
        "trial-output-exists",
        "trial CSV",
        "import onto an existing run without --force",
        ["import", "trials.csv", "-o", "run.h5", "--protocol", "takuma2014"],
        ["run.h5 already exists; use --force to overwrite it."],
    ),
    Case(
        "trial-rpam-protocol",
        "trial CSV",
        "trial CSV imported under the rPAM protocol",
        ["import", "trials.csv", "-o", "new.h5", "--protocol", "rpam2015"],
        [
            "rpam2015 is a protocol of kind 'rpam' with two experiments; labcli import reads its point tables "
            "with --experiment stretch (the stretch test) or --experiment joint (the joint map), and trial tables "
            "with a force protocol such as takuma2014."
        ],
    ),
    Case(
        "trial-rpam-experiment",
        "trial CSV",
        "trial CSV imported as an rPAM stretch test",
        ["import", "trials.csv", "-o", "new.h5", "--protocol", "rpam2015", "--experiment", "stretch"],
        [
            "trials.csv has 5 problems (rows counted as a spreadsheet shows them, the header included):",
            "trials.csv:row 1, column point: required column is missing from the header.",
            "trials.csv:row 1, column mass_g: required column is missing from the header.",
            "trials.csv:row 1, column P_A: required column is missing from the header.",
            "trials.csv:row 1, column P_B: required column is missing from the header.",
            "trials.csv:row 1, column L_m: required column is missing from the header.",
        ],
    ),
    Case(
        "trial-nul-in-extra",
        "trial CSV",
        "NUL character in an extra text column (import)",
        ["import", "bad.csv", "-o", "new.h5", "--protocol", "takuma2014"],
        [
            "bad.csv " + TABLE_HEAD,
            "bad.csv:row 2, column note: holds a NUL character, which a run file cannot store; remove it.",
        ],
        files={
            "bad.csv": (TRIAL_HEADER + ",note\n1,fit," + ",".join(["0.2"] * 8) + ",1.0,2.0,0.5,-0.5,a\x00b\n").encode()
        },
    ),
    Case(
        "trial-id-out-of-range",
        "trial CSV",
        "trial id a run file cannot hold (import)",
        ["import", "bad.csv", "-o", "new.h5", "--protocol", "takuma2014"],
        [
            "bad.csv " + TABLE_HEAD,
            "bad.csv:row 2, column trial: 1000000 is outside the trial ids a run file holds, 0 to 999999.",
        ],
        files={"bad.csv": (TRIAL_HEADER + "\n1000000,fit," + ",".join(["0.2"] * 8) + ",1.0,2.0,0.5,-0.5\n").encode()},
    ),
    # ---- push CSV
    Case(
        "push-bad-cell",
        "push CSV",
        "negative radius (import)",
        ["import", "bad.csv", "-o", "new.h5", "--protocol", "takuma2014-stiffness"],
        ["bad.csv " + TABLE_HEAD, "bad.csv:row 3, column R_m: -0.033 must be greater than 0."],
        files={"bad.csv": f"{PUSH_HEADER}\n1,{PUSH_ROW}\n2,{PUSH_ROW.replace('0.033', '-0.033')}\n".encode()},
    ),
    Case(
        "push-missing-column",
        "push CSV",
        "missing column (import)",
        ["import", "bad.csv", "-o", "new.h5", "--protocol", "takuma2014-stiffness"],
        ["bad.csv " + TABLE_HEAD, "bad.csv:row 1, column object: required column is missing from the header."],
        files={
            "bad.csv": (PUSH_HEADER.replace(",object", "") + "\n1," + PUSH_ROW.replace("pet-1,", "") + "\n").encode()
        },
    ),
    Case(
        "push-bad-cell-classify",
        "push CSV",
        "bad phi (classify)",
        ["classify", "bad.csv", "--model", "run.model.json"],
        ["bad.csv " + TABLE_HEAD, "bad.csv:row 2, column phi_deg: 'north' is not a number."],
        files={"bad.csv": f"{PUSH_HEADER}\n1,{PUSH_ROW.replace(',,', ',north,')}\n".encode()},
    ),
    # ---- HDF5 files
    Case(
        "h5-other-schema",
        "HDF5 file",
        "HDF5 file of another schema (inspect)",
        ["inspect", "other.h5"],
        ["other.h5 is an HDF5 file but not a labcli run file (no schema attribute, expected 'labcli-run')."],
        files={"other.h5": other_schema},
    ),
    Case(
        "h5-other-schema-fit",
        "HDF5 file",
        "HDF5 file of another schema (fit)",
        ["fit", "other.h5"],
        ["other.h5 is an HDF5 file but not a labcli run file (no schema attribute, expected 'labcli-run')."],
        files={"other.h5": other_schema},
    ),
    Case(
        "h5-truncated-export",
        "HDF5 file",
        "acquired run cut to half its length (export)",
        ["export", "cut.h5", "-o", "out.csv"],
        ["cut.h5 is damaged or truncated and HDF5 cannot open it; use a backup copy."],
        files={"cut.h5": cut("acq.h5", 0.5)},
    ),
    Case(
        "h5-truncated-fit",
        "HDF5 file",
        "acquired run missing its last bytes (fit)",
        ["fit", "cut.h5"],
        ["cut.h5 is damaged or truncated and HDF5 cannot open it; use a backup copy."],
        files={"cut.h5": cut("acq.h5", 0.99)},
    ),
    Case(
        "h5-truncated-resume",
        "HDF5 file",
        "acquired run cut short (acquire --resume)",
        ["acquire", "cut.h5", "--port", SIM, "--resume"],
        ["cut.h5 is damaged or truncated and HDF5 cannot open it; use a backup copy."],
        files={"cut.h5": cut("acq.h5", 0.75)},
    ),
    Case(
        "h5-text",
        "HDF5 file",
        "text file named .h5 (split)",
        ["split", "text.h5", "--fit", "2"],
        ["text.h5 is not an HDF5 file; run files are written by 'labcli acquire' or 'labcli import'."],
        files={"text.h5": b"trial,set\n1,fit\n"},
    ),
    Case(
        "h5-missing-inspect",
        "HDF5 file",
        "missing file (inspect)",
        ["inspect", "missing.h5"],
        ["missing.h5 does not exist; check the path."],
    ),
    Case(
        "h5-missing-validate",
        "HDF5 file",
        "missing file (validate)",
        ["validate", "missing.h5", "--model", "run.model.json"],
        ["missing.h5 does not exist; pass a run file (.h5) or a trial CSV."],
    ),
    Case(
        "h5-push-run-fit",
        "HDF5 file",
        "push run given to fit",
        ["fit", "push.h5"],
        [
            "push.h5 is a run of kind 'push' (protocol 'takuma2014-stiffness'), not a force run; fit and "
            "validate read the trials of a force run such as one recorded with protocol takuma2014."
        ],
    ),
    Case(
        "h5-force-run-classify",
        "HDF5 file",
        "force run given to classify",
        ["classify", "acq.h5", "--model", "run.model.json"],
        [
            "acq.h5 is a force run (protocol 'takuma2014'), not a push run; classify reads the pushes of a "
            "stiffness run such as one recorded with protocol takuma2014-stiffness."
        ],
    ),
    Case(
        "h5-no-fit-trials",
        "HDF5 file",
        "relative run name in a model message",
        ["fit", "unsplit.h5"],
        [
            "unsplit.h5 has no fit trials (no row with set = 'fit'); assign trials with `labcli split` (or "
            "fill the `set` column)."
        ],
        files={"unsplit.csv": trial_csv(lambda h, rows: (h, [r[:1] + [""] + r[2:] for r in rows]))},
    ),
    # ---- model JSON
    Case(
        "model-other-protocol",
        "model JSON",
        "model of another protocol",
        ["validate", "run.h5", "--model", "m.json"],
        [
            "The model file m.json was fitted for protocol 'rpam2015' but run.h5 uses protocol 'takuma2014'; "
            "fit a model on a run of this protocol."
        ],
        files={"m.json": model_edit(lambda d: d.update(protocol="rpam2015"))},
    ),
    Case(
        "model-other-geometry",
        "model JSON",
        "model of another rig geometry",
        ["validate", "run.h5", "--model", "m.json"],
        ["The model file m.json was fitted for h1 = 0.4 m but run.h5 has h1 = 0.355 m; fit a model for this rig."],
        files={"m.json": model_edit(lambda d: d["geometry"].update(h1=0.4))},
    ),
    Case(
        "model-malformed",
        "model JSON",
        "malformed JSON (cut short)",
        ["validate", "run.h5", "--model", "m.json"],
        ["The model file m.json is not valid JSON (line 12, column 22: Unterminated string starting at)."],
        files={"m.json": cut("run.model.json", 0.03)},
    ),
    Case(
        "model-not-a-model",
        "model JSON",
        "JSON that is not a model",
        ["validate", "run.h5", "--model", "m.json"],
        [
            "The model file m.json is not a labcli Takuma model (schema None, expected 'labcli-takuma-model'); "
            "pass a file written by `labcli fit`."
        ],
        files={"m.json": b'{"hello": 1}'},
    ),
    Case(
        "model-list",
        "model JSON",
        "JSON list instead of a model",
        ["validate", "run.h5", "--model", "m.json"],
        [
            "The model file m.json is not a labcli Takuma model (it holds a list, not an object with schema "
            "'labcli-takuma-model'); pass a file written by `labcli fit`."
        ],
        files={"m.json": b"[1, 2, 3]"},
    ),
    Case(
        "model-text-coefficient",
        "model JSON",
        "coefficient that is text",
        ["validate", "run.h5", "--model", "m.json"],
        [
            "The model file m.json: key 'coefficients.beta_Fx1' must be a finite number, not the string 'big'; "
            "refit with `labcli fit`."
        ],
        files={"m.json": model_edit(lambda d: d["coefficients"].update(beta_Fx1="big"))},
    ),
    Case(
        "model-coefficients-list",
        "model JSON",
        "coefficients as a list (classify)",
        ["classify", "push.h5", "--model", "m.json"],
        ["The model file m.json: key 'coefficients' must be an object, not a list; refit with `labcli fit`."],
        files={"m.json": model_edit(lambda d: d.update(coefficients=[1.0]))},
    ),
    Case(
        "model-missing-key",
        "model JSON",
        "model without its geometry",
        ["validate", "run.h5", "--model", "m.json"],
        ["The model file m.json lacks the key 'geometry'; refit with `labcli fit`."],
        files={"m.json": model_edit(lambda d: d.pop("geometry") and None)},
    ),
    Case(
        "model-not-utf8",
        "model JSON",
        "binary file as the model",
        ["validate", "run.h5", "--model", "acq.h5"],
        ["The model file acq.h5 is not UTF-8 text (bad byte at offset 0); pass the .json file `labcli fit` wrote."],
    ),
    Case(
        "model-missing",
        "model JSON",
        "missing model file",
        ["validate", "run.h5", "--model", "nope.json"],
        ["The model file nope.json does not exist; write one with `labcli fit`."],
    ),
    # ---- CLI arguments
    Case(
        "arg-fit-too-large",
        "CLI argument",
        "--fit larger than the trials",
        ["split", "acq.h5", "--fit", "10", "--validation", "1"],
        ["acq.h5: the run has 3 completed trials, fewer than the 11 asked for (10 fit + 1 validation)."],
    ),
    Case(
        "arg-fit-negative",
        "CLI argument",
        "negative --fit",
        ["split", "acq.h5", "--fit", "-1"],
        ["acq.h5: the fit set needs at least 1 trial and the validation set 0 or more, got -1 and 18."],
    ),
    Case(
        "arg-negative-seconds",
        "CLI argument",
        "negative --seconds",
        ["monitor", "--port", "sim://", "--seconds", "-1"],
        ["Invalid value for '--seconds': -1.0 is not in the range x>0."],
        code=2,
        usage="monitor [OPTIONS]",
    ),
    Case(
        "arg-bad-mode",
        "CLI argument",
        "bad --mode",
        ["validate", "run.h5", "--mode", "sideways"],
        ["Invalid value for '--mode': 'sideways' is not one of 'pressure-only', 'measured-angles'."],
        code=2,
        usage="validate [OPTIONS] RUN",
    ),
    Case(
        "arg-optimize-unknown-key",
        "CLI argument",
        "unknown --set key (optimize)",
        ["optimize", "--set", "actuator.L0_mm=0.08"],
        [
            "Unknown protocol key 'actuator.L0_mm' in --set; keys under actuator: A0_m2, L0_m, force_reading, "
            "n_turns, prestretch, thread_length_m."
        ],
    ),
    Case(
        "arg-optimize-bad-value",
        "CLI argument",
        "negative length by --set (optimize)",
        ["optimize", "--set", "actuator.L0_m=-1"],
        ["Protocol rpam2015 with --set actuator.L0_m=-1: key 'actuator.L0_m' must be greater than 0, not -1.0."],
    ),
    Case(
        "arg-optimize-negative-pa",
        "CLI argument",
        "negative --pa (optimize)",
        ["optimize", "--pa", "-5"],
        ["Invalid value for '--pa': -5 is not a gauge pressure; give 0 kPa or more."],
        code=2,
        usage="optimize [OPTIONS]",
    ),
    Case(
        "arg-max-amplification",
        "CLI argument",
        "--max-amplification below 1 (fit)",
        ["fit", "run.h5", "--max-amplification", "0.5"],
        ["Invalid value for '--max-amplification': 0.5 is not in the range x>1."],
        code=2,
        usage="fit [OPTIONS] RUN",
    ),
    Case(
        "arg-rate-zero",
        "CLI argument",
        "--rate 0 (acquire)",
        ["acquire", "new.h5", "--port", SIM, "--rate", "0"],
        ["Invalid value for '--rate': 0.0 is not in the range x>0."],
        code=2,
        usage="acquire [OPTIONS] RUN.h5",
    ),
    Case(
        "arg-rate-refused",
        "CLI argument",
        "--rate the firmware refuses (acquire)",
        ["acquire", "new.h5", "--port", SIM, "--unattended", "--plan", "plan3.csv", "--rate", "1e9"],
        [
            f"The device on {SIM} refused RATE 1000000000: 'ERR RATE must be within 1..50000 Hz, got 1000000000'. "
            "Check the values its firmware accepts for that command."
        ],
    ),
    Case(
        "arg-resume-and-force",
        "CLI argument",
        "--resume with --force (acquire)",
        ["acquire", "acq.h5", "--port", SIM, "--resume", "--force"],
        ["--resume continues a run and --force overwrites it: give one of them, not both."],
    ),
    # ---- ports and run files of acquire
    Case(
        "port-no-such-device",
        "port",
        "/dev/ttyNOPE (monitor)",
        ["monitor", "--port", "/dev/ttyNOPE", "--seconds", "1"],
        ["Cannot open serial port /dev/ttyNOPE: no such device. Check the cable and run `labcli ports` to list ports."],
    ),
    Case(
        "port-com99",
        "port",
        "COM99 (acquire)",
        ["acquire", "new.h5", "--port", "COM99"],
        ["Cannot open serial port COM99: no such device. Check the cable and run `labcli ports` to list ports."],
    ),
    Case(
        "port-sim-unknown-option",
        "port",
        "sim:// URL with an unknown option (acquire)",
        ["acquire", "new.h5", "--port", "sim://?foo=1"],
        [
            f"Cannot open serial port sim://?foo=1: unknown option 'foo' in sim:// URL; expected {SIM_URL_FORM}. "
            "Check the URL's options."
        ],
    ),
    Case(
        "port-sim-unknown-option-monitor",
        "port",
        "sim:// URL with an unknown option (monitor)",
        ["monitor", "--port", "sim://?sed=1", "--seconds", "1"],
        [
            f"Cannot open serial port sim://?sed=1: unknown option 'sed' in sim:// URL; expected {SIM_URL_FORM}. "
            "Check the URL's options."
        ],
    ),
    Case(
        "port-unknown-scheme",
        "port",
        "unknown URL scheme (monitor)",
        ["monitor", "--port", "bogus://x", "--seconds", "1"],
        [
            "Cannot open serial port bogus://x: unknown URL scheme 'bogus://'. Use a port name such as "
            "/dev/ttyUSB0 or COM3, or sim:// for the simulated rig."
        ],
    ),
    Case(
        "acquire-exists",
        "run file",
        "acquire onto an existing file without --force",
        ["acquire", "acq.h5", "--port", SIM, "--unattended", "--plan", "plan3.csv"],
        ["acq.h5 already exists; continue it with --resume, or pass --force to overwrite it."],
    ),
    Case(
        "acquire-unattended-real-port",
        "run file",
        "--unattended on a real port (pty)",
        ["acquire", "new.h5", "--port", "PTY", "--unattended", "--plan", "plan3.csv"],
        [
            "--unattended drives the simulated rig only, and PTY is a real port: run without --unattended and "
            "follow the prompts."
        ],
        pty=True,
    ),
    Case(
        "acquire-resume-missing",
        "run file",
        "--resume on a missing file",
        ["acquire", "missing.h5", "--port", SIM, "--resume"],
        ["missing.h5 does not exist; check the path."],
    ),
    Case(
        "acquire-resume-csv",
        "run file",
        "--resume on a CSV",
        ["acquire", "trials.csv", "--port", SIM, "--resume"],
        ["trials.csv is not an HDF5 file; run files are written by 'labcli acquire' or 'labcli import'."],
    ),
    Case(
        "acquire-no-folder",
        "run file",
        "run file in a folder that does not exist",
        ["acquire", "nodir/new.h5", "--port", SIM, "--unattended", "--plan", "plan3.csv"],
        ["cannot create nodir/new.h5: the directory {world}/nodir does not exist."],
    ),
    Case(
        "acquire-resume-imported-unattended",
        "run file",
        "--resume --unattended on an imported run (no plan)",
        ["acquire", "run.h5", "--port", SIM, "--resume", "--unattended"],
        [
            "run.h5 has no plan (it was imported from a table), so --unattended has nothing to follow; resume it "
            "without --unattended and type each load."
        ],
    ),
]
