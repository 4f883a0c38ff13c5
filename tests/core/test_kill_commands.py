"""Crash safety of every writer that changes a run, not only acquire: ``split``, ``fit`` recording its
model in the run, and ``import`` building one, each killed (SIGKILL) at chosen writes to the file,
the way ``strace -e inject=pwrite64:signal=KILL:when=N`` kills them.  After each kill the run
verifies, its trials are the ones it held, and the next writer (split, fit) extends it; a killed
import leaves no run, or a whole one, and nothing the next import trips on."""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import sys
from pathlib import Path

import pytest

KILL_CLI = Path(__file__).resolve().parents[1] / "support" / "kill_cli.py"
ROOT = Path(__file__).resolve().parents[2]
KILLS = 4  # kills spread over each command's writes: the first, the last and two between


def run(write: int, *args: str, cwd: Path) -> subprocess.CompletedProcess:
    env = dict(os.environ, PYTHONPATH=str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    return subprocess.run(
        [sys.executable, str(KILL_CLI), str(write), *args],
        cwd=cwd,
        capture_output=True,
        text=True,
        timeout=120,
        env=env,
        stdin=subprocess.DEVNULL,
    )


def labcli(*args: str, cwd: Path) -> subprocess.CompletedProcess:
    return run(-1, *args, cwd=cwd)


def writes_of(*args: str, cwd: Path) -> int:
    r = run(0, *args, cwd=cwd)
    assert r.returncode == 0, r.stderr
    return int(r.stdout.rsplit("writes ", 1)[1])


def spread(total: int) -> list[int]:
    return sorted({1, total, *(1 + (total - 1) * k // (KILLS - 1) for k in range(KILLS))})


@pytest.fixture(scope="module")
def world(tmp_path_factory: pytest.TempPathFactory) -> Path:
    import pandas as pd

    from labcli.papers.takuma2014.models.synthetic import paper_trials
    from labcli.papers.takuma2014.tables import write_trial_csv

    w = tmp_path_factory.mktemp("kill")
    table = pd.concat(
        [paper_trials(16, seed=1), paper_trials(4, seed=2, set_name="validation", start_id=17)], ignore_index=True
    )
    write_trial_csv(table, w / "trials.csv")
    r = labcli("import", "trials.csv", "-o", "run.h5", "--protocol", "takuma2014", cwd=w)
    assert r.returncode == 0, r.stderr
    r = labcli("export", "run.h5", "-o", "before.csv", cwd=w)
    assert r.returncode == 0, r.stderr
    return w


def fresh(world: Path, tmp_path: Path) -> Path:
    here = tmp_path / "w"
    shutil.copytree(world, here)
    return here


def trials(table: Path) -> list[str]:
    """A trial table's rows without the ``set`` column (a split killed after its commit is the new one)."""
    rows = [line.split(",") for line in table.read_text().splitlines()]
    j = rows[0].index("set")
    return [",".join(r[:j] + r[j + 1 :]) for r in rows]


def assert_intact_and_extendable(here: Path) -> None:
    """The run verifies, holds the trials it held, and split and fit (recording) still write it."""
    r = labcli("inspect", "--verify", "run.h5", cwd=here)
    assert r.returncode == 0, r.stdout + r.stderr
    r = labcli("export", "run.h5", "-o", "after.csv", cwd=here)
    assert r.returncode == 0, r.stderr
    assert trials(here / "after.csv") == trials(here / "before.csv")  # the split: the old or the new one
    r = labcli("split", "run.h5", "--fit", "15", "--validation", "5", "--strategy", "random", "--seed", "3", cwd=here)
    assert r.returncode == 0, r.stderr
    r = labcli("fit", "run.h5", "--form", "paper", cwd=here)
    assert r.returncode == 0, r.stderr
    assert "recorded in run.h5" in r.stdout
    r = labcli("inspect", "--verify", "run.h5", cwd=here)
    assert r.returncode == 0, r.stdout + r.stderr


def killed_at_spread_writes(world, tmp_path, args: tuple[str, ...]):
    """Each directory where ``labcli *args`` was killed at one of its spread writes."""
    total = writes_of(*args, cwd=fresh(world, tmp_path / "count"))
    assert total >= 3
    for write in spread(total):
        here = fresh(world, tmp_path / f"k{write}")
        r = run(write, *args, cwd=here)
        assert r.returncode == -signal.SIGKILL, (write, r.returncode, r.stderr)
        yield here


def test_split_killed_at_chosen_writes_leaves_a_run_the_next_writer_extends(world, tmp_path):
    args = ("split", "run.h5", "--fit", "14", "--validation", "6", "--strategy", "random", "--seed", "1")
    for here in killed_at_spread_writes(world, tmp_path, args):
        assert_intact_and_extendable(here)


def test_fit_recording_its_model_killed_at_chosen_writes_leaves_a_run_the_next_writer_extends(world, tmp_path):
    for here in killed_at_spread_writes(world, tmp_path, ("fit", "run.h5", "--form", "paper")):
        assert_intact_and_extendable(here)


def test_import_killed_at_chosen_writes_leaves_no_run_or_a_whole_one(world, tmp_path):
    args = ("import", "trials.csv", "-o", "new.h5", "--protocol", "takuma2014")
    for here in killed_at_spread_writes(world, tmp_path, args):
        if (here / "new.h5").exists():
            assert labcli("inspect", "--verify", "new.h5", cwd=here).returncode == 0
        r = labcli(*args, "--force", cwd=here)
        assert r.returncode == 0, (here.name, r.stderr)
        r = labcli("export", "new.h5", "-o", "again.csv", cwd=here)
        assert r.returncode == 0, r.stderr
        assert (here / "again.csv").read_text() == (here / "before.csv").read_text()
        assert sorted(p.name for p in here.iterdir() if p.name.startswith(".")) == [], "a partial file was left"


@pytest.mark.slow
@pytest.mark.parametrize(
    "args",
    [
        ("split", "run.h5", "--fit", "14", "--validation", "6", "--strategy", "random", "--seed", "1"),
        ("fit", "run.h5", "--form", "paper"),
    ],
    ids=["split", "fit"],
)
def test_killed_at_every_write(args, world, tmp_path):
    for write in range(1, writes_of(*args, cwd=fresh(world, tmp_path / "count")) + 1):
        here = fresh(world, tmp_path / f"k{write}")
        assert run(write, *args, cwd=here).returncode == -signal.SIGKILL
        assert_intact_and_extendable(here)
