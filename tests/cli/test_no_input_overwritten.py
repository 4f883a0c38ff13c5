"""No input is ever an output: a command refuses, in one sentence and whatever ``--force`` says, to
write onto a file it reads, by whichever name it reaches it (a symbolic or a hard link)."""

from __future__ import annotations

import hashlib
import os
import subprocess
from pathlib import Path

import pytest
from support import procs

ROOT = Path(__file__).resolve().parents[2]
SIM = "sim://?seed=1&clock=virtual"
OWN = "it is this command's input, and writing there would destroy it; choose another output name."
PLAN = "trial,set,mass_g,direction_deg\n1,fit,800,-60\n2,fit,500,-60\n"


def labcli(*args: str, cwd: Path) -> subprocess.CompletedProcess:
    return procs.labcli(*args, cwd=cwd, env={"PYTHONPATH": str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", "")})


def digest(folder: Path) -> dict[str, str]:
    return {p.name: hashlib.sha256(p.read_bytes()).hexdigest() for p in sorted(folder.iterdir()) if p.is_file()}


@pytest.mark.parametrize("link", ["symlink", "hardlink"])
@pytest.mark.parametrize("input_option", ["--plan", "--protocol"])
def test_acquire_never_writes_its_run_onto_an_input_by_another_name(tmp_path, link, input_option):
    (tmp_path / "plan.csv").write_text(PLAN)
    (tmp_path / "p.toml").write_bytes((ROOT / "protocols" / "takuma2014.toml").read_bytes())
    source = "plan.csv" if input_option == "--plan" else "p.toml"
    (os.symlink if link == "symlink" else os.link)(tmp_path / source, tmp_path / "out.h5")
    before = digest(tmp_path)
    r = labcli("acquire", "out.h5", "--force", input_option, source, "--port", SIM, "--unattended", cwd=tmp_path)
    assert r.returncode == 1 and r.stderr == f"Error: Cannot write the run to out.h5: {OWN}\n", r.stderr
    assert digest(tmp_path) == before


def test_fit_never_writes_its_model_onto_the_protocol_by_another_name(tmp_path):
    protocol = tmp_path / "p.toml"
    protocol.write_bytes((ROOT / "protocols" / "takuma2014.toml").read_bytes())
    os.symlink(protocol, tmp_path / "model.json")
    before = digest(tmp_path)
    r = labcli("fit", "trials.csv", "--protocol", "p.toml", "-o", "model.json", cwd=tmp_path)
    assert r.returncode == 1 and r.stderr == f"Error: Cannot write the model to model.json: {OWN}\n", r.stderr
    assert digest(tmp_path) == before
