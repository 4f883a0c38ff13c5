"""Bad input at every entry point: one clear sentence, a non-zero exit, no traceback, no file changed.

Each case runs the installed ``labcli`` in a subprocess, in a fresh copy of a small world of
files (a trial CSV, an imported run with its model, a run acquired from the simulated rig, a
push table, protocol and plan files, HDF5 files of another schema or cut short), with the case's
own bad file added.  Every file in the folder is hashed before and after: a failing command may
not create, change or delete anything, the run file a failing ``fit`` would record into included.

The expected messages are exact.  ``labcli`` prints one ``Error: ...`` line; a table with one
bad cell prints the count of problems, then the problem naming file, row and column; a bad
option is reported by click after its usage lines.

``python tests/cli/test_bad_input.py`` prints the table of cases as Markdown (for the README).
"""

from __future__ import annotations

import hashlib
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # run as a script: tests/ holds support/
from support import procs
from support.bad_input import PLAN_HEADER, PROTOCOLS, PUSH_HEADER, PUSH_ROW, SIM, Case, all_cases
from support.trial_tables import write_small_trial_table

CASES = all_cases()


# --------------------------------------------------------------------------- the world of files


def labcli(*args: str, cwd: Path, timeout: float = 120, stdin: str | None = None) -> subprocess.CompletedProcess:
    return procs.labcli(*args, cwd=cwd, timeout=timeout, stdin=stdin, env={"PYTHONWARNINGS": "ignore"})


@pytest.fixture(scope="module")
def world(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Good files every case starts from: trials.csv, run.h5 + run.model.json, acq.h5, push.h5, ..."""
    w = tmp_path_factory.mktemp("world")
    write_small_trial_table(w / "trials.csv")
    shutil.copy(PROTOCOLS / "takuma2014.toml", w / "good.toml")
    shutil.copy(PROTOCOLS / "takuma2014-plan.csv", w / "takuma2014-plan.csv")
    (w / "plan3.csv").write_text(PLAN_HEADER + "1,fit,500,-60\n2,fit,300,30\n3,validation,800,90\n")
    (w / "push_ok.csv").write_text(f"{PUSH_HEADER}\n1,{PUSH_ROW}\n2,{PUSH_ROW}\n")
    steps = [
        ("import", "trials.csv", "-o", "run.h5", "--protocol", "takuma2014"),
        ("fit", "run.h5", "--form", "paper"),  # 12 fit trials: too few for the posture form's 14 terms
        ("acquire", "acq.h5", "--port", SIM, "--plan", "plan3.csv", "--unattended"),
        ("import", "push_ok.csv", "-o", "push.h5", "--protocol", "takuma2014-stiffness"),
    ]
    for step in steps:
        r = labcli(*step, cwd=w)
        assert r.returncode == 0, (step, r.stderr)
    return w


def digest(folder: Path) -> dict[str, str]:
    """Every regular file's hash, and what else is there (a named pipe stays one)."""
    return {
        str(p.relative_to(folder)): hashlib.sha256(p.read_bytes()).hexdigest()
        if p.is_file()
        else "fifo"
        if p.is_fifo()
        else "dir"
        for p in sorted(folder.rglob("*"))
    }


def expected_stderr(case: Case, world: Path, port: str | None) -> str:
    lines = [s.replace("{world}", str(world)) for s in case.error]
    if port is not None:
        lines = [s.replace("PTY", port) for s in lines]
    lines[0] = "Error: " + lines[0]
    if case.usage is not None:
        command = case.usage.split()[0]
        lines = [f"Usage: labcli {case.usage}", f"Try 'labcli {command} --help' for help.", "", *lines]
    return "\n".join(lines) + "\n"


def run_case(case: Case, world: Path, tmp_path: Path) -> tuple[subprocess.CompletedProcess, str, dict, dict]:
    here = tmp_path / "w"
    shutil.copytree(world, here)
    for name, content in case.files.items():
        (here / name).write_bytes(content(here) if callable(content) else content)
    for name in case.fifos:
        os.mkfifo(here / name)
    if case.id == "h5-no-fit-trials":
        r = labcli("import", "unsplit.csv", "-o", "unsplit.h5", "--protocol", "takuma2014", cwd=here)
        assert r.returncode == 0, r.stderr
    before = digest(here)
    port = None
    if case.firmware is not None:
        from support.firmware import FakeFirmware

        with FakeFirmware(**case.firmware) as fw:
            port = fw.port
            result = labcli(*[a.replace("PTY", port) for a in case.args], cwd=here)
    elif case.pty:
        from labcli.core.sim.pty import serve_pty

        server = serve_pty(seed=1, rate=200)
        try:
            port = server.path
            result = labcli(*[a.replace("PTY", port) for a in case.args], cwd=here)
        finally:
            server.stop()
    else:
        result = labcli(*case.args, cwd=here, timeout=case.timeout, stdin=case.stdin)
    return result, expected_stderr(case, here, port), before, digest(here)


def _params():
    for case in CASES:
        marks = [pytest.mark.xfail(strict=True, reason=case.xfail)] if case.xfail else []
        yield pytest.param(case, id=case.id, marks=marks)


@pytest.mark.parametrize("case", list(_params()))
def test_bad_input(case: Case, world: Path, tmp_path: Path) -> None:
    result, want, before, after = run_case(case, world, tmp_path)
    assert "Traceback" not in result.stderr, result.stderr
    assert result.returncode == case.code, result.stderr
    assert result.stderr == want
    assert after == before, "a failing command changed, created or deleted a file"


def test_the_table_covers_every_entry_point() -> None:
    assert len(CASES) >= 30 and len({c.id for c in CASES}) == len(CASES)
    entries = {c.entry for c in CASES}
    assert entries == {
        "protocol TOML",
        "plan CSV",
        "trial CSV",
        "push CSV",
        "point CSV",
        "HDF5 file",
        "model JSON",
        "CLI argument",
        "port",
        "run file",
        "standard input",
        "rig",
        "output path",
    }
    commands = {c.args[0] for c in CASES}
    assert commands >= {
        "acquire",
        "fit",
        "validate",
        "classify",
        "optimize",
        "split",
        "inspect",
        "export",
        "import",
        "monitor",
    }


# --------------------------------------------------------------------------- a run held open elsewhere


def test_fit_on_a_run_open_in_a_viewer_changes_no_file(world: Path, tmp_path: Path) -> None:
    """fit reads the run, then cannot open it to record the model: neither file may change."""
    import h5py

    here = tmp_path / "w"
    shutil.copytree(world, here)
    (here / "run.model.json").unlink()
    before = digest(here)
    with h5py.File(here / "run.h5", "r"):  # a viewer (HDFView, a notebook) holds the run open
        r = labcli("fit", "run.h5", "--form", "paper", cwd=here)
    assert "Traceback" not in r.stderr
    assert r.returncode == 1 and r.stderr.startswith("Error: run.h5 is open ") and r.stderr.count("\n") == 1
    assert digest(here) == before


def test_a_run_open_for_reading_elsewhere_is_reported_as_such(world: Path, tmp_path: Path) -> None:
    import h5py

    here = tmp_path / "w"
    shutil.copytree(world, here)
    with h5py.File(here / "run.h5", "r"):
        r = labcli("fit", "run.h5", "--form", "paper", cwd=here)
    assert r.stderr == (
        "Error: run.h5 is open in another program (a viewer, or a run still recording); close it there and try again.\n"
    )


def test_a_failing_fit_leaves_an_existing_model_and_the_run_as_they_were(world: Path, tmp_path: Path) -> None:
    import h5py

    here = tmp_path / "w"
    shutil.copytree(world, here)
    (here / "run.model.json").write_text("an older model, kept\n")
    before = digest(here)
    with h5py.File(here / "run.h5", "r"):
        r = labcli("fit", "run.h5", "--form", "paper", cwd=here)
    assert r.returncode == 1 and "Traceback" not in r.stderr
    assert digest(here) == before


# --------------------------------------------------------------------------- the table for the README


TABLE_PATH = Path(__file__).resolve().parents[1] / "bad_input_table.md"
TABLE_HEADER = (
    "# Bad input: what labcli says\n\n"
    "Every case below runs the real `labcli` (`tests/cli/test_bad_input.py`): a non-zero exit, no traceback, "
    "and every file in the folder hashed unchanged before and after (the run file a failing `fit` would "
    "record into included). Table errors print a count line, then one line per problem naming file, row "
    "and column; option errors come from click after its two usage lines. Regenerate this file with "
    "`python tests/cli/test_bad_input.py > tests/bad_input_table.md`.\n\n"
)


def test_committed_table_lists_every_case():
    assert TABLE_PATH.read_text(encoding="utf-8") == markdown_table()


def markdown_table() -> str:
    rows = ["| # | input | case | command | message (first line) | exit |", "|---|---|---|---|---|---|"]
    for i, c in enumerate(CASES, 1):
        args = " ".join(a if " " not in a and "?" not in a and "&" not in a else f"'{a}'" for a in c.args)
        msg = c.error[0] if len(c.error) == 1 else f"{c.error[0]}<br>{c.error[1]}"
        msg = "Error: " + msg.replace("{world}", "/tmp/w").replace("|", "\\|")
        note = f" *(xfail: {c.xfail})*" if c.xfail else ""
        rows.append(f"| {i} | {c.entry} | {c.what}{note} | `labcli {args}` | {msg} | {c.code} |")
    return TABLE_HEADER + "\n".join(rows) + "\n"


if __name__ == "__main__":
    sys.stdout.write(markdown_table())
