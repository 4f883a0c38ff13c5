"""Under ``ulimit -n`` too low for what a command may hold open (a run file and its journal, the rig's
port, a figure's fonts), every command is one sentence before it reads or writes anything: it was a
traceback from matplotlib's fonts (``validate --plot``), or a model file written and then a failure
(``fit RUN.h5``).  A command that runs out of open files past that check ends in one sentence too."""

from __future__ import annotations

import errno
import hashlib
import shutil
from pathlib import Path

import pytest
from support.procs import labcli
from support.trial_tables import write_small_trial_table

from labcli import cli

resource = pytest.importorskip("resource")

SIM = "sim://?seed=1&clock=virtual"
PLAN = "trial,set,mass_g,direction_deg\n1,fit,300,-60\n2,fit,500,30\n3,validation,400,120\n"
LOW = 16
SENTENCE = (
    f"Error: the open-file limit (ulimit -n) is {LOW}, below the 32 files labcli may hold open at once (a run "
    "file and its journal, the rig's port, a figure's fonts); raise it (ulimit -n 1024) and run the command "
    "again. Nothing was read or written.\n"
)


@pytest.fixture(scope="module")
def world(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A run imported from a trial table, its model fitted (run.model.json, recorded in run.h5), a plan."""
    w = tmp_path_factory.mktemp("world")
    write_small_trial_table(w / "trials.csv")
    (w / "plan.csv").write_text(PLAN)
    for step in (("import", "trials.csv", "-o", "run.h5", "--protocol", "takuma2014"), ("fit", "run.h5")):
        assert labcli(*step, cwd=w).returncode == 0
    return w


def listing(folder: Path) -> dict[str, str]:
    return {p.name: hashlib.sha256(p.read_bytes()).hexdigest() for p in sorted(folder.iterdir())}


@pytest.mark.parametrize(
    "args",
    [
        ("fit", "run.h5"),
        ("validate", "run.h5", "--plot", "fig7.png"),
        ("acquire", "new.h5", "--port", SIM, "--unattended", "--plan", "plan.csv"),
        ("import", "trials.csv", "-o", "run.h5", "--protocol", "takuma2014", "--force"),
    ],
    ids=lambda a: a[0],
)
def test_a_low_open_file_limit_is_one_sentence_and_changes_nothing(world: Path, tmp_path: Path, args) -> None:
    here = tmp_path / "here"
    shutil.copytree(world, here)
    before = listing(here)
    r = labcli(*args, cwd=here, limits={resource.RLIMIT_NOFILE: LOW})
    assert (r.returncode, r.stderr) == (1, SENTENCE)
    assert listing(here) == before


def test_the_limit_leaves_room_for_a_figure(world: Path, tmp_path: Path) -> None:
    """At the limit the check asks for, the command that needs the most files (a figure: its fonts) runs."""
    here = tmp_path / "here"
    shutil.copytree(world, here)
    r = labcli(
        "validate", "run.h5", "--plot", "fig7.png", cwd=here, limits={resource.RLIMIT_NOFILE: cli.MIN_OPEN_FILES}
    )
    assert r.returncode == 0, r.stderr
    assert (here / "fig7.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_running_out_of_open_files_past_the_check_is_one_sentence(monkeypatch, capsys) -> None:
    """HDF5's own open failing for want of files (its OSError names errno 24) is not taken for a damaged run."""
    limit = cli._open_files_limit()

    def out_of_files(**_: object) -> None:
        raise OSError(
            errno.EMFILE,
            "Unable to open file (unable to open file: name = 'run.h5', errno = 24, error message = "
            "'Too many open files', flags = 0, o_flags = 0)",
        )

    monkeypatch.setattr(cli, "cli", out_of_files)
    monkeypatch.setattr(cli.signal, "signal", lambda *_: None)  # main's handlers are its own process's
    monkeypatch.setattr(cli.warnings, "showwarning", cli.warnings.showwarning)
    monkeypatch.setattr(cli, "_guard_streams", lambda: None)
    with pytest.raises(SystemExit) as ended:
        cli.main()
    assert ended.value.code == 1
    assert capsys.readouterr().err == (
        f"Error: labcli ran out of open files (the open-file limit, ulimit -n, is "
        f"{'unlimited' if limit is None else limit}); raise it (ulimit -n 1024) and run the command again.\n"
    )
