"""Checks a paper plug-in can run on itself, in the spirit of scikit-learn's ``check_estimator``.

A paper living in another repository tests that it plugs into labcli with one line::

    from labcli.testing import check_paper
    from mypackage.mypaper import PAPER

    def test_it_plugs_in():
        check_paper(PAPER)

:func:`check_paper` asks the paper only what :class:`labcli.core.paper.Paper` promises, without
a rig, a file or the command line: its declarations are consistent (kinds, shipped protocols,
the commands it is the default for, simulated-rig modes), every declared option set builds
with its defaults, every run kind has a record type that satisfies
:class:`~labcli.core.paper.RecordType`, every declared analysis is there (and an undeclared one
is None), and every simulated rig satisfies :class:`~labcli.core.paper.SimulatedRig`, samples
frames of the right shape and gives the same frames for the same seed.  A failed check raises
:class:`PaperCheckError` naming the paper and what is wrong, in one sentence.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from typing import Any

import numpy as np

from .core.options import build, declared
from .core.paper import Analysis, Paper, RecordType, SimulatedRig

# The members of RecordType a record type must carry, with the type each value must have.
RECORD_MEMBERS: dict[str, type | tuple[type, ...]] = {
    "kind": str,
    "collection": str,
    "id_column": str,
    "noun": str,
    "plural": str,
    "qualifier": str,
    "splits": bool,
    "known_columns": frozenset,
    "columns": tuple,
    "signal": str,
}
RECORD_METHODS = (
    "count",
    "check",
    "read",
    "table",
    "from_row",
    "from_table",
    "import_split",
    "read_csv",
    "write_csv",
    "summarise",
    "inspect_lines",
)
SAMPLES = 8  # frames drawn from each simulated rig
SAMPLE_RATE_HZ = 200.0


class PaperCheckError(AssertionError):
    """A paper does not keep one of the promises of :class:`labcli.core.paper.Paper`."""


def _fail(paper: Any, what: str) -> PaperCheckError:
    return PaperCheckError(f"paper {getattr(paper, 'name', paper)!r}: {what}")


def _missing(obj: Any, protocol: type) -> list[str]:
    """The members of ``protocol`` that ``obj`` lacks (Python 3.10 has no get_protocol_members)."""
    members = set(getattr(protocol, "__annotations__", {}))
    members |= {n for n, v in vars(protocol).items() if callable(v) or isinstance(v, property)}
    return sorted(m for m in members if not m.startswith("_") and not hasattr(obj, m))


def check_declarations(paper: Paper) -> None:
    """Names, kinds and defaults agree with each other."""
    if not isinstance(paper, Paper):
        raise _fail(paper, f"lacks {', '.join(_missing(paper, Paper))} of labcli.core.paper.Paper")
    if not paper.name or not paper.name.isidentifier():
        raise _fail(paper, "its name must be a Python identifier (the entry point's name)")
    if not paper.run_kinds:
        raise _fail(paper, "declares no run kind")
    if paper.untagged_run_kind is not None and paper.untagged_run_kind not in paper.run_kinds:
        raise _fail(paper, f"untagged_run_kind {paper.untagged_run_kind!r} is not one of its run kinds")
    for command, protocol in paper.default_protocols.items():
        if protocol not in paper.shipped_protocols:
            raise _fail(paper, f"is the default of labcli {command} with {protocol!r}, a protocol it does not ship")
    if paper.demo_protocol is not None and paper.demo_protocol not in paper.shipped_protocols:
        raise _fail(paper, f"runs its demo with {paper.demo_protocol!r}, a protocol it does not ship")
    if paper.default_sim_mode is not None and paper.default_sim_mode not in paper.sim_modes:
        raise _fail(paper, f"default_sim_mode {paper.default_sim_mode!r} is not one of its sim_modes")
    if paper.sim_options is not None and not paper.sim_modes:
        raise _fail(paper, "declares rig options but no simulated rig (sim_modes is empty)")


def default_options(paper: Paper, cls: type | None, where: str) -> Any:
    """An object of the declared options ``cls`` with every default (None for no declaration)."""
    if cls is None:
        return None
    if not dataclasses.is_dataclass(cls):
        raise _fail(paper, f"the options of {where} must be a dataclass of labcli.core.options fields")
    try:
        decls = declared(cls)
    except (TypeError, ValueError) as e:
        raise _fail(paper, f"the options of {where} are not declared as data: {e}") from None
    required = [d.name for d in decls if getattr(d, "required", False)]
    if required:
        return None  # a required option has no default to build with
    return build(cls, {})


def check_options(paper: Paper) -> None:
    """Every declared option set builds with its defaults."""
    for command, cls in paper.analysis_options.items():
        default_options(paper, cls, f"labcli {command}")
    default_options(paper, paper.sim_options, "its simulated rigs")
    default_options(paper, getattr(paper, "sensing_options", None), "labcli sense")


def check_record_type(paper: Paper, kind: str) -> RecordType:
    """The record type of ``kind`` carries every member of RecordType, consistently."""
    records = paper.record_type(kind)
    for name, expected in RECORD_MEMBERS.items():
        value = getattr(records, name, None)
        if not isinstance(value, expected):
            raise _fail(paper, f"the record type of {kind!r} has no {name} of the right type (got {value!r})")
    for name in RECORD_METHODS:
        if not callable(getattr(records, name, None)):
            raise _fail(paper, f"the record type of {kind!r} has no method {name}")
    if records.kind != kind:
        raise _fail(paper, f"the record type of {kind!r} says its kind is {records.kind!r}")
    spec = getattr(records, "table_spec", None)
    if spec is None or records.id_column not in getattr(spec, "names", ()):
        raise _fail(paper, f"the table of {kind!r} records has no {records.id_column!r} column")
    names = [c.name for c in records.columns]
    if len(set(names)) != len(names):
        raise _fail(paper, f"the record type of {kind!r} names a column twice")
    for n in (1, 2):
        if not records.count(n).startswith(f"{n} "):
            raise _fail(paper, f"count({n}) of {kind!r} records must begin with the number: {records.count(n)!r}")
    return records


def check_analyses(paper: Paper) -> None:
    """Every declared analysis is there; one not declared is None."""
    for command in paper.analysis_options:
        analysis = paper.analysis(command)
        if not isinstance(analysis, Analysis) or not (callable(analysis.run) and callable(analysis.show)):
            raise _fail(paper, f"declares options for labcli {command} but gives no analysis for it")
    if paper.analysis("no-such-command") is not None:
        raise _fail(paper, "gives an analysis for a command it declares no options for")


def _draw(paper: Paper, mode: str, seed: int) -> tuple[SimulatedRig, Any, Any]:
    options = default_options(paper, paper.sim_options, f"the {mode} rig")
    rig = paper.make_rig(mode, seed=seed, noise=1.0, drift=None, tau_s=0.7, options=options)
    if not isinstance(rig, SimulatedRig):
        lacks = ", ".join(_missing(rig, SimulatedRig))
        raise _fail(paper, f"its {mode} rig lacks {lacks} of labcli.core.paper.SimulatedRig")
    t, counts = rig.samples(SAMPLES, SAMPLE_RATE_HZ)
    return rig, np.asarray(t), np.asarray(counts)


def check_simulated_rigs(paper: Paper) -> None:
    """Each rig samples frames of its channels on its clock, the same for the same seed."""
    for mode in paper.sim_modes:
        rig, t, counts = _draw(paper, mode, seed=1)
        n = len(rig.channels)
        if t.shape != (SAMPLES,) or counts.shape != (SAMPLES, n):
            raise _fail(paper, f"its {mode} rig sampled {counts.shape} counts for {SAMPLES} frames of {n} channels")
        if not np.all(np.diff(t) > 0):
            raise _fail(paper, f"the times of its {mode} rig's frames do not increase")
        if not rig.time_s > 0:
            raise _fail(paper, f"its {mode} rig's clock did not run while it sampled")
        _, t2, counts2 = _draw(paper, mode, seed=1)
        if not (np.array_equal(t, t2) and np.array_equal(counts, counts2)):
            raise _fail(paper, f"its {mode} rig gives other frames for the same seed")


def check_record_types(paper: Paper) -> None:
    for kind in paper.run_kinds:
        check_record_type(paper, kind)


CHECKS: tuple[Callable[[Paper], None], ...] = (
    check_declarations,
    check_options,
    check_record_types,
    check_analyses,
    check_simulated_rigs,
)


def check_paper(paper: Any) -> None:
    """Run every check on ``paper`` (a :class:`~labcli.core.paper.Paper`, or a module or
    package holding one as ``PAPER``); :class:`PaperCheckError` on the first that fails."""
    target = getattr(paper, "PAPER", paper)
    for check in CHECKS:
        check(target)
