"""What a benchmark's figures were measured on: the commit and the simulated rig's realism.

regenerate.py stamps each run of a benchmark source with ``meta/commit`` (the checkout's HEAD,
``-dirty`` when labcli/, protocols/ or tests/benchmarks/ had changes not committed) and, for a
script that runs the simulated McKibben rig (it calls ``add_rig_options``), ``meta/realism``: the
``--realism`` of the run's arguments, else the script's own default.  A run's keys carry its
prefix as its figures do (``"literature meta/realism"``).

Figures measured before the stamp carry ``meta/committed_in`` instead: the commit that wrote the
figures into the file (git log; for guard.json the measuring commit before a relabelling one), the
nearest record there is of the code they were measured on.  A source named in ``PENDING`` is not
held to the record until ``regenerate.py NAME`` has stamped it; then take its name out.

A recorded commit must be HEAD or one of its ancestors (:func:`off_history`): a commit of a branch
that was rebased before it landed names code this history never had.  A checkout that cannot tell
(no git, a source tarball, a shallow clone: :func:`history_unknown`) is not held to it.
"""

from __future__ import annotations

import re
import subprocess
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[2]
BENCH = ROOT / "tests" / "benchmarks"
RIG_DEFAULT = re.compile(r"add_rig_options\(\s*\w+,\s*realism=\"([a-z,]+)\"")
# Sources whose files await the stamp of their next regeneration.
PENDING: frozenset[str] = frozenset()
# Sources whose files name a commit off this history (measured on a branch before its rebase) and
# that cannot be measured again at once.  Their figures stand; their record does not name the code
# measured.  Regenerate them, then take the name out.
OFF_HISTORY: frozenset[str] = frozenset()
# The directories whose changes move a benchmark's figures.
MEASURED_CODE = ("labcli", "protocols", "tests/benchmarks", "tests/support")


def key(prefix: str, name: str) -> str:
    """A run's figure key, as regenerate.py writes it: ``"PREFIX name"``, or ``name`` for the run ``""``."""
    return f"{prefix} {name}" if prefix else name


def script_realism(script: str) -> str | None:
    """The realism a benchmark script runs by default, None for a script without the simulated rig."""
    m = RIG_DEFAULT.search((BENCH / script).read_text(encoding="utf-8"))
    return m.group(1) if m else None


def run_realism(script: str, args: tuple[str, ...]) -> str | None:
    """The realism one run of ``script`` with ``args`` measures on (None: no McKibben rig of labcli's)."""
    default = script_realism(script)
    if default is None:
        return None
    split = [part for a in args for part in (a.split("=", 1) if a.startswith("--") and "=" in a else [a])]
    pairs = dict(zip(split, split[1:], strict=False))
    if pairs.get("--rig") == "second":  # phi_bent.py's second forward model has no realism
        return None
    return same_order(pairs.get("--realism", default))


def same_order(realism: str) -> str:
    """A comma list of realisms in one order, so that "kind,literature" and "literature,kind" agree."""
    return ",".join(sorted(realism.split(",")))


def head_commit() -> str:
    """HEAD of the checkout, ``-dirty`` when the measured code has uncommitted changes."""
    head = subprocess.run(["git", "rev-parse", "HEAD"], cwd=ROOT, capture_output=True, text=True, check=True)
    status = subprocess.run(
        ["git", "status", "--porcelain", "--", *MEASURED_CODE], cwd=ROOT, capture_output=True, text=True, check=True
    )
    return head.stdout.strip() + ("-dirty" if status.stdout.strip() else "")


def stamp(prefix: str, script: str, args: tuple[str, ...], commit: str) -> dict[str, Any]:
    """The provenance keys of one run."""
    out: dict[str, Any] = {key(prefix, "meta/commit"): commit}
    realism = run_realism(script, args)
    if realism is not None:
        out[key(prefix, "meta/realism")] = realism
    return out


def missing(figures: dict[str, Any], runs: dict[str, tuple[str, ...]], script: str) -> list[str]:
    """What a source's file lacks or contradicts of its runs' provenance (empty: all recorded)."""
    problems = []
    for prefix, args in runs.items():
        name = repr(prefix or "the run")
        if key(prefix, "meta/commit") not in figures and key(prefix, "meta/committed_in") not in figures:
            problems.append(f"{name} records no commit ({key(prefix, 'meta/commit')})")
        realism = run_realism(script, args)
        recorded = figures.get(key(prefix, "meta/realism"))
        if realism is not None and (not isinstance(recorded, str) or same_order(recorded) != realism):
            problems.append(f"{name} records realism {recorded!r}; its arguments run {realism!r}")
    return problems


def _git(*args: str) -> subprocess.CompletedProcess[str] | None:
    try:
        return subprocess.run(["git", *args], cwd=ROOT, capture_output=True, text=True)
    except OSError:
        return None


def history_unknown() -> str | None:
    """Why this checkout cannot tell whether a commit is in its history, or None when it can."""
    top = _git("rev-parse", "--show-toplevel")
    if top is None:
        return "git is not installed"
    if top.returncode != 0 or Path(top.stdout.strip()).resolve() != ROOT.resolve():
        return "not a git checkout of its own (a source tarball)"
    shallow = _git("rev-parse", "--is-shallow-repository")
    if shallow is None or shallow.stdout.strip() != "false":
        return "a shallow clone, without the history"
    return None


def off_history(figures: dict[str, Any]) -> list[str]:
    """The recorded commits (every run's ``meta/commit`` and ``meta/committed_in``) that are neither
    HEAD nor an ancestor of it, each as a sentence (empty: all in the history)."""
    problems = []
    for k, v in figures.items():
        if not k.endswith(("meta/commit", "meta/committed_in")):
            continue
        commit = str(v).removesuffix("-dirty")
        done = _git("merge-base", "--is-ancestor", commit, "HEAD") if commit else None
        if done is None or done.returncode != 0:
            problems.append(f"{k} {v!r} is not HEAD or an ancestor of it")
    return problems
