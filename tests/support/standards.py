"""Run files of every kind labcli writes, and the field's validator for the CSV sidecars.

* :func:`make_runs`: a force run, a push run, an rPAM stretch test and joint map (each acquired
  unattended on the simulated rig, virtual clock), an imported run and a schema-1 run upgraded
  by a write: every kind of file labcli writes today.  A new stream joins by adding its builder.
* :func:`frictionless_problems`: what Frictionless finds wrong with a CSV's sidecar.

The validator is a test extra (pyproject ``test``); a test that needs it skips, saying so,
where it is not installed.
"""

from __future__ import annotations

import importlib.util
import io
import json
import shutil
from pathlib import Path
from typing import Any

import pytest
from rich.console import Console

ROOT = Path(__file__).resolve().parents[2]
PLAN = "trial,set,mass_g,direction_deg\n1,fit,200,0\n2,fit,300,45\n3,validation,100,90\n"


def need(module: str, package: str) -> None:
    """Skip the calling test, naming the package, where ``module`` cannot be imported."""
    if importlib.util.find_spec(module) is None:
        pytest.skip(f"{package} is not installed (pip install '.[test]' brings it)")


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
