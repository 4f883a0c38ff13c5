"""Which paper's analysis reads a file the person named (a run file, a table, a protocol, a model).

A run file names its kind, and the kind its paper (:mod:`labcli.core.registry`);
anything else goes to the paper that ships the command's default protocol, whose
analysis then says in its own words what is wrong with it.  A model file names its
schema, which the paper that writes it declares (``model_schemas``).
"""

from __future__ import annotations

from collections.abc import Iterable
from pathlib import Path

from ..errors import ConfigError, LabcliError
from .files import RUN_FILE_SUFFIXES
from .paper import Paper
from .registry import for_model_schema, for_run_kind, for_shipped_protocol


def run_kind_of(path: str | Path) -> str | None:
    """The kind of a readable run file; None for a table, a missing or unreadable file."""
    p = Path(path)
    if p.suffix.lower() not in RUN_FILE_SUFFIXES or not p.is_file():
        return None
    from .store import RunFile  # h5py, only for a run file

    try:
        with RunFile.open(p) as run:
            return run.kind
    except LabcliError:
        return None


def for_analysis(name: str, *, inputs: Iterable[str | Path] = (), default_protocol: str) -> Paper:
    """The paper whose analysis ``name`` reads these inputs.

    A run file's own paper when it offers the analysis; anything else (a table, a
    protocol file, a file that does not open) goes to the paper that ships
    ``default_protocol``.
    """
    for path in inputs:
        kind = run_kind_of(path)
        if kind is None:
            continue
        try:
            owner = for_run_kind(kind)
        except LabcliError:
            continue
        if owner.analysis(name) is not None:
            return owner
    return for_shipped_protocol(default_protocol)


def for_model_file(path: str | Path, analysis: str) -> Paper:
    """The paper that wrote the model file ``path`` (its ``schema``), offering the analysis ``analysis``."""
    from .jsontext import JSONDepthError, json_kind, loads_bounded

    p = Path(path)
    try:
        d = loads_bounded(p.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise ConfigError(f"The model file {p} does not exist; write one with `labcli fit`.") from None
    except (OSError, UnicodeDecodeError, ValueError, JSONDepthError):
        raise ConfigError(f"{p} is not a model file (not JSON text); pass the .json file `labcli fit` wrote.") from None
    schema = d.get("schema") if isinstance(d, dict) else None
    if not isinstance(schema, str):
        raise ConfigError(
            f"{p} names no model schema (it holds {json_kind(d)} without a 'schema' key), so no paper reads it; "
            "pass the model .json file `labcli fit` wrote for a force run."
        )
    owner = for_model_schema(schema)
    if owner.analysis(analysis) is None:
        raise ConfigError(f"The {owner.name} model {p} has no `{analysis}`: the paper does not offer it.")
    return owner
