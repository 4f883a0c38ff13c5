"""Which paper owns a run kind, a protocol kind, a shipped protocol or a simulated rig.

Papers are found through the entry-point group ``labcli.papers`` (each entry
point names an object implementing :class:`labcli.core.paper.Paper`; labcli's
own are declared in ``pyproject.toml``), loaded on the first lookup and never before, so
``labcli --help`` loads none.  :func:`register` adds one at run time (a test, a notebook).
The map from kinds to papers is written here once: nothing else in the toolkit
compares a kind with a paper's name.
"""

from __future__ import annotations

from importlib.metadata import entry_points
from typing import Any

from ..errors import ConfigError, LabcliError
from .options import Option, build, declared
from .paper import Paper, ProtocolKind, RecordType

GROUP = "labcli.papers"

_papers: dict[str, Paper] = {}
_discovered = False
_generation = 0  # bumped whenever the set of papers changes (commands cache the options they built)


def register(paper: Paper) -> Paper:
    """Add a paper (replacing one of the same name); returns it."""
    global _generation
    if not isinstance(paper, Paper):
        raise TypeError(f"{paper!r} does not implement labcli.core.paper.Paper")
    _papers[paper.name] = paper
    _generation += 1
    return paper


def unregister(name: str) -> None:
    """Remove a paper added with :func:`register` (a test cleaning up)."""
    global _generation
    _papers.pop(name, None)
    _generation += 1


def generation() -> int:
    """A number that changes whenever a paper is added or removed."""
    _discover()
    return _generation


def _discover() -> None:
    global _discovered
    if _discovered:
        return
    _discovered = True
    found = {}
    for ep in entry_points(group=GROUP):
        found[ep.name] = ep.load()
    if not found and not _papers:
        raise ConfigError(
            f"No paper is installed (the entry-point group {GROUP} is empty); "
            "reinstall labcli (pip install .) so that its papers register."
        )
    # Installed papers first, in name order; those registered at run time keep theirs.
    runtime = dict(_papers)
    _papers.clear()
    for name in sorted(found):
        register(found[name])
    _papers.update(runtime)


def papers() -> list[Paper]:
    """Every paper, installed ones in name order."""
    _discover()
    return list(_papers.values())


# --------------------------------------------------------------------------- kinds


def protocol_kinds() -> dict[str, ProtocolKind]:
    """Protocol kind -> its sections, over every paper, in name order."""
    kinds = {name: spec for e in papers() for name, spec in e.protocol_kinds.items()}
    return dict(sorted(kinds.items()))


def for_protocol_kind(kind: str) -> Paper:
    """The paper that reads protocols of ``kind``."""
    for e in papers():
        if kind in e.protocol_kinds:
            return e
    raise ConfigError(f"No paper reads protocols of kind '{kind}'.")


def for_run_kind(kind: str) -> Paper:
    """The paper that records runs of ``kind``."""
    for e in papers():
        if kind in e.run_kinds:
            return e
    raise LabcliError(f"No paper records runs of kind '{kind}'.")


def record_type(kind: str) -> RecordType:
    """The record type of runs of ``kind``."""
    return for_run_kind(kind).record_type(kind)


def for_model_schema(schema: str) -> Paper:
    """The paper whose model files carry ``schema`` (a paper lists them in ``model_schemas``)."""
    for e in papers():
        if schema in getattr(e, "model_schemas", ()):
            return e
    raise ConfigError(f"No installed paper writes models of schema {schema!r}; pass a .json file `labcli fit` wrote.")


def for_shipped_protocol(name: str) -> Paper:
    """The paper that ships the protocol file ``name`` (e.g. ``takuma2014``)."""
    for e in papers():
        if name in e.shipped_protocols:
            return e
    raise ConfigError(f"No paper ships a protocol named '{name}'.")


def demo_protocols() -> list[str]:
    """Names ``labcli demo --protocol`` takes: the default (:func:`default_protocol`) first, then the others."""
    names = [e.demo_protocol for e in papers() if e.demo_protocol]
    default = default_protocol("demo")
    return [default] + sorted(n for n in names if n != default) if default in names else sorted(names)


# --------------------------------------------------------------------------- commands


def default_protocol(command: str) -> str:
    """The shipped protocol ``command`` uses when nothing names one (a table, a new run, ``optimize``).

    Declared once, by the paper shipping it (``Paper.default_protocols``); exactly one paper may.
    """
    found = [(e.name, e.default_protocols[command]) for e in papers() if command in e.default_protocols]
    if len(found) != 1:
        who = ", ".join(f"{n} ({p})" for n, p in found) or "none"
        raise ConfigError(f"Exactly one paper must name the default protocol of labcli {command}; found {who}.")
    return found[0][1]


def analysis_options(command: str) -> dict[str, type]:
    """Paper name -> the options declaration of its analysis for ``command``, over the papers offering it."""
    return {e.name: e.analysis_options[command] for e in papers() if command in e.analysis_options}


def experiments() -> dict[str, str]:
    """``--experiment`` choices (of protocols holding several) -> the run kind each records."""
    return {c: kind for spec in protocol_kinds().values() for c, kind in spec.experiments.items()}


def untagged_run_kind() -> str:
    """The kind of a run file that names none (schema-1 files written before files named their kind)."""
    found = [e.untagged_run_kind for e in papers() if e.untagged_run_kind]
    if len(found) != 1:
        raise ConfigError(f"Exactly one paper must name the kind of untagged run files; found {found or 'none'}.")
    return found[0]


def _unused_experiment_option(name: str, kind: str) -> ConfigError:
    holders = " or ".join(k.described_as for k in protocol_kinds().values() if k.experiments)
    return ConfigError(
        f"--experiment picks one experiment of {holders}; {name} is of kind '{kind}', so leave --experiment out."
    )


def run_protocol(
    protocol: Any, choice: str | None, *, stored_kind: str | None = None, run_path: str = ""
) -> tuple[Paper, Any]:
    """The paper of a loaded protocol and the protocol a run of it records with.

    ``choice`` is the ``--experiment`` option, for a protocol holding several experiments;
    ``stored_kind`` the kind of a run being resumed.
    """
    spec = protocol_kinds()[protocol.kind]
    if choice is not None and not spec.experiments:
        raise _unused_experiment_option(protocol.name, protocol.kind)
    owner = for_protocol_kind(protocol.kind)
    return owner, owner.run_protocol(protocol, choice, stored_kind=stored_kind, run_path=run_path)


def import_protocol(protocol: Any, choice: str | None, name: str) -> tuple[Paper, Any]:
    """As :func:`run_protocol`, for ``labcli import`` (``name`` as the person typed it)."""
    spec = protocol_kinds()[protocol.kind]
    if choice is not None and not spec.experiments:
        raise _unused_experiment_option(name, protocol.kind)
    owner = for_protocol_kind(protocol.kind)
    return owner, owner.import_protocol(protocol, choice, name)


# --------------------------------------------------------------------------- simulated rigs


def sim_modes() -> list[str]:
    """``sim://?mode=`` values, in name order."""
    return sorted(m for e in papers() for m in e.sim_modes)


def default_sim_mode() -> str:
    """The rig ``sim://`` gives without ``mode=``."""
    defaults = [e.default_sim_mode for e in papers() if e.default_sim_mode]
    if len(defaults) != 1:
        raise ConfigError(f"Exactly one paper must name the default simulated rig; found {defaults or 'none'}.")
    return defaults[0]


def sim_owner(mode: str) -> Paper:
    """The paper whose rig ``mode`` is (ValueError for an unknown mode)."""
    for e in papers():
        if mode in e.sim_modes:
            return e
    raise ValueError(f"unknown simulated rig mode {mode!r}; known: {', '.join(sim_modes())}")


def sim_options(mode: str | None = None) -> dict[str, Option]:
    """The rigs' own declared options: those of the paper whose rig ``mode`` is, or (None) all."""
    found: dict[str, Option] = {}
    for e in papers():
        if e.sim_options is not None and (mode is None or mode in e.sim_modes):
            found.update((o.name, o) for o in declared(e.sim_options))
    return found


def modes_taking(option: str) -> list[str]:
    """The ``sim://?mode=`` values whose rig takes the option ``option``, in name order."""
    return sorted(m for e in papers() if option in sim_options_of(e) for m in e.sim_modes)


def sim_options_of(paper: Paper) -> dict[str, Option]:
    """One paper's rig options by name."""
    return {} if paper.sim_options is None else {o.name: o for o in declared(paper.sim_options)}


def make_rig(
    mode: str, *, seed: int = 0, noise: float = 1.0, drift: float | None = None, tau_s: float = 0.7, **values: Any
) -> Any:
    """The simulated rig of ``mode``; ``values`` are the rig's own options (name -> parsed value).

    ValueError for an unknown mode or an option the rig does not declare.
    """
    owner = sim_owner(mode)
    if owner.sim_options is None:
        if values:
            raise ValueError(f"the {mode} rig has no option {sorted(values)[0]!r}")
        options: Any = None
    else:
        unknown = sorted(set(values) - set(sim_options_of(owner)))
        if unknown:
            raise ValueError(f"the {mode} rig has no option {unknown[0]!r}")
        options = build(owner.sim_options, values)
    return owner.make_rig(mode, seed=seed, noise=noise, drift=drift, tau_s=tau_s, options=options)
