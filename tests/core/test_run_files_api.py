"""docs/run-files-api.md shows the run file's facets from Python: its examples run as written.

Each ``python`` block of the page runs, in order and in one namespace, from a folder holding
a copy of ``sample_runs/`` (so nothing the examples write touches the samples), and every
facet the page's table names is a facet of a run file.
"""

from __future__ import annotations

import re
import shutil
from pathlib import Path

import pytest

from labcli.core.store import RunFile

ROOT = Path(__file__).resolve().parents[2]
PAGE = ROOT / "docs" / "run-files-api.md"


def blocks() -> list[str]:
    return re.findall(r"^```python\n(.*?)^```", PAGE.read_text(encoding="utf-8"), flags=re.S | re.M)


def test_the_page_examples_run_as_written(tmp_path, monkeypatch, capsys):
    shutil.copytree(ROOT / "sample_runs", tmp_path / "sample_runs")
    before = (tmp_path / "sample_runs" / "force.h5").read_bytes()
    monkeypatch.chdir(tmp_path)
    env: dict = {}
    assert len(blocks()) >= 4
    for code in blocks():
        exec(compile(code, str(PAGE), "exec"), env)  # noqa: S102 - the page's own example
    out = capsys.readouterr().out
    assert "force" in out and "takuma2014" in out  # what the blocks print: the run's kind, its model
    assert (tmp_path / "sample_runs" / "force.h5").read_bytes() == before  # examples write to a copy only
    with RunFile.open(tmp_path / "out-force-copy.h5") as run:
        assert run.split.get()["strategy"] == "random" and run.models.get("notes") is not None


def test_the_facets_the_page_names_are_the_run_files():
    text = PAGE.read_text(encoding="utf-8")
    named = set(re.findall(r"^\| `run\.(\w+)` \|", text, flags=re.M))
    with RunFile.open(ROOT / "sample_runs" / "force.h5") as run:
        assert named == {"records", "windows", "split", "models", "sessions"}
        for name in named:
            facet = getattr(run, name)
            assert type(facet).__module__ == f"labcli.core.store.{name}"


@pytest.mark.parametrize("call", sorted(set(re.findall(r"`run\.(\w+)\.(\w+)\(", PAGE.read_text(encoding="utf-8")))))
def test_every_call_the_page_shows_exists(call):
    facet, method = call
    with RunFile.open(ROOT / "sample_runs" / "force.h5") as run:
        assert callable(getattr(getattr(run, facet), method)), f"run.{facet}.{method}"
