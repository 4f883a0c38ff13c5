"""Which records fit a model and which validate it: ``/split`` of the run file.

The split is a run's own decision, stored once (``labcli split``, the plan's sets at the
end of a run, an imported table's ``set`` column) and read by everything that fits or
validates (the ``set`` column of the exchange table).
"""

from __future__ import annotations

from typing import Any, Iterable, Sequence

import h5py
import numpy as np

from ...errors import ConfigError, StoreError
from ..protocol import loads_protocol
from .h5 import dataset, text, utc_now


def choose_split(ids: Sequence[int], n_fit: int, n_validation: int, strategy: str = "sequential",
                 seed: int | None = None) -> tuple[list[int], list[int]]:
    """Pick fit and validation ids from ``ids`` (in recording order).

    ``sequential``: the first ``n_fit`` ids fit, the next ``n_validation``
    validate (the paper's 90 + 18); ``random``: a permutation seeded by ``seed``
    (0 when None), each set listed in recording order.
    """
    if n_fit < 1 or n_validation < 0:
        raise ConfigError(f"the fit set needs at least 1 trial and the validation set 0 or more, got {n_fit} and {n_validation}.")
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


def choose(ids: Sequence[int], n_fit: int, n_validation: int, strategy: str, seed: int | None,
           path: str) -> tuple[list[int], list[int]]:
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
        raise ConfigError(f"{path}: the run's protocol gives no fit and validation counts; "
                          "give --fit and --validation.")
    return int(sizes[0]), int(sizes[1])


def store(f: h5py.File, path: str, complete: Iterable[int], fit_ids: Iterable[int],
          validation_ids: Iterable[int], strategy: str, seed: int | None) -> None:
    """Write ``/split`` (replacing an earlier one); ``complete``: the ids that may join it."""
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
    if "split" not in f:
        f.create_group("split").attrs["NX_class"] = "NXcollection"
    g = f["split"]
    g.attrs["strategy"] = str(strategy)
    g.attrs["seed"] = -1 if seed is None else int(seed)
    g.attrs["created"] = utc_now()
    for name, ids in (("fit", fit), ("validation", val)):
        data = np.asarray(ids, dtype=np.int64)
        if name in g and g[name].shape == data.shape:
            g[name][...] = data  # in place: nothing freed (see the run file's docstring)
            continue
        if name in g:
            del g[name]
        dataset(g, name, data, "1")


def read(f: h5py.File) -> dict[str, Any] | None:
    """``{"fit": [...], "validation": [...], "strategy", "seed" (None), "created"}`` or None."""
    if "split" not in f or "fit" not in f["split"]:
        return None
    g = f["split"]
    seed = int(g.attrs.get("seed", -1))
    return {
        "fit": [int(i) for i in g["fit"][()]],
        "validation": [int(i) for i in g["validation"][()]],
        "strategy": text(g.attrs.get("strategy", "")),
        "seed": None if seed < 0 else seed,
        "created": text(g.attrs.get("created", "")),
    }


def set_of(split: dict[str, Any] | None) -> dict[int, str]:
    """Record id -> "fit" / "validation" (unassigned ids absent)."""
    if split is None:
        return {}
    out = {i: "fit" for i in split["fit"]}
    out.update({i: "validation" for i in split["validation"]})
    return out
