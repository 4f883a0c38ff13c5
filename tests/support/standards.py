"""Run files of every kind labcli writes, and the field's validator for the CSV sidecars.

* :func:`make_runs`: a force run, a push run, an rPAM stretch test and joint map (each acquired
  unattended on the simulated rig, virtual clock), an imported run and a schema-1 run upgraded
  by a write: every kind of file labcli writes today.  A new stream joins by adding its builder.
* :func:`frictionless_problems`: what Frictionless finds wrong with a CSV's sidecar.
* :func:`nxinspect_counts`, :func:`punx_errors`: what the NeXus validators find in a run file.

The validator is a test extra (pyproject ``test``); a test that needs it skips, saying so,
where it is not installed.
"""

from __future__ import annotations

import importlib.util
import io
import json
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest
from rich.console import Console

ROOT = Path(__file__).resolve().parents[2]
PLAN = "trial,set,mass_g,direction_deg\n1,fit,200,0\n2,fit,300,45\n3,validation,100,90\n"


def required() -> bool:
    """Whether a validator that is not installed fails the test rather than skips it
    (``LABCLI_STANDARDS=required``, as ``.ci/run`` sets)."""
    return os.environ.get("LABCLI_STANDARDS", "") == "required"


def _missing(message: str) -> None:
    if required():
        pytest.fail(f"{message}; LABCLI_STANDARDS=required", pytrace=False)
    pytest.skip(message)


def need(module: str, package: str) -> None:
    """Skip the calling test, naming the package, where ``module`` cannot be imported (fail it
    where the validators are :func:`required`)."""
    if importlib.util.find_spec(module) is None:
        _missing(f"{package} is not installed (pip install '.[test]' brings it)")


def _ui() -> Any:
    from labcli.core.ui import UnattendedUI

    return UnattendedUI(console=Console(file=io.StringIO()))


def _acquire(path: Path, port: str, **options: Any) -> Path:
    from labcli.core.acquisition import acquire

    outcome = acquire(path, port, unattended=True, force=True, ui=_ui(), **options)
    assert outcome.status == "finished", outcome.message
    return path


def _small_stiffness(folder: Path) -> Path:
    text = (ROOT / "protocols" / "takuma2014-stiffness.toml").read_text(encoding="utf-8")
    text = text.replace("pushes_per_object = 10", "pushes_per_object = 1")  # six objects, one push each
    path = folder / "stiffness-small.toml"
    path.write_text(text.replace('name = "takuma2014-stiffness"', 'name = "stiffness-small"'), encoding="utf-8")
    return path


def make_runs(folder: Path) -> dict[str, Path]:
    """One run file of each kind in ``folder`` (see the module docstring); kind -> path."""
    from cli.test_rpam_cli import small_protocol
    from click.testing import CliRunner

    from labcli.cli import cli

    plan = folder / "plan.csv"
    plan.write_text(PLAN)
    runs = {
        "force": _acquire(folder / "force.h5", "sim://?seed=2&clock=virtual", protocol="takuma2014", plan=str(plan)),
        "push": _acquire(folder / "push.h5", "sim://?seed=2&clock=virtual", protocol=str(_small_stiffness(folder))),
    }
    rpam = small_protocol(folder, "rpam-small")
    for experiment in ("stretch", "joint"):
        port = "sim://?mode=rpam&seed=4&clock=virtual"
        runs[f"rpam-{experiment}"] = _acquire(
            folder / f"{experiment}.h5", port, protocol=str(rpam), experiment=experiment
        )
    csv = folder / "force.csv"
    for args in (
        ["export", runs["force"], "-o", csv],
        ["import", csv, "-o", folder / "imported.h5", "--protocol", "takuma2014"],
    ):
        result = CliRunner().invoke(cli, [str(a) for a in args])
        assert result.exit_code == 0, result.output
    runs["imported"] = folder / "imported.h5"
    upgraded = folder / "upgraded.h5"
    shutil.copy(ROOT / "tests" / "data" / "v1" / "force.h5", upgraded)
    result = CliRunner().invoke(cli, ["split", str(upgraded), "--fit", "3", "--validation", "1"])  # a write upgrades it
    assert result.exit_code == 0, result.output
    runs["upgraded"] = upgraded
    return runs


def frictionless_problems(sidecar: Path) -> list[str]:
    """What Frictionless finds wrong with the table a sidecar describes (its rows checked against it)."""
    need("frictionless", "frictionless")
    from frictionless import Resource

    report = Resource(json.loads(sidecar.read_text()), basepath=str(sidecar.parent)).validate()
    return [e.message for e in report.errors] + [e.message for task in report.tasks for e in task.errors]


# The NeXus validators are command-line tools with dependencies of their own (nxvalidate
# 0.3.5b3, punx 0.3.5), so they live in any environment of the lab's choosing: on PATH, or in
# the bin directory LABCLI_NEXUS_VALIDATORS names (.ci/validators DIR makes one).  A test that
# needs one skips, saying so, or fails where they are required().
VALIDATORS = {"nxinspect": "nxvalidate==0.3.5b3", "punx": "punx==0.3.5"}
ANSI = re.compile(r"\x1b\[[0-9;]*m")


def validator(name: str) -> str:
    """The path of the validator ``name``, or skip the calling test naming where to get it."""
    folder = os.environ.get("LABCLI_NEXUS_VALIDATORS")
    found = shutil.which(name, path=folder) if folder else shutil.which(name)
    if found is None:
        where = f"in {folder}" if folder else "on PATH"
        _missing(
            f"{name} is not installed {where} (pip install '{VALIDATORS[name]}' into any environment, or run "
            ".ci/validators DIR, then put its bin directory on PATH or in LABCLI_NEXUS_VALIDATORS)"
        )
    assert found is not None
    return found


def _interpreter(script: str) -> str:
    """The Python a console script runs in (its #! line)."""
    first = Path(script).read_text(encoding="utf-8", errors="replace").splitlines()[0]
    return first[2:].strip() if first.startswith("#!") else sys.executable


def nxinspect_counts(path: Path) -> tuple[int, int, str]:
    """nxvalidate's nxinspect on ``path``: (warnings, errors, its report).  nxinspect sizes its
    output to the terminal, so it runs with a terminal size given (none exists under pytest)."""
    script = validator("nxinspect")
    code = (
        "import os, sys; os.get_terminal_size = lambda *a: os.terminal_size((200, 50)); "
        f"sys.argv = ['nxinspect', '-f', {str(path)!r}, '-w']; "
        "from nxvalidate.scripts.nxinspect import main; main()"
    )
    out = subprocess.run([_interpreter(script), "-c", code], capture_output=True, text=True, timeout=300)
    report = ANSI.sub("", out.stdout + out.stderr)
    counts = {k: re.search(rf"Total number of {k}: (\d+)", report) for k in ("warnings", "errors")}
    assert out.returncode == 0 and all(counts.values()), report[-2000:]
    return int(counts["warnings"][1]), int(counts["errors"][1]), report  # type: ignore[index]


def punx_errors(path: Path) -> tuple[int, str]:
    """punx's ERROR count for ``path`` (its summary statistics), and the ERROR lines."""
    out = subprocess.run([validator("punx"), "validate", str(path)], capture_output=True, text=True, timeout=300)
    m = re.search(r"^ERROR\s+(\d+)\s", out.stdout, re.M)
    assert out.returncode == 0 and m, (out.stdout + out.stderr)[-2000:]
    return int(m[1]), "\n".join(x for x in out.stdout.splitlines() if " ERROR " in x)
