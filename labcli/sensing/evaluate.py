"""One call of the model per block: the estimate, its standard error and its flags.

The estimator hands over two input vectors and their uncertainty (SI, per pressure channel):

* the pressures *now*, the heat removed: what the muscles' lengths, and so the joint angles,
  are now (``state`` quantities);
* the pressures the rig is settling to (the fitted step's settled value): what the load
  that caused the change is (``load`` quantities, constant from the moment a weight hangs).

Idle, both are the same.  The model is called once, on both vectors and on each moved by one
standard deviation up and down per channel (``sigma points``, 18 rows at most), so the
uncertainty of the inputs reaches the estimate through the model's own (non-linear) answer:
``var = sum_j ((q(P + s_j) - q(P - s_j)) / 2)^2``.  The standard error is that and the
model's own (the regression's prediction error) in quadrature.  A step larger than ``CAP_MPA``
is evaluated at the cap and scaled up linearly, so a guess still wild (the first blocks of a
change) does not feed the model pressures outside its world.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

from .model import LOAD, STATE, SensingModel

CAP_MPA = 0.01  # 10 kPa: the largest step the model is evaluated at


@dataclass(frozen=True)
class Inputs2:
    """What the model is asked about one block: baseline, rest posture, and the two pressure vectors."""

    P0: np.ndarray  # (p,)
    rest: np.ndarray  # (a,)
    P_state: np.ndarray
    var_state: np.ndarray
    P_load: np.ndarray
    var_load: np.ndarray
    motion_in: np.ndarray | None = None  # (a,) rad, for a model that reads the history of loads (.model)


@functools.cache
def _steps(p: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Where the sigma rows' steps go in a group's (1 + 2p, p) rows: rows up, rows down, channels."""
    diagonal = np.arange(p)
    return 1 + diagonal, 1 + p + diagonal, diagonal


@functools.cache
def _groups(kinds: tuple[str, ...]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The row group each quantity is read from with one group and with two (the load's for a
    ``load`` quantity), and the quantities' indices."""
    load = np.array([k == LOAD for k in kinds])
    return np.zeros(len(kinds), np.intp), np.where(load, 1, 0), np.arange(len(kinds))


def _rows(P: np.ndarray, sd: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per group (g, p): the centre, then + and - a step per channel, (g, 1 + 2p, p), and the steps (g, p)."""
    g, p = P.shape
    h = np.minimum(
        np.maximum(sd, 0.0), CAP_MPA
    )  # np.clip's, without its dispatch: the estimator calls this every block
    up, down, channel = _steps(p)
    rows = np.empty((g, 1 + 2 * p, p))
    rows[:] = P[:, None, :]
    rows[:, up, channel] += h
    rows[:, down, channel] -= h
    return rows, h


def evaluate(model: SensingModel, x: Inputs2) -> tuple[np.ndarray, np.ndarray, tuple[str, ...]]:
    """Values (q,), standard errors (q,) and flags of one block's estimate (module docstring).

    Both row groups (the state's, the load's) are built and read as one (groups, 1 + 2p, ...) array:
    the estimator calls this once a block, and on its dozen-odd rows each numpy call costs more
    than its arithmetic, so what depends only on the model's kinds is worked out once."""
    same = bool((x.P_state == x.P_load).all()) and bool((x.var_state == x.var_load).all())
    if same:
        centres, var = x.P_state[None, :], x.var_state[None, :]
    else:
        centres, var = np.array((x.P_state, x.P_load), dtype=float), np.array((x.var_state, x.var_load), dtype=float)
    sd = np.sqrt(np.asarray(var, dtype=float))
    rows, h = _rows(np.asarray(centres, dtype=float), sd)
    g, n, p = rows.shape
    P = rows.reshape(g * n, p)
    P0 = np.empty((g * n, p))
    P0[:] = x.P0
    rest = np.empty((g * n, len(x.rest)))
    rest[:] = x.rest
    if x.motion_in is None:
        pred = model.predict(P0, P, rest)
    else:
        moved = np.empty((g * n, len(x.motion_in)))
        moved[:] = x.motion_in
        pred = model.predict(P0, P, rest, motion_in=moved)  # type: ignore[call-arg]
    one, two, q_idx = _groups(tuple(model.kinds))
    group = one if same else two
    values = pred.values[group * n, q_idx]
    se_model = pred.se[group * n, q_idx]
    at = pred.values.reshape(g, n, -1)
    # The central difference per channel, zero where a channel's step is none (every channel has
    # one on the estimator's blocks: then there is nothing to stand in for).
    positive = h > 0
    with np.errstate(invalid="ignore", divide="ignore"):
        if positive.all():
            slope = (at[:, 1 : 1 + p] - at[:, 1 + p :]) / (2 * h)[:, :, None]
        else:
            slope = np.where(
                positive[:, :, None],
                (at[:, 1 : 1 + p] - at[:, 1 + p :]) / (2 * np.where(positive, h, 1.0))[:, :, None],
                0.0,
            )
    var_q = np.add.reduce(np.square(slope * sd[:, :, None]), axis=1)[group, q_idx]
    se = np.sqrt(se_model**2 + var_q)
    flags = pred.flags[0] if same else _merge(pred.flags[0], pred.flags[n], model)
    return values, se, flags


def _merge(state: tuple[str, ...], load: tuple[str, ...], model: SensingModel) -> tuple[str, ...]:
    """Flags naming a quantity from the row that quantity is read from; the others from both."""
    kind = _kind_of(tuple(model.quantities), tuple(model.kinds))
    out: list[str] = []
    for row, want in ((state, STATE), (load, LOAD)):
        for f in row:
            q = f.partition(":")[2]
            if q and kind.get(q, want) != want:
                continue
            if f not in out:
                out.append(f)
    return tuple(out)


@functools.cache
def _kind_of(quantities: tuple[str, ...], kinds: tuple[str, ...]) -> dict[str, str]:
    return dict(zip(quantities, kinds, strict=True))
