"""Every benchmark's figures say what they were measured on: a commit, and the rig's realism.

regenerate.py stamps each run (doc_provenance.py); a file measured before carries the commit that
wrote it.  A source whose arguments now run another realism than its file records fails here
until it is measured again.
"""

from __future__ import annotations

import json

import doc_markers as markers
import doc_provenance as provenance
import pytest
from doc_sources import SOURCES

BENCHMARKS = [s for s in SOURCES.values() if s.kind == "benchmark"]


def _figures(name: str) -> dict:
    return json.loads((markers.FIGURES / f"{name}.json").read_text(encoding="utf-8"))


@pytest.mark.parametrize("source", BENCHMARKS, ids=[s.name for s in BENCHMARKS])
def test_benchmark_figures_record_their_commit_and_realism(source):
    if source.name in provenance.PENDING:  # a new source has no file before its first regeneration
        pytest.skip(f"{source.name} is stamped at its next regeneration by regenerate.py")
    figures = _figures(source.name)
    runs = source.runs or {"": ()}
    problems = provenance.missing(figures, runs, source.script)
    assert not problems, f"docs/figures/{source.name}.json: " + "; ".join(problems)


def test_realism_follows_the_run_arguments_then_the_script_default():
    assert provenance.run_realism("phi_bent.py", ("--seeds", "11-30", "--realism", "literature")) == "literature"
    assert provenance.run_realism("phi_bent.py", ("--seeds", "11-30")) == provenance.script_realism("phi_bent.py")
    assert provenance.run_realism("phi_bent.py", ("--rig", "second")) is None
    assert provenance.run_realism("bench_reader.py", ()) is None  # no simulated rig
    assert provenance.script_realism("band_confidence.py") == "kind,literature"
    assert provenance.run_realism("phi_bent.py", ("--realism=literature",)) == "literature"
    assert provenance.run_realism("band_confidence.py", ("--realism", "literature,kind")) == "kind,literature"
    # A parser not named ``ap`` still declares the rig.
    assert provenance.script_realism("metadata_flips.py") is not None


def test_a_realism_list_in_another_order_is_the_same_record():
    runs = {"": ("--realism", "literature,kind")}
    assert (
        provenance.missing({"meta/commit": "abc", "meta/realism": "literature,kind"}, runs, "band_confidence.py") == []
    )
    assert provenance.missing({"meta/commit": "abc", "meta/realism": "kind"}, runs, "band_confidence.py") == [
        "'the run' records realism 'kind'; its arguments run 'kind,literature'"
    ]


def test_a_file_without_provenance_or_with_another_realism_is_reported():
    runs = {"": ("--seeds", "1-10"), "literature": ("--realism", "literature")}
    problems = provenance.missing({"meta/commit": "abc", "meta/realism": "kind"}, runs, "phi_bent.py")
    assert problems == [
        "'literature' records no commit (literature meta/commit)",
        "'literature' records realism None; its arguments run 'literature'",
    ]
    stamped = {
        **provenance.stamp("", "phi_bent.py", runs[""], "abc"),
        **provenance.stamp("literature", "phi_bent.py", runs["literature"], "abc"),
    }
    assert provenance.missing(stamped, runs, "phi_bent.py") == []
    assert provenance.missing({"meta/committed_in": "abc"}, {"": ()}, "bench_reader.py") == []
    # A file stamped kind whose source now runs the literature's rig is stale.
    assert provenance.missing(stamped, {"": ("--realism", "literature")}, "phi_bent.py") == [
        "'the run' records realism 'kind'; its arguments run 'literature'"
    ]


def test_head_commit_names_a_commit_of_this_repository():
    commit = provenance.head_commit()
    assert len(commit.removesuffix("-dirty")) == 40
    int(commit.removesuffix("-dirty"), 16)


def _history_or_skip() -> None:
    why = provenance.history_unknown()
    if why is not None:
        pytest.skip(f"{why}: whether a recorded commit is in the history cannot be told")


@pytest.mark.parametrize("source", BENCHMARKS, ids=[s.name for s in BENCHMARKS])
def test_benchmark_figures_name_a_commit_of_this_history(source):
    _history_or_skip()
    if source.name in provenance.PENDING:
        pytest.skip(f"{source.name} is stamped at its next regeneration by regenerate.py")
    off = provenance.off_history(_figures(source.name))
    if off and source.name in provenance.OFF_HISTORY:
        pytest.skip(f"{source.name} was measured on a commit off this history; regenerate it: " + "; ".join(off))
    assert not off, f"docs/figures/{source.name}.json: " + "; ".join(off) + " (measure it again on this history)"


def test_a_commit_off_the_history_is_reported_and_head_is_not():
    _history_or_skip()
    head = provenance.head_commit()
    made_up = "0123456789abcdef0123456789abcdef01234567"
    assert provenance.off_history({"meta/commit": head, "N2 meta/committed_in": head.removesuffix("-dirty")}) == []
    assert provenance.off_history({"meta/commit": made_up + "-dirty", "meta/seeds": "11-30", "x meta/commit": ""}) == [
        f"meta/commit '{made_up}-dirty' is not HEAD or an ancestor of it",
        "x meta/commit '' is not HEAD or an ancestor of it",
    ]


def test_a_checkout_without_its_history_says_why(tmp_path, monkeypatch):
    monkeypatch.setattr(provenance, "ROOT", tmp_path)  # a source tarball: no repository of its own
    assert provenance.history_unknown() == "not a git checkout of its own (a source tarball)"
