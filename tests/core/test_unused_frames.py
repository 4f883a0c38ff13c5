"""Raw frames no trial takes are marked in ``raw/unused`` with why: the windows of a redone, a skipped
and a quit trial, a baseline taken again after the air was supplied again, and what a SIGKILL left,
found on resuming.  Every frame written is a trial's or marked, once; ``inspect``, ``read_run`` and
the exports say how many; files without the marks read as before."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from support.long_capture import write_long_protocol
from support.standards import nxinspect_counts, punx_errors

import labcli
from labcli.cli import cli
from labcli.core.protocol import load_protocol
from labcli.core.store import RunFile
from labcli.core.store.unused import UNMARKED, Unused, mark

ROOT = Path(__file__).resolve().parents[2]
KILL_CLI = ROOT / "tests" / "support" / "kill_cli.py"
PLAN = "trial,set,mass_g,direction_deg\n1,fit,200,-60\n2,fit,500,30\n3,validation,300,150\n4,validation,400,-150\n"
PORT = "sim://?seed=7&clock=virtual"
REVIEW = "Accept [a], redo [r], skip [s], note [n] or quit [q]?"
HANG = "\n\n"  # weight hung, weight removed
ANSWERS = ["r", "a", "s", "a", "q"]  # trial 1 redone then accepted, 2 skipped, 3 accepted, 4 quit at its review


def written(run: RunFile) -> np.ndarray:
    """Which frames of raw/ were written (an unwritten frame's time is its fill, NaN)."""
    return np.isfinite(np.asarray(run.tables.frames.time[:], dtype=np.float64))


def trial_windows(run: RunFile) -> list[tuple[int, int]]:
    c = run.records.columns().cols
    return [
        (int(c[f"{w}_start"][i]), int(c[f"{w}_stop"][i]))
        for i in range(len(c["trial"]))
        for w in ("baseline", "loaded")
    ]


def assert_every_frame_once(run: RunFile, ranges: list[Unused]) -> None:
    """Each written frame is in exactly one trial window or one marked range; nothing else is."""
    owners = np.zeros(run.tables.frames.extent, dtype=int)
    for a, b in [*trial_windows(run), *((u.start, u.stop) for u in ranges)]:
        owners[a:b] += 1
    assert np.array_equal(owners, written(run).astype(int))


def attempts(output: str) -> list[int]:
    """Windows captured per trial attempt, read from what the session printed before each review."""
    return [seg.count("baseline: settled") + seg.count("load: settled") for seg in output.split(REVIEW)[:-1]]


@pytest.fixture(scope="module")
def scripted(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, str]:
    folder = tmp_path_factory.mktemp("unused")
    (folder / "plan.csv").write_text(PLAN)
    path = folder / "run.h5"
    answers = "".join(HANG + a + "\n" for a in ANSWERS)
    result = CliRunner().invoke(
        cli, ["acquire", str(path), "--port", PORT, "--plan", str(folder / "plan.csv")], input=answers
    )
    assert result.exit_code == 0, result.output
    return path, result.output


def test_a_scripted_session_marks_each_window_no_trial_took_and_why(scripted):
    path, output = scripted
    per_attempt = attempts(output)
    assert len(per_attempt) == len(ANSWERS) and all(n >= 2 for n in per_attempt)
    # What the answers mean for each attempt's windows: a redo, a skip or a quit leaves them all; an
    # accepted trial takes its last baseline and its load, a baseline before them was taken again.
    expected: list[tuple[str, int | None]] = []
    for answer, n, trial in zip(ANSWERS, per_attempt, (1, 1, 2, 3, 4), strict=True):
        if answer == "a":
            expected += [("retaken", trial)] * (n - 2)
        else:
            why = {"r": "redone", "s": "skipped", "q": "interrupted"}[answer]
            expected += [(why, None if why == "interrupted" else trial)] * n
    proto = load_protocol("takuma2014")
    frames_per_window = round(proto.settling.capture_s * proto.rate_hz)
    with RunFile.open(path) as run:
        ranges = run.windows.unused()
        assert run.records.ids() == [1, 3]
        assert [(u.why, u.record) for u in ranges] == expected
        assert {u.frames for u in ranges} == {frames_per_window}  # each a whole window
        assert {u.session for u in ranges} == {1}
        assert_every_frame_once(run, ranges)
        assert run.sessions.all()[0]["redone"] == [1] and run.sessions.all()[0]["skipped"] == [2]
    by = {why: sum(u.frames for u in ranges if u.why == why) for why, _ in expected}
    parts = ", ".join(f"{n} {why}" for why, n in by.items())
    result = CliRunner().invoke(cli, ["inspect", str(path)])
    assert result.exit_code == 0, result.output
    assert f"  raw         {sum(by.values())} frames in no trial ({parts})\n" in result.output
    assert labcli.read_run(path).attrs["provenance"]["unused_frames"] == by


def test_a_resumed_session_keeps_the_marks_and_adds_none(scripted, tmp_path):
    path = tmp_path / "run.h5"
    shutil.copy(scripted[0], path)
    with RunFile.open(path) as run:
        before = run.windows.unused()
    result = CliRunner().invoke(cli, ["acquire", str(path), "--port", PORT, "--resume"], input=(HANG + "a\n") * 2)
    assert result.exit_code == 0, result.output
    with RunFile.open(path) as run:
        after = run.windows.unused()
        assert run.records.ids() == [1, 3, 2, 4]  # the skipped trial is asked again
        assert_every_frame_once(run, after)
    assert after[: len(before)] == before and all(u.why == "retaken" for u in after[len(before) :])


def test_the_marks_are_what_the_nexus_validators_accept(scripted):
    path, _ = scripted
    warnings, errors, report = nxinspect_counts(path)
    assert (warnings, errors) == (0, 0), report
    errors, lines = punx_errors(path)
    assert errors == 0, lines


def _kill_at(write: int, path: Path, *args: str) -> subprocess.CompletedProcess:
    """``labcli acquire path args...``, SIGKILLed at its ``write``-th write to a run file (0: none, the
    count printed)."""
    env = dict(os.environ, PYTHONPATH=str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    return subprocess.run(
        [sys.executable, str(KILL_CLI), str(write), "acquire", str(path), "--port", PORT, "--unattended", *args],
        capture_output=True,
        text=True,
        timeout=120,
        env=env,
        stdin=subprocess.DEVNULL,
    )


@pytest.fixture(scope="module")
def killed(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, list[Unused]]:
    """A run SIGKILLed in trial 2 after some of its frames reached the file, and those frames."""
    folder = tmp_path_factory.mktemp("killed")
    # 10 s windows at 1 kHz fill chunks of frames as they arrive, so a kill mid-trial leaves some in the file.
    protocol = write_long_protocol(folder, capture_s=10.0)
    plan = folder / "plan.csv"
    plan.write_text("\n".join(PLAN.splitlines()[:3]) + "\n")
    args = ("--protocol", str(protocol), "--plan", str(plan))
    done = _kill_at(0, folder / "whole.h5", *args)
    assert done.returncode == 0, done.stderr
    total = int(done.stdout.rsplit("writes ", 1)[1])
    for fraction in (0.8, 0.85, 0.75, 0.9, 0.7):  # a write inside trial 2, after a chunk of its frames
        path = folder / f"killed-{fraction}.h5"
        assert _kill_at(int(total * fraction), path, *args).returncode == -9
        with RunFile.open(path, "a"):  # the journal replayed: the file as the kill left it, by itself
            pass
        with RunFile.open(path) as run:
            left = run.windows.unused()
            if left and run.records.ids() == [1]:
                return path, left
    pytest.fail("no kill left frames of trial 2 in the file")


def test_frames_a_kill_left_are_marked_interrupted_when_the_run_is_resumed(killed, tmp_path):
    path = tmp_path / "run.h5"
    shutil.copy(killed[0], path)
    left = killed[1]
    assert {u.why for u in left} == {UNMARKED}
    with RunFile.open(path) as run:
        assert run.windows.unused() == left  # reading marks nothing
        assert run.summary()["unused_frames"]["by_reason"] == {UNMARKED: sum(u.frames for u in left)}
        assert_every_frame_once(run, left)
    result = CliRunner().invoke(cli, ["acquire", str(path), "--port", PORT, "--resume", "--unattended"])
    assert result.exit_code == 0, result.output
    with RunFile.open(path) as run:
        marked = run.windows.unused()
        assert run.records.ids() == [1, 2]
        assert run.verify()["ok"]
        assert_every_frame_once(run, marked)
    assert [(u.start, u.stop) for u in marked] == [(u.start, u.stop) for u in left]
    assert {(u.why, u.record, u.session) for u in marked} == {("interrupted", None, 2)}
    n = sum(u.frames for u in left)
    result = CliRunner().invoke(cli, ["inspect", str(path)])
    assert f"  raw         {n} frames in no trial ({n} interrupted)\n" in result.output


def test_a_kill_while_the_marks_are_made_leaves_all_of_them_or_none(killed, tmp_path):
    # The killed run as a run from before the marks (no raw/unused, its attribute checksum taken
    # again): resuming it makes the table, retakes the checksum and commits the marks with the
    # session's start.  Killed at writes spread over that commit and past it, the run reads without
    # a warning (an error under pytest here), verifies, and holds every mark or none.
    import h5py

    from labcli.core.store.nexus import home
    from labcli.core.store.opening import metadata_checksum

    legacy = tmp_path / "legacy.h5"
    shutil.copy(killed[0], legacy)
    with h5py.File(legacy, "a") as f:
        del f["entry/raw/unused"]
        home(f).modify("metadata_checksum", np.uint64(metadata_checksum(f)))
    spans = [(u.start, u.stop) for u in killed[1]]
    seen = set()
    for write in (1, 20, 40, 55, 200):
        path = tmp_path / f"resumed-{write}.h5"
        shutil.copy(legacy, path)
        assert _kill_at(write, path, "--resume").returncode == -9
        with RunFile.open(path) as run:
            ranges = run.windows.unused()
            assert run.verify()["ok"]
        before, after = ranges[: len(spans)], ranges[len(spans) :]
        assert [(u.start, u.stop) for u in before] == spans
        whys = {u.why for u in before}
        assert whys in ({UNMARKED}, {"interrupted"})
        # Past the marks, the resumed session's own trial in progress: not marked yet.
        assert all(u.why == UNMARKED and u.start >= spans[-1][1] for u in after)
        seen |= whys
    assert seen == {UNMARKED, "interrupted"}  # the kills fell before the marks' commit and after it


def test_a_run_from_before_the_marks_is_given_them_and_still_checks_out(tmp_path):
    # tests/data/v3/force-before-marks.h5, the sample run as it was written before the marks (no
    # raw/unused), has baselines its trials took again after the air was supplied again
    # (unattended: never a redo).  Read, they are unmarked; resumed, they are marked
    # ``unknown`` (a run from before the marks cannot say redo from retake), a window left after the
    # last trial ``interrupted``, and the file's attribute checksum is taken again (a mismatch would
    # be a LabcliWarning, an error under pytest here).
    path = tmp_path / "force.h5"
    shutil.copy(ROOT / "tests" / "data" / "v3" / "force-before-marks.h5", path)
    with RunFile.open(path, "a") as run:
        old = run.windows.unused()
        assert "unused" not in run.h5["entry/raw"] and {u.why for u in old} == {UNMARKED}
        assert_every_frame_once(run, old)
        last = max(b for _, b in trial_windows(run))
        assert all(u.stop <= last for u in old)
        n = len(run.channels)
        w = run.windows.begin("a window no trial takes")
        w.append(np.arange(300) * 0.005, np.arange(300), np.ones((300, n)), np.zeros((300, n)))
        stored = w.finish().stored
        marks = mark(run, "interrupted", None, 7, resuming=True)
        assert marks is not None
        run.writer.commit([marks], 0, "the marks")
    with RunFile.open(path) as run:
        ranges = run.windows.unused()
        windows = sorted(
            (a, i) for a, i in zip(run.records.columns().cols["baseline_start"], run.records.ids(), strict=True)
        )
        after = [next(i for a, i in windows if a >= u.stop) for u in old]
        assert ranges == [
            *(Unused(u.start, u.stop, "unknown", rid, 7) for u, rid in zip(old, after, strict=True)),
            Unused(stored.start, stored.stop, "interrupted", None, 7),
        ]
        assert ranges[-1].frames == 300
        assert run.verify()["ok"]


@pytest.mark.parametrize("name", ["v1/force.h5", "v2/float-counts.h5"])
def test_runs_without_the_marks_read_as_before(name):
    with RunFile.open(ROOT / "tests" / "data" / name) as run:
        assert run.windows.unused() == []
        assert "unused_frames" not in run.summary()
    result = CliRunner().invoke(cli, ["inspect", str(ROOT / "tests" / "data" / name)])
    assert result.exit_code == 0 and "frames in no" not in result.output


@pytest.mark.parametrize("damage", ["torn while a writer commits", "lasting"])
def test_a_row_of_marks_that_fails_its_checksum_is_read_again_before_it_is_said(
    scripted, tmp_path, monkeypatch, damage
):
    """A row of raw/unused copied in by a writer's checkpoint while a reader read it fails its
    checksum as a damaged row does: the reader opens the file afresh and reads again, and warns
    only of damage that is still there (a reader of a run being recorded saw such a warning)."""
    from labcli.core.store import space
    from labcli.core.store.columns import Table

    path = tmp_path / "run.h5"
    shutil.copy(scripted[0], path)
    with RunFile.open(path) as run:
        expected = run.windows.unused()
    monkeypatch.setattr(space, "writer_holds", lambda p: True)
    reads = []
    real_read = Table.read

    def read(self, *args, **kwargs):
        rows = real_read(self, *args, **kwargs)
        if self.g.name.endswith("/raw/unused"):
            reads.append(self.g.name)
            if damage == "lasting" or len(reads) == 1:
                rows.damaged.append((0, "its checksum does not match its values"))
        return rows

    monkeypatch.setattr(Table, "read", read)
    with RunFile.open(path) as run:
        if damage == "lasting":
            with pytest.warns(labcli.errors.LabcliWarning, match="row 0 of raw/unused: its checksum does not match"):
                ranges = run.windows.unused()
            assert len(reads) > 2  # read again before the damage was believed
        else:
            ranges = run.windows.unused()  # no warning: pyproject turns one into an error
            assert len(reads) == 2
    assert ranges == expected
