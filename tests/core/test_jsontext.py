"""Bounded JSON reading: numbers beyond a float and deep nesting come back as values or one error."""

from __future__ import annotations

import json

import pytest

from labcli.core.jsontext import MAX_DEPTH, JSONDepthError, OutOfRange, json_kind, loads_bounded, nesting_depth


def test_ordinary_documents_read_as_json_loads_does():
    text = '{"a": [1, 2.5, -3e-7, {"b": null, "c": "x[{"}], "d": true}'
    assert loads_bounded(text) == json.loads(text)


@pytest.mark.parametrize("digits", [309, 400, 5000, 100_000])
def test_integers_beyond_a_float_are_marked_not_raised(digits):
    v = loads_bounded('{"x": ' + "9" * digits + "}")["x"]
    assert isinstance(v, OutOfRange)
    assert json_kind(v) == f"a {digits}-digit number (beyond the largest float, about 1.8e308)"


def test_the_largest_integer_a_float_holds_stays_an_integer():
    v = loads_bounded("9" * 308)
    assert v == int("9" * 308) and float(v) > 1e307


def test_a_float_literal_beyond_range_is_marked():
    assert isinstance(loads_bounded("-1e400"), OutOfRange)
    assert json_kind(loads_bounded("1e400")) == "the number 1e400 (beyond the largest float, about 1.8e308)"
    assert loads_bounded("1e-400") == 0.0  # underflow is a number, zero


def test_depth_is_counted_without_recursion_and_strings_do_not_count():
    assert nesting_depth('{"a": "[[[[[[", "b": [[1]]}') == 3
    assert nesting_depth(r'["\"[[[", []]') == 2
    with pytest.raises(JSONDepthError) as e:
        loads_bounded("[" * 100_000 + "]" * 100_000)
    assert e.value.depth == 100_000
    loads_bounded("[" * MAX_DEPTH + "]" * MAX_DEPTH)  # at the limit: read


def test_long_id_lists_go_on_one_line_and_the_value_is_unchanged():
    from labcli.core.jsontext import LONG_LIST, dumps_indented

    doc = {
        "fitted_trials": list(range(LONG_LIST + 1)),
        "short": [1, 2],
        "mixed": [1.5] * (LONG_LIST + 1),
        "text": "long-list-0",
        "nested": {"ids": [list(range(3 * LONG_LIST))]},
    }
    text = dumps_indented(doc)
    assert json.loads(text) == doc
    lines = text.splitlines()
    assert any(line.strip().startswith('"fitted_trials": [0, 1, 2') for line in lines)
    # Short lists and lists of floats keep json's own indented layout.
    assert text.count("\n") > LONG_LIST
    assert '"short": [\n    1,\n    2\n  ]' in text


def test_numbers_that_fit_parse_as_plain_json_and_huge_ones_are_still_marked():
    assert loads_bounded('{"a": [1, 2.5e300, -7]}') == {"a": [1, 2.5e300, -7]}
    out = loads_bounded('{"a": [1, 9e999], "b": "1e999"}')
    assert out["a"][0] == 1 and isinstance(out["a"][1], OutOfRange) and out["b"] == "1e999"


def test_long_texts_count_their_depth_whole_array_as_short_ones_do_char_by_char():
    import random

    def depth(text: str) -> int:  # the highest running count of open brackets, one bracket at a time
        runs, run = [], 0
        for c in text:
            if c in "[]{}":
                run += 1 if c in "[{" else -1
                runs.append(run)
        return max(runs) if runs else 0

    rng = random.Random(4)
    for size in (60, 30_000):  # below and above the whole-array length
        for _ in range(20):
            text = "".join(rng.choice("[]{}x ") for _ in range(size))
            assert nesting_depth(text) == depth(text)
    deep = "[" * 20_000 + "{}" + "]" * 20_000
    assert nesting_depth(deep) == depth(deep) == 20_001
    assert nesting_depth('["[[[[", ' * 3_000 + "1" + "]" * 3_000) == 3_000  # brackets in strings do not count


def test_long_texts_leave_the_brackets_in_strings_out_as_the_string_pattern_does():
    import itertools
    import random

    from labcli.core.jsontext import _STRING

    def depth(text: str) -> int:  # strings taken out by the pattern, then one bracket at a time
        bare = _STRING.sub("", text)
        return max(itertools.accumulate(1 if c in "[{" else -1 for c in bare if c in "[]{}"), default=0)

    rng = random.Random(5)
    strings = ['"[["', '"]"', '"{x}"', '"a[b"', '""', '"é[ü"']
    escaped = ['"\\"[["', '"\\\\"', '"q\\"]"']  # an escaped quote, an escaped backslash
    for pool in (strings, strings + escaped):
        for _ in range(10):
            tokens = [rng.choice(["[", "]", "{", "}", " ", "1", *pool]) for _ in range(12_000)]
            text = "".join(tokens)
            assert len(text) > 20_000
            assert nesting_depth(text) == depth(text)


def test_trial_ranges_go_on_one_line_and_read_back_as_written():
    from labcli.core import idranges
    from labcli.core.jsontext import LONG_LIST, dumps_indented

    ids = [t for t in range(12 * LONG_LIST) if t % 6 != 5]  # every sixth trial held out: 2 x LONG_LIST pairs
    ranges = idranges.to_ranges(ids)
    text = dumps_indented({"fitted_trials": ranges, "few": idranges.to_ranges([1, 2, 3, 7])})
    assert '"fitted_trials": [[0, 4], [6, 10], [12, 16]' in text
    assert '"few": [\n    [\n      1,' in text  # a short list keeps json's own layout
    back = json.loads(text)
    assert idranges.parse(back["fitted_trials"], "fitted_trials", None) == ranges == back["fitted_trials"]


def test_one_long_list_met_several_times_is_written_each_time_the_same():
    import json

    from labcli.core import idranges
    from labcli.core.jsontext import LONG_LIST, dumps_indented

    ranges = idranges.to_ranges([i for i in range(12 * LONG_LIST) if i % 6 != 5])
    other = idranges.to_ranges([i for i in range(12 * LONG_LIST) if i % 6 != 4])
    doc = {"a": ranges, "b": {"x": ranges, "y": other, "z": ranges}, "ids": list(range(LONG_LIST + 1))}
    text = dumps_indented(doc)
    assert json.loads(text) == json.loads(json.dumps(doc))
    one_line = json.dumps(ranges, separators=(", ", ": "))
    assert text.count(one_line) == 3 and json.dumps(other, separators=(", ", ": ")) in text


def test_long_texts_find_huge_numbers_whole_array_as_the_pattern_does():
    import random

    from labcli.core.jsontext import _HUGE_NUMBER, LONG_TEXT, _may_hold_huge_number

    rng = random.Random(5)
    filler = '[1, 2.5e-05, "x"], '
    seen = set()
    for _ in range(40):
        # A long plain document with one spot of digits, exponent letters and signs spliced in.
        spot = "".join(rng.choice("0123456789eE+-. ,") for _ in range(rng.randrange(1, 12)))
        spot += "7" * rng.choice([0, 3, 308, 309, 400])
        text = filler * (LONG_TEXT // len(filler)) + spot + rng.choice(["", "e", "E+", "e-1", "]"])
        found = _may_hold_huge_number(text)
        assert found == (_HUGE_NUMBER.search(text) is not None), spot
        seen.add(found)
    assert seen == {True, False}
    for text in ("9" * (LONG_TEXT + 5), "9" * 308 + "," + filler * LONG_TEXT, filler * LONG_TEXT + "1E+300"):
        assert _may_hold_huge_number(text) == (_HUGE_NUMBER.search(text) is not None)
    assert isinstance(loads_bounded("[" + filler * 2_000 + "1e999]")[-1], OutOfRange)


# --------------------------------------------------------------------------- long lists of pairs


def _document(pairs: list[list[int]], *, pair_text: str | None = None, extra: str = "") -> str:
    """A model-like document holding ``pairs`` as the writer writes them (or as ``pair_text``)."""
    from labcli.core.jsontext import PlainList, dumps_indented

    doc = {"schema": "x", "coefficients": [[0.5, -1.25e-3], [2.0, 1e-300]], "trials": PlainList(pairs)}
    text = dumps_indented(doc)
    if pair_text is not None:
        text = text.replace(json.dumps(pairs, separators=(", ", ": ")), pair_text)
    return text.replace('"schema": "x"', '"schema": "x"' + extra)


def test_long_lists_of_pairs_read_as_json_reads_them_and_carry_their_array():
    import random

    import numpy as np

    from labcli.core.jsontext import PairList

    rng = random.Random(8)
    for _ in range(20):
        pairs = [[rng.randint(-(10**14), 10**14), rng.choice([0, 7, -3, 10**14 - 1])] for _ in range(3000)]
        text = _document(pairs)
        got = loads_bounded(text)
        assert got == json.loads(text)
        assert isinstance(got["trials"], PairList)
        np.testing.assert_array_equal(got["trials"].array, np.array(pairs, dtype=np.int64))
        assert all(type(x) is int for p in got["trials"] for x in p)


@pytest.mark.parametrize(
    "odd",
    [
        "[1, 2], [-0, 5]",  # -0: json reads 0, the text is not the writer's
        "[1, 2], [05, 6]",  # a leading zero: not JSON at all
        "[1, 2], [1.5, 6]",  # a float
        "[1, 2], [1e3, 6]",  # an exponent
        "[1, 2], [1,2]",  # other spacing
        "[1, 2], [1, 2, 3]",  # not a pair
        "[1, 2], [9999999999999999999999, 6]",  # beyond int64
        "[1, 2], [5-3, 6]",  # a stray sign
        "[1, 2], [--5, 6]",
        "[1, 2], [true, 6]",
    ],
)
def test_anything_but_the_writers_pairs_is_read_as_json_reads_it(odd):
    from labcli.core.jsontext import PairList

    pairs = [[i, i + 1] for i in range(0, 6000, 2)]
    written = json.dumps(pairs, separators=(", ", ": "))
    text = _document(pairs, pair_text="[" + odd + ", " + written[1:])
    try:
        expected = json.loads(text)
    except json.JSONDecodeError as e:
        with pytest.raises(json.JSONDecodeError) as got:
            loads_bounded(text)
        assert (got.value.lineno, got.value.colno, got.value.msg) == (e.lineno, e.colno, e.msg)
        return
    got = loads_bounded(text)
    assert got == expected
    if "9999999999" in odd:
        assert isinstance(got["trials"][1][0], int) and got["trials"][1][0] == 9999999999999999999999
    assert not isinstance(got["trials"], PairList)


def test_pairs_in_a_string_a_key_or_a_broken_document_are_read_as_json_reads_them():
    pairs = [[i, i + 3] for i in range(0, 9000, 5)]
    written = json.dumps(pairs, separators=(", ", ": "))
    in_string = '{"note": "' + written + '", "n": 1}'
    assert loads_bounded(in_string) == json.loads(in_string)
    as_key = '{"a": 1, ' + written + ": 2}"  # not JSON: a key must be a string
    broken = '{"a": ' + written + ', "b": [1, 2}'
    for text in (as_key, broken):
        with pytest.raises(json.JSONDecodeError) as expected:
            json.loads(text)
        with pytest.raises(json.JSONDecodeError) as got:
            loads_bounded(text)
        assert (got.value.lineno, got.value.colno) == (expected.value.lineno, expected.value.colno)


def test_depth_and_huge_numbers_are_checked_with_long_pairs_in_the_document():
    pairs = [[i, i + 1] for i in range(0, 8000, 2)]
    huge = _document(pairs, extra=', "big": 1e999')
    got = loads_bounded(huge)
    assert isinstance(got["big"], OutOfRange) and got["trials"] == pairs
    written = json.dumps(pairs, separators=(", ", ": "))
    for levels, refused in ((61, False), (62, False), (63, True)):  # the pairs add two levels
        text = "[" * levels + written + "]" * levels
        if refused:
            with pytest.raises(JSONDepthError) as e:
                loads_bounded(text)
            assert e.value.depth == levels + 2
        else:
            value = loads_bounded(text)
            for _ in range(levels):
                value = value[0]
            assert value == pairs


def test_ranges_read_whole_array_parse_as_the_lists_do():
    from labcli.core import idranges

    def bad(key: str, what: str):
        raise ValueError(f"{key} {what}")

    good = [[i, i + 2] for i in range(0, 12_000, 5)]
    unsorted = good[::-1]
    for pairs in (good, unsorted):
        fast = loads_bounded(_document(pairs))["trials"]
        plain = json.loads(_document(pairs))["trials"]
        assert idranges.parse(fast, "t", bad) == idranges.parse(plain, "t", bad)
        assert type(idranges.parse(fast, "t", bad)) is idranges.Ranges
