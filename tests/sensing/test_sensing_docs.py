"""docs/sensing.md's controller loop runs as printed, on the simulated rig, and finds its load."""

from __future__ import annotations

import contextlib
import io
import json
import os
import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def test_the_controller_loop_of_the_docs_runs_and_reports_the_scripted_load():
    text = (ROOT / "docs" / "sensing.md").read_text(encoding="utf-8")
    code = re.search(r"```python\n(import json\n\nfrom labcli.core.device import Device.*?)```", text, re.S).group(1)
    out = io.StringIO()
    cwd = os.getcwd()
    os.chdir(ROOT)  # the example names its files from the repository's top
    try:
        with contextlib.redirect_stdout(out):
            exec(compile(code, "docs/sensing.md", "exec"), {})
    finally:
        os.chdir(cwd)
    events = [json.loads(line) for line in out.getvalue().splitlines()]
    kinds = [e["event"] for e in events]
    assert kinds == ["load", "settled", "release"]
    assert abs(events[0]["t_device_s"] - 20.0) < 0.2 and abs(events[2]["t_device_s"] - 35.0) < 0.2
