"""The run-file recipe in docs/run-files.md reads the record tables with h5py and pandas alone.

The block after the ``run-file-recipe`` marker runs in a fresh Python that never imports labcli
(checked), and what it reads is held against labcli's own reading of the same runs, so the page
cannot drift from the file layout.
"""

from __future__ import annotations

import json
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[2]


def recipe() -> str:
    text = (ROOT / "docs" / "run-files.md").read_text(encoding="utf-8")
    m = re.search(r"<!-- run-file-recipe -->\n```python\n(.*?)```", text, re.S)
    assert m, "docs/run-files.md lost its run-file-recipe block"
    return m.group(1)


def read_without_labcli(path: Path, name: str) -> dict:
    """The recipe's table of ``path`` as JSON, from a Python whose modules never include labcli."""
    code = recipe().split("\ntrials = read_table(")[0] + (
        "\nimport json, sys\n"
        f"df = read_table({str(path)!r}, {name!r})\n"
        "assert not any(m == 'labcli' or m.startswith('labcli.') for m in sys.modules), 'labcli imported'\n"
        "print(json.dumps({'columns': {c: df[c].tolist() for c in df.columns}, 'units': df.attrs['units']}))\n"
    )
    out = subprocess.run([sys.executable, "-I", "-c", code], capture_output=True, text=True, timeout=120, cwd=ROOT)
    assert out.returncode == 0, out.stderr
    return json.loads(out.stdout)


def test_the_recipe_runs_as_printed():
    out = subprocess.run([sys.executable, "-I", "-c", recipe()], capture_output=True, text=True, timeout=120, cwd=ROOT)
    assert out.returncode == 0, out.stderr
    assert "F_Fx" in out.stdout and len(out.stdout.splitlines()) == 6  # header and five trials


@pytest.fixture(scope="module")
def fresh(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    from support.standards import make_runs

    return make_runs(tmp_path_factory.mktemp("recipe"))


@pytest.mark.parametrize(
    "run,name",
    [
        ("force.h5", "trials"),
        ("pushes.h5", "pushes"),
        ("v2:float-counts.h5", "trials"),
        ("new:force", "trials"),
        ("new:push", "pushes"),
    ],
)
def test_the_recipe_reads_what_labcli_reads(run, name, request):
    """The sample runs, a file kept as schema 2 wrote it (texts as str) and runs written today
    (schema 3: texts as bytes)."""
    from labcli.core.store import RunFile

    if run.startswith("new:"):
        path = request.getfixturevalue("fresh")[run[4:]]
    elif run.startswith("v2:"):
        path = ROOT / "tests" / "data" / "v2" / run[3:]
    else:
        path = ROOT / "sample_runs" / run
    got = read_without_labcli(path, name)
    with RunFile.open(path) as rf:
        ids = rf.records.ids()
        first = rf.records.read(int(ids[0]))
    cols = got["columns"]
    key = "trial" if name == "trials" else "push"
    assert cols[key] == [int(i) for i in ids]
    assert got["units"]["P0_P_L1"] == "MPa" and got["units"]["theta_theta1"] == "rad"
    np.testing.assert_array_equal([cols[f"P0_{c}"][0] for c in ("P_L1", "P_R1", "P_L2", "P_R2")], first["P0_MPa"])
    np.testing.assert_array_equal([cols["theta_theta1"][0], cols["theta_theta2"][0]], first["theta_rad"])
    if name == "trials":
        assert got["units"]["F_Fx"] == "N"
        np.testing.assert_array_equal([cols["F_Fx"][0], cols["F_Fy"][0]], first["force_N"])
    else:
        assert got["units"]["R"] == "m" and cols["R"][0] == first["R_m"] and cols["object"][0] == first["object"]
    if run.startswith("new:") and name == "trials":  # the plan's set, under the NeXus-safe name of its dataset
        assert cols["plan_set_"] == [first["plan"]["set"], "fit", "validation"]
