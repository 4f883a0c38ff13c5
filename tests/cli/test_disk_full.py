"""A full disk during ``acquire`` and ``import``: one sentence, non-zero exit, nothing lost.

Under a file size limit (``ulimit -f``: RLIMIT_FSIZE set in the child, SIGXFSZ ignored as a
shell's ``ulimit`` leaves it) and on a small tmpfs (where this machine lets us mount one):

* ``acquire`` stops part-way; the trials completed before are kept, the file opens with every
  one of them and checks out, and the sentence says which trial was not written and what was
  kept.  Under ``ulimit -f`` the same run resumes to its end once the limit is raised.
* ``import`` leaves no output and no temporary file behind (or, with ``--force``, the run it
  would have replaced byte for byte as it was).

Trials are recorded at 2 kHz (``--rate 2000``) so that a few of them fill the room a run
file is given, which keeps each run to seconds.
"""

from __future__ import annotations

import hashlib
import re
import resource
import shutil
import subprocess
import uuid
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest
from support import procs
from support.big_table import big_table

from labcli.core.store import RunFile
from labcli.core.store.verify import verify

ROOT = Path(__file__).resolve().parents[2]
SIM = "sim://?seed=1&clock=virtual"
N_TRIALS = 24  # about 2.1 MB at 2 kHz: past both rooms below, about 17 trials in
PLAN = "trial,set,mass_g,direction_deg\n" + "".join(
    f"{i},fit,{500 + 100 * (i % 4)},{-150 + 30 * (i % 11)}\n" for i in range(1, N_TRIALS + 1)
)
ACQUIRE = ("acquire", "run.h5", "--port", SIM, "--unattended", "--plan", "plan.csv", "--rate", "2000")
LIMIT = 1600 * 1024  # room for the new run (its reserve) and about 17 trials at 2 kHz


def labcli(*args: str, cwd: Path, limit: int | None = None) -> subprocess.CompletedProcess:
    limits = {resource.RLIMIT_FSIZE: limit} if limit is not None else {}
    return procs.labcli(*args, cwd=cwd, timeout=300, env={"PYTHONPATH": str(ROOT)}, limits=limits)


def listing(folder: Path) -> dict[str, str]:
    return {p.name: hashlib.sha256(p.read_bytes()).hexdigest() for p in sorted(folder.iterdir()) if p.is_file()}


@pytest.fixture(scope="module")
def small_disk(tmp_path_factory) -> Iterator[Callable[[str], Path]]:
    """``small_disk(size)``: a fresh tmpfs of that size (e.g. "1600k"); skipped where mounting is refused."""
    mounted: list[Path] = []

    def mount(size: str) -> Path:
        where = tmp_path_factory.mktemp("tmpfs")
        r = subprocess.run(
            ["mount", "-t", "tmpfs", "-o", f"size={size}", f"labcli-{uuid.uuid4().hex[:8]}", str(where)],
            capture_output=True,
            text=True,
        )
        if r.returncode != 0:
            pytest.skip(
                f"cannot mount a tmpfs here ({(r.stderr or r.stdout).strip() or 'mount failed'}); "
                "the ulimit -f tests cover the same paths"
            )
        mounted.append(where)
        return where

    if shutil.which("mount") is None:
        pytest.skip("no mount command here; the ulimit -f tests cover the same paths")
    yield mount
    for where in mounted:
        subprocess.run(["umount", str(where)], capture_output=True)


def stopped_part_way(folder: Path, r: subprocess.CompletedProcess, reason: str, advice: str) -> int:
    """The acquisition stopped in one sentence; the trials it kept open and check out. Returns how many."""
    assert r.returncode == 1 and "Traceback" not in r.stderr, r.stderr
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1, r.stderr
    m = re.fullmatch(
        rf"Error: {reason}, so trial (\d+) was not written; the (\d+) trials stored before are intact\. "
        f"{advice}",
        lines[0],
    )
    assert m, lines[0]
    kept = int(m[2])
    assert int(m[1]) == kept + 1 and 0 < kept < N_TRIALS
    with RunFile.open(folder / "run.h5") as f:
        assert f.records.ids() == list(range(1, kept + 1))
        checked = verify(f)
    assert checked["ok"] and checked["records"] == kept, checked
    assert not [p for p in folder.iterdir() if p.name.startswith(".labcli-")]
    return kept


def test_acquire_under_a_file_size_limit_keeps_its_trials_and_resumes_once_the_limit_is_raised(tmp_path):
    (tmp_path / "plan.csv").write_text(PLAN)
    r = labcli(*ACQUIRE, cwd=tmp_path, limit=LIMIT)
    kept = stopped_part_way(
        tmp_path,
        r,
        r"run\.h5 cannot grow past the file size limit of 1\.6 MB \(ulimit -f\)",
        r"Raise the limit, then try again\.",
    )
    r = labcli("acquire", "run.h5", "--port", SIM, "--unattended", "--rate", "2000", "--resume", cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    assert f"Session complete: {N_TRIALS} trials stored in run.h5 ({N_TRIALS - kept} this session" in r.stdout
    with RunFile.open(tmp_path / "run.h5") as f:
        assert f.records.ids() == list(range(1, N_TRIALS + 1))


def test_acquire_on_a_full_disk_keeps_its_trials(small_disk):
    disk = small_disk("1600k")
    (disk / "plan.csv").write_text(PLAN)
    r = labcli(*ACQUIRE, cwd=disk)
    stopped_part_way(disk, r, r"The disk holding run\.h5 is full \(\d+ kB free\)", r"Free some space, then try again\.")


@pytest.fixture(scope="module")
def table(tmp_path_factory) -> tuple[Path, int]:
    path = tmp_path_factory.mktemp("table") / "big.csv"
    return path, big_table(path)


@pytest.mark.parametrize("force", [False, True])
def test_import_under_a_file_size_limit_leaves_nothing_half_written(tmp_path, table, force):
    csv, n = table
    args = ["import", str(csv), "-o", "run.h5", "--protocol", "takuma2014"]
    if force:  # an existing run in the way: kept byte for byte
        assert (
            labcli(
                "import",
                str(ROOT / "sample_runs" / "trials.csv"),
                "-o",
                "run.h5",
                "--protocol",
                "takuma2014",
                cwd=tmp_path,
            ).returncode
            == 0
        )
        args.append("--force")
    before = listing(tmp_path)
    r = labcli(*args, cwd=tmp_path, limit=3000 * 1024)
    kept = "run.h5 is as it was" if force else "no file was made"
    assert (r.returncode, r.stderr) == (
        1,
        f"Error: run.h5 cannot grow past the file size limit of 3.1 MB (ulimit -f), "
        f"so the batch of {n} trials was not written; {kept}. Raise the limit, "
        "then try again.\n",
    )
    assert listing(tmp_path) == before  # no output, no temporary file, the old run unchanged
    assert [p.name for p in tmp_path.iterdir() if p.name.startswith(".")] == []


def test_import_on_a_full_disk_leaves_nothing_half_written(small_disk, table):
    csv, n = table
    disk = small_disk("1600k")
    r = labcli("import", str(csv), "-o", "run.h5", "--protocol", "takuma2014", cwd=disk)
    assert r.returncode == 1, r.stderr
    assert re.fullmatch(
        rf"Error: The disk holding run\.h5 is full \((\d+ kB|\d+\.\d MB) free\), so the batch of {n} "
        r"trials was not written; no file was made\. Free some space, then try again\.\n",
        r.stderr,
    ), r.stderr
    assert list(disk.iterdir()) == []
