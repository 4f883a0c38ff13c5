"""A killed import's temporary file is removed at the next start; a live builder's is left alone.

``labcli import`` builds its run under ``.labcli-import-<random>.partial`` beside the output,
held open (and so locked) until it is put in place.  One import is killed (SIGKILL) while its
file is being built; another is paused (SIGSTOP) at the same point, still holding its lock.
The next import into the folder removes the killed one's file only (the killed one, starting
while the other was paused, had left that one's alone); the paused one, resumed, completes its run.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

from support.big_table import big_table

from labcli.core.store import RunFile

ROOT = Path(__file__).resolve().parents[2]


def start_import(csv: Path, out: str, cwd: Path) -> subprocess.Popen:
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    return subprocess.Popen(
        [sys.executable, "-m", "labcli", "import", str(csv), "-o", out, "--protocol", "takuma2014"],
        cwd=cwd,
        env=env,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )


def partials(folder: Path) -> set[str]:
    return {p.name for p in folder.iterdir() if p.name.startswith(".labcli-import-") and p.name.endswith(".partial")}


def caught_building(proc: subprocess.Popen, folder: Path, known: set[str], sig: int) -> str:
    """Send ``sig`` to the import the moment its temporary file appears; that file's name."""
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline:
        new = partials(folder) - known
        if new:
            proc.send_signal(sig)
            return new.pop()
        assert proc.poll() is None, f"the import finished before its temporary file was seen: {proc.stderr.read()}"
        time.sleep(0.002)
    raise AssertionError("no temporary file appeared within 120 s")


def test_a_killed_imports_file_is_cleaned_at_the_next_start_and_a_live_ones_kept(tmp_path):
    csv = tmp_path / "big.csv"
    n = big_table(csv)
    out = tmp_path / "out"
    out.mkdir()

    paused = start_import(csv, "paused.h5", out)
    try:
        live = caught_building(paused, out, set(), signal.SIGSTOP)
        killed = start_import(csv, "killed.h5", out)  # its own start leaves the paused builder's file alone
        dead = caught_building(killed, out, {live}, signal.SIGKILL)
        killed.wait(60)
        assert partials(out) == {dead, live} and not (out / "killed.h5").exists()

        r = subprocess.run(
            [
                sys.executable,
                "-m",
                "labcli",
                "import",
                str(ROOT / "sample_runs" / "trials.csv"),
                "-o",
                "next.h5",
                "--protocol",
                "takuma2014",
            ],
            cwd=out,
            capture_output=True,
            text=True,
            env=dict(os.environ, PYTHONPATH=str(ROOT)),
            timeout=120,
        )
        assert r.returncode == 0, r.stderr
        assert partials(out) == {live}  # the killed import's file is gone; the paused builder still holds its own
    finally:
        paused.send_signal(signal.SIGCONT)
    _, err = paused.communicate(timeout=120)
    assert paused.returncode == 0, err
    assert partials(out) == set()
    assert sorted(p.name for p in out.iterdir()) == ["next.h5", "paused.h5"]
    with RunFile.open(out / "paused.h5") as f:
        assert len(f.records.ids()) == n
