"""labcli: lab acquisition for pneumatic-actuator rigs.

The library is usable without the command line::

    import labcli
    df = labcli.load_trials("run.h5")      # the trial table as a DataFrame

Heavy dependencies (numpy, pandas, h5py, scipy) are imported only by the
functions that need them, so ``labcli --help`` stays fast.
"""

from __future__ import annotations

from .core.version import __version__

__all__ = ["__version__", "load_trials", "load_pushes"]


def load_trials(path):
    """Return the trial table of a run file (``.h5``) or a trial CSV as a DataFrame.

    ``df.attrs["units"]`` maps each column to its unit ("MPa", "deg", "N", "g");
    ``df.attrs["provenance"]`` says where the rows came from (run uid where recorded,
    protocol, device, labcli version, source file, ...), from the run file or from the
    sidecar ``<csv>.json`` that ``labcli export`` writes beside a CSV.
    """
    # Here, not at the top: ``import labcli`` (and ``labcli --help``) load no h5py or pandas.
    from .core.registry import record_type
    from .core.table_meta import load_described

    return load_described(path, record_type("force"))


def load_pushes(path):
    """Return the push table of a run file (``.h5``) or a push CSV as a DataFrame (attrs as load_trials)."""
    from .core.registry import record_type  # h5py, pandas: only here (see load_trials)
    from .core.table_meta import load_described

    return load_described(path, record_type("push"))
