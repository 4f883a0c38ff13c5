"""The layers, as the imports draw them: no cycle, the core knows no paper, no paper another.

Every module of the package is read with ``ast`` (imports inside functions too, relative
imports resolved) into a graph of labcli modules (:mod:`support.imports`).

==========================  ================================================================
layer                       may import
==========================  ================================================================
labcli.errors               nothing from labcli
labcli.core.*               labcli.errors, labcli.core.*
labcli.sensing.*            labcli.errors, labcli.core.*, labcli.sensing.*: never a paper (its
                            models come through the registry, ``Paper.sensing_model``)
labcli.papers.<p>.*         labcli.errors, labcli.core.*, labcli.sensing.*, its own subpackage
labcli.commands.*, cli      anything but a paper: papers only through the registry
==========================  ================================================================
"""

from __future__ import annotations

import pytest
from support.imports import GRAPH, MODULES, RUNTIME


def paper_of(name: str) -> str | None:
    parts = name.split(".")
    return parts[2] if len(parts) > 2 and parts[1] == "papers" else None


def test_the_graph_sees_function_level_and_relative_imports():
    # commands import the core inside their functions; the rPAM model names its actuator module relatively.
    assert "labcli.core.acquisition" in GRAPH["labcli.commands.acquire"]
    assert "labcli.papers.rpam2015.actuator" in GRAPH["labcli.papers.rpam2015.models.rpam"]
    assert "labcli.papers.takuma2014.analyses" in GRAPH["labcli.papers.takuma2014"]
    # A facet names its run file for the type checker only: an edge of the graph, not of the runtime's.
    assert "labcli.core.store.runfile" in GRAPH["labcli.core.store.records"]
    assert "labcli.core.store.runfile" not in RUNTIME["labcli.core.store.records"]
    assert RUNTIME["labcli.core.store.records"] <= GRAPH["labcli.core.store.records"]


def test_no_import_cycle():
    # Imports under ``if TYPE_CHECKING:`` are read by type checkers only: they make no cycle.
    state: dict[str, int] = {}  # 1: on the current path, 2: done
    path: list[str] = []

    def visit(node: str) -> None:
        state[node] = 1
        path.append(node)
        for nxt in sorted(RUNTIME.get(node, ())):
            if state.get(nxt) == 1:
                cycle = path[path.index(nxt) :] + [nxt]
                pytest.fail("import cycle: " + " -> ".join(cycle))
            if nxt not in state:
                visit(nxt)
        path.pop()
        state[node] = 2

    for name in sorted(RUNTIME):
        if name not in state:
            visit(name)


def test_errors_import_nothing_from_labcli():
    assert GRAPH["labcli.errors"] == set()


@pytest.mark.parametrize("name", sorted(n for n in MODULES if n.startswith("labcli.core")))
def test_core_imports_only_the_core_and_errors(name):
    outside = {m for m in GRAPH[name] if not (m == "labcli.errors" or m.startswith("labcli.core"))}
    assert not outside, f"{name} imports {sorted(outside)}"


@pytest.mark.parametrize("name", sorted(n for n in MODULES if n.startswith("labcli.sensing")))
def test_sensing_imports_the_core_errors_and_itself_only(name):
    outside = {
        m
        for m in GRAPH[name]
        if not (m == "labcli.errors" or m.startswith("labcli.core") or m.startswith("labcli.sensing"))
    }
    assert not outside, f"{name} imports {sorted(outside)}"


def test_the_sensing_layer_exists_and_the_core_does_not_reach_it():
    assert "labcli.sensing.estimator" in GRAPH["labcli.sensing"]
    assert not any(m.startswith("labcli.sensing") for n in MODULES if n.startswith("labcli.core") for m in GRAPH[n])


@pytest.mark.parametrize("name", sorted(n for n in MODULES if paper_of(n)))
def test_a_paper_imports_the_core_sensing_errors_and_itself_only(name):
    own = f"labcli.papers.{paper_of(name)}"
    outside = {
        m
        for m in GRAPH[name]
        if not (
            m == "labcli.errors"
            or m.startswith("labcli.core")
            or m.startswith("labcli.sensing")
            or m == own
            or m.startswith(own + ".")
        )
    }
    assert not outside, f"{name} imports {sorted(outside)}"


@pytest.mark.parametrize(
    "name", sorted(n for n in MODULES if n.startswith("labcli.commands") or n == "labcli.cli" or n == "labcli")
)
def test_commands_reach_a_paper_only_through_the_registry(name):
    papers = {m for m in GRAPH[name] if paper_of(m) or m == "labcli.papers"}
    assert not papers, f"{name} imports {sorted(papers)}"
