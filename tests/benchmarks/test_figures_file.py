"""The benchmarks' figures file and cache (figures_file.py): what the long benchmarks resume from and write.

A cache is read back as it was written, a record of another measurement is never taken for this
one, and a run stopped part-way measures only the seeds it had not; the figures file is the flat,
sorted object regenerate.py reads.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))
from figures_file import cache_append, cache_records, cached, cached_seeds, git_head, write_figures  # noqa: E402


class Counting:
    """A measurement of a seed that counts its calls."""

    def __init__(self) -> None:
        self.calls: list[int] = []

    def __call__(self, seed: int) -> dict[str, float]:
        self.calls.append(seed)
        return {"rmse": seed / 10, "err": [seed, -seed]}


def test_a_stopped_run_resumes_where_it_stopped(tmp_path):
    cache = tmp_path / "c.jsonl"
    first = Counting()
    assert cached_seeds(cache, [11, 12], first, tag={"realism": "kind"}) == {11: first(11), 12: first(12)}
    assert first.calls[:2] == [11, 12]
    again = Counting()
    got = cached_seeds(cache, [13, 11, 12], again, tag={"realism": "kind"})
    assert again.calls == [13]  # only the seed not measured before
    assert list(got) == [13, 11, 12] and got[11] == {"rmse": 1.1, "err": [11, -11]}  # JSON round trip
    assert len(cache.read_text().splitlines()) == 3


def test_a_record_of_another_measurement_is_not_taken_for_this_one(tmp_path):
    cache = tmp_path / "c.jsonl"
    cached_seeds(cache, [1], Counting(), tag={"realism": "kind"})
    other = Counting()
    cached_seeds(cache, [1], other, tag={"realism": "literature"})
    assert other.calls == [1]
    # A record written before a tag existed is read as the caller says it was measured.
    cache_append(cache, {"seed": 2, "raw": {"rmse": 9.0}})
    legacy = Counting()
    got = cached_seeds(
        cache,
        [2],
        legacy,
        tag={"realism": "literature"},
        same=lambda rec: rec.get("realism", "literature") == "literature",
    )
    assert legacy.calls == [] and got == {2: {"rmse": 9.0}}


def test_cached_keeps_its_kind_records_and_says_each_new_seed(tmp_path, capsys):
    cache = tmp_path / "c.jsonl"
    cached(cache, "floor literature", [3], Counting())
    assert json.loads(cache.read_text()) == {
        "kind": "floor literature",
        "seed": 3,
        "raw": {"rmse": 0.3, "err": [3, -3]},
    }
    assert capsys.readouterr().err == "  floor literature: seed 3\n"
    assert cache_records(cache, lambda rec: rec["kind"] == "other") == []


def test_no_cache_measures_every_seed_and_writes_nothing(tmp_path):
    fn = Counting()
    assert cached_seeds(None, [1, 2], fn, tag={}) == {1: fn(1), 2: fn(2)}
    assert cache_records(None, lambda rec: True) == [] and cache_records(tmp_path / "absent", lambda rec: True) == []
    assert list(tmp_path.iterdir()) == []


def test_the_figures_file_is_flat_sorted_and_names_the_commit_measured(tmp_path, capsys):
    path = tmp_path / "deep" / "f.json"
    meta = {"meta/seeds": "11-30", "meta/realism": "literature"}
    figs = {"b/rmse": 0.5, "a/ratio_ci95": [0.4, 0.6], "c/n": 18}
    write_figures(path, meta, figs, commit="abc")
    # The file the benchmarks wrote themselves before: {**meta, **figures} sorted, intervals flat.
    flat = {"meta/commit": "abc", **meta, "b/rmse": 0.5, "a/ratio_ci95/lo": 0.4, "a/ratio_ci95/hi": 0.6, "c/n": 18}
    assert path.read_text() == json.dumps(flat, indent=1, sort_keys=True) + "\n"
    assert capsys.readouterr().out == f"wrote {path}\n"


def test_without_a_commit_given_the_file_names_head(tmp_path):
    head = git_head()
    if not head:
        pytest.skip("no git checkout (a source tarball): no commit to record")
    int(head, 16)
    write_figures(tmp_path / "f.json", {}, {})
    assert json.loads((tmp_path / "f.json").read_text()) == {"meta/commit": head}
