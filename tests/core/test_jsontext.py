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
