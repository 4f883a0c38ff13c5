"""A load captured N times (``acquisition.captures_per_load``), averaged into one row before a model sees it.

A run of N captures a load stores every capture as its own record (record id
``(trial - 1) N + capture``, :func:`.session.capture_id`); nothing is averaged at acquisition.
``labcli fit``, ``validate`` and ``predict`` read such a run as one row per plan load: the
pressures (baseline and loaded), the deflection labels and the rest posture are the mean of the
load's captures; the rest (set, force, mass, direction) is its first capture's, and the row's
``trial`` is the plan's.  A capture skipped at the rig leaves its load the mean of the others.

What an averaged row's standard errors mean: the pressure sensors' repeatability is a fresh error
per capture, so the mean of N has 1/N of its variance (tests/benchmarks/multi_capture.py).  A
model fitted on averaged rows estimates its residual spread from them, so its standard errors and
95 % intervals are those of an averaged row, the repeatability's share divided by N; applied to a
single capture they would be too narrow.  A run of one capture a load is read unchanged.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from .tables import BASELINE, LOADED, REST

AVERAGED = (*BASELINE, *LOADED, "theta1_deg", "theta2_deg", *REST)


def captures_of(protocol: Any) -> int:
    """The captures a run of ``protocol`` took of each load (1 for a protocol without the key)."""
    air = getattr(protocol, "air", None)
    return int(getattr(air, "captures_per_load", 1) or 1)


def load_ids(ids: Any, captures: int) -> np.ndarray:
    """The plan trial of each record id (:func:`.session.capture_load`, vectorised)."""
    return (np.asarray(ids, dtype=np.int64) - 1) // captures + 1


def record_ids(loads: Any, captures: int) -> np.ndarray:
    """Every capture's record id of the plan trials ``loads``, in order."""
    base = (np.asarray(loads, dtype=np.int64) - 1) * captures
    return (base[:, None] + np.arange(1, captures + 1)[None, :]).ravel()


def averaged(table: Any, captures: int) -> Any:
    """One row per plan load of a trial table of ``captures`` records a load (module docstring)."""
    if captures == 1 or not len(table):
        return table
    key = load_ids(table["trial"], captures)
    first = table.loc[~_duplicated(key)].copy()
    present = [c for c in AVERAGED if c in table.columns]
    means = table[present].groupby(key, sort=False).mean()
    for c in present:
        first[c] = means[c].to_numpy()
    first["trial"] = means.index.to_numpy().astype(table["trial"].dtype)  # in order of first capture, as the rows
    return first.reset_index(drop=True)


def _duplicated(key: np.ndarray) -> np.ndarray:
    import pandas as pd

    return np.asarray(pd.Series(key).duplicated(), dtype=bool)
