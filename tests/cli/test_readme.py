"""The README's commands are the ones a new user types first: they must work as written."""

from __future__ import annotations

import re
import shlex
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
README = (ROOT / "README.md").read_text(encoding="utf-8")


# The suite on every core, a module per worker (its module-scoped simulated runs made once).
TEST_COMMAND = "pip install '.[test]' && python -m pytest -q -n auto --dist loadscope"


def code_blocks(lang: str) -> list[str]:
    return re.findall(rf"```{lang}\n(.*?)```", README, flags=re.S)


def test_top_two_commands_install_and_run_demo_and_tests():
    top = README[: README.index("## What the demo shows")]
    assert "pip install . && labcli demo out/demo" in top
    assert f"{TEST_COMMAND}\n" in top


def test_ci_runs_exactly_the_readme_test_command():
    # The same extraction .ci/run performs.
    awk = r"""/<!-- readme-test-command -->/{getline; while ($0 !~ /^[a-z]/) getline; print; exit}"""
    out = subprocess.run(["awk", awk, "README.md"], cwd=ROOT, capture_output=True, text=True, check=True)
    assert out.stdout.strip() == TEST_COMMAND
    assert "awk '/<!-- readme-test-command -->/" in (ROOT / ".ci" / "run").read_text()


def test_python_example_runs_and_predicts_the_stored_angles():
    (code,) = [b for b in code_blocks("python") if "load_trials" in b]
    env: dict = {}
    exec(compile(code, "README.md", "exec"), env)  # noqa: S102 - the README's own example
    import numpy as np

    trials, pred = env["trials"], env["pred"]
    err = np.degrees(pred["theta1_rad"]) - trials["theta1_deg"].to_numpy()
    # deg: the sample run comes from the default (realistic) rig, whose 0.2 deg potentiometer play
    # and sleeve friction put the angles' error near 0.14 deg; a broken example is off by degrees.
    assert np.sqrt(np.mean(err**2)) < 0.25


def runnable_blocks() -> list[list[str]]:
    """Shell blocks that run on the simulated rig or the sample runs (no hardware, no waiting)."""
    blocks = []
    for block in code_blocks("sh"):
        if "--unattended" not in block and "sample_runs/" not in block:
            continue
        lines = []
        for line in block.splitlines():
            cmd = line.split("#", 1)[0].strip() if not line.strip().startswith("labcli sim") else ""
            if cmd.startswith("labcli ") and " monitor " not in f" {cmd} " and "--pty" not in cmd:
                lines.append(cmd)
            elif cmd.startswith("mkdir -p ") and lines == []:
                lines.append(cmd)
        if lines:
            blocks.append(lines)
    return blocks


def outputs(cmd: str) -> list[str]:
    args = shlex.split(cmd)
    return [args[i + 1] for i, a in enumerate(args[:-1]) if a in ("-o", "--plot")] + (
        [args[2]] if args[1] == "acquire" else []
    )


@pytest.mark.parametrize("block", runnable_blocks(), ids=lambda b: b[0][:40])
def test_shell_blocks_run_as_written(block, tmp_path):
    sample = ROOT / "sample_runs"
    before = {p.name: p.read_bytes() for p in sample.iterdir()}
    for cmd in block:
        if cmd.startswith("mkdir -p "):
            (tmp_path / cmd.split()[2]).mkdir(parents=True)
            continue
        args = shlex.split(cmd.replace("sample_runs/", f"{sample}/"))
        r = subprocess.run(
            [sys.executable, "-m", "labcli", *args[1:]], cwd=tmp_path, capture_output=True, text=True, timeout=300
        )
        assert r.returncode == 0, (cmd, r.stdout[-2000:], r.stderr[-2000:])
        assert "Traceback" not in r.stderr
        for out in outputs(cmd):
            assert (tmp_path / out).stat().st_size > 0, (cmd, out)
    # Trying the samples never changes them.
    assert {p.name: p.read_bytes() for p in sample.iterdir()} == before


def test_there_are_runnable_blocks():
    cmds = [c for b in runnable_blocks() for c in b]
    assert any("acquire" in c and "--unattended" in c for c in cmds)
    assert any(c.startswith("labcli fit sample_runs/") for c in cmds)
    assert any("rpam2015" in c for c in cmds)


def test_example_outputs_stay_in_one_ignored_folder():
    # Every file a README example writes lands under out/, which .gitignore covers.
    written = [
        o
        for block in code_blocks("sh")
        for line in block.splitlines()
        if line.startswith("labcli ")
        for o in outputs(line.split("#", 1)[0].strip())
    ]
    assert written and all(o.startswith("out/") for o in written), written
    assert "/out/" in (ROOT / ".gitignore").read_text().split()


def test_docs_cited_by_the_code_exist_and_are_linked_from_the_readme():
    cited = set()
    for path in [*(ROOT / "labcli").rglob("*.py"), *(ROOT / "protocols").glob("*.toml")]:
        cited.update(re.findall(r"docs/[\w-]+\.md", path.read_text(encoding="utf-8")))
    assert cited, "the code cites no docs"
    for doc in cited | {"docs/wire-protocol.md", "docs/table-formats.md", "docs/errata.md"}:
        assert (ROOT / doc).is_file(), doc
        assert f"]({doc})" in README, f"README does not link {doc}"
