"""A load captured N times (``acquisition.captures_per_load``), averaged into one row before a model sees it.

A run of N captures a load stores every capture as its own record (record id
``(trial - 1) N + capture``, :func:`record_ids`); nothing is averaged at acquisition.
``labcli fit``, ``validate`` and ``predict`` read such a run as one row per plan load: the
pressures (baseline and loaded), the deflection labels and the rest posture are the mean of the
load's captures; the rest (force) is its first capture's, and the row's ``trial`` is the plan's
(the side the relief vented, ``relief_vent``, the load's where its captures agree, else empty).
A load's captures share its set, mass and direction (``labcli split`` assigns whole loads): a table
whose captures of one load disagree on them is refused, since its ids are not a run of N captures
a load (a plain run read with a captures protocol) or its split divides a load.  A capture skipped at the rig leaves its load the mean of the others.

What an averaged row's standard errors mean: the pressure sensors' repeatability is a fresh error
per capture, so the mean of N has 1/N of its variance (tests/benchmarks/multi_capture.py).  A
model fitted on averaged rows estimates its residual spread from them, so its standard errors and
95 % intervals are those of an averaged row, the repeatability's share divided by N; applied to a
single capture they would be too narrow.  A run of one capture a load is read unchanged.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ...core.air import load_ids, record_ids  # the record-id formula, which labcli split needs too
from ...errors import ConfigError
from .tables import BASELINE, LOADED, REST

__all__ = ["AVERAGED", "averaged", "captures_of", "load_ids", "record_ids"]

AVERAGED = (*BASELINE, *LOADED, "theta1_deg", "theta2_deg", *REST)


def captures_of(protocol: Any) -> int:
    """The captures a run of ``protocol`` took of each load (1 for a protocol without the key)."""
    air = getattr(protocol, "air", None)
    return int(getattr(air, "captures_per_load", 1) or 1)


def averaged(table: Any, captures: int) -> Any:
    """One row per plan load of a trial table of ``captures`` records a load (module docstring)."""
    if captures == 1 or not len(table):
        return table
    key = load_ids(table["trial"], captures)
    _check_constant(table, key, captures)
    first = table.loc[~_duplicated(key)].copy()
    present = [c for c in AVERAGED if c in table.columns]
    means = table[present].groupby(key, sort=False).mean()
    for c in present:
        first[c] = means[c].to_numpy()
    first["trial"] = means.index.to_numpy().astype(table["trial"].dtype)  # in order of first capture, as the rows
    if "relief_vent" in table.columns:  # the side each capture was relieved from: the load's where they agree
        one = table["relief_vent"].groupby(key, sort=False).nunique(dropna=False).to_numpy() == 1
        first["relief_vent"] = np.where(one, first["relief_vent"].to_numpy(), "")
    out = first.reset_index(drop=True)
    out.attrs["records"] = len(table)  # the captures averaged, for the sentences that count them
    return out


CONSTANT = ("set", "mass_g", "direction_deg")  # a load's, so the same in each of its captures


def _check_constant(table: Any, key: np.ndarray, captures: int) -> None:
    """Refuse a table whose captures of one load differ in :data:`CONSTANT` (module docstring)."""
    for c in (c for c in CONSTANT if c in table.columns):
        col = table[c].reset_index(drop=True)
        differ = col.groupby(key, sort=False).nunique(dropna=False) > 1
        if differ.any():
            load = int(differ.index[differ.to_numpy()][0])
            ids = ", ".join(str(int(i)) for i in table["trial"].to_numpy()[key == load])
            raise ConfigError(
                f"records {ids} would be the {captures} captures of load {load} but differ in {c}: "
                f"these are not captures of one load (read the table with the protocol it was recorded "
                f"with), or its split divides a load (split it again with labcli split, which assigns loads)."
            )


def _duplicated(key: np.ndarray) -> np.ndarray:
    import pandas as pd

    return np.asarray(pd.Series(key).duplicated(), dtype=bool)
