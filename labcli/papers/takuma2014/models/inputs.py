"""Where fit and validate get their trials and their rig: a run file or a trial CSV.

A run file (``.h5``) carries its protocol verbatim, so its geometry is the one the trials were
recorded with; a CSV carries none, so the protocol is named (default ``takuma2014``).  A run of
several captures a load (``acquisition.captures_per_load``) gives one row per load, its captures
averaged (:mod:`..captures`), and so does a CSV read with such a protocol (the run's export), so the
two give the same model.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ....core.files import RUN_FILE_SUFFIXES
from ....core.protocol import load_protocol, loads_protocol
from ....core.provenance import run_identity, table_identity
from ....core.store import RunFile
from ....errors import ConfigError
from ..captures import averaged, captures_of
from ..options import TRIAL_PROTOCOL  # the paper declares it (fit and validate read a table with it)
from ..records import load_trials


@dataclass
class TrialSource:
    path: Path
    table: Any  # the trial table (pandas DataFrame, contract columns)
    protocol: Any  # labcli.core.protocol.Protocol
    is_run: bool  # True for a run file, False for a CSV
    identity: dict = field(default_factory=dict)  # core.provenance: the data, the rig, the protocol
    captures: int = 1  # records a row of ``table`` averages (a run's acquisition.captures_per_load)

    @property
    def label(self) -> str:
        return str(self.path)


def _read_table(path: Path) -> Any:
    return load_trials(path)


def load_trial_source(path: str | Path, protocol: str | None = None) -> TrialSource:
    """Trials and protocol of a run file or a trial CSV (``protocol`` names one for a CSV)."""
    p = Path(path)
    if not p.exists():
        raise ConfigError(f"{p} does not exist; pass a run file (.h5) or a trial CSV.")
    if p.suffix.lower() in RUN_FILE_SUFFIXES:
        with RunFile.open(p) as run:
            text = run.protocol_text
            name = str(run.attrs.get("protocol", ""))
            identity = run_identity(run, p)
        if protocol is not None and protocol != name:
            raise ConfigError(
                f"{p} was recorded with protocol '{name}'; --protocol applies to "
                "trial CSV files only, so leave it out for a run file."
            )
        proto = (
            loads_protocol(text, source=f"{p} (embedded protocol)")
            if text.strip()
            else load_protocol(name or TRIAL_PROTOCOL)
        )
        if proto.kind != "force":
            raise ConfigError(
                f"{p} is a run of kind '{proto.kind}' (protocol '{proto.name}'), not a force run; "
                "fit and validate read the trials of a force run such as one recorded "
                f"with protocol {TRIAL_PROTOCOL}."
            )
        n = captures_of(proto)
        return TrialSource(p, averaged(_read_table(p), n), proto, True, identity, n)
    proto = load_protocol(protocol or TRIAL_PROTOCOL)
    if proto.kind != "force":
        # A model fitted under a push or rPAM protocol would be refused by every later check.
        raise ConfigError(
            f"--protocol {protocol} is of kind '{proto.kind}'; a trial CSV is read with a "
            f"force protocol such as {TRIAL_PROTOCOL}."
        )
    # A CSV read with a protocol of N captures a load is the export of such a run: read as the run is.
    n = captures_of(proto)
    return TrialSource(p, averaged(_read_table(p), n), proto, False, table_identity(p, proto), n)
