"""Bad-input cases of special and oversized inputs: a device such as /dev/zero, a named pipe with no
writer, a file beyond the size an input of its kind may have, each refused in one sentence at once
(the case's timeout is the hang it would otherwise be); and outputs that ``--force`` may not replace
because they are not an earlier output of the same kind."""

from __future__ import annotations

from support.bad_input import SIM, Case, toml_edit

ORDER = 50
QUICK = 30  # s: far beyond the second a refusal takes, far below a reader waiting forever

DEVICE = "is a device, not a regular file; labcli reads {} only from a regular file, so give the path of one."
FIFO = "is a FIFO (named pipe), not a regular file; labcli reads {} only from a regular file, so give the path of one."
ACQUIRE = ["acquire", "new.h5", "--port", SIM, "--unattended"]


def case(id: str, entry: str, what: str, args: list[str], error: str, **kw) -> Case:
    return Case(id, entry, what, args, [error], timeout=QUICK, **kw)


CASES = [
    case(
        "special-table-dev-zero-import",
        "trial CSV",
        "/dev/zero as the table (import)",
        ["import", "/dev/zero", "-o", "new.h5", "--protocol", "takuma2014"],
        "/dev/zero " + DEVICE.format("a table"),
    ),
    case(
        "special-table-dev-zero-fit",
        "trial CSV",
        "/dev/zero as the table (fit)",
        ["fit", "/dev/zero"],
        "/dev/zero " + DEVICE.format("a table"),
    ),
    case(
        "special-model-dev-zero",
        "model JSON",
        "/dev/zero as the model (validate)",
        ["validate", "trials.csv", "--model", "/dev/zero"],
        "The model file /dev/zero " + DEVICE.format("a model file"),
    ),
    case(
        "special-plan-dev-zero",
        "plan CSV",
        "/dev/zero as the plan (acquire)",
        [*ACQUIRE, "--plan", "/dev/zero"],
        "/dev/zero " + DEVICE.format("a plan"),
    ),
    case(
        "special-protocol-dev-zero",
        "protocol TOML",
        "/dev/zero as the protocol (acquire)",
        [*ACQUIRE, "--protocol", "/dev/zero"],
        "Protocol file /dev/zero " + DEVICE.format("a protocol file"),
    ),
    case(
        "special-table-fifo-fit",
        "trial CSV",
        "a named pipe as the table (fit)",
        ["fit", "pipe.csv"],
        "pipe.csv " + FIFO.format("a table"),
        fifos=("pipe.csv",),
    ),
    case(
        "special-table-fifo-import",
        "trial CSV",
        "a named pipe as the table (import)",
        ["import", "pipe.csv", "-o", "new.h5", "--protocol", "takuma2014"],
        "pipe.csv " + FIFO.format("a table"),
        fifos=("pipe.csv",),
    ),
    case(
        "special-push-fifo-classify",
        "push CSV",
        "a named pipe as the push table (classify)",
        ["classify", "pipe.csv", "--model", "run.model.json"],
        "pipe.csv " + FIFO.format("a table"),
        fifos=("pipe.csv",),
    ),
    case(
        "special-model-fifo-validate",
        "model JSON",
        "a named pipe as the model (validate)",
        ["validate", "run.h5", "--model", "pipe.json"],
        "The model file pipe.json " + FIFO.format("a model file"),
        fifos=("pipe.json",),
    ),
    case(
        "special-model-fifo-classify",
        "model JSON",
        "a named pipe as the model (classify)",
        ["classify", "push.h5", "--model", "pipe.json"],
        "The model file pipe.json " + FIFO.format("a model file"),
        fifos=("pipe.json",),
    ),
    case(
        "special-plan-fifo",
        "plan CSV",
        "a named pipe as the plan (acquire)",
        [*ACQUIRE, "--plan", "pipe.csv"],
        "pipe.csv " + FIFO.format("a plan"),
        fifos=("pipe.csv",),
    ),
    case(
        "special-protocol-fifo",
        "protocol TOML",
        "a named pipe as the protocol (fit)",
        ["fit", "trials.csv", "--protocol", "pipe.toml"],
        "Protocol file pipe.toml " + FIFO.format("a protocol file"),
        fifos=("pipe.toml",),
    ),
    case(
        "special-run-fifo-fit",
        "HDF5 file",
        "a named pipe as the run (fit)",
        ["fit", "pipe.h5"],
        "pipe.h5 is a FIFO (named pipe), not a run file.",
        fifos=("pipe.h5",),
    ),
    case(
        "special-run-fifo-resume",
        "HDF5 file",
        "a named pipe as the run (acquire --resume)",
        ["acquire", "pipe.h5", "--port", SIM, "--resume"],
        "pipe.h5 is a FIFO (named pipe), not a run file.",
        fifos=("pipe.h5",),
    ),
    case(
        "special-protocol-2mb",
        "protocol TOML",
        "a 2 MB protocol file",
        ["fit", "trials.csv", "--protocol", "big.toml"],
        "Protocol file big.toml is 2 MB, larger than the 1 MB a protocol file may be; check that it is the right file.",
        files={"big.toml": b"#" * 2_000_000},
    ),
    case(
        "force-import-onto-a-table",
        "output path",
        "import --force onto a table, not a run",
        ["import", "trials.csv", "-o", "plan3.csv", "--force", "--protocol", "takuma2014"],
        "Cannot replace plan3.csv: it is not a run file, and --force replaces only a run file (an earlier output "
        "of acquire or import); choose another output name.",
    ),
    case(
        "force-acquire-onto-notes",
        "output path",
        "acquire --force onto a text file, not a run",
        ["acquire", "notes.txt", "--force", "--port", SIM, "--unattended", "--plan", "plan3.csv"],
        "Cannot replace notes.txt: it is not a run file, and --force replaces only a run file (an earlier output "
        "of acquire or import); choose another output name.",
        files={"notes.txt": b"trial 3: the weight slipped\n"},
    ),
    case(
        "fit-model-onto-a-table",
        "output path",
        "the model written onto a table, not a model",
        ["fit", "run.h5", "-o", "push_ok.csv"],
        "Cannot write the model to push_ok.csv: it is not a model file, and fit replaces only a model it wrote "
        "earlier; choose another output name.",
    ),
]

BIG_CELL = 50_000


def _big_cell(world) -> bytes:
    lines = (world / "trials.csv").read_text().splitlines()
    rows = [lines[0] + ",note", *[r + "," + ("x" * BIG_CELL if i == 0 else "ok") for i, r in enumerate(lines[1:6])]]
    return ("\n".join(rows) + "\n").encode()


CASES += [
    Case(
        "import-text-cell-50kb",
        "trial CSV",
        "a 50 kB cell in an extra text column (import)",
        ["import", "big.csv", "-o", "new.h5", "--protocol", "takuma2014"],
        [
            "big.csv has 1 problem (rows counted as a spreadsheet shows them, the header included):",
            f"big.csv:row 2, column note: holds {BIG_CELL} bytes of text, more than the 16384 a run file keeps in "
            "one cell; shorten it.",
        ],
        files={"big.csv": _big_cell},
    ),
    Case(
        "split-seed-negative",
        "CLI argument",
        "--seed -1 (split)",
        ["split", "acq.h5", "--strategy", "random", "--seed", "-1"],
        ["Invalid value for '--seed': -1 is not in the range 0<=x<=4294967295."],
        code=2,
        usage="split [OPTIONS] RUN",
    ),
    Case(
        "split-seed-huge",
        "CLI argument",
        "--seed 10**30 (split)",
        ["split", "acq.h5", "--strategy", "random", "--seed", str(10**30)],
        [f"Invalid value for '--seed': {10**30} is not in the range 0<=x<=4294967295."],
        code=2,
        usage="split [OPTIONS] RUN",
    ),
]

SILENT = SIM + "&faults=drop:1"
CASES += [
    case(
        "rig-every-frame-dropped",
        "rig",
        "a link that delivers no frame (`faults=drop:1`), on the virtual clock",
        ["acquire", "new.h5", "--port", SILENT, "--unattended", "--plan", "plan3.csv"],
        f"The rig on {SILENT} stopped sending data during the setup, before anything was written to new.h5. "
        "Check the cable and power, then run the same command again.",
    ),
]

CASES += [
    case(
        "protocol-link-1e300-m",
        "protocol TOML",
        "a rig link of 1e300 m (fit)",
        ["fit", "trials.csv", "--protocol", "p.toml"],
        "p.toml: key 'rig.h1_m' must be at most 1 m, not 1e+300.",
        files={"p.toml": toml_edit("h1_m = 0.355", "h1_m = 1e300")},
    ),
    case(
        "protocol-pulley-1e-300-m",
        "protocol TOML",
        "a pulley radius of 1e-300 m (acquire)",
        [*ACQUIRE, "--protocol", "p.toml"],
        "p.toml: key 'rig.r1_m' must be at least 0.001 m, not 1e-300.",
        files={"p.toml": toml_edit("r1_m = 0.075", "r1_m = 1e-300")},
    ),
]
