"""A benchmark's figures file and its resumable cache of measured seeds.

* :func:`write_figures`: ``docs/figures/<name>.json`` as regenerate.py reads it, one flat object
  (the commit measured first, each interval ``[lo, hi]`` as ``KEY/lo`` and ``KEY/hi``);
* :func:`cached`: a per-seed measurement read from and appended to a JSON-lines file, so that a
  long run stopped part-way resumes where it stopped.
"""

from __future__ import annotations

import json
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[2]


def write_figures(path: Path, meta: dict[str, Any], figs: dict[str, Any]) -> None:
    """``meta`` (the seeds, ...) and ``figs`` into ``path``, flat and sorted, with the commit measured."""
    head = subprocess.run(["git", "rev-parse", "HEAD"], cwd=ROOT, capture_output=True, text=True).stdout.strip()
    flat: dict[str, Any] = {}
    for k, v in {"meta/commit": head, **meta, **figs}.items():
        if isinstance(v, list):
            flat[f"{k}/lo"], flat[f"{k}/hi"] = v
        else:
            flat[k] = v
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(flat, indent=1, sort_keys=True) + "\n")
    print(f"wrote {path}")


def cached(path: Path | None, kind: str, seeds: list[int], fn: Callable[[int], dict[str, Any]]) -> dict[int, Any]:
    """``fn(seed)`` for each seed, read from and appended to the JSON-lines ``path`` (None: no
    cache) under ``kind`` (a record of another kind is another measurement)."""
    done: dict[int, Any] = {}
    if path is not None and path.exists():
        for line in path.read_text().splitlines():
            rec = json.loads(line) if line.strip() else {}
            if rec.get("kind") == kind:
                done[int(rec["seed"])] = rec["raw"]
    for seed in seeds:
        if seed not in done:
            done[seed] = fn(seed)
            print(f"  {kind}: seed {seed}", file=sys.stderr, flush=True)
            if path is not None:
                with path.open("a") as f:
                    f.write(json.dumps({"kind": kind, "seed": seed, "raw": done[seed]}) + "\n")
    return {s: done[s] for s in seeds}
