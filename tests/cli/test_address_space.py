"""Under ``ulimit -v`` too low to load numpy, pandas and HDF5, every command is one sentence before
it reads or writes anything (it was an ImportError traceback, OpenBLAS's abort or a segfault)."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

resource = pytest.importorskip("resource")


def test_a_low_address_space_limit_is_one_sentence_and_writes_nothing(tmp_path: Path) -> None:
    limit = 300 * 2**20

    def low() -> None:
        resource.setrlimit(resource.RLIMIT_AS, (limit, resource.getrlimit(resource.RLIMIT_AS)[1]))

    r = subprocess.run(
        [sys.executable, "-m", "labcli", "acquire", "r.h5", "--port", "sim://?seed=1&clock=virtual", "--unattended"],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=60,
        preexec_fn=low,
        env=dict(os.environ),
    )
    assert r.returncode == 1
    assert r.stderr == (
        "Error: the address-space limit (ulimit -v) is 300 MiB, below the 448 MiB labcli needs to load numpy, "
        "pandas and HDF5; raise it (ulimit -v unlimited) and run the command again. Nothing was read or written.\n"
    )
    assert list(tmp_path.iterdir()) == []
