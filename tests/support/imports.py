"""labcli's import graph as ``ast`` reads it: imports inside functions too, relative ones resolved.

An import of ``pkg.name`` counts as an import of the module ``pkg.name`` when there is one,
else of ``pkg``.  A module's parent packages are not edges: they hold no code a module
reaches unless it names it.  :data:`GRAPH` has every import; :data:`RUNTIME` leaves out those
under ``if TYPE_CHECKING:``, which only a type checker reads (a facet naming the run file it
belongs to in its annotations, say), so they cannot make an import cycle.
"""

from __future__ import annotations

import ast
from pathlib import Path

import labcli

PACKAGE = Path(labcli.__file__).resolve().parent


def module_name(path: Path) -> str:
    parts = path.relative_to(PACKAGE.parent).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


MODULES = {module_name(p): p for p in PACKAGE.rglob("*.py")}


def _type_checking_only(tree: ast.AST) -> set[int]:
    """The ids of the import nodes under ``if TYPE_CHECKING:`` (or ``typing.TYPE_CHECKING``)."""
    out: set[int] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.If) and ast.unparse(node.test) in ("TYPE_CHECKING", "typing.TYPE_CHECKING"):
            out.update(id(n) for stmt in node.body for n in ast.walk(stmt))
    return out


def imports_of(name: str, runtime: bool = False) -> set[str]:
    """The labcli modules ``name`` imports, anywhere in its body (``runtime``: those Python runs)."""
    path = MODULES[name]
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    found: set[str] = set()
    tree = ast.parse(path.read_text(encoding="utf-8"))
    skip = _type_checking_only(tree) if runtime else set()
    for node in ast.walk(tree):
        if id(node) in skip:
            continue
        if isinstance(node, ast.Import):
            targets = [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")
                base = base[: len(base) - (node.level - 1)]
                origin = ".".join(base + ([node.module] if node.module else []))
            else:
                origin = node.module or ""
            targets = [f"{origin}.{a.name}" if f"{origin}.{a.name}" in MODULES else origin for a in node.names]
        else:
            continue
        found.update(t for t in targets if t == "labcli" or t.startswith("labcli."))
    return found - {name}


GRAPH = {name: imports_of(name) for name in MODULES}
RUNTIME = {name: imports_of(name, runtime=True) for name in MODULES}


def reachable(name: str) -> set[str]:
    """Every labcli module ``name`` imports, directly or through the modules it imports."""
    seen: set[str] = set()
    todo = [name]
    while todo:
        for nxt in GRAPH.get(todo.pop(), ()):
            if nxt not in seen:
                seen.add(nxt)
                todo.append(nxt)
    return seen - {name}
