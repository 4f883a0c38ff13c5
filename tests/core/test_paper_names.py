"""The core and the commands name no paper: what a paper owns is reached through the registry.

Read with ``ast``: no string in ``labcli/core`` or ``labcli/commands`` is a run kind of an
installed paper, and none names a paper or one of its shipped protocols (docstrings are
documentation, with examples a person types, and are left out); the default protocol of a
command is declared by the paper that ships it and answered by the registry, so the name
``DEFAULT_PROTOCOL`` lives in one module at most.
"""

from __future__ import annotations

import ast
import re
from pathlib import Path

import pytest

import labcli
from labcli.core import registry

PACKAGE = Path(labcli.__file__).resolve().parent
PAPER_FREE = sorted([*(PACKAGE / "core").rglob("*.py"), *(PACKAGE / "commands").rglob("*.py"), PACKAGE / "cli.py"])


def strings(path: Path) -> list[tuple[int, str]]:
    """Every string constant of a module but its docstrings (f-string parts included)."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    docs = set()
    for node in ast.walk(tree):
        if isinstance(node, (ast.Module, ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)) and node.body:
            first = node.body[0]
            if isinstance(first, ast.Expr) and isinstance(first.value, ast.Constant):
                docs.add(id(first.value))
    return [
        (node.lineno, node.value)
        for node in ast.walk(tree)
        if isinstance(node, ast.Constant) and isinstance(node.value, str) and id(node) not in docs
    ]


def paper_names() -> tuple[set[str], list[str]]:
    """(run kinds, names that are a paper's own: paper names, shipped protocols, hyphenated kinds)."""
    kinds = {k for p in registry.papers() for k in p.run_kinds}
    own = {p.name for p in registry.papers()} | {s for p in registry.papers() for s in p.shipped_protocols}
    return kinds, sorted(own | {k for k in kinds if not k.isalpha()}, key=len, reverse=True)


def test_the_check_knows_the_installed_papers():
    kinds, own = paper_names()
    assert {"force", "push", "rpam-stretch", "rpam-joint"} <= kinds
    assert {"takuma2014", "rpam2015", "takuma2014-stiffness"} <= set(own)


@pytest.mark.parametrize("path", PAPER_FREE, ids=lambda p: str(p.relative_to(PACKAGE)))
def test_no_string_names_a_run_kind_or_a_paper(path):
    kinds, own = paper_names()
    if path.name == "cli.py":
        from labcli.cli import COMMANDS

        kinds -= set(COMMANDS)  # `labcli sense` writes runs of kind sense: the table names the command
    word = re.compile(r"(?<![\w-])(" + "|".join(map(re.escape, own)) + r")(?![\w-])")
    found = [f"{line}: {text!r}" for line, text in strings(path) if text in kinds or word.search(text)]
    assert not found, f"{path.relative_to(PACKAGE)} names what a paper owns: {found}"


def test_the_check_finds_what_it_looks_for(tmp_path):
    sample = tmp_path / "sample.py"
    sample.write_text(
        '"""Docstring: labcli fit run.h5 --protocol takuma2014."""\nKIND = "force"\nP = f"{x} rpam2015"\n'
    )
    kinds, own = paper_names()
    word = re.compile(r"(?<![\w-])(" + "|".join(map(re.escape, own)) + r")(?![\w-])")
    hits = [text for _, text in strings(sample) if text in kinds or word.search(text)]
    assert hits == ["force", " rpam2015"]


def test_default_protocol_is_named_in_one_module_at_most():
    holders = set()
    for path in PACKAGE.rglob("*.py"):
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            name = (
                node.id
                if isinstance(node, ast.Name)
                else node.attr
                if isinstance(node, ast.Attribute)
                else node.name
                if isinstance(node, ast.alias)
                else None
            )
            if name == "DEFAULT_PROTOCOL":
                holders.add(str(path.relative_to(PACKAGE)))
    assert holders <= {"core/registry.py"}, sorted(holders)


@pytest.mark.parametrize("command", ["acquire", "monitor", "demo", "fit", "validate", "classify", "optimize"])
def test_each_command_default_protocol_is_declared_by_exactly_one_paper(command):
    declaring = [p.name for p in registry.papers() if command in p.default_protocols]
    assert len(declaring) == 1
    owner = registry.for_shipped_protocol(registry.default_protocol(command))
    assert owner.name == declaring[0]
