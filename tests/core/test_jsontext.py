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
