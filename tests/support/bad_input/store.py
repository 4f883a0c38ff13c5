"""Bad-input cases of the run file, schema 2: a newer schema, a damaged record, outputs that are not files."""

from __future__ import annotations

import shutil
import tempfile
from pathlib import Path
from typing import Callable

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

    with h5py.File(path, "a") as f:
        f.attrs["schema_version"] = 3


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


CASES: list[Case] = [
    Case("run-newer-schema", "run file", "run file of a newer schema version (inspect)",
         ["inspect", "new.h5"],
         ["new.h5 uses run-file schema version 3, newer than this labcli reads (2); upgrade labcli."],
         files={"new.h5": edited_run("acq.h5", newer_schema)}),
    Case("run-damaged-record-verify", "run file", "one flipped bit in a stored trial (inspect --verify)",
         ["inspect", "--verify", "bad.h5"],
         ["bad.h5: 1 damaged item found; 2 trials and 4 raw windows check out."],
         files={"bad.h5": edited_run("acq.h5", flip_in_trial_row(1))}),
    Case("run-output-device", "run file", "a device node as the run file, with --force (acquire)",
         ["acquire", "/dev/null", "--force", "--port", SIM, "--unattended", "--plan", "plan3.csv"],
         ["/dev/null is a device, not a regular file; labcli writes only regular files, so give the path of a file."]),
]
