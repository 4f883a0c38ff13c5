"""Measure again the figures the README and docs/ quote, and (with --docs) write them into the pages.

    python tests/docfigures/regenerate.py                  # every fast and slow source (a few minutes)
    python tests/docfigures/regenerate.py demo rpam-demo   # only these
    python tests/docfigures/regenerate.py --benchmarks     # also the benchmarks (tens of minutes)
    python tests/docfigures/regenerate.py --docs           # no measuring: rewrite the pages from the files
    python tests/docfigures/regenerate.py --list           # the sources, and which figures each page uses

Each source writes ``docs/figures/<source>.json`` (see doc_sources.py).  ``--docs`` then rewrites every
marked figure of README.md and docs/*.md from those files, at the decimals the page shows, and
lists what changed: read the changes, since a sentence around a figure may no longer hold.
``tests/docfigures/test_doc_figures.py`` fails while a page and its file disagree.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from collections import Counter
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

import doc_markers as markers  # noqa: E402
import doc_provenance as provenance  # noqa: E402
from doc_sources import BENCH, ROOT, SOURCES, Source  # noqa: E402


def write(name: str, figures: dict) -> Path:
    path = markers.FIGURES / f"{name}.json"
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(figures, indent=1, ensure_ascii=False) + "\n", encoding="utf-8")
    return path


def measure(source: Source) -> dict:
    if source.produce is not None:
        return source.produce()
    figures: dict = {}
    commit = provenance.head_commit()
    for prefix, args in (source.runs or {"": ()}).items():
        with tempfile.TemporaryDirectory() as tmp:
            out = Path(tmp) / "figures.json"
            cmd = [sys.executable, str(BENCH / source.script), *args, "--figures", str(out)]
            print(f"  python tests/benchmarks/{source.script} {' '.join(args)}", file=sys.stderr, flush=True)
            subprocess.run(cmd, cwd=ROOT, check=True, stdout=subprocess.DEVNULL)
            run = json.loads(out.read_text(encoding="utf-8"))
        figures[f"{prefix} command" if prefix else "command"] = (
            f"python tests/benchmarks/{source.script} {' '.join(args)}"
        )
        figures.update({f"{prefix} {k}" if prefix else k: v for k, v in run.items()})
        # What the run measured on (doc_provenance.py), over any record of the script's own: only
        # this checkout's stamp knows whether the measured code had changes not committed.
        figures.update(provenance.stamp(prefix, source.script, args, commit))
    if source.derive is not None:
        figures.update(source.derive(figures))
    return figures


def rewrite_pages() -> list[str]:
    values = {path.stem: json.loads(path.read_text(encoding="utf-8")) for path in markers.FIGURES.glob("*.json")}
    changes = []
    for path in markers.pages():
        page = path.relative_to(ROOT).as_posix()
        text = path.read_text(encoding="utf-8")
        new, changed = markers.rewrite(text, values, page)
        if new != text:
            path.write_text(new, encoding="utf-8")
        changes += changed
    return changes


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("sources", nargs="*", help="sources to measure (default: every fast and slow one)")
    ap.add_argument("--benchmarks", action="store_true", help="also run the benchmark sources")
    ap.add_argument("--docs", action="store_true", help="rewrite the pages' marked figures from docs/figures/")
    ap.add_argument("--list", action="store_true", help="list the sources and how many figures each page uses")
    args = ap.parse_args(argv)

    if args.list:
        used = Counter(m.source for m in markers.check_pages()[0])
        for s in SOURCES.values():
            print(f"{s.name:20s} {s.kind:9s} {used.get(s.name, 0):4d} marks  {s.what}")
        for name in sorted(set(used) - set(SOURCES)):
            print(f"{name:20s} {'?':9s} {used[name]:4d} marks  (no source of that name)")
        return 0
    unknown = [n for n in args.sources if n not in SOURCES]
    if unknown:
        ap.error(f"unknown source {unknown[0]!r}; choose from {', '.join(SOURCES)}")
    if args.sources:
        chosen = [SOURCES[n] for n in args.sources]
    elif args.docs:
        chosen = []
    else:
        chosen = [s for s in SOURCES.values() if s.kind != "benchmark" or args.benchmarks]
    for source in chosen:
        t0 = time.perf_counter()
        print(f"measuring {source.name}: {source.what}", file=sys.stderr, flush=True)
        path = write(source.name, measure(source))
        print(f"  wrote {path.relative_to(ROOT)} ({time.perf_counter() - t0:.0f} s)", file=sys.stderr)
    if args.docs:
        for line in rewrite_pages():
            print(line)
    _, problems = markers.check_pages()
    for p in problems:
        print(p, file=sys.stderr)
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
