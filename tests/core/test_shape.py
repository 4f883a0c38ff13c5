"""The shape of the code, as ``ast`` reads it: small classes, small modules, short functions.

A big object is reached through small facets (the run file's ``run.records``, ``run.windows``,
...), each a class of its own module; modules stay small enough to read whole and functions
short enough to see whole.  The limits:

=====================================================  =========
no class in labcli/core/store/ over                    400 lines
no module of labcli/core/ over                         600 lines
no function of core/store/ or the engine's modules over 80 lines
no function of labcli/ over                            80 lines
=====================================================  =========

``python tests/core/test_shape.py`` prints any function of the tree over the limit.  That no
module but one writes ``DEFAULT_PROTOCOL`` and that no core or command module names a paper's
run kind are checked by tests/core/test_paper_names.py.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

import labcli

PACKAGE = Path(labcli.__file__).resolve().parent
CORE = PACKAGE / "core"
STORE = CORE / "store"

MAX_CLASS = 400
MAX_MODULE = 600
MAX_FUNCTION = 80
# The engine's modules (what ran in one 745-line module before it was split by concern), the
# acquisition that drives it, and the window and record types from the engine to the file.
ENGINE = (
    "engine.py",
    "stream.py",
    "outcome.py",
    "reconnect.py",
    "setupcheck.py",
    "simoperator.py",
    "capture.py",
    "acquisition.py",
    "window.py",
    "record.py",
)


def lines(node: ast.AST) -> int:
    return node.end_lineno - node.lineno + 1  # type: ignore[attr-defined]


def tree(path: Path) -> ast.Module:
    return ast.parse(path.read_text(encoding="utf-8"))


def functions(path: Path) -> list[tuple[str, int]]:
    """(name, lines) of every function and method of a module, nested ones included."""
    return [
        (node.name, lines(node))
        for node in ast.walk(tree(path))
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef))
    ]


def rel(path: Path) -> str:
    return path.relative_to(PACKAGE.parent).as_posix()


def test_the_measures_count_what_they_say(tmp_path):
    src = tmp_path / "m.py"
    src.write_text("class A:\n    def f(self):\n        x = 1\n        return x\n\n\ndef g():\n    pass\n")
    t = tree(src)
    (cls,) = [n for n in t.body if isinstance(n, ast.ClassDef)]
    assert lines(cls) == 4
    assert sorted(functions(src)) == [("f", 3), ("g", 2)]


@pytest.mark.parametrize("path", sorted(STORE.glob("*.py")), ids=lambda p: p.name)
def test_no_class_of_the_run_file_is_over_400_lines(path):
    big = [(n.name, lines(n)) for n in ast.walk(tree(path)) if isinstance(n, ast.ClassDef) and lines(n) > MAX_CLASS]
    assert not big, f"{rel(path)}: {big}"


@pytest.mark.parametrize("path", sorted(CORE.rglob("*.py")), ids=lambda p: rel(p))
def test_no_core_module_is_over_600_lines(path):
    n = len(path.read_text(encoding="utf-8").splitlines())
    assert n <= MAX_MODULE, f"{rel(path)} has {n} lines (at most {MAX_MODULE})"


@pytest.mark.parametrize("path", [*sorted(STORE.glob("*.py")), *(CORE / name for name in ENGINE)], ids=lambda p: rel(p))
def test_no_function_of_the_run_file_or_the_engine_is_over_80_lines(path):
    long = [(name, n) for name, n in functions(path) if n > MAX_FUNCTION]
    assert not long, f"{rel(path)}: {long}"


def long_functions() -> list[str]:
    """Every function of the tree over the limit."""
    return [
        f"{rel(path)}:{name} ({n} lines)"
        for path in sorted(PACKAGE.rglob("*.py"))
        for name, n in functions(path)
        if n > MAX_FUNCTION
    ]


def test_no_function_of_the_tree_is_over_80_lines():
    assert long_functions() == [], "over 80 lines (cut them)"


if __name__ == "__main__":  # python tests/core/test_shape.py: what the tree still has to cut
    found = long_functions()
    print(*found, f"{len(found)} functions over {MAX_FUNCTION} lines", sep="\n")
