"""Nobody at the prompts: standard input at end of file or closed ends the session with "No input", exit 1."""

from __future__ import annotations

import os
import subprocess
import sys

import pytest

SIM = "sim://?seed=1&clock=virtual"


def run(tmp_path, how, port):
    kwargs = (
        {"stdin": subprocess.DEVNULL} if how == "devnull" else {"stdin": None, "preexec_fn": lambda: os.close(0)}
    )  # as `<&-` in a shell
    return subprocess.run(
        [sys.executable, "-m", "labcli", "acquire", "run.h5", "--port", port],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=60,
        env=dict(os.environ, COLUMNS="400"),
        **kwargs,
    )


@pytest.mark.parametrize("how", ["devnull", "closed"])
def test_no_input_at_the_first_prompt_ends_with_one_sentence_and_no_file(tmp_path, how):
    # A 1.0 board: its first prompt asks for the air supply, before the run file exists.
    r = run(tmp_path, how, SIM + "&fw=1.0")
    assert "Traceback" not in r.stderr
    assert r.returncode == 1
    assert r.stderr == (
        "Error: No input (standard input ended) during the setup, before anything was written to "
        "run.h5; run the command where someone at the rig can answer its prompts.\n"
    )
    assert not (tmp_path / "run.h5").exists()


@pytest.mark.parametrize("how", ["devnull", "closed"])
def test_no_input_at_the_first_load_on_a_board_with_valves(tmp_path, how):
    # The board supplies and holds the chambers by command: the first prompt is the first load.
    r = run(tmp_path, how, SIM)
    assert "Traceback" not in r.stderr
    assert r.returncode == 1
    assert r.stderr == (
        "Error: No input: standard input ended at a question during trial 1, so trial 1 was not stored; 0 trials "
        f"stored in run.h5. Resume where someone at the rig can answer: labcli acquire run.h5 --port '{SIM}' --resume\n"
    )
