"""labcli: lab acquisition for pneumatic-actuator rigs.

The library is usable without the command line::

    import labcli
    df = labcli.load_trials("run.h5")      # the trial table as a DataFrame
    df = labcli.read_run("any-run.h5")     # the records of a run of any kind; df.attrs["kind"]

Heavy dependencies (numpy, pandas, h5py, scipy) are imported only by the
functions that need them, so ``labcli --help`` stays fast.
"""

from __future__ import annotations

from .core.version import __version__

__all__ = ["__version__", "load_trials", "load_pushes", "read_run"]


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


def read_run(path, *, all_columns=False):
    """Return the record table of a run file of any kind as a DataFrame.

    ``df.attrs["kind"]`` is the run's kind ("force", "push", an rPAM stand's, "sense"),
    ``df.attrs["units"]`` and ``df.attrs["provenance"]`` as :func:`load_trials`'s;
    ``all_columns`` adds what every record carries (timestamps, acceptance, flags, settle times).
    """
    from .core.table_meta import read_run as read  # h5py, pandas: only here (see load_trials)

    return read(path, all_columns=all_columns)
