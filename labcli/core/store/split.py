"""Which records fit a model and which validate it: choosing a split and checking one.

The split is a run's own decision (``labcli split``, the plan's sets at the end of a run,
an imported table's ``set`` column), kept in the run file's split log
(:mod:`labcli.core.store.logs`) and read by everything that fits or validates (the ``set``
column of the exchange table).
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from typing import Any

import numpy as np

from ...errors import ConfigError, StoreError
from ..protocol import loads_protocol


def choose_split(
    ids: Sequence[int], n_fit: int, n_validation: int, strategy: str = "sequential", seed: int | None = None
) -> tuple[list[int], list[int]]:
    """Pick fit and validation ids from ``ids`` (in recording order).

    ``sequential``: the first ``n_fit`` ids fit, the next ``n_validation``
    validate (the paper's 90 + 18); ``random``: a permutation seeded by ``seed``
    (0 when None), each set listed in recording order.
    """
    if n_fit < 1 or n_validation < 0:
        raise ConfigError(
            f"the fit set needs at least 1 trial and the validation set 0 or more, got {n_fit} and {n_validation}."
        )
    need = n_fit + n_validation
    if need > len(ids):
        raise ConfigError(
            f"the run has {len(ids)} completed trials, fewer than the {need} asked for "
            f"({n_fit} fit + {n_validation} validation)."
        )
    ids = [int(i) for i in ids]
    if strategy == "sequential":
        return ids[:n_fit], ids[n_fit:need]
    if strategy == "random":
        rng = np.random.default_rng(0 if seed is None else seed)
        picked = [ids[i] for i in rng.permutation(len(ids))[:need]]
        rank = {t: i for i, t in enumerate(ids)}
        return sorted(picked[:n_fit], key=rank.__getitem__), sorted(picked[n_fit:], key=rank.__getitem__)
    raise ConfigError(f"unknown split strategy {strategy!r}; use sequential or random.")


def choose(
    ids: Sequence[int], n_fit: int, n_validation: int, strategy: str, seed: int | None, path: str
) -> tuple[list[int], list[int]]:
    """:func:`choose_split`, its sentences naming the run file."""
    try:
        return choose_split(ids, n_fit, n_validation, strategy, seed)
    except ConfigError as e:
        raise ConfigError(f"{path}: {e}") from None


def default_sizes(protocol_text: str, path: str) -> tuple[int, int]:
    """The fit and validation counts of a run's embedded protocol (its settings' ``default_split``)."""
    try:
        settings = loads_protocol(protocol_text, source=f"{path} (embedded protocol)").settings
    except ConfigError:
        settings = None
    sizes = getattr(settings, "default_split", None)
    if sizes is None:
        raise ConfigError(
            f"{path}: the run's protocol gives no fit and validation counts; give --fit and --validation."
        )
    return int(sizes[0]), int(sizes[1])


def checked(
    path: str, complete: Iterable[int], fit_ids: Iterable[int], validation_ids: Iterable[int]
) -> tuple[list[int], list[int]]:
    """The fit and validation ids of a split, refused in one sentence unless each is a complete record once."""
    fit = [int(i) for i in fit_ids]
    val = [int(i) for i in validation_ids]
    both = sorted(set(fit) & set(val))
    if both:
        raise StoreError(f"trial {both[0]} cannot be in both the fit and the validation set.")
    if len(set(fit)) != len(fit) or len(set(val)) != len(val):
        raise StoreError("a trial id appears twice in the split.")
    done = set(complete)
    missing = [i for i in fit + val if i not in done]
    if missing:
        raise StoreError(f"trial {missing[0]} is not a complete trial in {path}, so it cannot join the split.")
    return fit, val


def set_of(split: dict[str, Any] | None) -> dict[int, str]:
    """Record id -> "fit" / "validation" (unassigned ids absent)."""
    if split is None:
        return {}
    out = {i: "fit" for i in split["fit"]}
    out.update({i: "validation" for i in split["validation"]})
    return out
