"""A run can be read while it is recorded: another process loads the trials completed so far,
and the acquisition goes on to complete every trial intact."""

from __future__ import annotations

import subprocess
import sys
import time
from pathlib import Path

import pytest

import labcli

ROOT = Path(__file__).resolve().parents[2]
READ = "import sys, labcli; t = labcli.load_trials(sys.argv[1]); print(len(t), int(t['trial'].max()) if len(t) else 0)"


@pytest.mark.xfail(
    strict=False,
    reason="known fault, open: on a loaded machine a reader mid-run of a schema-3 run file has twice read "
    "0 trials after it had read 34 (never a partial trial); the cause is not yet found",
)
def test_a_reader_process_loads_the_completed_trials_while_the_run_goes_on(tmp_path):
    run = tmp_path / "run.h5"
    writer = subprocess.Popen(
        [sys.executable, "-m", "labcli", "acquire", str(run), "--port", "sim://?seed=2", "--unattended"],
        cwd=tmp_path,
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
    )
    seen = []
    try:
        deadline = time.monotonic() + 120
        while writer.poll() is None and time.monotonic() < deadline:
            if run.exists():
                r = subprocess.run(
                    [sys.executable, "-c", READ, str(run)], cwd=ROOT, capture_output=True, text=True, timeout=60
                )
                if r.returncode == 0:
                    n, last = map(int, r.stdout.split())
                    assert n == last  # trials 1..n, each whole: no partial trial is ever read
                    seen.append(n)
            time.sleep(0.3)
        out, _ = writer.communicate(timeout=120)
    finally:
        if writer.poll() is None:
            writer.kill()
    assert writer.returncode == 0, out
    assert "Session complete: 108 trials stored" in out
    assert any(0 < n < 108 for n in seen), seen  # read mid-run
    assert seen == sorted(seen)
    trials = labcli.load_trials(run)
    assert trials["trial"].tolist() == list(range(1, 109))
