"""Bad input at every entry point: one clear sentence, a non-zero exit, no traceback, no file changed.

Each case runs the installed ``labcli`` in a subprocess, in a fresh copy of a small world of
files (a trial CSV, an imported run with its model, a run acquired from the simulated rig, a
push table, protocol and plan files, HDF5 files of another schema or cut short), with the case's
own bad file added.  Every file in the folder is hashed before and after: a failing command may
not create, change or delete anything, the run file a failing ``fit`` would record into included.

The expected messages are exact.  ``labcli`` prints one ``Error: ...`` line; a table with one
bad cell prints the count of problems, then the problem naming file, row and column; a bad
option is reported by click after its usage lines.

``python tests/cli/test_bad_input.py`` prints the table of cases as Markdown (for the README).
"""

from __future__ import annotations

import hashlib
import json
import os
import shutil
import subprocess
import sys
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

import pytest

SIM = "sim://?seed=1&clock=virtual"
PROTOCOLS = Path(__file__).resolve().parents[2] / "protocols"
TRIAL_HEADER = "trial,set,P_L10,P_R10,P_L20,P_R20,P_L1,P_R1,P_L2,P_R2,theta1_deg,theta2_deg,Fx_N,Fy_N"
PUSH_HEADER = "push,object,R_m,d_m,phi_deg,P_L10,P_R10,P_L20,P_R20,P_L1,P_R1,P_L2,P_R2,category"
PUSH_ROW = "pet-1,0.033,0.01,,0.2,0.2,0.2,0.2,0.21,0.19,0.2,0.2,soft"
TABLE_HEAD = "has 1 problem (rows counted as a spreadsheet shows them, the header included):"
SIM_URL_FORM = ("sim://[?seed=N][&rate=HZ][&noise=X][&drift=X][&clock=virtual|wall][&tau=S]"
                "[&mode=mckibben|rpam][&faults=KIND:RATE[@X],...]")


# --------------------------------------------------------------------------- the cases


@dataclass
class Case:
    id: str
    entry: str                      # which kind of input is bad
    what: str                       # the case, in words, for the table
    args: list[str]                 # labcli arguments
    error: list[str]                # the exact error lines (first one without "Error: ")
    code: int = 1
    files: dict[str, bytes | Callable[[Path], bytes]] = field(default_factory=dict)
    usage: str | None = None        # click usage line when click itself refuses an option
    pty: bool = False               # serve the simulated rig on a pseudo-terminal; PTY in args is its path
    xfail: str | None = None        # a bug in a module still being edited (see the report)


def _toml(old: str, new: str) -> Callable[[Path], bytes]:
    def make(world: Path) -> bytes:
        text = (world / "good.toml").read_text()
        assert old in text
        return text.replace(old, new, 1).encode()
    return make


def _trial_csv(edit: Callable[[list[str], list[list[str]]], tuple[list[str], list[list[str]]]]) -> Callable[[Path], bytes]:
    def make(world: Path) -> bytes:
        lines = (world / "trials.csv").read_text().splitlines()
        header, rows = edit(lines[0].split(","), [r.split(",") for r in lines[1:6]])
        return ("\n".join(",".join(r) for r in [header, *rows]) + "\n").encode()
    return make


def _set_cell(row: int, column: str, value: str):
    def edit(header, rows):
        rows[row - 2][header.index(column)] = value  # spreadsheet row numbers: header is row 1
        return header, rows
    return edit


def _drop_column(column: str):
    def edit(header, rows):
        j = header.index(column)
        return header[:j] + header[j + 1:], [r[:j] + r[j + 1:] for r in rows]
    return edit


def _model(edit: Callable[[dict], object]) -> Callable[[Path], bytes]:
    def make(world: Path) -> bytes:
        d = json.loads((world / "run.model.json").read_text())
        out = edit(d)
        return json.dumps(d if out is None else out).encode()
    return make


def _cut(name: str, fraction: float) -> Callable[[Path], bytes]:
    def make(world: Path) -> bytes:
        data = (world / name).read_bytes()
        return data[: int(len(data) * fraction)]
    return make


def _other_schema(world: Path) -> bytes:
    import h5py
    import numpy as np

    tmp = world / ".other.h5"
    with h5py.File(tmp, "w") as f:
        f["data"] = np.arange(10.0)
        f.attrs["creator"] = "another program"
    data = tmp.read_bytes()
    tmp.unlink()
    return data


PLAN_HEADER = "trial,set,mass_g,direction_deg\n"

CASES: list[Case] = [
    # ---- protocol TOML
    Case("toml-unknown-key", "protocol TOML", "unknown key",
         ["acquire", "new.h5", "--port", SIM, "--unattended", "--protocol", "p.toml"],
         ["p.toml: unknown key 'acquisition.rate_hzz'; the keys allowed there are rate_hz."],
         files={"p.toml": _toml("rate_hz = 200.0", "rate_hz = 200.0\nrate_hzz = 3")}),
    Case("toml-missing-key", "protocol TOML", "missing key",
         ["acquire", "new.h5", "--port", SIM, "--unattended", "--protocol", "p.toml"],
         ["p.toml: missing key 'rig.h1_m', expected a number in m."],
         files={"p.toml": _toml("h1_m = 0.355\n", "")}),
    Case("toml-wrong-type", "protocol TOML", "wrong type",
         ["acquire", "new.h5", "--port", SIM, "--unattended", "--protocol", "p.toml"],
         ["p.toml: key 'rig.h1_m' must be a number in m, not the string 'tall'."],
         files={"p.toml": _toml("h1_m = 0.355", 'h1_m = "tall"')}),
    Case("toml-bad-value", "protocol TOML", "value out of range",
         ["acquire", "new.h5", "--port", SIM, "--unattended", "--protocol", "p.toml"],
         ["p.toml: key 'rig.h1_m' must be greater than 0, not -0.355."],
         files={"p.toml": _toml("h1_m = 0.355", "h1_m = -0.355")}),
    Case("toml-syntax", "protocol TOML", "syntax error",
         ["monitor", "--port", "sim://", "--seconds", "1", "--protocol", "p.toml"],
         ["p.toml: TOML syntax error at line 34, column 14: expected newline or end of document after a statement."],
         files={"p.toml": _toml("h1_m = 0.355", "h1_m = 0.355 ]")}),
    Case("toml-not-utf8", "protocol TOML", "not UTF-8",
         ["acquire", "new.h5", "--port", SIM, "--protocol", "p.toml"],
         ["p.toml: not UTF-8 text (byte 9); save the file as UTF-8."],
         files={"p.toml": b'name = "x\xff"\n'}),
    Case("toml-no-such-name", "protocol TOML", "no shipped protocol of that name",
         ["import", "trials.csv", "-o", "new.h5", "--protocol", "takuma2041"],
         ["There is no shipped protocol named 'takuma2041'; shipped protocols are rpam2015, takuma2014, "
          "takuma2014-stiffness, or give the path of a .toml file."]),
    Case("toml-missing-file", "protocol TOML", "missing file",
         ["acquire", "new.h5", "--port", SIM, "--protocol", "nope.toml"],
         ["Protocol file nope.toml does not exist; check the path."]),
    Case("toml-wrong-kind", "protocol TOML", "force protocol given to the rPAM optimiser",
         ["optimize", "--protocol", "good.toml"],
         ["Protocol file good.toml has kind = 'force'; the rPAM model needs kind = \"rpam\"."]),
    # ---- plan CSV
    Case("plan-missing-column", "plan CSV", "missing column",
         ["acquire", "new.h5", "--port", SIM, "--unattended", "--plan", "plan.csv"],
         ["plan.csv " + TABLE_HEAD, "plan.csv:row 1, column mass_g: required column is missing from the header."],
         files={"plan.csv": b"trial,set,direction_deg\n1,fit,-60\n"}),
    Case("plan-negative-mass", "plan CSV", "negative mass",
         ["acquire", "new.h5", "--port", SIM, "--unattended", "--plan", "plan.csv"],
         ["plan.csv " + TABLE_HEAD, "plan.csv:row 3, column mass_g: -300 must be greater than 0."],
         files={"plan.csv": (PLAN_HEADER + "1,fit,500,-60\n2,fit,-300,30\n").encode()}),
    Case("plan-duplicate-id", "plan CSV", "duplicate trial id",
         ["acquire", "new.h5", "--port", SIM, "--unattended", "--plan", "plan.csv"],
         ["plan.csv " + TABLE_HEAD, "plan.csv:row 3, column trial: trial 1 is already used on row 2."],
         files={"plan.csv": (PLAN_HEADER + "1,fit,500,-60\n1,fit,300,30\n").encode()}),
    Case("plan-non-numeric", "plan CSV", "non-numeric mass",
         ["acquire", "new.h5", "--port", SIM, "--unattended", "--plan", "plan.csv"],
         ["plan.csv " + TABLE_HEAD, "plan.csv:row 3, column mass_g: 'heavy' is not a number."],
         files={"plan.csv": (PLAN_HEADER + "1,fit,500,-60\n2,fit,heavy,30\n").encode()}),
    Case("plan-beyond-limits", "plan CSV", "mass beyond the protocol's limits",
         ["acquire", "new.h5", "--port", SIM, "--unattended", "--plan", "plan.csv"],
         ["plan.csv " + TABLE_HEAD, "plan.csv:row 2, column mass_g: 5000 g is outside the protocol's range 1 to 2000 g."],
         files={"plan.csv": (PLAN_HEADER + "1,fit,5000,-60\n").encode()}),
    Case("plan-bad-set", "plan CSV", "set neither fit nor validation",
         ["acquire", "new.h5", "--port", SIM, "--unattended", "--plan", "plan.csv"],
         ["plan.csv " + TABLE_HEAD, "plan.csv:row 2, column set: 'train' must be fit or validation."],
         files={"plan.csv": (PLAN_HEADER + "1,train,500,-60\n").encode()}),
    Case("plan-missing-file", "plan CSV", "missing file",
         ["acquire", "new.h5", "--port", SIM, "--unattended", "--plan", "nope.csv"],
         ["nope.csv does not exist; check the path."]),
    # ---- trial CSV
    Case("trial-bad-cell", "trial CSV", "text in a pressure cell (import)",
         ["import", "bad.csv", "-o", "new.h5", "--protocol", "takuma2014"],
         ["bad.csv " + TABLE_HEAD, "bad.csv:row 3, column P_R1: 'abc' is not a number."],
         files={"bad.csv": _trial_csv(_set_cell(3, "P_R1", "abc"))}),
    Case("trial-missing-column", "trial CSV", "missing column (import)",
         ["import", "bad.csv", "-o", "new.h5", "--protocol", "takuma2014"],
         ["bad.csv " + TABLE_HEAD, "bad.csv:row 1, column theta2_deg: required column is missing from the header."],
         files={"bad.csv": _trial_csv(_drop_column("theta2_deg"))}),
    Case("trial-beyond-span", "trial CSV", "pressure beyond the sensor span (fit)",
         ["fit", "bad.csv"],
         ["bad.csv " + TABLE_HEAD, "bad.csv:row 4, column P_L1: 1.5 MPa is outside the sensor span 0 to 1 MPa."],
         files={"bad.csv": _trial_csv(_set_cell(4, "P_L1", "1.5"))}),
    Case("trial-not-utf8", "trial CSV", "binary file given as a table (import)",
         ["import", "acq.h5", "-o", "new.h5", "--protocol", "takuma2014"],
         ["acq.h5 is not UTF-8 text (bad byte at offset 0); save it as CSV UTF-8."]),
    Case("trial-push-protocol", "trial CSV", "trial CSV fitted under a push protocol",
         ["fit", "trials.csv", "--protocol", "takuma2014-stiffness"],
         ["--protocol takuma2014-stiffness is of kind 'push'; a trial CSV is read with a force protocol "
          "such as takuma2014."]),
    Case("trial-output-exists", "trial CSV", "import onto an existing run without --force",
         ["import", "trials.csv", "-o", "run.h5", "--protocol", "takuma2014"],
         ["run.h5 already exists; use --force to overwrite it."]),
    Case("trial-rpam-protocol", "trial CSV", "trial CSV imported under the rPAM protocol",
         ["import", "trials.csv", "-o", "new.h5", "--protocol", "rpam2015"],
         ["rpam2015 is a protocol of kind 'rpam' with two experiments; labcli import reads its point tables "
          "with --experiment stretch (the stretch test) or --experiment joint (the joint map), and trial tables "
          "with a force protocol such as takuma2014."]),
    Case("trial-rpam-experiment", "trial CSV", "trial CSV imported as an rPAM stretch test",
         ["import", "trials.csv", "-o", "new.h5", "--protocol", "rpam2015", "--experiment", "stretch"],
         ["trials.csv has 5 problems (rows counted as a spreadsheet shows them, the header included):",
          "trials.csv:row 1, column point: required column is missing from the header.",
          "trials.csv:row 1, column mass_g: required column is missing from the header.",
          "trials.csv:row 1, column P_A: required column is missing from the header.",
          "trials.csv:row 1, column P_B: required column is missing from the header.",
          "trials.csv:row 1, column L_m: required column is missing from the header."]),
    Case("trial-nul-in-extra", "trial CSV", "NUL character in an extra text column (import)",
         ["import", "bad.csv", "-o", "new.h5", "--protocol", "takuma2014"],
         ["bad.csv " + TABLE_HEAD, "bad.csv:row 2, column note: holds a NUL character, which a run file "
          "cannot store; remove it."],
         files={"bad.csv": (TRIAL_HEADER + ",note\n1,fit," + ",".join(["0.2"] * 8) + ",1.0,2.0,0.5,-0.5,a\x00b\n").encode()}),
    Case("trial-id-out-of-range", "trial CSV", "trial id a run file cannot hold (import)",
         ["import", "bad.csv", "-o", "new.h5", "--protocol", "takuma2014"],
         ["bad.csv " + TABLE_HEAD, "bad.csv:row 2, column trial: 1000000 is outside the trial ids a run "
          "file holds, 0 to 999999."],
         files={"bad.csv": (TRIAL_HEADER + "\n1000000,fit," + ",".join(["0.2"] * 8) + ",1.0,2.0,0.5,-0.5\n").encode()}),
    # ---- push CSV
    Case("push-bad-cell", "push CSV", "negative radius (import)",
         ["import", "bad.csv", "-o", "new.h5", "--protocol", "takuma2014-stiffness"],
         ["bad.csv " + TABLE_HEAD, "bad.csv:row 3, column R_m: -0.033 must be greater than 0."],
         files={"bad.csv": f"{PUSH_HEADER}\n1,{PUSH_ROW}\n2,{PUSH_ROW.replace('0.033', '-0.033')}\n".encode()}),
    Case("push-missing-column", "push CSV", "missing column (import)",
         ["import", "bad.csv", "-o", "new.h5", "--protocol", "takuma2014-stiffness"],
         ["bad.csv " + TABLE_HEAD, "bad.csv:row 1, column object: required column is missing from the header."],
         files={"bad.csv": (PUSH_HEADER.replace(",object", "") + "\n1," + PUSH_ROW.replace("pet-1,", "")
                            + "\n").encode()}),
    Case("push-bad-cell-classify", "push CSV", "bad phi (classify)",
         ["classify", "bad.csv", "--model", "run.model.json"],
         ["bad.csv " + TABLE_HEAD, "bad.csv:row 2, column phi_deg: 'north' is not a number."],
         files={"bad.csv": f"{PUSH_HEADER}\n1,{PUSH_ROW.replace(',,', ',north,')}\n".encode()}),
    # ---- HDF5 files
    Case("h5-other-schema", "HDF5 file", "HDF5 file of another schema (inspect)",
         ["inspect", "other.h5"],
         ["other.h5 is an HDF5 file but not a labcli run file (no schema attribute, expected 'labcli-run')."],
         files={"other.h5": _other_schema}),
    Case("h5-other-schema-fit", "HDF5 file", "HDF5 file of another schema (fit)",
         ["fit", "other.h5"],
         ["other.h5 is an HDF5 file but not a labcli run file (no schema attribute, expected 'labcli-run')."],
         files={"other.h5": _other_schema}),
    Case("h5-truncated-export", "HDF5 file", "acquired run cut to half its length (export)",
         ["export", "cut.h5", "-o", "out.csv"],
         ["cut.h5 is damaged or truncated and HDF5 cannot open it; use a backup copy."],
         files={"cut.h5": _cut("acq.h5", 0.5)}),
    Case("h5-truncated-fit", "HDF5 file", "acquired run missing its last bytes (fit)",
         ["fit", "cut.h5"],
         ["cut.h5 is damaged or truncated and HDF5 cannot open it; use a backup copy."],
         files={"cut.h5": _cut("acq.h5", 0.99)}),
    Case("h5-truncated-resume", "HDF5 file", "acquired run cut short (acquire --resume)",
         ["acquire", "cut.h5", "--port", SIM, "--resume"],
         ["cut.h5 is damaged or truncated and HDF5 cannot open it; use a backup copy."],
         files={"cut.h5": _cut("acq.h5", 0.75)}),
    Case("h5-text", "HDF5 file", "text file named .h5 (split)",
         ["split", "text.h5", "--fit", "2"],
         ["text.h5 is not an HDF5 file; run files are written by 'labcli acquire' or 'labcli import'."],
         files={"text.h5": b"trial,set\n1,fit\n"}),
    Case("h5-missing-inspect", "HDF5 file", "missing file (inspect)",
         ["inspect", "missing.h5"], ["missing.h5 does not exist; check the path."]),
    Case("h5-missing-validate", "HDF5 file", "missing file (validate)",
         ["validate", "missing.h5", "--model", "run.model.json"],
         ["missing.h5 does not exist; pass a run file (.h5) or a trial CSV."]),
    Case("h5-push-run-fit", "HDF5 file", "push run given to fit",
         ["fit", "push.h5"],
         ["push.h5 is a run of kind 'push' (protocol 'takuma2014-stiffness'), not a force run; fit and "
          "validate read the trials of a force run such as one recorded with protocol takuma2014."]),
    Case("h5-force-run-classify", "HDF5 file", "force run given to classify",
         ["classify", "acq.h5", "--model", "run.model.json"],
         ["acq.h5 is a force run (protocol 'takuma2014'), not a push run; classify reads the pushes of a "
          "stiffness run such as one recorded with protocol takuma2014-stiffness."]),
    Case("h5-no-fit-trials", "HDF5 file", "relative run name in a model message",
         ["fit", "unsplit.h5"],
         ["unsplit.h5 has no fit trials (no row with set = 'fit'); assign trials with `labcli split` (or "
          "fill the `set` column)."],
         files={"unsplit.csv": _trial_csv(lambda h, rows: (h, [r[:1] + [""] + r[2:] for r in rows]))}),
    # ---- model JSON
    Case("model-other-protocol", "model JSON", "model of another protocol",
         ["validate", "run.h5", "--model", "m.json"],
         ["The model file m.json was fitted for protocol 'rpam2015' but run.h5 uses protocol 'takuma2014'; "
          "fit a model on a run of this protocol."],
         files={"m.json": _model(lambda d: d.update(protocol="rpam2015"))}),
    Case("model-other-geometry", "model JSON", "model of another rig geometry",
         ["validate", "run.h5", "--model", "m.json"],
         ["The model file m.json was fitted for h1 = 0.4 m but run.h5 has h1 = 0.355 m; fit a model for this rig."],
         files={"m.json": _model(lambda d: d["geometry"].update(h1=0.4))}),
    Case("model-malformed", "model JSON", "malformed JSON (cut short)",
         ["validate", "run.h5", "--model", "m.json"],
         ["The model file m.json is not valid JSON (line 12, column 22: Unterminated string starting at)."],
         files={"m.json": _cut("run.model.json", 0.03)}),
    Case("model-not-a-model", "model JSON", "JSON that is not a model",
         ["validate", "run.h5", "--model", "m.json"],
         ["The model file m.json is not a labcli Takuma model (schema None, expected 'labcli-takuma-model'); "
          "pass a file written by `labcli fit`."],
         files={"m.json": b'{"hello": 1}'}),
    Case("model-list", "model JSON", "JSON list instead of a model",
         ["validate", "run.h5", "--model", "m.json"],
         ["The model file m.json is not a labcli Takuma model (it holds a list, not an object with schema "
          "'labcli-takuma-model'); pass a file written by `labcli fit`."],
         files={"m.json": b"[1, 2, 3]"}),
    Case("model-text-coefficient", "model JSON", "coefficient that is text",
         ["validate", "run.h5", "--model", "m.json"],
         ["The model file m.json: key 'coefficients.beta_Fx1' must be a finite number, not the string 'big'; "
          "refit with `labcli fit`."],
         files={"m.json": _model(lambda d: d["coefficients"].update(beta_Fx1="big"))}),
    Case("model-coefficients-list", "model JSON", "coefficients as a list (classify)",
         ["classify", "push.h5", "--model", "m.json"],
         ["The model file m.json: key 'coefficients' must be an object, not a list; refit with `labcli fit`."],
         files={"m.json": _model(lambda d: d.update(coefficients=[1.0]))}),
    Case("model-missing-key", "model JSON", "model without its geometry",
         ["validate", "run.h5", "--model", "m.json"],
         ["The model file m.json lacks the key 'geometry'; refit with `labcli fit`."],
         files={"m.json": _model(lambda d: d.pop("geometry") and None)}),
    Case("model-not-utf8", "model JSON", "binary file as the model",
         ["validate", "run.h5", "--model", "acq.h5"],
         ["The model file acq.h5 is not UTF-8 text (bad byte at offset 0); pass the .json file `labcli fit` wrote."]),
    Case("model-missing", "model JSON", "missing model file",
         ["validate", "run.h5", "--model", "nope.json"],
         ["The model file nope.json does not exist; write one with `labcli fit`."]),
    # ---- CLI arguments
    Case("arg-fit-too-large", "CLI argument", "--fit larger than the trials",
         ["split", "acq.h5", "--fit", "10", "--validation", "1"],
         ["acq.h5: the run has 3 completed trials, fewer than the 11 asked for (10 fit + 1 validation)."]),
    Case("arg-fit-negative", "CLI argument", "negative --fit",
         ["split", "acq.h5", "--fit", "-1"],
         ["acq.h5: the fit set needs at least 1 trial and the validation set 0 or more, got -1 and 18."]),
    Case("arg-negative-seconds", "CLI argument", "negative --seconds",
         ["monitor", "--port", "sim://", "--seconds", "-1"],
         ["Invalid value for '--seconds': -1.0 is not in the range x>0."], code=2, usage="monitor [OPTIONS]"),
    Case("arg-bad-mode", "CLI argument", "bad --mode",
         ["validate", "run.h5", "--mode", "sideways"],
         ["Invalid value for '--mode': 'sideways' is not one of 'pressure-only', 'measured-angles'."],
         code=2, usage="validate [OPTIONS] RUN"),
    Case("arg-optimize-unknown-key", "CLI argument", "unknown --set key (optimize)",
         ["optimize", "--set", "actuator.L0_mm=0.08"],
         ["Unknown protocol key 'actuator.L0_mm' in --set; keys under actuator: A0_m2, L0_m, n_turns, "
          "prestretch, thread_length_m."]),
    Case("arg-optimize-bad-value", "CLI argument", "negative length by --set (optimize)",
         ["optimize", "--set", "actuator.L0_m=-1"],
         ["Protocol key 'actuator.L0_m' in protocol rpam2015 with --set actuator.L0_m=-1 must be "
          "a positive number, got -1."]),
    Case("arg-optimize-negative-pa", "CLI argument", "negative --pa (optimize)",
         ["optimize", "--pa", "-5"],
         ["Invalid value for --pa: -5 is not a gauge pressure; give 0 kPa or more."], code=2,
         usage="optimize [OPTIONS]"),
    Case("arg-max-amplification", "CLI argument", "--max-amplification below 1 (fit)",
         ["fit", "run.h5", "--max-amplification", "0.5"],
         ["Invalid value for '--max-amplification': 0.5 is not in the range x>1."], code=2,
         usage="fit [OPTIONS] RUN"),
    Case("arg-rate-zero", "CLI argument", "--rate 0 (acquire)",
         ["acquire", "new.h5", "--port", SIM, "--rate", "0"],
         ["Invalid value for '--rate': 0.0 is not in the range x>0."], code=2, usage="acquire [OPTIONS] RUN.h5"),
    Case("arg-rate-refused", "CLI argument", "--rate the firmware refuses (acquire)",
         ["acquire", "new.h5", "--port", SIM, "--unattended", "--plan", "plan3.csv", "--rate", "1e9"],
         [f"The device on {SIM} refused RATE 1000000000: 'ERR RATE must be within 1..5000 Hz, got 1000000000'. "
          "Check the values its firmware accepts for that command."]),
    Case("arg-resume-and-force", "CLI argument", "--resume with --force (acquire)",
         ["acquire", "acq.h5", "--port", SIM, "--resume", "--force"],
         ["--resume continues a run and --force overwrites it: give one of them, not both."]),
    # ---- ports and run files of acquire
    Case("port-no-such-device", "port", "/dev/ttyNOPE (monitor)",
         ["monitor", "--port", "/dev/ttyNOPE", "--seconds", "1"],
         ["Cannot open serial port /dev/ttyNOPE: no such device. Check the cable and run `labcli ports` to "
          "list ports."]),
    Case("port-com99", "port", "COM99 (acquire)",
         ["acquire", "new.h5", "--port", "COM99"],
         ["Cannot open serial port COM99: no such device. Check the cable and run `labcli ports` to list ports."]),
    Case("port-sim-unknown-option", "port", "sim:// URL with an unknown option (acquire)",
         ["acquire", "new.h5", "--port", "sim://?foo=1"],
         [f"Cannot open serial port sim://?foo=1: unknown option 'foo' in sim:// URL; expected {SIM_URL_FORM}. "
          "Check the URL's options."]),
    Case("port-sim-unknown-option-monitor", "port", "sim:// URL with an unknown option (monitor)",
         ["monitor", "--port", "sim://?sed=1", "--seconds", "1"],
         [f"Cannot open serial port sim://?sed=1: unknown option 'sed' in sim:// URL; expected {SIM_URL_FORM}. "
          "Check the URL's options."]),
    Case("port-unknown-scheme", "port", "unknown URL scheme (monitor)",
         ["monitor", "--port", "bogus://x", "--seconds", "1"],
         ["Cannot open serial port bogus://x: unknown URL scheme 'bogus://'. Use a port name such as "
          "/dev/ttyUSB0 or COM3, or sim:// for the simulated rig."]),
    Case("acquire-exists", "run file", "acquire onto an existing file without --force",
         ["acquire", "acq.h5", "--port", SIM, "--unattended", "--plan", "plan3.csv"],
         ["acq.h5 already exists; continue it with --resume, or pass --force to overwrite it."]),
    Case("acquire-unattended-real-port", "run file", "--unattended on a real port (pty)",
         ["acquire", "new.h5", "--port", "PTY", "--unattended", "--plan", "plan3.csv"],
         ["--unattended drives the simulated rig only, and PTY is a real port: run without --unattended and "
          "follow the prompts."], pty=True),
    Case("acquire-resume-missing", "run file", "--resume on a missing file",
         ["acquire", "missing.h5", "--port", SIM, "--resume"],
         ["missing.h5 does not exist; check the path."]),
    Case("acquire-resume-csv", "run file", "--resume on a CSV",
         ["acquire", "trials.csv", "--port", SIM, "--resume"],
         ["trials.csv is not an HDF5 file; run files are written by 'labcli acquire' or 'labcli import'."]),
    Case("acquire-no-folder", "run file", "run file in a folder that does not exist",
         ["acquire", "nodir/new.h5", "--port", SIM, "--unattended", "--plan", "plan3.csv"],
         ["cannot create nodir/new.h5: the directory {world}/nodir does not exist."]),
    Case("acquire-resume-imported-unattended", "run file", "--resume --unattended on an imported run (no plan)",
         ["acquire", "run.h5", "--port", SIM, "--resume", "--unattended"],
         ["run.h5 has no plan (it was imported from a table), so --unattended has nothing to follow; resume it "
          "without --unattended and type each load."]),
]


# --------------------------------------------------------------------------- the world of files


def labcli(*args: str, cwd: Path, timeout: float = 120) -> subprocess.CompletedProcess:
    env = dict(os.environ, COLUMNS="400", PYTHONWARNINGS="ignore")
    return subprocess.run([sys.executable, "-m", "labcli", *args], cwd=cwd, capture_output=True, text=True,
                          timeout=timeout, env=env)


@pytest.fixture(scope="module")
def world(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Good files every case starts from: trials.csv, run.h5 + run.model.json, acq.h5, push.h5, ..."""
    import pandas as pd

    from labcli.experiments.takuma2014.models.synthetic import paper_trials
    from labcli.experiments.takuma2014.tables import write_trial_csv

    w = tmp_path_factory.mktemp("world")
    table = pd.concat([paper_trials(12, seed=1), paper_trials(4, seed=2, set_name="validation", start_id=13)],
                      ignore_index=True)
    write_trial_csv(table, w / "trials.csv")
    shutil.copy(PROTOCOLS / "takuma2014.toml", w / "good.toml")
    shutil.copy(PROTOCOLS / "takuma2014-plan.csv", w / "takuma2014-plan.csv")
    (w / "plan3.csv").write_text(PLAN_HEADER + "1,fit,500,-60\n2,fit,300,30\n3,validation,800,90\n")
    (w / "push_ok.csv").write_text(f"{PUSH_HEADER}\n1,{PUSH_ROW}\n2,{PUSH_ROW}\n")
    steps = [
        ("import", "trials.csv", "-o", "run.h5", "--protocol", "takuma2014"),
        ("fit", "run.h5"),
        ("acquire", "acq.h5", "--port", SIM, "--plan", "plan3.csv", "--unattended"),
        ("import", "push_ok.csv", "-o", "push.h5", "--protocol", "takuma2014-stiffness"),
    ]
    for step in steps:
        r = labcli(*step, cwd=w)
        assert r.returncode == 0, (step, r.stderr)
    return w


def digest(folder: Path) -> dict[str, str]:
    return {str(p.relative_to(folder)): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(folder.rglob("*")) if p.is_file()}


def expected_stderr(case: Case, world: Path, port: str | None) -> str:
    lines = [s.replace("{world}", str(world)) for s in case.error]
    if port is not None:
        lines = [s.replace("PTY", port) for s in lines]
    lines[0] = "Error: " + lines[0]
    if case.usage is not None:
        command = case.usage.split()[0]
        lines = [f"Usage: labcli {case.usage}", f"Try 'labcli {command} --help' for help.", "", *lines]
    return "\n".join(lines) + "\n"


def run_case(case: Case, world: Path, tmp_path: Path) -> tuple[subprocess.CompletedProcess, str, dict, dict]:
    here = tmp_path / "w"
    shutil.copytree(world, here)
    for name, content in case.files.items():
        (here / name).write_bytes(content(here) if callable(content) else content)
    if case.id == "h5-no-fit-trials":
        r = labcli("import", "unsplit.csv", "-o", "unsplit.h5", "--protocol", "takuma2014", cwd=here)
        assert r.returncode == 0, r.stderr
    before = digest(here)
    port = None
    if case.pty:
        from labcli.core.sim.pty import serve_pty

        server = serve_pty(seed=1, rate=200)
        try:
            port = server.path
            result = labcli(*[a.replace("PTY", port) for a in case.args], cwd=here)
        finally:
            server.stop()
    else:
        result = labcli(*case.args, cwd=here)
    return result, expected_stderr(case, here, port), before, digest(here)


def _params():
    for case in CASES:
        marks = [pytest.mark.xfail(strict=True, reason=case.xfail)] if case.xfail else []
        yield pytest.param(case, id=case.id, marks=marks)


@pytest.mark.parametrize("case", list(_params()))
def test_bad_input(case: Case, world: Path, tmp_path: Path) -> None:
    result, want, before, after = run_case(case, world, tmp_path)
    assert "Traceback" not in result.stderr, result.stderr
    assert result.returncode == case.code, result.stderr
    assert result.stderr == want
    assert after == before, "a failing command changed, created or deleted a file"


def test_the_table_covers_every_entry_point() -> None:
    assert len(CASES) >= 30 and len({c.id for c in CASES}) == len(CASES)
    entries = {c.entry for c in CASES}
    assert entries == {"protocol TOML", "plan CSV", "trial CSV", "push CSV", "HDF5 file", "model JSON",
                       "CLI argument", "port", "run file"}
    commands = {c.args[0] for c in CASES}
    assert commands >= {"acquire", "fit", "validate", "classify", "optimize", "split", "inspect", "export",
                        "import", "monitor"}


# --------------------------------------------------------------------------- a run held open elsewhere


def test_fit_on_a_run_open_in_a_viewer_changes_no_file(world: Path, tmp_path: Path) -> None:
    """fit reads the run, then cannot open it to record the model: neither file may change."""
    import h5py

    here = tmp_path / "w"
    shutil.copytree(world, here)
    (here / "run.model.json").unlink()
    before = digest(here)
    with h5py.File(here / "run.h5", "r"):  # a viewer (HDFView, a notebook) holds the run open
        r = labcli("fit", "run.h5", cwd=here)
    assert "Traceback" not in r.stderr
    assert r.returncode == 1 and r.stderr.startswith("Error: run.h5 is open ") and r.stderr.count("\n") == 1
    assert digest(here) == before


def test_a_run_open_for_reading_elsewhere_is_reported_as_such(world: Path, tmp_path: Path) -> None:
    import h5py

    here = tmp_path / "w"
    shutil.copytree(world, here)
    with h5py.File(here / "run.h5", "r"):
        r = labcli("fit", "run.h5", cwd=here)
    assert r.stderr == ("Error: run.h5 is open in another program (a viewer, or a run still recording); "
                        "close it there and try again.\n")


def test_a_failing_fit_leaves_an_existing_model_and_the_run_as_they_were(world: Path, tmp_path: Path) -> None:
    import h5py

    here = tmp_path / "w"
    shutil.copytree(world, here)
    (here / "run.model.json").write_text("an older model, kept\n")
    before = digest(here)
    with h5py.File(here / "run.h5", "r"):
        r = labcli("fit", "run.h5", cwd=here)
    assert r.returncode == 1 and "Traceback" not in r.stderr
    assert digest(here) == before


# --------------------------------------------------------------------------- the table for the README


TABLE_PATH = Path(__file__).resolve().parents[1] / "bad_input_table.md"
TABLE_HEADER = (
    "# Bad input: what labcli says\n\n"
    "Every case below runs the real `labcli` (`tests/cli/test_bad_input.py`): a non-zero exit, no traceback, "
    "and every file in the folder hashed unchanged before and after (the run file a failing `fit` would "
    "record into included). Table errors print a count line, then one line per problem naming file, row "
    "and column; option errors come from click after its two usage lines. Regenerate this file with "
    "`python tests/cli/test_bad_input.py > tests/bad_input_table.md`.\n\n"
)


def test_committed_table_lists_every_case():
    assert TABLE_PATH.read_text(encoding="utf-8") == markdown_table()


def markdown_table() -> str:
    rows = ["| # | input | case | command | message (first line) | exit |", "|---|---|---|---|---|---|"]
    for i, c in enumerate(CASES, 1):
        args = " ".join(a if " " not in a and "?" not in a and "&" not in a else f"'{a}'" for a in c.args)
        msg = c.error[0] if len(c.error) == 1 else f"{c.error[0]}<br>{c.error[1]}"
        msg = "Error: " + msg.replace("{world}", "/tmp/w").replace("|", "\\|")
        note = f" *(xfail: {c.xfail})*" if c.xfail else ""
        rows.append(f"| {i} | {c.entry} | {c.what}{note} | `labcli {args}` | {msg} | {c.code} |")
    return TABLE_HEADER + "\n".join(rows) + "\n"


if __name__ == "__main__":
    sys.stdout.write(markdown_table())
