"""What the campaign of damaged files and odd standard streams found, each now one sentence:
metadata changed behind the run's back fails ``inspect --verify``; a missing ``versions`` group or an
unreadable attribute is no traceback; an imported table's own columns live in a namespace of their
own (named like the run file's columns, ``.`` or ``a/``); standard output on a full device or in
ASCII; the rPAM stand on the monitor."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import h5py
import pytest
from support import procs

SIM = "sim://?seed=1&clock=virtual"
PLAN = "trial,set,mass_g,direction_deg\n1,fit,500,-60\n2,fit,300,30\n3,validation,800,90\n"


def labcli(*args: str, cwd: Path, env: dict | None = None, stdout=subprocess.PIPE) -> subprocess.CompletedProcess:
    return procs.labcli(*args, cwd=cwd, env=env, stdout=stdout, errors="surrogateescape")


@pytest.fixture(scope="module")
def acquired(tmp_path_factory: pytest.TempPathFactory) -> Path:
    d = tmp_path_factory.mktemp("acq")
    (d / "plan3.csv").write_text(PLAN)
    r = labcli("acquire", "acq.h5", "--port", SIM, "--unattended", "--plan", "plan3.csv", cwd=d)
    assert r.returncode == 0, r.stderr
    return d / "acq.h5"


def copy(run: Path, tmp_path: Path) -> Path:
    shutil.copy(run, tmp_path / "r.h5")
    return tmp_path / "r.h5"


def test_verify_fails_on_metadata_changed_after_writing(acquired, tmp_path):
    run = copy(acquired, tmp_path)
    with h5py.File(run, "a") as f:
        f["entry"].attrs["operator"] = "someone else"  # the metadata checksum is not updated
    r = labcli("inspect", "--verify", "r.h5", cwd=tmp_path)
    assert r.returncode == 1 and "Traceback" not in r.stderr
    assert "damaged: metadata: the attributes of the run's groups and datasets do not match their checksum" in r.stdout
    assert r.stderr.splitlines()[-1] == "Error: r.h5: 1 damaged item found; 3 trials and 6 raw windows check out."


def test_a_run_without_its_versions_group_exports_with_a_warning(acquired, tmp_path):
    run = copy(acquired, tmp_path)
    with h5py.File(run, "a") as f:
        del f["entry/versions"]
    r = labcli("export", "r.h5", "-o", "r.csv", cwd=tmp_path)
    assert r.returncode == 0 and "Traceback" not in r.stderr, r.stderr
    assert r.stderr.startswith("Warning: r.h5: the run's metadata")
    assert len((tmp_path / "r.csv").read_text().splitlines()) == 4
    assert labcli("inspect", "--verify", "r.h5", cwd=tmp_path).returncode == 1


def test_an_unreadable_attribute_is_one_sentence_in_export_and_fails_verify(acquired, tmp_path):
    """A bit flipped in the heap of the versions group's attributes (found by the flip campaign:
    h5py's 'Error iterating over attributes')."""
    run = copy(acquired, tmp_path)
    with h5py.File(run, "r") as f:
        names = list(f["entry/versions"].attrs)
    data = bytearray(run.read_bytes())
    hits = []
    for name in names:  # the attribute names sit in the object header: cut one short
        at = data.find(name.encode() + b"\x00")
        if at > 0:
            hits.append(at)
    assert hits
    data[hits[0] - 8 : hits[0] - 4] = b"\xff\xff\xff\x7f"  # the message sizes before the name
    run.write_bytes(bytes(data))
    for args in (("export", "r.h5", "-o", "r.csv"), ("inspect", "--verify", "r.h5"), ("fit", "r.h5")):
        r = labcli(*args, cwd=tmp_path)
        assert "Traceback" not in r.stderr, (args, r.stderr)
        assert r.returncode == 1, (args, r.stderr)
        assert r.stderr.splitlines()[-1].startswith("Error: "), r.stderr
    assert not (tmp_path / "r.csv").exists()


@pytest.mark.parametrize(
    "name", ["P", "P0", "F", "theta", "checksum", "mass", "baseline_start", ".", "a/", "extra:x", "100%"]
)
def test_an_imported_tables_own_column_never_meets_the_run_files(name, tmp_path):
    """(``started`` and ``flags`` are not a table's own: they are columns of ``export --all-columns``,
    which import takes back as what they say.)"""
    from labcli.papers.takuma2014.models.synthetic import paper_trials
    from labcli.papers.takuma2014.tables import write_trial_csv

    write_trial_csv(paper_trials(14, seed=1), tmp_path / "t.csv")
    lines = (tmp_path / "t.csv").read_text().splitlines()
    rows = [f"{lines[0]},{name}", *[f"{r},{i * 7}" for i, r in enumerate(lines[1:])]]
    (tmp_path / "x.csv").write_text("\n".join(rows) + "\n")
    r = labcli("import", "x.csv", "-o", "x.h5", "--protocol", "takuma2014", cwd=tmp_path)
    assert r.returncode == 0 and "Traceback" not in r.stderr, r.stderr
    assert labcli("inspect", "--verify", "x.h5", cwd=tmp_path).returncode == 0
    r = labcli("export", "x.h5", "-o", "back.csv", cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    import pandas as pd

    back = pd.read_csv(tmp_path / "back.csv")
    assert back.columns[-1] == name and list(back[name]) == [i * 7 for i in range(14)]
    from labcli.core.store import RunFile

    with RunFile.open(tmp_path / "x.h5") as run:
        fourth = run.records.read(run.records.ids()[3])
        assert fourth["extra"] == {name: 21}
        assert fourth["P_MPa"].shape == (4,)  # the run file's own pressures, untouched


def test_standard_output_on_a_full_device_is_one_sentence(acquired, tmp_path):
    run = copy(acquired, tmp_path)
    with open("/dev/full", "w") as full:
        r = labcli("inspect", run.name, cwd=tmp_path, stdout=full)
    assert r.stderr == (
        "Error: standard output cannot take what labcli writes (No space left on device); send it to a file "
        "on a disk with room, or to the terminal.\n"
    )
    assert r.returncode == 1


@pytest.mark.parametrize("encoding", ["ascii", "latin-1"])
def test_standard_output_that_is_not_utf8_shows_what_it_cannot_encode_escaped(acquired, tmp_path, encoding):
    run = tmp_path / os.fsdecode(b"r\xff\xe9.h5")
    shutil.copy(acquired, run)
    r = labcli("inspect", run.name, cwd=tmp_path, env={"PYTHONIOENCODING": encoding})
    assert r.returncode == 0 and "Traceback" not in r.stderr, r.stderr
    assert "labcli run file" in r.stdout
    r = labcli("inspect", "--json", run.name, cwd=tmp_path, env={"PYTHONIOENCODING": encoding})
    assert r.returncode == 0 and "Traceback" not in r.stderr, r.stderr


def test_monitor_reads_the_rpam_stand_with_the_rpam_protocol(tmp_path):
    r = labcli(
        "monitor",
        "--port",
        "sim://?mode=rpam&clock=virtual",
        "--protocol",
        "rpam2015",
        "--seconds",
        "1",
        "--json",
        cwd=tmp_path,
    )
    assert r.returncode == 0 and "Traceback" not in r.stderr, r.stderr
    summary = json.loads(r.stdout)
    text = json.dumps(summary)
    for channel in ("P_A", "P_B", "POT", "LEN"):
        assert channel in text


def test_no_python_warning_reaches_the_user_from_an_absurd_rig_option(tmp_path):
    """numpy overflows on sim://?noise=1e308: the command's own sentence, never a RuntimeWarning."""
    (tmp_path / "plan3.csv").write_text(PLAN)
    url = SIM + "&noise=1e308"
    r = labcli("acquire", "r.h5", "--port", url, "--unattended", "--plan", "plan3.csv", cwd=tmp_path)
    assert r.returncode == 1 and "Traceback" not in r.stderr
    assert "Warning" not in r.stderr and r.stderr.count("\n") == 1, r.stderr
    assert r.stderr.startswith("Error: ")


@pytest.mark.parametrize("sig", ["SIGTERM", "SIGHUP"])
def test_sigterm_and_sighup_end_acquire_as_ctrl_c_does(tmp_path, sig):
    """A stopping service or a closed terminal: one sentence and exit 130, not a silent death."""
    import signal
    import time

    (tmp_path / "plan3.csv").write_text(PLAN)
    proc = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "labcli",
            "acquire",
            "r.h5",
            "--port",
            "sim://?seed=1&clock=wall",
            "--unattended",
            "--plan",
            "plan3.csv",
        ],
        cwd=tmp_path,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        stdin=subprocess.DEVNULL,
        text=True,
    )
    # Signalled once the rig is open and checked (its line printed), when the session is under
    # way, however long a busy machine takes to get there.
    started = time.monotonic()
    seen = ""
    while "readings in range" not in seen and time.monotonic() - started < 120:
        line = proc.stdout.readline()
        if not line:
            break
        seen += line
    assert "readings in range" in seen, seen
    time.sleep(0.5)
    proc.send_signal(getattr(signal, sig))
    out, err = proc.communicate(timeout=60)
    assert proc.returncode == 130, err
    assert "Traceback" not in err
    assert err.splitlines()[-1].startswith("Interrupted during "), err
