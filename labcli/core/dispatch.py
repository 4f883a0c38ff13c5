"""Which paper's analysis reads a file the person named (a run file, a table, a protocol, a
model), and the options that analysis takes.

A run file names its kind, and the kind its paper (:mod:`labcli.core.registry`);
anything else goes to the paper that ships the command's default protocol
(:func:`labcli.core.registry.default_protocol`), whose analysis then says in its own words
what is wrong with it.  The options a person typed are then checked against what that paper
declares for the command (:mod:`labcli.core.options`): one it does not declare is refused in
one sentence naming the papers that do.  A model file names its schema, which the paper that
writes it declares (``model_schemas``).
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ..errors import ConfigError, LabcliError
from .files import RUN_FILE_SUFFIXES
from .options import Typed, bind, names
from .paper import Analysis, Paper
from .registry import analysis_options, default_protocol, for_model_schema, for_run_kind, for_shipped_protocol


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


def _owner(name: str, inputs: Iterable[str | Path], default: str | None) -> tuple[Paper, Path | None, str | None]:
    """The paper for analysis ``name`` of these inputs, and the run file (with its kind) that chose it."""
    for path in inputs:
        kind = run_kind_of(path)
        if kind is None:
            continue
        try:
            owner = for_run_kind(kind)
        except LabcliError:
            continue
        if name in owner.analysis_options:
            return owner, Path(path), kind
    return for_shipped_protocol(default or default_protocol(name)), None, None


def for_analysis(name: str, *, inputs: Iterable[str | Path] = (), default_protocol: str | None = None) -> Paper:
    """The paper whose analysis ``name`` reads these inputs.

    A run file's own paper when it offers the analysis; anything else (a table, a
    protocol file, a file that does not open) goes to the paper that ships the command's
    default protocol (``default_protocol``, else the one the registry names for ``name``).
    """
    return _owner(name, inputs, default_protocol)[0]


@dataclass(frozen=True)
class Prepared:
    """An analysis ready to run: its paper, its functions, the options object it takes, and the
    protocol a command without inputs runs with (``optimize``)."""

    paper: Paper
    analysis: Analysis
    options: Any
    protocol: str | None = None


def prepare(command: str, typed: Typed, *, inputs: Sequence[str | Path] = (), protocol: str | None = None) -> Prepared:
    """The analysis of ``command`` for these inputs, with the options a person ``typed`` bound to it.

    ConfigError (one sentence) for an option the paper does not declare for ``command``, or
    a required one left out.
    """
    paper, run, kind = _owner(command, inputs, None)
    if run is not None:
        subject = f"{run} is a run of kind {kind} ({paper.name})"
    elif inputs:
        subject = f"labcli {command} reads {inputs[0]} with {paper.name}"
    else:
        subject = f"labcli {command} runs with {paper.name}"
    declared = analysis_options(command)

    def owners(name: str) -> list[str]:
        holders = [p for p, cls in declared.items() if name in names(cls)]
        return [" and ".join(holders) + (" runs" if inputs else "")] if holders else []

    options = bind(paper.analysis_options.get(command), typed, owners=owners, subject=subject)
    analysis = paper.analysis(command)
    if analysis is None:
        raise ConfigError(f"{paper.name} offers no analysis for labcli {command}.")
    chosen = protocol if inputs or protocol is not None else default_protocol(command)
    return Prepared(paper, analysis, options, chosen)


def for_model_file(path: str | Path, analysis: str) -> Paper:
    """The paper that wrote the model file ``path`` (its ``schema``), offering the analysis ``analysis``."""
    from .files import read_input
    from .jsontext import JSONDepthError, json_kind, loads_bounded

    p = Path(path)
    try:
        d = loads_bounded(read_input(p, "a model file", label=f"The model file {p}").decode("utf-8"))
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
