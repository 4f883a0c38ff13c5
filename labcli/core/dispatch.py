"""Which paper's analysis reads a file the person named (a run file, a table, a protocol).

A run file names its kind, and the kind its paper (:mod:`labcli.core.registry`);
anything else goes to the paper that ships the command's default protocol, whose
analysis then says in its own words what is wrong with it.
"""

from __future__ import annotations

from collections.abc import Iterable
from pathlib import Path

from ..errors import LabcliError
from .files import RUN_FILE_SUFFIXES
from .paper import Paper
from .registry import for_run_kind, for_shipped_protocol


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
