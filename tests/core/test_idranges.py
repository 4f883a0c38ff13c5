"""Trial-number sets as [first, last] ranges: round trips against plain sets, and the old one-by-one lists."""

from __future__ import annotations

import numpy as np
import pytest

from labcli.core import idranges


class Bad(Exception):
    pass


def bad(key, what):
    raise Bad(f"{key} {what}")


def members(ranges):
    return {t for lo, hi in ranges for t in range(lo, hi + 1)}


@pytest.mark.parametrize("seed", range(20))
def test_ranges_hold_exactly_the_numbers(seed):
    rng = np.random.default_rng(seed)
    ids = rng.choice(400, size=rng.integers(0, 300), replace=False) - 50
    ids = np.concatenate([ids, ids[: len(ids) // 3]])  # repeats are one member
    r = idranges.to_ranges(ids)
    assert members(r) == set(ids.tolist())
    assert idranges.count(r) == len(set(ids.tolist()))
    # sorted, disjoint and not touching: the shortest form, so equal sets give equal ranges
    assert all(a[1] + 1 < b[0] for a, b in zip(r, r[1:], strict=False))
    probe = np.arange(-60, 360)
    assert idranges.contains(r, probe).tolist() == [t in set(ids.tolist()) for t in probe]


def test_a_contiguous_fit_set_is_one_pair():
    assert idranges.to_ranges(np.arange(800_000)[::-1]) == [[0, 799_999]]
    assert idranges.to_ranges([]) == [] and idranges.contains([], [1, 2]).tolist() == [False, False]


def test_older_files_one_number_each_read_as_ranges():
    assert idranges.parse([5, 1, 2, 3, 9], "fitted_trials", bad) == [[1, 3], [5, 5], [9, 9]]
    assert idranges.parse([], "fitted_trials", bad) == []


def test_pairs_are_merged_without_listing_them():
    assert idranges.parse([[10, 20], [0, 3], [4, 4], [15, 10**15]], "k", bad) == [[0, 4], [10, 10**15]]
    assert idranges.count([[0, 10**15]]) == 10**15 + 1


@pytest.mark.parametrize(
    "value",
    [
        "1-3",
        {"ranges": [[1, 2]]},
        [1.5],
        [True],
        [[3, 1]],
        [[1, 2, 3]],
        [[1, "2"]],
        [1, [2, 3]],
        [10**30],
        [[0, 4], [6, True]],
        [[0, 4], [6, 10**30]],
        [[0, 4], [6, 2.0]],
    ],
)
def test_anything_else_is_refused_in_the_callers_words(value):
    with pytest.raises(Bad) as e:
        idranges.parse(value, "fitted_trials.Fx", bad)
    assert str(e.value) == "fitted_trials.Fx must list whole trial numbers, or [first, last] ranges of them"


@pytest.mark.parametrize("seed", range(10))
def test_ranges_as_written_read_back_as_themselves_and_others_are_merged(seed):
    # Ranges as to_ranges writes them take the whole-array path; shuffled, overlapping or
    # touching pairs the one-by-one merge: both give to_ranges' answer for the same members.
    rng = np.random.default_rng(seed)
    ids = np.flatnonzero(rng.random(3000) < 0.8)
    written = idranges.to_ranges(ids)
    assert idranges.parse([list(r) for r in written], "k", bad) == written
    pairs = [list(r) for r in written] + [[int(a), int(a) + int(rng.integers(0, 3))] for a in ids[::7]]
    rng.shuffle(pairs)
    assert idranges.parse(pairs, "k", bad) == idranges.to_ranges(sorted(members(pairs)))


@pytest.mark.parametrize("seed", range(5))
def test_disjoint_pairs_in_any_order_merge_to_the_same_ranges(seed):
    # Pairs that neither overlap nor touch take merge's whole-array path; its answer is the loop's.
    rng = np.random.default_rng(seed)
    written = idranges.to_ranges(np.flatnonzero(rng.random(2000) < 0.6))
    shuffled = [list(r) for r in written]
    rng.shuffle(shuffled)
    assert idranges.merge(shuffled) == written
    assert idranges.merge(shuffled + [[written[0][0], written[-1][1]]]) == [[written[0][0], written[-1][1]]]


def test_the_collector_is_paused_only_inside_and_left_as_it_was():
    import gc

    from labcli.core.nogc import paused_gc

    assert gc.isenabled()
    with paused_gc():
        assert not gc.isenabled()
    assert gc.isenabled()
    gc.disable()
    try:
        with paused_gc():
            pass
        assert not gc.isenabled()  # a caller that had switched it off keeps it off
    finally:
        gc.enable()
    with pytest.raises(ValueError), paused_gc():
        raise ValueError
    assert gc.isenabled()


def test_what_is_built_while_paused_goes_to_the_oldest_generation_and_stays_collectable():
    import gc
    import weakref

    from labcli.core.nogc import paused_gc

    class Node:
        pass

    assert gc.isenabled() and gc.get_freeze_count() == 0
    with paused_gc():
        lists = [[i, i + 1] for i in range(5000)]
        a, b = Node(), Node()
        a.other, b.other = b, a  # a reference cycle: only the collector frees it
        gone = weakref.ref(a)
    assert gc.get_count()[0] < 100  # nothing young left for the next collection to walk
    oldest = {id(o) for o in gc.get_objects(generation=2)}
    assert id(lists) in oldest and id(lists[-1]) in oldest
    assert gc.get_freeze_count() == 0  # nothing left frozen
    del a, b
    gc.collect()
    assert gone() is None  # the cycle is still collected


def test_objects_a_program_froze_stay_frozen():
    import gc

    from labcli.core.nogc import paused_gc

    keep = [[1, 2], [3, 4]]
    gc.freeze()
    try:
        frozen = gc.get_freeze_count()
        with paused_gc():
            built = [[i] for i in range(100)]
        assert gc.get_freeze_count() == frozen  # not handed back to the collector
        assert built and keep
    finally:
        gc.unfreeze()


@pytest.mark.parametrize("seed", range(20))
def test_the_whole_array_merge_is_the_pair_by_pair_one(seed):
    rng = np.random.default_rng(seed)
    lo = rng.integers(-50, 300, size=int(rng.integers(1, 80)))
    pairs = [[int(a), int(a + rng.integers(0, 6))] for a in lo]
    want = merged_by_loop(pairs)
    assert idranges.merge(pairs) == want
    assert idranges.merge(pairs + [[-(2**63), -(2**63) + 1]]) == [
        [-(2**63), -(2**63) + 1],
        *want,
    ]  # past 2^62: the loop


def merged_by_loop(pairs):
    out = []
    for a, b in sorted(pairs, key=lambda r: r[0]):
        if out and a <= out[-1][1] + 1:
            out[-1][1] = max(out[-1][1], b)
        else:
            out.append([a, b])
    return out
