"""The closed chambers' leak in calibration data: when each trial's windows were taken, and P0 moved to its capture.

A trial's baseline P0 is averaged over a window taken several seconds before its loaded
window (the load, then the protocol's wait for equilibrium), and the chambers leak meanwhile
(about 1 kPa/min on the simulated rig, each chamber at its own rate).  So P0 - P holds, besides
the load, the leak over that gap.  Two ways to live with it, and the model file says which
(``baseline`` in the model JSON, written by ``labcli fit``):

* as measured (the default): the fit learns the load together with the typical gap's leak,
  and the run-time estimator reproduces it by giving the model the baseline as it stood that
  long before (``gap_s``, the median gap of the fit trials);
* leak-corrected (``fit(..., leak_correct=True)``): each trial's P0 is moved along the run's
  leak, a straight line through the baselines against their device time (as ``labcli
  inspect`` reports it), to the loaded window's time; a model fitted so must be applied to P0
  moved the same way (``validate`` does so; the estimator gives it the baseline at the
  estimate's time).

Measured on the simulated rig (seeds 1-10, posture form, 108 trials each; the sensing page of the docs),
with the trials taken 8 s after each change and the valves held for the whole run: with every
non-ideality on, correcting P0 made the validation RMSE of theta2 and Fx worse (x1.23 and x1.18),
with the leak alone better (x0.81, x0.90): sleeve friction holds the arm through the leak's slow
change of the tensions and lets it go at the next load, so the loaded window carries part of the
gap's leak in the posture too.  So ``fit`` leaves P0 as measured unless asked.

Taken as ``labcli acquire`` takes them (15 s waits, the chambers supplied again past
``acquisition.repressurise_kPa``; docs/fit-and-validate.md), the baselines rise at every supply
and fall between, and the one line through them is flat (seed 1: within 0.003 kPa/min of level,
where the chambers lose 0.65-1.0 kPa/min between supplies): the correction then moves P0 by
almost nothing (kind rig, Fx 0.305 / 0.232 N straight / bent against 0.305 / 0.230 as measured).
A line per supply interval, the leak itself, measured worse (0.334 / 0.250 N), and the leak costs
little on such a run (the leak alone: Fx 0.033 N against 0.030 with no effect at all); what is
left of the forces' error there is the sleeves' friction.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np

from ....core.files import RUN_FILE_SUFFIXES
from ....core.store import RunFile
from ....errors import ConfigError, StoreError
from .takuma import BASELINE_COLUMNS

GAP_SAMPLE = 200  # records whose windows give the median gap (a large archive is not read whole)


def _window_time(run: Any, rec: Any, i: int, rid: int, name: str) -> float:
    """Mean device time (s) of one record's window, NaN when it has none or it cannot be read.

    Read as a range of the run's raw frames where the run file keeps them so (schema 2), else
    through the record (as records.py reads the baselines' times for ``labcli inspect``)."""
    try:
        if getattr(run, "version", 1) >= 2 and f"{name}_start" in rec.cols:
            a, b = int(rec.cols[f"{name}_start"][i]), int(rec.cols[f"{name}_stop"][i])
            if a < 0 or b <= a:
                return math.nan
            return float(np.mean(run.windows.frames(a, b).t_s))
        window = run.records.read(rid)["raw"].get("baseline" if name == "baseline" else "load")
        return math.nan if window is None or not len(window.t_s) else float(np.mean(window.t_s))
    except StoreError:
        return math.nan


def window_times(path: str | Path, ids: Any = None, sample: int | None = None) -> dict[int, tuple[float, float]]:
    """Trial id -> (baseline window's, loaded window's mean device time, s), for the trials of a run
    file that have both; ``ids`` limits the trials, ``sample`` takes that many evenly spread."""
    with RunFile.open(path) as run:
        rec = run.records.columns()
        order = list(rec.ids)
        pos = {rid: i for i, rid in enumerate(order)}
        want = order if ids is None else [int(t) for t in ids if int(t) in pos]
        if sample is not None and len(want) > sample:
            want = [want[int(k)] for k in np.linspace(0, len(want) - 1, sample)]
        out = {}
        for rid in want:
            i = pos[rid]
            tb, tl = (_window_time(run, rec, i, rid, name) for name in ("baseline", "loaded"))
            if math.isfinite(tb) and math.isfinite(tl):
                out[int(rid)] = (tb, tl)
    return out


def baseline_gap(path: str | Path, ids: Any = None) -> float | None:
    """The median time from a trial's baseline window to its loaded window (s), None without windows."""
    times = window_times(path, ids, sample=GAP_SAMPLE)
    gaps = [tl - tb for tb, tl in times.values() if tl > tb]
    return float(np.median(gaps)) if gaps else None


def corrected(table: Any, path: str | Path, what: str) -> Any:
    """A copy of the trial table with each trial's P0 moved along the run's leak to its loaded window.

    ``what`` names the step in the sentence of a refusal (ConfigError when the trials carry no
    window times: a CSV, an imported run)."""
    times = window_times(path, table["trial"]) if Path(path).suffix.lower() in RUN_FILE_SUFFIXES else {}
    ids = np.asarray(table["trial"], dtype=np.int64)
    have = np.array([int(t) in times for t in ids])
    if not have.any() or have.sum() < 2:
        raise ConfigError(
            f"{what} needs each trial's baseline and loaded window times to correct P0 for the leak, and {path} "
            "has none (a trial CSV or an imported run); use the run file `labcli acquire` recorded."
        )
    tb = np.array([times[int(t)][0] if h else math.nan for t, h in zip(ids, have, strict=True)])
    tl = np.array([times[int(t)][1] if h else math.nan for t, h in zip(ids, have, strict=True)])
    P0 = np.column_stack([np.asarray(table[c], dtype=float) for c in BASELINE_COLUMNS])
    slope = np.polyfit(tb[have], P0[have], 1)[0]  # MPa/s per chamber (negative: air lost)
    out = table.copy()
    moved = P0 + np.where(have[:, None], slope[None, :] * (tl - tb)[:, None], 0.0)
    for j, c in enumerate(BASELINE_COLUMNS):
        out[c] = moved[:, j]
    return out
