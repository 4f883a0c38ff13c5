"""One writer per run file: every other labcli process that would replace or add to a run being
recorded is refused in one sentence, readers are served, and the recording completes whole.

The live run is a real ``labcli acquire`` process on the simulated rig, driven at its prompts
through a pipe: it is held at the load prompt of trial 2 (trial 1 committed, the file open and
locked) while the other processes act, so the test does not depend on how fast either side
runs.  Two fresh acquisitions of one path started together leave exactly one run, whole, and
the other is refused in one sentence; a few pairs run by default, many in the ``slow`` campaign.
"""

from __future__ import annotations

import hashlib
import json
import os
import subprocess
import sys
from pathlib import Path

import pytest
from test_acquire_pty import REVIEW, Session

from labcli.core.store import RunFile
from labcli.core.store.verify import verify

ROOT = Path(__file__).resolve().parents[2]
SIM = "sim://?seed=2&clock=virtual"
PLAN = "trial,set,mass_g,direction_deg\n1,fit,800,-60\n2,fit,500,30\n3,validation,800,150\n"
BUSY = "Error: run.h5 is open in another program (a viewer, or a run still recording); close it there and try again"


def start(*args: str, cwd: Path) -> subprocess.Popen:
    env = dict(os.environ, COLUMNS="300", PYTHONPATH=str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    return subprocess.Popen(
        [sys.executable, "-m", "labcli", *args],
        cwd=cwd,
        env=env,
        stdin=subprocess.DEVNULL,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )


def finish(proc: subprocess.Popen) -> tuple[int, str, str]:
    out, err = proc.communicate(timeout=120)
    return proc.returncode, out, err


def sha(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def answer_trial(s: Session, label: str, *, prompted: bool = False) -> None:
    """Enter at the load prompts, then accept (``prompted``: the load prompt was already seen)."""
    if not prompted:
        s.expect(f"{label}: hang")
    s.type("")
    s.expect(f"{label}: remove the weight, then press Enter")
    s.type("")
    s.expect(REVIEW)
    s.type("a")


# What each writer is told while the run records: the lock's one sentence, naming the file.
WRITERS = {
    "acquire --force": (
        ["acquire", "run.h5", "--force", "--port", "sim://?seed=5&clock=virtual", "--unattended", "--plan", "plan.csv"],
        f"{BUSY}; --force never replaces a run another program has open.",
    ),
    "import --force": (
        ["import", "t.csv", "-o", "run.h5", "--force", "--protocol", "takuma2014"],
        f"{BUSY}; --force never replaces a run another program has open.",
    ),
    "fit": (["fit", "run.h5", "--form", "paper"], f"{BUSY}."),
    "split": (["split", "run.h5", "--fit", "1", "--validation", "0"], f"{BUSY}."),
}


def test_writers_are_refused_readers_served_and_the_live_run_completes(tmp_path, invoke):
    (tmp_path / "plan.csv").write_text(PLAN)
    (tmp_path / "t.csv").write_bytes((ROOT / "sample_runs" / "trials.csv").read_bytes())
    run = tmp_path / "run.h5"
    s = Session(["run.h5", "--port", SIM, "--plan", "plan.csv"], cwd=tmp_path)
    try:
        # The simulated board supplies and holds the chambers by command: the first prompt is the first load.
        answer_trial(s, "Trial 1/3 (fit)")
        s.expect("Trial 2/3 (fit): hang")  # trial 1 is committed; the run waits at the rig, file open
        before = sha(run)
        procs = {name: start(*args, cwd=tmp_path) for name, (args, _) in WRITERS.items()}
        readers = {
            "inspect": start("inspect", "run.h5", "--json", cwd=tmp_path),
            "export": start("export", "run.h5", "-o", "so-far.csv", cwd=tmp_path),
        }
        results = {name: finish(p) for name, p in {**procs, **readers}.items()}
        assert s.proc.poll() is None, "the recording ended before the others had acted"
        got = {name: results[name][0:3:2] for name in WRITERS}
        assert got == {name: (1, want + "\n") for name, (_, want) in WRITERS.items()}
        assert sha(run) == before  # nothing written into the run by the refused writers
        assert not (tmp_path / "run.model.json").exists()  # the refused fit left no model file behind
        for name in readers:
            code, out, err = results[name]
            assert code == 0 and "Traceback" not in err, (name, err)
        shown = json.loads(results["inspect"][1])
        assert (shown["complete"], shown["planned"]) == (1, 3)
        assert (tmp_path / "so-far.csv").read_text().count("\n") == 2  # header and trial 1

        answer_trial(s, "Trial 2/3 (fit)", prompted=True)
        answer_trial(s, "Trial 3/3 (validation)")
        s.expect("Session complete: 3 trials stored in run.h5")
        assert s.finish() == 0, s.out
    finally:
        if s.proc.poll() is None:
            s.proc.kill()
    whole(run, [1, 2, 3])
    # The run is free again: the writer refused above now works.
    result = invoke(*WRITERS["split"][0][:1], run, *WRITERS["split"][0][2:])
    assert result.exit_code == 0, result.output


def whole(run: Path, ids: list[int]) -> None:
    """The run opens with exactly ``ids`` complete, and every record and raw window checks out."""
    with RunFile.open(run) as f:
        assert f.records.ids() == ids
        checked = verify(f)
    assert checked["ok"] and checked["records"] == len(ids), checked


def race(tmp_path: Path, seeds: tuple[int, int]) -> None:
    """Two fresh acquisitions of one path at once: one run, whole; the other refused in one sentence."""
    (tmp_path / "plan.csv").write_text(PLAN.splitlines()[0] + "\n" + PLAN.splitlines()[1] + "\n")
    run = tmp_path / "new.h5"
    run.unlink(missing_ok=True)
    procs = [
        start(
            "acquire",
            "new.h5",
            "--port",
            f"sim://?seed={seed}&clock=virtual",
            "--unattended",
            "--plan",
            "plan.csv",
            cwd=tmp_path,
        )
        for seed in seeds
    ]
    results = [finish(p) for p in procs]
    codes = sorted(code for code, _, _ in results)
    assert codes == [0, 1], results
    ((_, won, _),) = [r for r in results if r[0] == 0]
    ((_, _, lost),) = [r for r in results if r[0] == 1]
    assert "Session complete: 1 trial stored in new.h5" in won
    assert lost in (
        "Error: new.h5 already exists; continue it with --resume, or pass --force to overwrite it.\n",
        "Error: new.h5 is open in another program (a viewer, or a run still recording); close it "
        "there and try again.\n",
    ), lost
    whole(run, [1])
    assert [p.name for p in tmp_path.iterdir() if p.name.startswith(".labcli-")] == []  # no builder's leftovers


def test_two_fresh_acquisitions_of_one_path_leave_one_run(tmp_path):
    for i in range(2):
        race(tmp_path, (2 * i + 1, 2 * i + 2))


@pytest.mark.slow
def test_two_fresh_acquisitions_of_one_path_leave_one_run_many(tmp_path):
    for i in range(40):
        race(tmp_path, (2 * i + 1, 2 * i + 2))
