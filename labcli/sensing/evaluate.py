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


def _rows(P: np.ndarray, sd: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per group (g, p): the centre, then + and - a step per channel, (g, 1 + 2p, p), and the steps (g, p)."""
    g, p = P.shape
    h = np.clip(sd, 0.0, CAP_MPA)
    eye = np.zeros((g, p, p))
    diagonal = np.arange(p)
    eye[:, diagonal, diagonal] = h
    rows = np.empty((g, 1 + 2 * p, p))
    rows[:, 0] = P
    np.add(P[:, None, :], eye, out=rows[:, 1 : 1 + p])
    np.subtract(P[:, None, :], eye, out=rows[:, 1 + p :])
    return rows, h


def evaluate(model: SensingModel, x: Inputs2) -> tuple[np.ndarray, np.ndarray, tuple[str, ...]]:
    """Values (q,), standard errors (q,) and flags of one block's estimate (module docstring).

    Both row groups (the state's, the load's) are built and read as one (groups, 1 + 2p, ...) array:
    the estimator calls this once a block, and per-group loops were a fifth of the call."""
    same = np.array_equal(x.P_state, x.P_load) and np.array_equal(x.var_state, x.var_load)
    centres = np.array([x.P_state] if same else [x.P_state, x.P_load], dtype=float)
    sd = np.sqrt(np.array([x.var_state] if same else [x.var_state, x.var_load], dtype=float))
    rows, h = _rows(centres, sd)
    g, n, p = rows.shape
    P = rows.reshape(g * n, p)
    pred = model.predict(np.broadcast_to(x.P0, P.shape), P, np.broadcast_to(x.rest, (g * n, len(x.rest))))
    load = np.array([k == LOAD for k in model.kinds])
    group = np.where(load & (not same), 1, 0)  # the row group each quantity is read from
    q_idx = np.arange(len(load))
    values = pred.values[group * n, q_idx]
    se_model = pred.se[group * n, q_idx]
    at = pred.values.reshape(g, n, -1)
    up, down = at[:, 1 : 1 + p], at[:, 1 + p :]
    with np.errstate(invalid="ignore", divide="ignore"):
        slope = np.where(h[:, :, None] > 0, (up - down) / (2 * np.where(h > 0, h, 1.0))[:, :, None], 0.0)
    var = ((slope * sd[:, :, None]) ** 2).sum(axis=1)[group, q_idx]
    se = np.sqrt(se_model**2 + var)
    flags = pred.flags[0] if same else _merge(pred.flags[0], pred.flags[n], model)
    return values, se, flags


def _merge(state: tuple[str, ...], load: tuple[str, ...], model: SensingModel) -> tuple[str, ...]:
    """Flags naming a quantity from the row that quantity is read from; the others from both."""
    kind = dict(zip(model.quantities, model.kinds, strict=True))
    out: list[str] = []
    for row, want in ((state, STATE), (load, LOAD)):
        for f in row:
            q = f.partition(":")[2]
            if q and kind.get(q, want) != want:
                continue
            if f not in out:
                out.append(f)
    return tuple(out)
