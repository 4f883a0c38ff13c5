"""Every kind of run labcli writes, exported, and each CSV's sidecar checked by Frictionless
against the rows beside it (field order, types, units), with and without ``--all-columns``."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from click.testing import CliRunner
from support.standards import ROOT, frictionless_problems, make_runs

from labcli.cli import cli
from labcli.core.table_meta import sidecar

KINDS = ("force", "push", "rpam-stretch", "rpam-joint", "imported", "upgraded")


@pytest.fixture(scope="module")
def runs(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    return make_runs(tmp_path_factory.mktemp("kinds"))


def invoke(*args: object) -> object:
    return CliRunner().invoke(cli, [str(a) for a in args])


@pytest.mark.parametrize("kind", KINDS)
@pytest.mark.parametrize("all_columns", [False, True])
def test_every_sidecar_passes_frictionless(runs, kind, all_columns, tmp_path):
    out = tmp_path / f"{kind}.csv"
    res = invoke("export", runs[kind], "-o", out, *(["--all-columns"] if all_columns else []))
    assert res.exit_code == 0, res.output
    assert frictionless_problems(Path(f"{out}.json")) == []


@pytest.mark.parametrize("name", ["force", "pushes", "stretch", "joint", "bent"])
def test_the_sample_runs_sidecars_pass_frictionless(name, tmp_path):
    out = tmp_path / f"{name}.csv"
    res = invoke("export", ROOT / "sample_runs" / f"{name}.h5", "-o", out)
    assert res.exit_code == 0, res.output
    assert frictionless_problems(Path(f"{out}.json")) == []


def test_the_sidecar_lists_the_fields_in_the_csvs_order(runs, tmp_path):
    # A push table's rest posture comes before true_stiffness_N_per_m in the CSV; the sidecar
    # once took the DataFrame's order, and Frictionless checks fields by position.
    out = tmp_path / "push.csv"
    assert invoke("export", runs["push"], "-o", out).exit_code == 0
    header = out.read_text(encoding="utf-8").splitlines()[0].split(",")
    fields = [f["name"] for f in json.loads(Path(f"{out}.json").read_text())["schema"]["fields"]]
    assert fields == header


def test_a_sidecar_made_in_another_order_is_caught(runs, tmp_path):
    out = tmp_path / "push.csv"
    assert invoke("export", runs["push"], "-o", out).exit_code == 0
    meta = json.loads(Path(f"{out}.json").read_text())
    meta["schema"]["fields"] = meta["schema"]["fields"][::-1]  # what the older sidecar did, in effect
    Path(f"{out}.json").write_text(json.dumps(meta))
    assert frictionless_problems(Path(f"{out}.json")) != []


def test_sidecar_without_a_header_follows_the_frame():
    import pandas as pd

    from labcli.core.registry import record_type

    rt = record_type("force")
    df = pd.DataFrame({"trial": [1], "set": ["fit"]})
    names = [f["name"] for f in sidecar(df, rt.table_spec, "x.csv")["schema"]["fields"]]
    assert names == ["trial", "set"]
