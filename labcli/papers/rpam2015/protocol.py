"""The rPAM protocol kind, ``rpam``, as plain data for the loader.

An rPAM protocol (``protocols/rpam2015.toml``) holds the joint, its actuators and their
materials, the stretch correction, the grids of its two experiments, the optimiser's
settings and the ``[sensors]`` table of its DAQ.  The loader checks the core's sections
(``[acquisition]``, ``[settling]``, ...) and keeps every other table as written
(``Protocol.sections``); the model (:mod:`labcli.papers.rpam2015.models.rpam`)
checks its own keys, with its own sentences, when it reads them.

One protocol, two experiments: ``--experiment stretch`` records a run of kind
``rpam-stretch``, ``--experiment joint`` one of kind ``rpam-joint``.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from ...core.paper import ProtocolKind
from ...core.protocol import OPEN, SHIPPED_DIR, ProtocolFileError, load_protocol, loads_protocol, shipped_protocols
from ...errors import ConfigError

EXPERIMENTS: dict[str, str] = {"stretch": "rpam-stretch", "joint": "rpam-joint"}

KINDS: dict[str, ProtocolKind] = {
    "rpam": ProtocolKind(
        name="rpam",
        sections={
            "device": ("optional", "device"),
            "acquisition": ("optional", "acquisition"),
            "rig": ("optional", OPEN),
            "channels": ("optional", "channel-map"),
            "settling": ("optional", "settling"),
        },
        extra_sections=True,
        experiments=EXPERIMENTS,
        described_as="an rPAM protocol",
    ),
}


# --------------------------------------------------------------------------- reading


def resolve_protocol_path(path_or_name: str | Path) -> Path:
    """A path as given, or a shipped protocol name such as ``rpam2015``."""
    p = Path(path_or_name)
    if p.suffix == ".toml" or p.exists():
        if not p.is_file():
            raise ConfigError(f"Protocol file {p} does not exist; give a .toml path or a shipped name like rpam2015.")
        return p
    shipped = SHIPPED_DIR / f"{p.name}.toml"
    if shipped.is_file():
        return shipped
    raise ConfigError(
        f"No protocol named '{path_or_name}'; give a .toml path or a shipped name ({', '.join(shipped_protocols())})."
    )


def where(path: str | Path) -> str:
    """How an error names a protocol: ``protocol rpam2015`` for a shipped one, else its path."""
    p = Path(path)
    return f"protocol {p.stem}" if p.parent == SHIPPED_DIR else str(p)


def read_rpam_protocol(path_or_name: str | Path) -> tuple[Path, dict[str, Any]]:
    """The tables of an rPAM protocol (``kind = "rpam"``), as plain data, and its path.

    Read and checked by the one loader (:func:`labcli.core.protocol.load_protocol`); the
    failures the rPAM model's callers have always reported in their own words keep them.
    """
    path = resolve_protocol_path(path_or_name)
    try:
        return path, load_protocol(path, kinds=tuple(KINDS)).document
    except ProtocolFileError as e:
        if e.problem == "syntax":
            raise ConfigError(f"Protocol file {path} is not valid TOML: {e.detail}.") from None
        if e.problem == "kind":
            raise ConfigError(
                f'Protocol file {where(path)} has kind = {e.detail!r}; the rPAM model needs kind = "rpam".'
            ) from None
        if e.problem == "unreadable":
            raise ConfigError(f"Cannot read protocol file {path}: {e.detail}.") from None
        raise


def stored_protocol(text: str, run: str | Path) -> dict[str, Any]:
    """The tables of the protocol a run file keeps, as plain data (read by the one loader)."""
    try:
        return loads_protocol(text, source=f"{run} (protocol)").document
    except ProtocolFileError as e:
        if e.problem == "syntax":
            raise ConfigError(f"{run}: the protocol stored in the run is not valid TOML ({e.detail}).") from None
        raise
