"""Which records fit a model and which validate it: ``run.split``, the run file's split log.

The split is a run's own decision (``labcli split``, the plan's sets at the end of a run,
an imported table's ``set`` column), kept in the run file's split log and read by
everything that fits or validates (the ``set`` column of the exchange table).  The log is
an append-only table (:mod:`.columns`), one row per split assigned; a split's ids live in a
blob beside it (:mod:`.blobs`).  The last row that checks out is the split in force;
earlier ones stay, as the run's history.

>>> run.split.assign(90, 18)              # doctest: +SKIP
>>> run.split.get()["fit"][:3]            # doctest: +SKIP
[1, 2, 3]
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from typing import TYPE_CHECKING, TypedDict

import h5py
import numpy as np

from ...errors import ConfigError, StoreError
from ..protocol import loads_protocol
from ..timestamps import utc_now
from ..words import count
from .blobs import blob_read, blob_write, cell_text
from .columns import Table
from .layout import SPLIT_COLUMNS

if TYPE_CHECKING:
    from .runfile import RunFile


CHECKSUM_VERSION = 2  # of the ids' checksum in a new file (:func:`~.blobs.blob_checksum`)


class Split(TypedDict):
    """A split as stored: the fit and validation ids (recording order), how it was chosen, when."""

    fit: list[int]
    validation: list[int]
    strategy: str  # sequential, random, manual, plan, imported
    seed: int | None  # the random split's seed (None for the others)
    created: str  # ISO 8601


class Splits:
    """``run.split``: the split in force, and assigning a new one (see the module docstring)."""

    def __init__(self, run: RunFile) -> None:
        self._run = run
        # A writer's split read once (the store asks for it with every record it checks): it holds
        # the file's lock, so the split changes only through :meth:`set`, which forgets it.
        self._held: tuple[Split | None] | None = None

    def get(self) -> Split | None:
        """The split in force, or None when the run has none."""
        run = self._run
        if run.v1 is not None:
            return run.v1.split()
        if self._held is not None:
            return self._held[0]
        s, problems = run.read_checked(lambda: read_split(run.tables.split), "its split", lambda got: bool(got[1]))
        if problems:
            run.warn(f"{run.path}: {problems[0]}; the last split that checks out is used.")
        if run.mode == "a" and not problems:
            self._held = (s,)
        return s

    def set_of(self) -> dict[int, str]:
        """Record id -> "fit" / "validation" from the split in force (unassigned ids absent)."""
        return set_of(self.get())

    def sizes(self) -> tuple[int, int]:
        """The fit and validation counts of the run's embedded protocol (its settings' ``default_split``)."""
        return default_sizes(self._run.protocol_text, self._run.path)

    def set(
        self, fit_ids: Iterable[int], validation_ids: Iterable[int], strategy: str = "manual", seed: int | None = None
    ) -> None:
        """Store which complete records fit and which validate (the split in force from now on)."""
        run = self._run
        run.writer.check()
        done = run.records.id_array() if run.record_type.splits else np.empty(0, dtype=np.int64)
        fit, val = checked(run.path, done, fit_ids, validation_ids)
        run.check_v2("a split")
        t = run.tables.split
        self._held = None
        written: dict[str, object] = {}

        # The ids' checksum whole-array (version 2) where the log has the column saying so; a log
        # of a file written before it keeps the word-by-word fold its readers check.
        version = CHECKSUM_VERSION if "ids_checksum_version" in t.names else 1

        def row() -> dict[str, object]:
            written.update(split_row(t.g, fit, val, str(strategy), seed, version))
            return written

        run.writer.commit_row(t, {c.name: c for c in SPLIT_COLUMNS}, row, 8 * (len(fit) + len(val)), "the split")
        # What was just committed is the split in force (the writer holds the file's lock): held as
        # written, so that its ids are not read back and folded again (a million ids for an import).
        stored_seed = -1 if seed is None else int(seed)  # as split_row stores it, as read_split reads it
        split: Split = {
            "fit": fit,
            "validation": val,
            "strategy": str(strategy),
            "seed": None if stored_seed < 0 else stored_seed,
            "created": str(written["created"]),
        }
        self._held = (split,)

    def assign(
        self, n_fit: int | None, n_validation: int | None, strategy: str = "sequential", seed: int | None = None
    ) -> Split:
        """Choose (see :func:`choose_split`) and store a split; returns it as :meth:`get` reads it back.

        A count left None comes from the run's protocol (:meth:`sizes`).
        """
        if n_fit is None or n_validation is None:
            default_fit, default_validation = self.sizes()
            n_fit = default_fit if n_fit is None else n_fit
            n_validation = default_validation if n_validation is None else n_validation
        fit, val = choose(self._candidates(), n_fit, n_validation, strategy, seed, self._run.path)
        self.set(fit, val, strategy, seed_used(strategy, seed))
        self._held = None  # read back from the file: what a later open will find
        split = self.get()
        if split is None:
            raise StoreError(f"{self._run.path}: the split just stored cannot be read back; the file is damaged.")
        return split

    def _candidates(self) -> list[int]:
        """The records a split may hold: the complete ones, if the record type splits at all."""
        return self._run.records.ids() if self._run.record_type.splits else []


def seed_used(strategy: str, seed: int | None) -> int | None:
    """The seed a split records: a random split's (0 when none was given, as :func:`choose_split`
    draws with it), none for the others."""
    return (0 if seed is None else seed) if strategy == "random" else None


def split_row(
    g: h5py.Group,
    fit: Sequence[int],
    validation: Sequence[int],
    strategy: str,
    seed: int | None,
    version: int = CHECKSUM_VERSION,
) -> dict[str, object]:
    """Write the split's ids to the blob; the row that refers to them (not yet committed), its ids'
    checksum of ``version`` (1 for a log without the ``ids_checksum_version`` column)."""
    ids = np.concatenate([np.asarray(fit, dtype=np.int64), np.asarray(validation, dtype=np.int64)])
    start, stop, checksum = blob_write(g["ids"], ids, version)
    mid = start + len(fit)
    return {
        "strategy": strategy,
        "seed": -1 if seed is None else int(seed),
        "created": utc_now(),
        "fit_start": start,
        "fit_stop": mid,
        "validation_start": mid,
        "validation_stop": stop,
        "ids_checksum": checksum,
        "ids_checksum_version": version,  # left out by a log without the column (its own is 1)
    }


def read_split(t: Table) -> tuple[Split | None, list[str]]:
    """The split in force (the last good row) and what was found damaged."""
    rows = t.read()
    problems = [f"split row {r}: {why}" for r, why in rows.damaged]
    c = rows.cols
    for i in range(len(rows.rows) - 1, -1, -1):
        a, m, b = int(c["fit_start"][i]), int(c["fit_stop"][i]), int(c["validation_stop"][i])
        version = int(c["ids_checksum_version"][i]) if "ids_checksum_version" in c else 1
        ids = blob_read(t.g, "ids", a, b, int(c["ids_checksum"][i]), version)
        if ids is None:
            problems.append(f"the ids of split {i + 1} do not match their checksum")
            continue
        seed = int(c["seed"][i])
        split: Split = {
            "fit": ids[: m - a].astype(np.int64).tolist(),  # Python ints, as int() of each
            "validation": ids[m - a :].astype(np.int64).tolist(),
            "strategy": cell_text(c["strategy"][i]),
            "seed": None if seed < 0 else seed,
            "created": cell_text(c["created"][i]),
        }
        return split, problems
    return None, problems


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
            f"the run has {count(len(ids), 'completed trial')}, fewer than the {need} asked for "
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
    """The fit and validation ids of a split, refused in one sentence unless each is a complete record once.

    Whole-array (an imported archive's split holds 10^6 ids): the first id of each kind of fault
    is the one a check id by id would name.
    """
    fit, val = _ints(fit_ids), _ints(validation_ids)
    if not (isinstance(complete, np.ndarray) and complete.dtype.kind == "i"):  # a run's ids: an array already
        complete = list(complete)
    try:
        f, v = np.asarray(fit, dtype=np.int64), np.asarray(val, dtype=np.int64)
        done = np.asarray(complete)  # ints already (a run's record ids): read in C, not one at a time
        if done.dtype.kind != "i" or done.ndim != 1:
            done = np.fromiter((int(i) for i in complete), dtype=np.int64)
    except OverflowError:  # an id past int64 is no record's: the checks id by id name it
        return _checked_one_by_one(path, complete, fit, val)
    fs, vs = np.sort(f), np.sort(v)  # sorts, not np.unique: numpy 2 hashes, ten times slower here
    both = vs[np.isin(vs, fs)]  # sorted: the smallest id in both comes first
    if len(both):
        raise StoreError(f"trial {int(both[0])} cannot be in both the fit and the validation set.")
    if np.any(fs[1:] == fs[:-1]) or np.any(vs[1:] == vs[:-1]):
        raise StoreError("a trial id appears twice in the split.")
    every = np.concatenate([f, v])
    missing = ~np.isin(every, done)
    if missing.any():
        first = int(every[int(np.argmax(missing))])
        raise StoreError(f"trial {first} is not a complete trial in {path}, so it cannot join the split.")
    return fit, val


def _ints(ids: Iterable[int]) -> list[int]:
    """``ids`` as a list of Python ints: copied whole when they are ints already (an import's million)."""
    out = list(ids)
    return out if set(map(type, out)) <= {int} else [int(i) for i in out]


def _checked_one_by_one(
    path: str, complete: Iterable[int], fit: list[int], val: list[int]
) -> tuple[list[int], list[int]]:
    both = sorted(set(fit) & set(val))
    if both:
        raise StoreError(f"trial {both[0]} cannot be in both the fit and the validation set.")
    if len(set(fit)) != len(fit) or len(set(val)) != len(val):
        raise StoreError("a trial id appears twice in the split.")
    done = {int(i) for i in complete}
    missing = [i for i in fit + val if i not in done]
    if missing:
        raise StoreError(f"trial {missing[0]} is not a complete trial in {path}, so it cannot join the split.")
    return fit, val


def set_of(split: Split | None) -> dict[int, str]:
    """Record id -> "fit" / "validation" (unassigned ids absent)."""
    if split is None:
        return {}
    out = {i: "fit" for i in split["fit"]}
    out.update({i: "validation" for i in split["validation"]})
    return out
