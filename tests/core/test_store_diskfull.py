"""Writes into an existing run under `ulimit -f` or on a full tmpfs: one sentence, file untouched.

fit records its model in the run and split records the split; under a limit that leaves no room
for them, each says so in one sentence (what was kept), exits 1, and the run file is byte for
byte what it was, opening with every record it had.  An acquisition that reaches the limit while
it streams a capture window into the file stops there in one sentence; the file keeps the trials
completed before (the window's frames in no trial), its session log says "disk full", and the run
resumes to the end once there is room.
"""

from __future__ import annotations

import hashlib
import resource
import subprocess
from pathlib import Path

import pytest
from support import procs

from labcli.core.store import RunFile

ROOT = Path(__file__).resolve().parents[2]


def labcli(*args: str, cwd: Path, limit: int | None = None) -> subprocess.CompletedProcess:
    limits = {} if limit is None else {resource.RLIMIT_FSIZE: limit}
    return procs.labcli(*args, cwd=cwd, timeout=300, env={"PYTHONPATH": str(ROOT)}, limits=limits)


def sha(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


@pytest.fixture(scope="module")
def imported(tmp_path_factory) -> Path:
    folder = tmp_path_factory.mktemp("full")
    r = labcli(
        "import", str(ROOT / "sample_runs" / "trials.csv"), "-o", "run.h5", "--protocol", "takuma2014", cwd=folder
    )
    assert r.returncode == 0, r.stderr
    return folder / "run.h5"


@pytest.mark.parametrize("command", [("fit", "run.h5"), ("split", "run.h5", "--strategy", "random", "--seed", "7")])
def test_no_room_leaves_the_run_as_it_was(imported, tmp_path, command):
    run = tmp_path / "run.h5"
    run.write_bytes(imported.read_bytes())
    before = sha(run)
    with RunFile.open(run) as f:
        ids = f.records.ids()
    r = labcli(*command, cwd=tmp_path, limit=run.stat().st_size + 4096)
    assert r.returncode == 1, (r.stdout, r.stderr)
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in r.stderr, r.stderr
    assert "cannot grow past the file size limit" in lines[0] and "(ulimit -f)" in lines[0]
    assert f"the {len(ids)} trials stored before are intact" in lines[0]
    assert sha(run) == before
    with RunFile.open(run) as f:
        assert f.records.ids() == ids
    r = labcli(*command, cwd=tmp_path)  # with room again, the same command works
    assert r.returncode == 0, r.stderr


def test_acquire_reaching_the_limit_mid_window_keeps_the_trials_before_and_resumes(tmp_path):
    import h5py
    from support.long_capture import write_long_protocol

    write_long_protocol(tmp_path, 30.0)
    (tmp_path / "plan.csv").write_text(
        "trial,set,mass_g,direction_deg\n1,fit,800,-60\n2,fit,500,-60\n3,validation,1000,-60\n"
    )
    port = "sim://?seed=21&clock=virtual"
    r = labcli(
        "acquire",
        "run.h5",
        "--port",
        port,
        "--unattended",
        "--plan",
        "plan.csv",
        "--protocol",
        "long.toml",
        cwd=tmp_path,
        limit=1_700_000,
    )
    assert r.returncode == 1, (r.stdout, r.stderr)
    assert r.stderr == (
        "Error: run.h5 cannot grow past the file size limit of 1.7 MB (ulimit -f), so trial 2 was "
        "not written; the 1 trial stored before is intact. Raise the limit, then try again.\n"
    )
    run = tmp_path / "run.h5"
    with RunFile.open(run) as f:
        assert f.records.ids() == [1] and f.records.incomplete_ids() == []
        assert f.verify() == {"ok": True, "records": 1, "windows": 2, "problems": []}
        assert f.sessions.all()[-1]["how"] == "disk full"
    with h5py.File(run, "r") as f:  # trial 2's frames streamed before the limit lie past trial 1's
        assert f["entry/raw/time"].shape[0] > f["entry/trials/loaded_stop"][0] + 4096
    r = labcli("acquire", "run.h5", "--port", port, "--unattended", "--resume", cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    with RunFile.open(run) as f:
        assert f.records.ids() == [1, 2, 3]
        assert f.verify() == {"ok": True, "records": 3, "windows": 6, "problems": []}


@pytest.fixture
def full_disk(tmp_path):
    """``full_disk(run)``: a tmpfs holding a copy of ``run`` and a filler that leaves it no free
    block; skipped where this machine refuses to mount one (the ulimit tests cover the paths)."""
    import shutil
    import uuid

    where = tmp_path / "tmpfs"
    where.mkdir()
    mounted = []

    def make(run: Path) -> tuple[Path, Path]:
        size = (run.stat().st_size // 4096 + 64) * 4096
        r = subprocess.run(
            ["mount", "-t", "tmpfs", "-o", f"size={size}", f"labcli-{uuid.uuid4().hex[:8]}", str(where)],
            capture_output=True,
            text=True,
        )
        if r.returncode != 0:
            pytest.skip(f"cannot mount a tmpfs here ({(r.stderr or r.stdout).strip() or 'mount failed'})")
        mounted.append(where)
        shutil.copyfile(run, where / "run.h5")
        filler = where / "filler"
        with open(filler, "wb", buffering=0) as f:
            try:
                while True:
                    f.write(b"\0" * 4096)
            except OSError:
                pass
        return where / "run.h5", filler

    if shutil.which("mount") is None:
        pytest.skip("no mount command here")
    yield make
    for m in mounted:
        subprocess.run(["umount", str(m)], capture_output=True)


@pytest.mark.parametrize("command", [("fit", "run.h5"), ("split", "run.h5", "--strategy", "random", "--seed", "7")])
def test_a_full_disk_leaves_the_run_as_it_was(imported, full_disk, command):
    run, filler = full_disk(imported)
    before = sha(run)
    with RunFile.open(run) as f:
        ids = f.records.ids()
    r = labcli(*command, cwd=run.parent)
    assert r.returncode == 1, (r.stdout, r.stderr)
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in r.stderr, r.stderr
    if command[0] == "fit":  # the model file beside the run is written first, and is what cannot be
        assert lines[0] == "Error: Cannot write the model to run.model.json: No space left on device."
        assert sorted(p.name for p in run.parent.iterdir()) == ["filler", "run.h5"]  # no half-written model
    else:
        assert lines[0].startswith("Error: The disk holding run.h5 is full") and "Free some space" in lines[0], lines[0]
        assert f"the {len(ids)} trials stored before are intact" in lines[0]
    assert sha(run) == before
    with RunFile.open(run) as f:
        assert f.records.ids() == ids
    filler.unlink()  # with room again (and a disk the size of a lab's), the same command works
    subprocess.run(["mount", "-o", "remount,size=64m", str(run.parent)], check=True, capture_output=True)
    assert labcli(*command, cwd=run.parent).returncode == 0
