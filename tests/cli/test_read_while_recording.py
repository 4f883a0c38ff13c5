"""A run can be read while it is recorded: other processes load the trials completed so far,
and the acquisition goes on to complete every trial intact.

Several readers read in a loop, each opening the file afresh every time, so that some of them
open it while a commit's checkpoint copies HDF5's pages in (a torn read, which a reader reads
again).  Every read gives trials 1..n, whole, with no warning; a read never gives fewer trials
than any read that ended before it began, in any reader.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import labcli

ROOT = Path(__file__).resolve().parents[2]
READERS = 2
# One line a read: when it began and ended (the system's monotonic clock, shared by every
# process), trials read, the last trial's id, and the warnings or the error it gave.
READ_LOOP = """
import os, sys, time, warnings, labcli
path, stop = sys.argv[1], sys.argv[2]
while not os.path.exists(path) and not os.path.exists(stop):
    time.sleep(0.01)
while not os.path.exists(stop):
    began = time.monotonic()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            t = labcli.load_trials(path)
            n, last, said = len(t), int(t["trial"].max()) if len(t) else 0, ""
        except Exception as e:
            n, last, said = -1, -1, f"{type(e).__name__}: {e}"
    said = " | ".join([said, *(str(w.message) for w in caught)]).strip(" |")
    print(began, time.monotonic(), n, last, said.replace(chr(10), " "), flush=True)
"""


def reads_of(out: str) -> list[tuple[float, float, int, int, str]]:
    rows = []
    for line in out.splitlines():
        began, ended, n, last, *said = line.split(" ", 4)
        rows.append((float(began), float(ended), int(n), int(last), " ".join(said)))
    return rows


def test_reader_processes_load_the_completed_trials_while_the_run_goes_on(tmp_path):
    run, stop = tmp_path / "run.h5", tmp_path / "stop"
    writer = subprocess.Popen(
        [sys.executable, "-m", "labcli", "acquire", str(run), "--port", "sim://?seed=2", "--unattended"],
        cwd=tmp_path,
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
    )
    readers = [
        subprocess.Popen(
            [sys.executable, "-c", READ_LOOP, str(run), str(stop)], cwd=ROOT, stdout=subprocess.PIPE, text=True
        )
        for _ in range(READERS)
    ]
    try:
        out, _ = writer.communicate(timeout=300)
    finally:
        stop.touch()
        if writer.poll() is None:
            writer.kill()
    reads = [reads_of(r.communicate(timeout=120)[0]) for r in readers]
    assert writer.returncode == 0, out
    assert "Session complete: 108 trials stored" in out
    everything = [read for mine in reads for read in mine]
    assert [read for read in everything if read[4] or read[2] != read[3]] == []  # 1..n whole, nothing said
    for mine in reads:
        assert any(0 < n < 108 for _, _, n, _, _ in mine), mine  # each reader read mid-run
        assert [n for _, _, n, _, _ in mine] == sorted(n for _, _, n, _, _ in mine)
    # Across readers: a read that began after another ended read at least as many trials.
    for began, _, n, _, _ in everything:
        before = [m for _, ended, m, _, _ in everything if ended < began]
        assert n >= max(before, default=0), (began, n, max(before))
    trials = labcli.load_trials(run)
    assert trials["trial"].tolist() == list(range(1, 109))
