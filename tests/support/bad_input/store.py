"""Bad-input cases of the run file, schema 2: a newer schema, a damaged record, outputs that are not files;
and of output paths: onto the command's own input, onto another run file, a name too long."""

from __future__ import annotations

import shutil
import tempfile
from collections.abc import Callable
from pathlib import Path

from support.bad_input import SIM, Case

ORDER = 20


def edited_run(name: str, edit: Callable[[str], None]) -> Callable[[Path], bytes]:
    """The bytes of a copy of the world's run ``name`` after ``edit(path_of_copy)``."""

    def make(world: Path) -> bytes:
        with tempfile.TemporaryDirectory() as d:
            copy = str(Path(d) / name)
            shutil.copy(world / name, copy)
            edit(copy)
            return Path(copy).read_bytes()

    return make


def newer_schema(path: str) -> None:
    import h5py

    with h5py.File(path, "a") as f:  # the schema lives in /entry/labcli from schema 3
        (f["entry/labcli"] if "entry/labcli" in f else f).attrs["schema_version"] = 5


def flip_in_trial_row(row: int) -> Callable[[str], None]:
    """Flip one bit inside the stored pressures of record ``row`` (one row per chunk in an acquired run)."""

    def edit(path: str) -> None:
        import h5py

        with h5py.File(path, "r") as f:
            ds = f["entry/trials/P"]
            offset = ds.id.get_chunk_info_by_coord((row, 0)).byte_offset
        with open(path, "r+b") as fh:
            fh.seek(offset + 4)
            byte = fh.read(1)[0]
            fh.seek(offset + 4)
            fh.write(bytes([byte ^ 0x10]))

    return edit


OWN_INPUT = "it is this command's input, and writing there would destroy it; choose another output name."
A_RUN = "it is a run file (HDF5), and writing there would destroy its records; choose another output name."
NOT_A_FILE = "not a regular file; labcli writes only regular files, so give the path of a file."
LONG = "r" * 300


def too_long(size: int) -> str:
    return f"the file name is too long ({size} bytes; this file system allows at most 255), so choose a shorter name."


CASES: list[Case] = [
    Case(
        "run-newer-schema",
        "run file",
        "run file of a newer schema version (inspect)",
        ["inspect", "new.h5"],
        ["new.h5 uses run-file schema version 5, newer than this labcli reads (4); upgrade labcli."],
        files={"new.h5": edited_run("acq.h5", newer_schema)},
    ),
    Case(
        "run-damaged-record-verify",
        "run file",
        "one flipped bit in a stored trial (inspect --verify)",
        ["inspect", "--verify", "bad.h5"],
        ["bad.h5: 1 damaged item found; 2 trials and 4 raw windows check out."],
        files={"bad.h5": edited_run("acq.h5", flip_in_trial_row(1))},
    ),
    Case(
        "run-output-device",
        "run file",
        "a device node as the run file, with --force (acquire)",
        ["acquire", "/dev/null", "--force", "--port", SIM, "--unattended", "--plan", "plan3.csv"],
        ["/dev/null is a device, not a regular file; labcli writes only regular files, so give the path of a file."],
    ),
    Case(
        "out-export-onto-input",
        "output path",
        "export a run onto itself",
        ["export", "run.h5", "-o", "run.h5"],
        [f"Cannot write run.h5: {OWN_INPUT}"],
    ),
    Case(
        "out-export-onto-input-other-name",
        "output path",
        "export a run onto itself, named another way",
        ["export", "run.h5", "-o", "./run.h5"],
        [f"Cannot write ./run.h5: {OWN_INPUT}"],
    ),
    Case(
        "out-fit-onto-input",
        "output path",
        "the model written onto the run it is fitted to",
        ["fit", "run.h5", "-o", "run.h5"],
        [f"Cannot write the model to run.h5: {OWN_INPUT}"],
    ),
    Case(
        "out-fit-onto-table",
        "output path",
        "the model written onto the trial CSV it is fitted to",
        ["fit", "trials.csv", "-o", "trials.csv"],
        [f"Cannot write the model to trials.csv: {OWN_INPUT}"],
    ),
    Case(
        "out-import-onto-input",
        "output path",
        "import a table onto itself, with --force",
        ["import", "trials.csv", "-o", "trials.csv", "--force", "--protocol", "takuma2014"],
        [f"Cannot write trials.csv: {OWN_INPUT}"],
    ),
    Case(
        "out-acquire-onto-plan",
        "output path",
        "a run acquired onto its own plan, with --force",
        ["acquire", "plan.csv", "--force", "--plan", "plan.csv", "--port", SIM, "--unattended"],
        [f"Cannot write the run to plan.csv: {OWN_INPUT}"],
        files={"plan.csv": b"trial,set,mass_g,direction_deg\n1,fit,800,-60\n"},
    ),
    Case(
        "out-acquire-onto-protocol",
        "output path",
        "a run acquired onto its own protocol, with --force",
        ["acquire", "good.toml", "--force", "--protocol", "good.toml", "--port", SIM, "--unattended"],
        [f"Cannot write the run to good.toml: {OWN_INPUT}"],
    ),
    Case(
        "out-fit-onto-protocol",
        "output path",
        "the model written onto the protocol file it is fitted with",
        ["fit", "trials.csv", "--protocol", "good.toml", "-o", "good.toml"],
        [f"Cannot write the model to good.toml: {OWN_INPUT}"],
    ),
    Case(
        "out-export-onto-run",
        "output path",
        "export onto another run file",
        ["export", "acq.h5", "-o", "push.h5"],
        [f"Cannot write push.h5: {A_RUN}"],
    ),
    Case(
        "out-fit-onto-run",
        "output path",
        "the model written onto another run file",
        ["fit", "run.h5", "-o", "acq.h5"],
        [f"Cannot write the model to acq.h5: {A_RUN}"],
    ),
    Case(
        "out-export-fifo",
        "output path",
        "export onto a named pipe",
        ["export", "run.h5", "-o", "pipe.csv"],
        [f"pipe.csv is a FIFO (named pipe), {NOT_A_FILE}"],
        fifos=("pipe.csv",),
    ),
    Case(
        "out-fit-fifo",
        "output path",
        "the model written onto a named pipe",
        ["fit", "run.h5", "-o", "pipe.json"],
        [f"pipe.json is a FIFO (named pipe), {NOT_A_FILE}"],
        fifos=("pipe.json",),
    ),
    Case(
        "out-import-fifo",
        "output path",
        "import onto a named pipe, with --force",
        ["import", "trials.csv", "-o", "pipe.h5", "--force", "--protocol", "takuma2014"],
        [f"pipe.h5 is a FIFO (named pipe), {NOT_A_FILE}"],
        fifos=("pipe.h5",),
    ),
    Case(
        "out-acquire-fifo",
        "output path",
        "a named pipe as the run file, with --force (acquire)",
        ["acquire", "pipe.h5", "--force", "--port", SIM, "--unattended", "--plan", "plan3.csv"],
        [f"pipe.h5 is a FIFO (named pipe), {NOT_A_FILE}"],
        fifos=("pipe.h5",),
    ),
    Case(
        "out-export-device",
        "output path",
        "export onto a device node",
        ["export", "run.h5", "-o", "/dev/null"],
        [f"/dev/null is a device, {NOT_A_FILE}"],
    ),
    Case(
        "out-fit-device",
        "output path",
        "the model written onto a device node",
        ["fit", "run.h5", "-o", "/dev/null"],
        [f"/dev/null is a device, {NOT_A_FILE}"],
    ),
    Case(
        "out-import-device",
        "output path",
        "import onto a device node, with --force",
        ["import", "trials.csv", "-o", "/dev/null", "--force", "--protocol", "takuma2014"],
        [f"/dev/null is a device, {NOT_A_FILE}"],
    ),
    Case(
        "out-fit-directory",
        "output path",
        "the model written onto a directory",
        ["fit", "run.h5", "-o", "."],
        ["Invalid value for '-o' / '--output': File '.' is a directory."],
        code=2,
        usage="fit [OPTIONS] RUN",
    ),
    Case(
        "out-acquire-long-name",
        "output path",
        "a 300-character run file name (acquire)",
        ["acquire", LONG + ".h5", "--port", SIM, "--unattended", "--plan", "plan3.csv"],
        [f"Cannot create {LONG}.h5: {too_long(303)}"],
    ),
    Case(
        "out-import-long-name",
        "output path",
        "a 300-character run file name (import)",
        ["import", "trials.csv", "-o", LONG + ".h5", "--protocol", "takuma2014"],
        [f"Cannot write {LONG}.h5: {too_long(303)}"],
    ),
    Case(
        "out-export-long-name",
        "output path",
        "a 300-character table name (export)",
        ["export", "run.h5", "-o", LONG + ".csv"],
        [f"Cannot write {LONG}.csv: {too_long(304)}"],
    ),
    Case(
        "out-fit-long-name",
        "output path",
        "a 300-character model file name (fit -o)",
        ["fit", "run.h5", "-o", LONG + ".json"],
        [f"Cannot write the model to {LONG}.json: {too_long(305)}"],
    ),
]
