"""Key specs: what a protocol file may hold, as plain data, and the checker that reads it.

A key spec is a dict::

    {"type": ..., "unit": ..., "check": ..., "optional": bool, "default": value, "help": ...}

type
    ``"str"`` | ``"int"`` | ``"number"`` | ``"bool"`` | ``"str-list"`` | ``"number-list"`` |
    ``"pair"`` (``[low, high]``) | ``"table"`` (a nested table; its key specs in ``"keys"``).
    A ``number-list`` may give its ``"length"``.
check
    None | ``"positive"`` | ``"nonnegative"`` | ``"nonzero"`` | ``"nonempty"`` |
    ``"identifier"`` | ``"unique"`` | ``"increasing"`` | ``["min", v]`` | ``["one-of", [values]]``;
    a ``number-list`` checks each of its numbers.  ``"max"``: an upper bound of a number, ``"least"`` a lower one (a positive length too small to be meant).
optional, default
    A key left out is an error unless it is ``optional`` or has a ``default`` (then the checked
    table holds the default).

A table spec (a protocol section, or a ``"table"`` key's ``"keys"``) maps key names to key
specs; its entry :data:`OTHER_KEYS` (``"*"``), when present, is the table spec of every other
key, each of which must then be a table (a channel's table inside a device's, named freely).

Every failure is one :class:`~labcli.errors.ConfigError` sentence naming the source and the
key (:meth:`Checker.fail`)::

    my-rig.toml: key 'rig.h1_m' must be greater than 0, not -0.355.
"""

from __future__ import annotations

import math
import re
from collections.abc import Iterable
from typing import Any, NoReturn

from ..errors import ConfigError

OPEN = "open"  # a section kept as written, not checked
OTHER_KEYS = "*"  # a table spec's entry for the keys it does not name

_TYPE_TEXT = {
    "str": "a string",
    "int": "an integer",
    "number": "a number",
    "bool": "true or false",
    "str-list": "a list of strings",
    "number-list": "a list of numbers",
    "pair": "a list of two numbers [low, high]",
    "table": "a table",
}


def _is_number(v: Any) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)


class Checker:
    """Checks values against key specs; every failure is one ConfigError naming the source."""

    def __init__(self, source: str) -> None:
        self.source = source

    def fail(self, message: str) -> NoReturn:
        raise ConfigError(f"{self.source}: {message}")

    def value(self, v: Any, spec: dict[str, Any], key: str) -> Any:
        """One value against one key spec; the value converted (numbers as floats)."""
        t = spec["type"]
        if t == "table":
            return self.table(v, spec["keys"], key + ".")
        if t == "number-list":
            return self._numbers(v, spec, key)
        if t == "str" and not isinstance(v, str):
            self._wrong(v, spec, key)
        elif t == "int" and (isinstance(v, bool) or not isinstance(v, int)):
            self._wrong(v, spec, key)
        elif t == "bool" and not isinstance(v, bool):
            self._wrong(v, spec, key)
        elif t == "number":
            if not _is_number(v):
                self._wrong(v, spec, key)
            if not math.isfinite(v):
                self.fail(f"key '{key}' must be a finite number, not {show(v)}.")
            v = float(v)
        elif t == "str-list":
            if not isinstance(v, list) or not all(isinstance(x, str) for x in v):
                self._wrong(v, spec, key)
            if not v:
                self.fail(f"key '{key}' must list at least one name.")
        elif t == "pair":
            v = self._pair(v, spec, key)
        self._check(v, spec.get("check"), key)
        if "max" in spec and v > spec["max"]:
            unit = f" {spec['unit']}" if spec.get("unit") else ""
            limit = spec["max"]
            text = f"{limit:g}" if isinstance(limit, float) else str(limit)
            self.fail(f"key '{key}' must be at most {text}{unit}, not {show(v)}.")
        if "least" in spec and v < spec["least"]:  # a positive value too small to be meant
            unit = f" {spec['unit']}" if spec.get("unit") else ""
            self.fail(f"key '{key}' must be at least {spec['least']:g}{unit}, not {show(v)}.")
        return v

    def _pair(self, v: Any, spec: dict[str, Any], key: str) -> list[float]:
        if not isinstance(v, list) or len(v) != 2 or not all(_is_number(x) for x in v):
            self._wrong(v, spec, key)
        if any(math.isnan(x) for x in v):
            self.fail(f"key '{key}' must be two numbers, not {show(v)}.")
        if v[0] == -math.inf:
            self.fail(f"key '{key}' must have a finite low end, not {show(v)}.")
        return [float(x) for x in v]

    def _numbers(self, v: Any, spec: dict[str, Any], key: str) -> list[float]:
        n = spec.get("length")
        if not isinstance(v, list) or not all(_is_number(x) for x in v) or (n is not None and len(v) != n):
            self._wrong(v, spec, key)
        if not v:
            self.fail(f"key '{key}' must list at least one number.")
        if not all(math.isfinite(x) for x in v):
            self.fail(f"key '{key}' must hold finite numbers, not {show(v)}.")
        for x in v:
            self._check(float(x), spec.get("check"), key)
        return [float(x) for x in v]

    def _wrong(self, v: Any, spec: dict[str, Any], key: str) -> NoReturn:
        self.fail(f"key '{key}' must be {describe(spec)}, not {kind_of(v)} {show(v)}.")

    def _check(self, v: Any, check: Any, key: str) -> None:
        if check is None:
            return
        bad = None
        if check == "positive" and not v > 0:
            bad = "greater than 0"
        elif check == "nonnegative" and not v >= 0:
            bad = "at least 0"
        elif check == "nonzero" and v == 0:
            bad = "non-zero"
        elif check == "nonempty" and not v.strip():
            bad = "a non-empty string"
        elif check == "identifier" and not re.fullmatch(r"[A-Za-z0-9][A-Za-z0-9_.-]*", v):
            bad = "letters, digits, '-', '_' or '.'"
        elif check == "unique" and len(set(v)) != len(v):
            dup = sorted({x for x in v if v.count(x) > 1})
            self.fail(f"key '{key}' must list each name once, but {', '.join(dup)} repeats.")
        elif check == "increasing" and not v[0] < v[1]:
            bad = "[low, high] with low < high"
        elif isinstance(check, list) and check[0] == "min" and not v >= check[1]:
            bad = f"at least {check[1]}"
        elif isinstance(check, list) and check[0] == "one-of" and v not in check[1]:
            bad = f"one of {', '.join(str(x) for x in check[1])}"
        if bad is not None:
            self.fail(f"key '{key}' must be {bad}, not {show(v)}.")

    def table(self, data: Any, spec: dict[str, Any], prefix: str) -> dict[str, Any]:
        """A table against a table spec; returns the checked, converted values."""
        if not isinstance(data, dict):
            self.fail(f"key '{prefix.rstrip('.')}' must be a table, not {kind_of(data)} {show(data)}.")
        named = {k: s for k, s in spec.items() if k != OTHER_KEYS}
        other = spec.get(OTHER_KEYS)
        for k in data:
            if k not in named and other is None:
                self.fail(f"unknown key '{prefix}{k}'; the keys allowed there are {', '.join(named)}.")
        out: dict[str, Any] = {}
        for k, kspec in named.items():
            if k in data:
                out[k] = self.value(data[k], kspec, prefix + k)
            elif "default" in kspec:
                out[k] = kspec["default"]
            elif not kspec.get("optional"):
                self.fail(f"missing key '{prefix}{k}', expected {describe(kspec)}.")
        for k in data:
            if k not in named:
                out[k] = self.table(data[k], other, f"{prefix}{k}.")  # type: ignore[arg-type]
        return out


def describe(spec: dict[str, Any]) -> str:
    """What a key spec asks for, for a sentence: ``a number in m (the link length)``."""
    text = _TYPE_TEXT[spec["type"]]
    if spec["type"] == "number-list" and spec.get("length"):
        text = f"a list of {spec['length']} numbers"
    unit = spec.get("unit")
    if unit:
        text += f" in {unit}"
    if spec.get("help"):
        text += f" ({spec['help']})"
    return text


def kind_of(v: Any) -> str:
    """What a TOML value is, for a sentence: ``the integer``, ``a table``..."""
    if isinstance(v, bool):
        return "the boolean"
    if isinstance(v, int):
        return "the integer"
    if isinstance(v, float):
        return "the number"
    if isinstance(v, str):
        return "the string"
    if isinstance(v, list):
        return "the list"
    if isinstance(v, dict):
        return "a table"
    return "the date/time"


def show(v: Any) -> str:
    """A TOML value as a sentence shows it (long strings, lists and tables cut short)."""
    if isinstance(v, dict):
        return "{" + ", ".join(list(v)[:4]) + (", ..." if len(v) > 4 else "") + "}"
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, str):
        s = v if len(v) <= 40 else v[:37] + "..."
        return repr(s)
    if isinstance(v, float):
        return repr(v)
    if isinstance(v, list):
        s = "[" + ", ".join(show(x) for x in v[:6]) + (", ..." if len(v) > 6 else "") + "]"
        return s
    return str(v)


def fmt_num(x: float) -> str:
    """A number in a sentence: six significant digits, ``inf`` as such."""
    if math.isinf(x):
        return "inf" if x > 0 else "-inf"
    return f"{x:.6g}"


def or_list(values: Iterable[Any]) -> str:
    """``A, B or C``."""
    items = [str(v) for v in values]
    return items[0] if len(items) == 1 else ", ".join(items[:-1]) + " or " + items[-1]
