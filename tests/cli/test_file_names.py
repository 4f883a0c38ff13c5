"""File names that are not valid UTF-8 (bytes Python keeps as lone surrogates): every command that
reads or writes them works, and what a run file records of them (its own name, the command line,
the table it came from) is written with ``\\xff`` escapes instead of a traceback."""

from __future__ import annotations

import os
import subprocess
from pathlib import Path

import h5py
from support import procs
from support.trial_tables import write_small_trial_table

SIM = "sim://?seed=1&clock=virtual"
PLAN = "trial,set,mass_g,direction_deg\n1,fit,500,-60\n2,fit,300,30\n3,validation,800,90\n"


def labcli(*args: str, cwd: Path) -> subprocess.CompletedProcess:
    return procs.labcli(*args, cwd=cwd, errors="surrogateescape")


def name(raw: bytes) -> str:
    return os.fsdecode(raw)


def test_acquire_resume_split_export_and_inspect_take_a_name_that_is_not_utf8(tmp_path):
    run, plan = name(b"run\xff.h5"), name(b"plan\xfe.csv")
    (tmp_path / plan).write_text(PLAN)
    for args in (
        ("acquire", run, "--port", SIM, "--unattended", "--plan", plan, "--operator", name(b"op\xff")),
        ("acquire", run, "--port", SIM, "--unattended", "--resume"),
        ("split", run, "--fit", "2", "--validation", "1"),
        ("export", run, "-o", name(b"out\xff.csv")),
        ("inspect", "--verify", run),
        ("note", run, name(b"a note \xff")),
    ):
        r = labcli(*args, cwd=tmp_path)
        assert "Traceback" not in r.stderr, (args, r.stderr)
        assert r.returncode == 0, (args, r.stderr)
    with h5py.File(tmp_path / run, "r") as f:
        assert f.attrs["file_name"] == b"run\\xff.h5"
        assert b"plan\\xfe.csv" in f["entry/program_name"].attrs["configuration"]
        assert f["entry/user/name"][0] == b"op\\xff"
    assert (tmp_path / name(b"out\xff.csv")).stat().st_size > 0


def test_import_and_fit_take_a_table_and_a_run_whose_names_are_not_utf8(tmp_path):
    _write_trials(tmp_path / name(b"t\xff.csv"))
    r = labcli("import", name(b"t\xff.csv"), "-o", name(b"r\xff.h5"), "--protocol", "takuma2014", cwd=tmp_path)
    assert r.returncode == 0 and "Traceback" not in r.stderr, r.stderr
    with h5py.File(tmp_path / name(b"r\xff.h5"), "r") as f:
        assert f["entry/labcli"].attrs["source"] == b"t\\xff.csv"
    r = labcli("fit", name(b"r\xff.h5"), "--form", "paper", cwd=tmp_path)
    assert r.returncode == 0 and "Traceback" not in r.stderr, r.stderr
    assert (tmp_path / name(b"r\xff.model.json")).is_file()


def _write_trials(path: Path) -> None:
    write_small_trial_table(path)
