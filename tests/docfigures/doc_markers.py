"""Figures quoted in the README and docs/, tied to the JSON their scripts write.

A page marks every figure it quotes with the key of its value, in an HTML comment that GitHub
does not render:

* a number: ``<!--fig:demo.accuracy.Fx.rmse-->0.202``.  The figure is the number right after
  the comment (digits, an optional sign, thousands commas, decimals, an exponent).  It matches
  its value when the value rounds to it at the decimals shown: 0.202 stands for anything in
  [0.2015, 0.2025], 42 for [41.5, 42.5].  So the page chooses the precision and the value keeps
  all of it.
* a text (a transcript, a table, a phrase): ``<!--text:demo.transcript-->`` on its own line, the
  block, then ``<!--/text-->`` on its own line; or inline, ``<!--text:KEY-->a phrase<!--/text-->``.
  The text between must equal the value, a string, exactly, but for a transcript's wall-clock
  seconds ("60 pushes, 37.7 s."), which are the machine's that ran it.

The key's first part, up to the first dot, names the source: ``docs/figures/<source>.json``, one
flat JSON object ``{name: value}`` (units in the names, as the benchmarks write them); the rest of
the key is a name in it (dots and spaces allowed).  ``tests/docfigures/regenerate.py`` writes those files
(``doc_sources.py`` says how each is measured) and, with ``--docs``, rewrites the marked figures in
place at the precision each page shows.
"""

from __future__ import annotations

import json
import math
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[2]
FIGURES = ROOT / "docs" / "figures"

NUMBER = r"[-+−]?(?:\d{1,3}(?:,\d{3})+|\d+)(?:\.\d+)?(?:[eE][-+]?\d+)?"
_OPEN = re.compile(r"<!--(fig|text):(\w.*?)-->")  # a key may hold ">" (">= 0.9"), not "-->"
_CLOSE = "<!--/text-->"


@dataclass(frozen=True)
class Mark:
    page: str
    line: int
    key: str
    text: str  # as the page shows it
    start: int  # offsets of ``text`` in the page
    end: int
    block: bool  # a closed marker (text, block) rather than a number

    @property
    def source(self) -> str:
        return self.key.split(".", 1)[0]

    @property
    def name(self) -> str:
        return self.key.split(".", 1)[1] if "." in self.key else ""

    def where(self) -> str:
        return f"{self.page}:{self.line}: {self.key}"


class MarkError(ValueError):
    pass


def pages(root: Path = ROOT) -> list[Path]:
    """The pages whose figures are checked: the README and every page under docs/."""
    return [root / "README.md", *sorted((root / "docs").rglob("*.md"))]


_FENCE = re.compile(r"^(```|~~~).*?^\1[ \t]*$", flags=re.S | re.M)


def marks(text: str, page: str = "<text>") -> list[Mark]:
    """Every marked figure of ``text``, in order; a marker with nothing it can mark is an error.

    A marker inside a fenced code block is an example of one, not a marker (a marked block puts
    its markers outside the fence)."""
    out = []
    fences = [(f.start(), f.end()) for f in _FENCE.finditer(text)]
    for m in _OPEN.finditer(text):
        if any(a <= m.start() < b for a, b in fences):
            continue
        line = text.count("\n", 0, m.start()) + 1
        kind, key, after = m.group(1), m.group(2), m.end()
        if kind == "text":
            close = text.find(_CLOSE, after)
            if close < 0:
                raise MarkError(f"{page}:{line}: {m.group(0)} has no {_CLOSE}")
            start, end = after, close
            if text.startswith("\n", after):  # a block: the lines between the two markers
                start, end = after + 1, close - 1 if text[close - 1 : close] == "\n" else close
            out.append(Mark(page, line, key, text[start:end], start, end, True))
            continue
        n = re.match(NUMBER, text[after:])
        if not n:
            raise MarkError(f"{page}:{line}: {m.group(0)} is followed by no number")
        out.append(Mark(page, line, key, n.group(0), after, after + n.end(), False))
    return out


def parse_number(text: str) -> tuple[float, int]:
    """The number a page shows and its decimals: '1,454' -> (1454.0, 0), '−0.73' -> (-0.73, 2)."""
    t = text.replace(",", "").replace("−", "-")
    mant = re.split(r"[eE]", t)[0]
    decimals = len(mant.split(".")[1]) if "." in mant else 0
    if re.search(r"[eE]", t):
        decimals -= int(re.split(r"[eE]", t)[1])
    return float(t), decimals


def matches(shown: str, value: Any) -> bool:
    """Does the number ``shown`` stand for ``value`` at the decimals it shows?"""
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        return False
    number, decimals = parse_number(shown)
    half = 0.5 * 10.0 ** (-decimals)
    return abs(value - number) <= half * (1 + 1e-9) + 1e-12 * abs(value)


def render(shown: str, value: float) -> str:
    """``value`` written the way ``shown`` is: the same decimals, sign style and thousands commas."""
    if re.search(r"[eE]", shown):
        mantissa = re.split(r"[eE]", shown)[0]
        return f"{value:.{len(mantissa.split('.')[1]) if '.' in mantissa else 0}e}"
    _, decimals = parse_number(shown)
    text = f"{value:{',' if ',' in shown else ''}.{decimals}f}"
    if shown.startswith("+") and value >= 0:
        text = "+" + text
    return text.replace("-", "−") if "−" in shown else text


def mask_times(text: str) -> str:
    """A transcript with its wall-clock seconds blanked ("..., 60 pushes, 37.7 s."): they are the
    machine's that ran it, not the code's, so they neither fail a check nor churn a page."""
    return re.sub(r"\b\d+\.\d s\.", "#.# s.", text)


def load(source: str, root: Path = ROOT) -> dict[str, Any]:
    path = root / "docs" / "figures" / f"{source}.json"
    try:
        return json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise MarkError(f"no {path.relative_to(root)} (run python tests/docfigures/regenerate.py {source})") from None


def check(mark: Mark, figures: dict[str, Any]) -> str | None:
    """Why ``mark`` does not match ``figures`` (a source's mapping), or None when it does."""
    if mark.name not in figures:
        return f"{mark.where()}: no figure {mark.name!r} in docs/figures/{mark.source}.json"
    value = figures[mark.name]
    if mark.block:
        if not isinstance(value, str):
            return f"{mark.where()}: the value is {value!r}, not a text"
        if mask_times(mark.text) != mask_times(value):
            return f"{mark.where()}: the page's text differs from the source's (regenerate with --docs)"
        return None
    if not matches(mark.text, value):
        return f"{mark.where()}: the page shows {mark.text} but the source says {value!r}"
    return None


def check_pages(root: Path = ROOT, values: dict[str, dict[str, Any]] | None = None) -> tuple[list[Mark], list[str]]:
    """Every mark of every page, and what is wrong with them (``values``: source -> figures)."""
    values = {} if values is None else values
    found, problems = [], []
    for path in pages(root):
        page = path.relative_to(root).as_posix()
        try:
            page_marks = marks(path.read_text(encoding="utf-8"), page)
        except MarkError as e:
            problems.append(str(e))
            continue
        for mark in page_marks:
            found.append(mark)
            if mark.source not in values:
                try:
                    values[mark.source] = load(mark.source, root)
                except MarkError as e:
                    problems.append(f"{mark.where()}: {e}")
                    values[mark.source] = {}
                    continue
            problem = check(mark, values[mark.source])
            if problem:
                problems.append(problem)
    return found, problems


def rewrite(text: str, values: dict[str, dict[str, Any]], page: str = "<text>") -> tuple[str, list[str]]:
    """``text`` with each marked figure written from ``values`` at its shown precision; the changes."""
    changes, out, pos = [], [], 0
    for mark in marks(text, page):
        figures = values.get(mark.source)
        if figures is None or mark.name not in figures:
            continue
        value = figures[mark.name]
        if mark.block:
            same = isinstance(value, str) and mask_times(value) == mask_times(mark.text)
            new = value if isinstance(value, str) and not same else mark.text
        elif matches(mark.text, value) or isinstance(value, (str, bool)) or value is None:
            new = mark.text
        else:
            new = render(mark.text, float(value))
        if new != mark.text:
            changes.append(
                f"{mark.where()}: {mark.text if not mark.block else '(block)'} -> {new if not mark.block else '(block)'}"
            )
        out.append(text[pos : mark.start])
        out.append(new)
        pos = mark.end
    out.append(text[pos:])
    return "".join(out), changes
