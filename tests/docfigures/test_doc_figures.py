"""Every figure the README and docs/ quote matches the file its source wrote (docs/figures/*.json).

Fast: it reads the pages and the JSON files only.  A figure that drifts from its source (a page
edited by hand, a source measured again without ``--docs``) fails here, naming the page, the
line, the key and both values.  ``test_doc_sources.py`` measures the sources again.
"""

from __future__ import annotations

import json

import doc_markers as markers
import pytest
from doc_sources import SOURCES


def test_every_marked_figure_matches_its_source():
    found, problems = markers.check_pages()
    assert not problems, "\n".join(problems)
    # The pages quote figures from most sources; a marker-less README would pass vacuously.
    assert len(found) > 100
    assert {m.page for m in found} >= {"README.md", "docs/fit-and-validate.md", "docs/rpam.md"}


def test_every_figure_file_has_a_source_and_is_flat():
    files = sorted(markers.FIGURES.glob("*.json"))
    assert files
    for path in files:
        assert path.stem in SOURCES, f"{path.name}: no source of that name in sources.py"
        figures = json.loads(path.read_text(encoding="utf-8"))
        assert isinstance(figures, dict)
        bad = [k for k, v in figures.items() if isinstance(v, (dict, list))]
        assert not bad, f"{path.name}: nested values {bad[:3]} (the file is one flat object)"


def test_every_marked_source_is_registered():
    used = {m.source for m in markers.check_pages()[0]}
    assert used <= set(SOURCES), used - set(SOURCES)


# ----------------------------------------------------------------------------- the rules


@pytest.mark.parametrize(
    "shown, value, ok",
    [
        ("0.202", 0.20219615, True),
        ("0.20", 0.20219615, True),
        ("0.203", 0.20219615, False),
        ("0.2", 0.2499, True),
        ("0.2", 0.2501, False),
        ("42", 42.4, True),
        ("42", 42.6, False),
        ("1,454", 1454.3, True),
        ("−0.73", -0.7349, True),
        ("-0.73", 0.73, False),
        ("+1.37", 1.3651, True),
        ("2e-13", 2.4e-13, True),
        ("3e-14", 2.8e-14, True),
        ("3e-14", 4e-14, False),
        ("0", 0.4, True),
        ("108", 108, True),
        ("108", 107, False),
    ],
)
def test_a_number_matches_its_value_at_the_decimals_shown(shown, value, ok):
    assert markers.matches(shown, value) is ok


@pytest.mark.parametrize("value", [float("nan"), float("inf"), None, "0.2", True])
def test_a_number_never_matches_what_is_not_a_finite_number(value):
    assert not markers.matches("0.2", value)


def test_marks_numbers_texts_and_blocks():
    text = (
        "RMSE <!--fig:demo.Fx-->0.202 N and <!--fig:demo.n-->1,454 objects; "
        "<!--text:optimize.active-->g4: L3 at lower bound<!--/text--> ends it.\n"
        "<!--text:demo.transcript-->\n```text\nline one\n```\n<!--/text-->\nafter\n"
    )
    got = markers.marks(text, "p.md")
    assert [(m.key, m.text, m.block, m.line) for m in got] == [
        ("demo.Fx", "0.202", False, 1),
        ("demo.n", "1,454", False, 1),
        ("optimize.active", "g4: L3 at lower bound", True, 1),
        ("demo.transcript", "```text\nline one\n```", True, 2),
    ]
    assert got[0].source == "demo" and got[0].name == "Fx"
    assert text[got[3].start : got[3].end] == got[3].text


def test_a_key_may_hold_a_comparison():
    # classify_heldout.py's "fit wrong with confidence >= 0.9": a ">" once ended the key's match, so
    # such a figure was no marker at all and a page kept a stale count unchecked.
    (mark,) = markers.marks("wrong: <!--fig:classify-heldout.none wrong with confidence >= 0.9-->0 of 120")
    assert (mark.key, mark.text) == ("classify-heldout.none wrong with confidence >= 0.9", "0")
    assert "the source says 1" in markers.check(mark, {"none wrong with confidence >= 0.9": 1})


@pytest.mark.parametrize(
    "text, why",
    [("<!--fig:demo.x--> 0.2", "followed by no number"), ("<!--text:demo.x-->abc", "has no <!--/text-->")],
)
def test_a_marker_with_nothing_to_mark_is_an_error(text, why):
    with pytest.raises(markers.MarkError, match=why):
        markers.marks(text)


def test_check_names_the_page_line_key_and_both_values():
    (mark,) = markers.marks("x\n<!--fig:demo.Fx-->0.232", "README.md")
    assert (
        markers.check(mark, {"Fx": 0.20219}) == "README.md:2: demo.Fx: the page shows 0.232 but the source says 0.20219"
    )
    assert "no figure 'Fx'" in markers.check(mark, {})
    assert markers.check(mark, {"Fx": 0.2321}) is None


def test_rewrite_keeps_each_pages_precision_and_style():
    text = "a <!--fig:s.x-->0.232, b <!--fig:s.y-->1,454, c <!--fig:s.z-->−0.73, d <!--fig:s.w-->+1.4\n"
    text += "<!--text:s.t-->\nold\n<!--/text-->\n"
    values = {"s": {"x": 0.20219, "y": 1796.2, "z": -0.61, "w": 1.44, "t": "new\nlines"}}
    new, changes = markers.rewrite(text, values)
    assert new == (
        "a <!--fig:s.x-->0.202, b <!--fig:s.y-->1,796, c <!--fig:s.z-->−0.61, d <!--fig:s.w-->+1.4\n"
        "<!--text:s.t-->\nnew\nlines\n<!--/text-->\n"
    )
    assert len(changes) == 4  # w still rounds to +1.4
    assert markers.rewrite(new, values)[1] == []


@pytest.mark.parametrize("summary, source", [("summary.json", "demo"), ("rpam-summary.json", "rpam-demo")])
def test_the_sample_runs_are_the_demo_the_pages_quote(summary, source):
    """sample_runs/ (whose figures the pages show) and docs/figures/ come from the same seeded demo:
    regenerate one, regenerate the other (`labcli demo sample_runs --seed 1 --force`)."""
    from doc_sources import ROOT, flatten

    data = json.loads((ROOT / "sample_runs" / summary).read_text(encoding="utf-8"))
    for k in ("files", "outdir", "timings_s"):
        data.pop(k, None)
    sample, quoted = flatten(data), markers.load(source)
    assert set(sample) <= set(quoted), sorted(set(sample) - set(quoted))[:5]
    differ = [
        k
        for k, v in sample.items()
        if not (
            v == quoted[k]
            or (isinstance(v, float) and isinstance(quoted[k], float) and abs(v - quoted[k]) <= 1e-6 * abs(v))
        )
    ]
    assert not differ, [(k, sample[k], quoted[k]) for k in differ[:5]]


def test_a_marker_inside_a_fenced_block_is_an_example_not_a_marker():
    text = "~~~markdown\nRMSE <!--fig:demo.x-->0.2\n<!--text:demo.t-->\n~~~\nreal <!--fig:demo.y-->1\n"
    assert [m.key for m in markers.marks(text)] == ["demo.y"]
