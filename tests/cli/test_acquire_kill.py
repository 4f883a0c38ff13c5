"""``labcli acquire`` killed at random moments: SIGKILL and SIGINT against a running process.

Each run is a real process, unattended on the simulated rig in virtual time
with a fixed seed, so its data are fixed by the seed.  A seeded schedule
picks the signal and the delay across the run; then the run is resumed
(``--resume``, killed again or not) until it completes.  After every kill:

* the file opens; every trial complete before is still complete and
  byte-identical (datasets and attributes); at most the trial being written
  is left incomplete, and it never counts;
* trials recorded by the first session of a file (never resumed) are
  byte-identical to a reference run of the same seed; trials recorded after
  a resume come from a freshly started rig, so they are held to their own
  snapshot from then on;
* SIGINT exits 130 with one sentence naming what was discarded, how many
  trials are safe and the exact resume command.

At the end every planned trial is stored once and the plan's split is set.
Where each kill landed is told from the file and the per-trial lines the
process printed (see :func:`phase`).
"""

from __future__ import annotations

import os
import random
import re
import signal
import subprocess
import sys
import threading
import time
from collections import Counter
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest
from support.long_capture import write_long_protocol
from support.procs import at_a_terminal
from support.records import stored_trials

from labcli.core.acquisition import acquire
from labcli.core.protocol import load_protocol
from labcli.core.store import RunFile
from labcli.core.store.records import Records
from labcli.core.store.split import Splits
from labcli.errors import StoreError
from labcli.papers.takuma2014.protocol import load_plan

ROOT = Path(__file__).resolve().parents[2]
SEED = 21
PORT = f"sim://?seed={SEED}&clock=virtual"
READY = "readings in range."  # printed once the setup check passed (just before the file is created)
REVIEW = "  trial "  # the unattended session prints one such line per trial, once it is stored


# ---------------------------------------------------------------- the file's contents


def trial_data(path: Path) -> dict[int, dict[str, Any]]:
    """Every complete trial's arrays and values (dtype, shape, bytes) and its metadata ("@" keys)."""
    return stored_trials(path)


def datasets(items: dict[str, Any]) -> dict[str, Any]:
    return {k: v for k, v in items.items() if not k.startswith("@")}


# ---------------------------------------------------------------- a process


class Acquire:
    """One ``labcli acquire`` process; stdout and stderr collected as they come."""

    def __init__(self, args: list[str], preexec: Callable[[], None] = at_a_terminal) -> None:
        env = dict(
            os.environ,
            PYTHONUNBUFFERED="1",
            COLUMNS="200",
            PYTHONPATH=str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""),
        )
        self.t0 = time.monotonic()
        self.proc = subprocess.Popen(
            [sys.executable, "-m", "labcli", "acquire", *args],
            cwd=ROOT,
            env=env,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            preexec_fn=preexec,
        )
        self.out: list[str] = []
        self.err: list[str] = []
        self.ready = threading.Event()
        self.t_ready: float | None = None
        self._threads = [
            threading.Thread(target=self._pump, args=(self.proc.stdout, self.out), daemon=True),
            threading.Thread(target=self._pump, args=(self.proc.stderr, self.err), daemon=True),
        ]
        for t in self._threads:
            t.start()

    def _pump(self, stream, sink: list[str]) -> None:
        for raw in iter(stream.readline, b""):
            line = raw.decode("utf-8", "replace")
            sink.append(line)
            if READY in line and not self.ready.is_set():
                self.t_ready = time.monotonic() - self.t0
                self.ready.set()

    def wait_ready(self, timeout: float = 60.0) -> bool:
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            if self.ready.wait(0.005):
                return True
            if self.proc.poll() is not None:
                return self.ready.is_set()
        raise AssertionError(f"no setup line within {timeout} s: {self.stdout}{self.stderr}")

    def wait(self, timeout: float = 120.0) -> int:
        rc = self.proc.wait(timeout)
        for t in self._threads:
            t.join(10)
        return rc

    @property
    def stdout(self) -> str:
        return "".join(self.out)

    @property
    def stderr(self) -> str:
        return "".join(self.err)

    @property
    def reviews(self) -> int:
        return sum(line.startswith(REVIEW) for line in self.out)


def run_args(path: Path, plan: Path, protocol: tuple[str, ...] = ()) -> list[str]:
    # What the person would type: resume a file that exists, start one that does not.
    if path.exists():
        return [str(path), "--port", PORT, "--unattended", "--resume"]
    return [str(path), "--port", PORT, "--unattended", "--plan", str(plan), *protocol]


def resume_sentence(path: Path) -> str:
    return f"Resume with: labcli acquire {path} --port '{PORT}' --resume --unattended"


# ---------------------------------------------------------------- the campaign


class Campaign:
    """Kill runs of one plan; check every file after every kill; count where the kills landed."""

    def __init__(
        self, tmp_path: Path, plan_rows: list[tuple[int, str, float, float]], protocol: tuple[str, ...] = ()
    ) -> None:
        self.tmp = tmp_path
        self.protocol = protocol  # ("--protocol", path) for a run of another protocol than takuma2014
        self.plan = tmp_path / "plan.csv"
        self.plan.write_text(
            "trial,set,mass_g,direction_deg\n" + "".join(f"{t},{s},{m:g},{d:g}\n" for t, s, m, d in plan_rows)
        )
        self.ids = [r[0] for r in plan_rows]
        self.fit = [r[0] for r in plan_rows if r[1] == "fit"]
        self.validation = [r[0] for r in plan_rows if r[1] == "validation"]
        self.phases: Counter[str] = Counter()
        self.landed = Counter()  # signal name -> kills that hit a running process
        self.resumes = 0
        # The reference: the same seed and plan, never interrupted, as a process (timed).
        ref = tmp_path / "reference.h5"
        p = Acquire(run_args(ref, self.plan, self.protocol))
        assert p.wait() == 0, p.stderr
        self.t_end = time.monotonic() - p.t0
        self.t_ready = p.t_ready
        self.reference = {t: datasets(d) for t, d in trial_data(ref).items()}
        assert sorted(self.reference) == self.ids

    # -- one file, killed until it completes

    def episode(self, name: str, rng: random.Random, signals: list[signal.Signals]) -> list[signal.Signals]:
        """Start a file, send ``signals`` in turn to its runs (one per run), resume it to the end.

        Returns the signals that did not land because the run completed first.
        """
        path = self.tmp / f"{name}.h5"
        seen: dict[int, dict[str, Any]] = {}
        pending = list(signals)
        while pending:
            sig = pending[0]
            pristine = not path.exists()  # this process starts the file: its trials equal the reference's
            before = len(seen)
            proc = Acquire(run_args(path, self.plan, self.protocol))
            if sig == signal.SIGINT:
                # Python's own start-up is not the toolkit's: Ctrl-C lands once the rig answered.
                if not proc.wait_ready():
                    proc.wait()
                    break  # nothing left to run: the file was complete
                time.sleep(rng.uniform(0.0, max(0.05, self.t_end - self.t_ready)))
            else:
                time.sleep(rng.uniform(0.5 * self.t_ready, self.t_end))
            proc.proc.send_signal(sig)
            rc = proc.wait()
            ids = self.check(path, seen, pristine)
            if rc == 0 or (rc == -signal.SIGINT and "Session complete: " in proc.stdout):
                # Done before the signal, or it came while the interpreter was exiting after the
                # run (Python restores the default SIGINT action then): the run is complete either way.
                self.phases["finished before the signal" if rc == 0 else "interpreter exit after the run"] += 1
                assert proc.stderr == "", proc.stderr
                # The reference run was slower than this one (a busy machine then): aim earlier.
                self.t_end = self.t_ready + 0.7 * (self.t_end - self.t_ready)
                if len(ids) == len(self.ids):
                    break
                continue
            pending.pop(0)
            self.landed[sig.name] += 1
            self.phases[self.phase(proc, path, ids, len(ids) - before)] += 1
            if sig == signal.SIGKILL:
                assert rc == -signal.SIGKILL, (rc, proc.stderr)
            else:
                self.check_sigint(proc, rc, path, ids)
        # Resume until complete, as the messages say.
        for _ in range(5):
            if path.exists():
                with RunFile.open(path) as run:
                    if len(run.records.ids()) == len(self.ids) and run.split.get() is not None:
                        break
            pristine = not path.exists()
            proc = Acquire(run_args(path, self.plan, self.protocol))
            assert proc.wait() == 0, proc.stdout + proc.stderr
            self.resumes += 1
            self.check(path, seen, pristine)
        self.check_complete(path, seen)
        return pending

    def check(self, path: Path, seen: dict[int, dict[str, Any]], pristine: bool) -> list[int]:
        """The file after a process ended: opens, keeps everything, holds only whole trials."""
        if not path.exists():
            assert not seen, "a file with complete trials vanished"
            return []
        with RunFile.open(path) as run:
            ids = run.records.ids()
            incomplete = run.records.incomplete_ids()
            assert len(run.records.table()) == len(ids)
        # Trials are recorded in plan order, each once.
        assert ids == self.ids[: len(ids)], ids
        assert incomplete in ([], self.ids[len(ids) : len(ids) + 1]), incomplete
        assert set(seen) <= set(ids), "a trial complete before the kill was lost"
        data = trial_data(path)
        for t in ids:
            if t in seen:
                assert data[t] == seen[t], f"trial {t} changed after it was stored"
            else:
                if pristine:
                    assert datasets(data[t]) == self.reference[t], f"trial {t} differs from the reference run"
                seen[t] = data[t]
        return ids

    def phase(self, proc: Acquire, path: Path, ids: list[int], new: int) -> str:
        """Where a kill landed, from the process's lines and the file."""
        if not proc.ready.is_set():
            return "start-up and setup check" + ("" if path.exists() else " (no file yet)")
        if len(ids) == len(self.ids):
            return "after the last trial (split)"
        # Every trial line printed is a trial stored; only the last one stored may have no line yet.
        assert proc.reviews in (new, new - 1), (proc.reviews, new, proc.stdout)
        if proc.reviews == new - 1:
            return "between a trial's commit and its line"
        if path.exists():  # (a kill right after the setup check may come before the file)
            with RunFile.open(path) as run:
                if run.records.incomplete_ids():
                    return "writing a trial (incomplete group on disk)"
        said = proc.stderr.strip().splitlines()[-1:] or [""]
        if "during the setup" in said[0]:
            return "air supply and valves"
        if "between trials" in said[0]:
            return "between trials"
        return "acquiring a trial" if said[0] else "air supply, valves, acquiring or writing a trial"

    def check_sigint(self, proc: Acquire, rc: int, path: Path, ids: list[int]) -> None:
        assert rc == 130, (rc, proc.stdout, proc.stderr)
        last = proc.stderr.strip().splitlines()[-1]
        if not path.exists():  # Ctrl-C after the setup check, before the first trial made the file
            assert last == (
                f"Interrupted during the setup, before anything was written to {path}; "
                "run the same command again to start the run."
            ), last
            return
        n = len(ids)
        safe = f"{n} trial{'' if n == 1 else 's'} stored in {path} {'is' if n == 1 else 'are'} safe"
        m = re.fullmatch(
            rf"Interrupted during (trial (\d+), which was discarded|the pause between trials|the setup); "
            rf"{re.escape(safe)}\. {re.escape(resume_sentence(path))}",
            last,
        )
        assert m, last
        if m.group(2) is not None:
            assert int(m.group(2)) == self.ids[n]  # the trial in progress is the first one missing

    def check_complete(self, path: Path, seen: dict[int, dict[str, Any]]) -> None:
        with RunFile.open(path) as run:
            assert sorted(run.records.ids()) == self.ids
            split = run.split.get()
            assert split is not None and split["strategy"] == "plan"
            assert split["fit"] == self.fit and split["validation"] == self.validation
            table = run.records.table()
        assert table["trial"].tolist() == self.ids
        assert table["set"].tolist() == ["fit" if t in self.fit else "validation" for t in self.ids]
        data = trial_data(path)
        assert all(data[t] == seen[t] for t in seen)

    def report(self) -> str:
        kills = sum(self.landed.values())
        parts = ", ".join(f"{k}: {v}" for k, v in sorted(self.phases.items()))
        return f"{kills} kills ({dict(self.landed)}), {self.resumes} final resumes; phases: {parts}"


def plan_rows(n: int, n_validation: int) -> list[tuple[int, str, float, float]]:
    rows = load_plan(load_protocol("takuma2014")).head(n).to_dict("records")
    return [
        (
            int(r["trial"]),
            "validation" if i >= n - n_validation else "fit",
            float(r["mass_g"]),
            float(r["direction_deg"]),
        )
        for i, r in enumerate(rows)
    ]


# ---------------------------------------------------------------- tests


def test_a_handful_of_kills(tmp_path):
    """Two SIGKILLs and two SIGINTs on a 40-trial plan, two per file, each file resumed to the end."""
    c = Campaign(tmp_path, plan_rows(40, 8))
    rng = random.Random(7)
    pending = [signal.SIGKILL, signal.SIGINT, signal.SIGINT, signal.SIGKILL]
    n = 0
    # A run faster than the reference (a machine less busy than when the reference ran) completes
    # before its signal; each such episode aims earlier, and enough of them are allowed to get there.
    while pending and n < 12:
        pending = c.episode(f"run{n}", rng, pending[:2]) + pending[2:]
        n += 1
    print(c.report())
    assert c.landed["SIGKILL"] == 2 and c.landed["SIGINT"] == 2


def test_a_run_started_with_ctrl_c_ignored_runs_through_it(tmp_path):
    """``nohup labcli acquire ... &`` asks for a run that Ctrl-C does not stop: none lands, not even
    in a write, where the session otherwise holds a Ctrl-C back and honours it after."""
    rows = plan_rows(12, 2)
    plan = tmp_path / "plan.csv"
    plan.write_text("trial,set,mass_g,direction_deg\n" + "".join(f"{t},{s},{m:g},{d:g}\n" for t, s, m, d in rows))
    path = tmp_path / "run.h5"
    proc = Acquire(run_args(path, plan), preexec=lambda: signal.signal(signal.SIGINT, signal.SIG_IGN))
    assert proc.wait_ready()
    sent = 0
    while proc.proc.poll() is None:
        proc.proc.send_signal(signal.SIGINT)
        sent += 1
        time.sleep(0.005)
    assert proc.wait() == 0, proc.stderr
    assert sent > 100 and proc.stderr == ""
    assert "Session complete: 12 trials stored" in proc.stdout
    with RunFile.open(path) as run:
        assert run.records.ids() == [r[0] for r in rows] and run.split.get() is not None


def test_ctrl_c_during_the_setup_check_leaves_no_file_and_says_so(tmp_path, monkeypatch):
    from labcli.core.device import Device

    def interrupted(self, timeout=1.0):
        raise KeyboardInterrupt

    monkeypatch.setattr(Device, "read", interrupted)
    path = tmp_path / "run.h5"
    outcome = acquire(path, PORT, protocol="takuma2014", unattended=True, ui=quiet())
    assert outcome.exit_code == 130
    assert outcome.message == (
        f"Interrupted during the setup, before anything was written to {path}; "
        "run the same command again to start the run."
    )
    assert not path.exists()


def quiet():
    import io

    from rich.console import Console

    from labcli.core.ui import UnattendedUI

    return UnattendedUI(console=Console(file=io.StringIO()))


def ctrl_c_inside(monkeypatch, facet: type, name: str, when=lambda *a: True) -> None:
    """Press Ctrl-C (a real SIGINT to this process) as ``<facet>.<name>`` of a run file starts."""
    real = getattr(facet, name)

    # As a terminal starts labcli: the runner may have passed this process SIGINT ignored.
    signal.signal(signal.SIGINT, signal.default_int_handler)

    def pressed(self, *args, **kwargs):
        if when(*args):
            os.kill(os.getpid(), signal.SIGINT)
        return real(self, *args, **kwargs)

    monkeypatch.setattr(facet, name, pressed)


def test_ctrl_c_during_a_write_stores_the_trial_whole_and_says_so(tmp_path, monkeypatch):
    plan = tmp_path / "plan.csv"
    plan.write_text(
        "trial,set,mass_g,direction_deg\n1,fit,200,-60\n2,fit,500,30\n3,validation,300,150\n4,validation,400,-150\n"
    )
    path = tmp_path / "run.h5"
    ctrl_c_inside(monkeypatch, Records, "write", lambda record: record["trial"] == 3)
    outcome = acquire(path, PORT, protocol="takuma2014", plan=plan, unattended=True, ui=quiet())
    assert outcome.exit_code == 130
    assert outcome.message == (
        f"Interrupted during the pause between trials; 3 trials stored in {path} are safe. {resume_sentence(path)}"
    )
    with RunFile.open(path) as run:
        assert run.records.ids() == [1, 2, 3] and run.records.incomplete_ids() == [] and run.split.get() is None


def test_a_trial_line_is_printed_only_once_the_trial_is_stored(tmp_path, monkeypatch):
    """The unattended run's line per trial tells whoever watches that the trial is in the file: a write
    that fails (here the disk's I/O error; a kill alike) leaves its trial without a line."""
    import io

    from rich.console import Console

    from labcli.core.ui import UnattendedUI

    plan = tmp_path / "plan.csv"
    plan.write_text("trial,set,mass_g,direction_deg\n1,fit,200,-60\n2,fit,500,30\n3,validation,300,150\n")
    path = tmp_path / "run.h5"
    real = Records.write

    def dies_on_trial_2(self, record):
        if record["trial"] == 2:
            raise StoreError(f"{path} could not be written (Input/output error), so trial 2 was not stored.")
        return real(self, record)

    monkeypatch.setattr(Records, "write", dies_on_trial_2)
    out = io.StringIO()
    with pytest.raises(StoreError, match="trial 2 was not stored"):
        acquire(path, PORT, protocol="takuma2014", plan=plan, unattended=True, ui=UnattendedUI(Console(file=out)))
    lines = [line for line in out.getvalue().splitlines() if line.startswith(REVIEW)]
    assert [line.split()[1] for line in lines] == ["1"], out.getvalue()
    with RunFile.open(path) as run:
        assert run.records.ids() == [1]


def test_ctrl_c_while_the_split_is_written_finishes_the_run(tmp_path, monkeypatch):
    plan = tmp_path / "plan.csv"
    plan.write_text("trial,set,mass_g,direction_deg\n1,fit,200,-60\n2,validation,500,30\n")
    path = tmp_path / "run.h5"
    ctrl_c_inside(monkeypatch, Splits, "set")
    outcome = acquire(path, PORT, protocol="takuma2014", plan=plan, unattended=True, ui=quiet())
    assert outcome.exit_code == 0
    assert outcome.message.startswith(f"Session complete: 2 trials stored in {path} (2 this session, ")
    with RunFile.open(path) as run:
        assert run.split.get()["fit"] == [1] and run.split.get()["validation"] == [2]


def uncommitted_frames(path: Path) -> tuple[int, int]:
    """(raw frames in the file, the end of the last committed trial's windows), read as a viewer would."""
    import h5py

    with h5py.File(path, "r", locking=False) as f:
        trials, n = f["entry/trials"], int(f["entry/trials"].attrs["committed"])
        stop = max([int(trials[f"{w}_stop"][:n].max()) for w in ("baseline", "loaded")] if n else [0])
        return int(f["entry/raw/time"].shape[0]), stop


def kill_mid_window(proc: Acquire, path: Path, frames: int, timeout: float = 120.0) -> int:
    """SIGKILL ``proc`` once ``frames`` frames of a window it streams are in the file, not yet in any trial."""
    start = None
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline and proc.proc.poll() is None:
        try:
            extent, stop = uncommitted_frames(path)
        except (OSError, KeyError, ValueError):  # no file yet, or read while the writer commits
            time.sleep(0.01)
            continue
        start = extent if start is None else start  # frames an earlier process left are not this one's
        if extent - max(stop, start) >= frames:
            proc.proc.send_signal(signal.SIGKILL)
            assert proc.wait() == -signal.SIGKILL, proc.stderr
            return extent - max(stop, start)
        time.sleep(0.005)
    raise AssertionError(f"no streamed window of {frames} frames seen: {proc.stdout}{proc.stderr}")


def test_kills_in_the_middle_of_a_streamed_capture_window(tmp_path):
    """30 s windows at 1 kHz, streamed into the file as they arrive: SIGKILL while a window's frames
    are in the file but its trial is not committed, twice, then resume to the end.

    (Not 60 s, the longest a protocol allows: the simulated muscles creep over a minute under
    load, and trial 3's baseline is then rightly refused as still loaded.)"""
    c = Campaign(tmp_path, plan_rows(3, 1), ("--protocol", str(write_long_protocol(tmp_path, 30.0))))
    path = tmp_path / "run.h5"
    seen: dict[int, dict[str, Any]] = {}
    for frames in (20_000, 45_000):  # in trial 1's baseline; in the loaded window of the first trial resumed
        pristine = not path.exists()
        proc = Acquire(run_args(path, c.plan, c.protocol))
        left = kill_mid_window(proc, path, frames)
        assert left >= frames
        before = sorted(seen)
        ids = c.check(path, seen, pristine)
        assert ids == before  # the window's trial was not stored; every one before it is
        with RunFile.open(path) as run:
            assert run.verify()["ok"], run.verify()
        extent, stop = uncommitted_frames(path)
        assert extent - stop >= frames  # the killed window's frames are in the file, in no trial
    for _ in range(3):
        proc = Acquire(run_args(path, c.plan, c.protocol))
        assert proc.wait() == 0, proc.stdout + proc.stderr
        c.check(path, seen, False)
        with RunFile.open(path) as run:
            if len(run.records.ids()) == len(c.ids):
                break
    c.check_complete(path, seen)
    with RunFile.open(path) as run:
        assert run.verify() == {"ok": True, "records": 3, "windows": 6, "problems": []}


@pytest.mark.slow
def test_sixty_kills_across_whole_runs(tmp_path):
    """The shipped 108-trial plan; 60 kills, a third SIGINT, one to three per file before it completes."""
    c = Campaign(tmp_path, plan_rows(108, 18))
    rng = random.Random(2024)
    n = 0
    while sum(c.landed.values()) < 60:
        k = min(rng.randint(1, 3), 60 - sum(c.landed.values()))
        c.episode(f"run{n}", rng, [signal.SIGINT if rng.random() < 1 / 3 else signal.SIGKILL for _ in range(k)])
        n += 1
    print(c.report())
    assert sum(c.landed.values()) >= 60 and c.landed["SIGINT"] >= 10 and c.landed["SIGKILL"] >= 30
