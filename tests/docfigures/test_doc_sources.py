"""The sources measured again: the pages' figures must still be what the code and the rig give.

``test_figures.py`` holds the pages to the files in docs/figures/; this holds the files' sources
to the code.  A fast source (constants read from the protocol files and the code) is measured
in every run; the seeded demos, the optimiser and the paper's scale take from seconds to minutes
and run with ``-m slow``.  A figure counts as drifted when the fresh value no longer rounds to
what a page shows (a transcript: when its text differs beyond its wall-clock seconds); the fix
is ``python tests/docfigures/regenerate.py SOURCE --docs``.  The benchmarks (many seeds, or
timings) are not measured here: regenerate.py runs them, and the pages are held to their files.
"""

from __future__ import annotations

import doc_markers as markers
import pytest
from doc_markers import mask_times
from doc_sources import SOURCES


def _drift(name: str) -> list[str]:
    fresh = SOURCES[name].produce()
    problems = []
    for mark in markers.check_pages()[0]:
        if mark.source != name:
            continue
        if mark.name not in fresh:
            problems.append(f"{mark.where()}: the source no longer gives this figure")
        elif mark.block and isinstance(fresh[mark.name], str):
            if mask_times(mark.text) != mask_times(fresh[mark.name]):
                problems.append(f"{mark.where()}: the text the source prints now differs")
        elif not mark.block and not markers.matches(mark.text, fresh[mark.name]):
            problems.append(f"{mark.where()}: the page shows {mark.text}, the source now gives {fresh[mark.name]!r}")
    return problems


FAST = [s.name for s in SOURCES.values() if s.kind == "fast"]
SLOW = [s.name for s in SOURCES.values() if s.kind == "slow"]


@pytest.mark.parametrize("name", FAST)
def test_fast_sources_give_the_figures_the_pages_show(name):
    problems = _drift(name)
    assert not problems, "\n".join(problems)


@pytest.mark.slow
@pytest.mark.parametrize("name", SLOW)
def test_slow_sources_give_the_figures_the_pages_show(name):
    problems = _drift(name)
    assert not problems, "\n".join(problems)


def test_mask_times_blanks_only_wall_clock_seconds():
    line = "labcli demo on the simulated rig (seed 1): 108 force trials, 60 pushes, 37.7 s."
    assert mask_times(line) == "labcli demo on the simulated rig (seed 1): 108 force trials, 60 pushes, #.# s."
    assert (
        mask_times("RMSE 0.161 N; chi^2 3.26 (4 degrees of freedom)")
        == "RMSE 0.161 N; chi^2 3.26 (4 degrees of freedom)"
    )
