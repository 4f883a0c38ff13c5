"""A benchmark's figures file and its resumable cache of measured seeds.

* :func:`write_figures`: ``docs/figures/<name>.json`` as regenerate.py reads it, one flat object
  (the commit measured first, each interval ``[lo, hi]`` as ``KEY/lo`` and ``KEY/hi``);
  :func:`git_head` reads that commit at a run's start (the code measured is the code then);
* :func:`cached`: a per-seed measurement read from and appended to a JSON-lines file, so that a
  long run stopped part-way resumes where it stopped; :func:`cached_seeds` the same under any tag
  (the record's keys that say which measurement it is), and :func:`cache_records` /
  :func:`cache_append` the file itself, for a cache keyed by more than the seed.
"""

from __future__ import annotations

import json
import subprocess
import sys
from collections.abc import Callable, Iterable, Mapping
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[2]


def git_head() -> str:
    """The checkout's HEAD ("" where git or the repository is missing: a tarball)."""
    try:
        out = subprocess.run(["git", "rev-parse", "HEAD"], cwd=ROOT, capture_output=True, text=True)
    except OSError:
        return ""
    return out.stdout.strip()


def write_figures(path: Path, meta: dict[str, Any], figs: dict[str, Any], *, commit: str | None = None) -> None:
    """``meta`` (the seeds, ...) and ``figs`` into ``path``, flat and sorted, with the commit measured
    (``commit``, read at the run's start; None: HEAD now)."""
    head = git_head() if commit is None else commit
    flat: dict[str, Any] = {}
    for k, v in {"meta/commit": head, **meta, **figs}.items():
        if isinstance(v, list):
            flat[f"{k}/lo"], flat[f"{k}/hi"] = v
        else:
            flat[k] = v
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(flat, indent=1, sort_keys=True) + "\n")
    print(f"wrote {path}")


def cache_records(path: Path | None, same: Callable[[dict[str, Any]], bool]) -> list[dict[str, Any]]:
    """The records of the JSON-lines ``path`` (None or no file: none) that ``same`` accepts, in order."""
    if path is None or not path.exists():
        return []
    records = (json.loads(line) for line in path.read_text().splitlines() if line.strip())
    return [rec for rec in records if same(rec)]


def cache_append(path: Path | None, record: Mapping[str, Any]) -> None:
    """One record appended to the JSON-lines ``path`` (None: no cache)."""
    if path is not None:
        with path.open("a") as f:
            f.write(json.dumps(record) + "\n")


def cached_seeds(
    path: Path | None,
    seeds: Iterable[int],
    fn: Callable[[int], Any],
    *,
    tag: Mapping[str, Any],
    same: Callable[[dict[str, Any]], bool] | None = None,
    said: str = "measured",
) -> dict[int, Any]:
    """``fn(seed)`` for each seed, read from and appended to the JSON-lines ``path`` (None: no cache)
    as ``{**tag, "seed", "raw"}``.  A record counts when ``same`` accepts it (default: it carries
    ``tag``); a record of another measurement is left alone.  Each new seed is said on stderr
    (``"  {said} seed N"``)."""
    seeds = list(seeds)
    accept = same or (lambda rec: all(rec.get(k) == v for k, v in tag.items()))
    done = {int(rec["seed"]): rec["raw"] for rec in cache_records(path, accept)}
    for seed in seeds:
        if seed not in done:
            done[seed] = fn(seed)
            print(f"  {said} seed {seed}", file=sys.stderr, flush=True)
            cache_append(path, {**tag, "seed": seed, "raw": done[seed]})
    return {s: done[s] for s in seeds}


def cached(path: Path | None, kind: str, seeds: list[int], fn: Callable[[int], dict[str, Any]]) -> dict[int, Any]:
    """``fn(seed)`` for each seed, read from and appended to the JSON-lines ``path`` (None: no
    cache) under ``kind`` (a record of another kind is another measurement)."""
    return cached_seeds(path, seeds, fn, tag={"kind": kind}, said=f"{kind}:")
