"""Nobody at the prompts: standard input at end of file or closed ends the session with "No input", exit 1."""

from __future__ import annotations

import os
import subprocess
import sys

import pytest

SIM = "sim://?seed=1&clock=virtual"


@pytest.mark.parametrize("how", ["devnull", "closed"])
def test_no_input_at_the_first_prompt_ends_with_one_sentence_and_no_file(tmp_path, how):
    kwargs = (
        {"stdin": subprocess.DEVNULL} if how == "devnull" else {"stdin": None, "preexec_fn": lambda: os.close(0)}
    )  # as `<&-` in a shell
    r = subprocess.run(
        [sys.executable, "-m", "labcli", "acquire", "run.h5", "--port", SIM],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=60,
        env=dict(os.environ, COLUMNS="400"),
        **kwargs,
    )
    assert "Traceback" not in r.stderr
    assert r.returncode == 1
    assert r.stderr == (
        "Error: No input (standard input ended) during the setup, before anything was written to "
        "run.h5; run the command where someone at the rig can answer its prompts.\n"
    )
    assert not (tmp_path / "run.h5").exists()
