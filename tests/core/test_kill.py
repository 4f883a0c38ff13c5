"""Crash safety: a process writing trials is killed with SIGKILL at random moments.

After every kill the file must open, every complete trial must be bit-for-bit
what the writer was given (``store_fixtures.make_record``), nothing complete
before the kill may be lost, and the unfinished trial is ignored and replaced
when the next writer resumes.
"""

from __future__ import annotations

import os
import random
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from support.records import assert_record_stored, make_record

from labcli.core.store import RunFile

WRITER = Path(__file__).resolve().parents[1] / "support" / "records.py"
ROOT = Path(__file__).resolve().parents[2]
N_TRIALS = 1_000_000  # never reached: the writer is always killed first


def start_writer(path: str, n_samples: int) -> subprocess.Popen:
    env = dict(os.environ, PYTHONPATH=str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    proc = subprocess.Popen(
        [sys.executable, str(WRITER), path, str(N_TRIALS), str(n_samples)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        env=env,
    )
    line = proc.stdout.readline()
    if line != b"ready\n":
        proc.kill()
        proc.wait()
        raise AssertionError(f"writer did not start: {line!r} {proc.stderr.read()!r}")
    return proc


def kill_loop(
    path: str, kills: int, n_samples: int, seed: int, max_delay_s: float, require_progress: bool = True
) -> None:
    rng = random.Random(seed)
    verified: set[int] = set()
    for k in range(kills):
        proc = start_writer(path, n_samples)
        if k == 0:
            # While a writer holds the file, a reader opens it and sees only whole trials.
            with RunFile.open(path) as run:
                seen = run.records.ids()
                assert seen == list(range(len(seen)))
                for i in seen:
                    assert_record_stored(run.records.read(i), make_record(i, n_samples))
        if require_progress:
            # one trial stored by this writer first, so every round adds to what must survive
            assert proc.stdout.readline().startswith(b"stored ")
        time.sleep(rng.uniform(0.0, max_delay_s))
        proc.send_signal(signal.SIGKILL)
        proc.wait()
        assert proc.returncode == -signal.SIGKILL, proc.stderr.read().decode()
        with RunFile.open(path) as run:
            ids = run.records.ids()
            # the writer always writes the first missing id, so complete ids are dense
            assert ids == list(range(len(ids)))
            assert verified <= set(ids), "a trial complete before the kill was lost"
            for i in sorted(set(ids) - verified):
                assert_record_stored(run.records.read(i), make_record(i, n_samples))
            verified |= set(ids)
            incomplete = run.records.incomplete_ids()
            assert incomplete in ([], [len(ids)])
            assert len(run.records.table()) == len(ids)
            assert run.records.first_incomplete(range(N_TRIALS)) == len(ids)
    # At the end, everything once complete is still intact (later writes touched nothing).
    with RunFile.open(path) as run:
        for i in run.records.ids():
            assert_record_stored(run.records.read(i), make_record(i, n_samples))
    if require_progress:
        assert len(verified) >= kills


def test_kill_during_writes(tmp_path):
    kill_loop(str(tmp_path / "run.h5"), kills=6, n_samples=200, seed=1, max_delay_s=0.3)


@pytest.mark.slow
def test_kill_during_writes_many(tmp_path):
    kill_loop(str(tmp_path / "run.h5"), kills=60, n_samples=400, seed=2, max_delay_s=0.25)


@pytest.mark.slow
def test_kill_soon_after_resume_many(tmp_path):
    """Kills within the first trial after a resume: the leftovers of one kill meet the next writer."""
    kill_loop(str(tmp_path / "run.h5"), kills=80, n_samples=300, seed=11, max_delay_s=0.1, require_progress=False)


def test_kill_during_create_leaves_no_half_run(tmp_path):
    """A kill before the file is whole leaves either nothing or a complete empty run."""
    rng = random.Random(3)
    for k in range(5):
        path = str(tmp_path / f"run{k}.h5")
        env = dict(os.environ, PYTHONPATH=str(ROOT))
        proc = subprocess.Popen(
            [sys.executable, str(WRITER), path, str(N_TRIALS), "50"],
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
            env=env,
        )
        time.sleep(rng.uniform(0.2, 1.0))  # somewhere in interpreter start-up, create, or the first trials
        proc.send_signal(signal.SIGKILL)
        proc.wait()
        if os.path.exists(path):
            with RunFile.open(path) as run:
                assert run.attrs["schema"] == "labcli-run"
                for i in run.records.ids():
                    assert_record_stored(run.records.read(i), make_record(i, 50))
