"""``labcli split`` as one library call: a run file's split, or a trial CSV's ``set`` column.

A run file keeps every split it was given (:mod:`labcli.core.store.split`); a CSV holds
only its ``set`` column, which is rewritten in place (or to ``output``), its sidecar with it.

Sizes left out come from the protocol (the paper's 90 fit + 18 validation); a run shorter
than that is split in the protocol's proportion (12 trials: 10 fit + 2 validation), and the
result says so.  Given one count, the other is what the protocol says or what is left.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ..errors import ConfigError
from .files import RUN_FILE_SUFFIXES
from .words import count


@dataclass(frozen=True)
class SplitDone:
    """What a split did: the sizes, how they were chosen, where it went."""

    path: str
    fit: int
    validation: int
    total: int  # complete records (rows of a table)
    strategy: str
    seed: int | None
    sizes: str  # how sizes not given were chosen ("" when both were given or the protocol's fit)
    written: str = ""  # the CSV written (a table's split); "" for a run file
    captures: int = 1  # records a load (``acquisition.captures_per_load``): sizes and total count loads
    records: int = 0  # complete records (captures) when ``captures`` > 1

    def sentence(self) -> str:
        how = self.strategy if self.seed is None else f"{self.strategy}, seed {self.seed}"
        unassigned = self.total - self.fit - self.validation
        where = self.path if not self.written else f"{self.path} -> {self.written} (its set column)"
        # One bracket: a run of several captures a load says its captures beside the strategy.
        of = count(self.total, "completed trial")
        if self.captures > 1:
            of, how = count(self.total, "load"), f"{count(self.records, 'capture')}, {self.captures} a load; {how}"
        text = f"{where}: {self.fit} fit, {self.validation} validation, {unassigned} unassigned of {of} ({how})."
        return text + (f" {self.sizes[:1].upper()}{self.sizes[1:]}." if self.sizes else "")


def split_sizes(
    n: int, defaults: tuple[int, int] | None, n_fit: int | None, n_validation: int | None, path: str
) -> tuple[int, int, str]:
    """The fit and validation sizes for ``n`` complete records, and how any not given were chosen.

    ``defaults``: the protocol's (fit, validation), None when it gives none.
    """
    if n_fit is not None and n_validation is not None:
        return n_fit, n_validation, ""
    if defaults is None:
        raise ConfigError(f"{path}: the protocol gives no fit and validation counts; give --fit and --validation.")
    d_fit, d_val = defaults
    if n_fit is None and n_validation is None:
        if n >= d_fit + d_val:
            return d_fit, d_val, ""
        if n < 2:
            raise ConfigError(
                f"{path} has {count(n, 'completed trial')}; a split needs at least 2 (1 fit, 1 validation)."
            )
        val = min(n - 1, max(1, round(n * d_val / (d_fit + d_val))))
        return (
            n - val,
            val,
            f"the protocol's {d_fit} fit + {d_val} validation need {d_fit + d_val} trials and there are {n}, "
            "so the sizes keep its proportion (--fit and --validation choose others)",
        )
    if n_fit is not None and not 1 <= n_fit <= n:
        return n_fit, d_val, ""  # refused by the split itself, in its own words
    if n_validation is not None and not 0 <= n_validation < n:
        return d_fit, n_validation, ""
    if n_fit is not None:
        val = max(0, min(d_val, n - n_fit))
        return n_fit, val, "" if val == d_val else f"{val} validation: the trials left after {n_fit} fit"
    assert n_validation is not None
    fit = min(d_fit, n - n_validation)
    return fit, n_validation, "" if fit == d_fit else f"{fit} fit: the trials left after {n_validation} validation"


def split(
    path: str | os.PathLike,
    n_fit: int | None = None,
    n_validation: int | None = None,
    strategy: str = "sequential",
    seed: int | None = None,
    *,
    protocol: str | None = None,
    output: str | os.PathLike | None = None,
) -> SplitDone:
    """Assign the fit and validation sets of a run file (stored in it) or a trial CSV (its ``set`` column).

    ``protocol``: a CSV's protocol (name or .toml; default the registry's for ``split``), for its default
    sizes and its table; a run file carries its own.  ``output``: where a CSV's split goes
    (default: the CSV itself).  Raises :class:`~labcli.errors.LabcliError` in one sentence.
    """
    p = os.fspath(path)
    if seed is not None and strategy != "random":
        raise ConfigError("--seed applies only to --strategy random.")
    if p.lower().endswith(RUN_FILE_SUFFIXES):
        if protocol is not None or output is not None:
            raise ConfigError(
                f"{p} is a run file, which carries its protocol and keeps its split: drop --protocol and -o."
            )
        return _split_run(p, n_fit, n_validation, strategy, seed)
    from .registry import default_protocol

    return _split_table(p, n_fit, n_validation, strategy, seed, protocol or default_protocol("split"), output)


def _choose_loads(
    ids: list[int],
    captures: int,
    defaults: tuple[int, int] | None,
    n_fit: int | None,
    n_val: int | None,
    strategy: str,
    seed: int | None,
    path: str,
) -> tuple[list[int], list[int], tuple[int, int, int], str]:
    """Fit and validation record ids, the count of units split and the sizes' note: with several captures a
    load the units are loads (the counts given count loads) and each set takes every capture of its loads.
    The counts returned: fit, validation and all units."""
    from .air import load_ids, record_ids
    from .store.split import choose

    if captures == 1:
        units = ids
    else:
        units = [int(u) for u in dict.fromkeys(load_ids(ids, captures).tolist())]
    fit_n, val_n, note = split_sizes(len(units), defaults, n_fit, n_val, path)
    if captures > 1 and fit_n >= 1 and val_n >= 0 and fit_n + val_n > len(units):
        raise ConfigError(
            f"{path}: the run has {count(len(units), 'load')} ({count(len(ids), 'capture')}, {captures} a load), "
            f"fewer than the {fit_n + val_n} loads asked for ({fit_n} fit + {val_n} validation): the sizes count loads."
        )
    fit, val = choose(units, fit_n, val_n, strategy, seed, path)
    sizes = (len(fit), len(val), len(units))
    if captures == 1:
        return fit, val, sizes, note
    done = set(ids)
    return (
        [int(i) for i in record_ids(fit, captures) if int(i) in done],
        [int(i) for i in record_ids(val, captures) if int(i) in done],
        sizes,
        note,
    )


def _split_run(path: str, n_fit: int | None, n_val: int | None, strategy: str, seed: int | None) -> SplitDone:
    from .protocol import run_captures
    from .store import RunFile
    from .store.split import default_sizes, seed_used

    with RunFile.open(path, "a") as rf:
        ids = rf.records.ids() if rf.record_type.splits else []
        if not rf.record_type.splits:
            raise ConfigError(
                f"{path} holds {rf.record_type.plural}, which are not split into fit and validation sets."
            )
        try:
            defaults: tuple[int, int] | None = default_sizes(rf.protocol_text, path)
        except ConfigError:
            defaults = None
        n = run_captures(rf.protocol_text, path)
        fit, val, (fits, vals, units), note = _choose_loads(list(ids), n, defaults, n_fit, n_val, strategy, seed, path)
        used_seed = seed_used(strategy, seed)
        rf.split.set(fit, val, strategy, used_seed)
    return SplitDone(path, fits, vals, units, strategy, used_seed, note, "", n, len(ids))


def _captures_of(protocol: Any) -> int:
    return int(getattr(getattr(protocol, "air", None), "captures_per_load", 1) or 1)


def _split_table(
    path: str,
    n_fit: int | None,
    n_val: int | None,
    strategy: str,
    seed: int | None,
    protocol: str,
    output: str | os.PathLike | None,
) -> SplitDone:
    from .protocol import load_protocol
    from .registry import record_type
    from .store.split import seed_used
    from .table_meta import SIDECAR_SUFFIX, load_described, write_sidecar

    if not Path(path).is_file():
        raise ConfigError(f"{path} does not exist or is not a file: give a run file (.h5) or a trial CSV.")
    proto = load_protocol(protocol)
    kind: Any = record_type(proto.kind)  # a record type with a table spec
    if not kind.splits:
        raise ConfigError(
            f"protocol {proto.name} records {kind.plural}, which are not split; give the protocol of a trial table."
        )
    df = load_described(path, kind)
    ids = [int(i) for i in df[kind.id_column]]
    n = _captures_of(proto)
    defaults = getattr(proto.settings, "default_split", None)
    fit, val, (fits, vals, units), note = _choose_loads(ids, n, defaults, n_fit, n_val, strategy, seed, path)
    sets = {i: "fit" for i in fit} | {i: "validation" for i in val}
    had = "set" in df.columns and any(str(v) for v in df["set"])
    df["set"] = [sets.get(i, "") for i in ids]
    out = os.fspath(output) if output is not None else path
    kind.write_csv(df, out)
    if os.path.exists(path + SIDECAR_SUFFIX):  # the table's description follows it
        write_sidecar(df, kind.table_spec, out)
    if had and out == path:
        note = (note + "; " if note else "") + "the set column it had is replaced"
    used_seed = seed_used(strategy, seed)
    return SplitDone(path, fits, vals, units, strategy, used_seed, note, out, n, len(ids))
