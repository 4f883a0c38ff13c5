"""Figures say what they show and where it came from: Figure 9 names methods and categories as
they are, Figure 6 marks the fitted range and the default held constant, Figure 8 puts model and
measured contours on one axis beside a residual map, and every figure names its run, protocol and
model (its text read from an SVG written with text kept as text)."""

from __future__ import annotations

import html
import shutil
from pathlib import Path

import matplotlib
import pytest
from click.testing import CliRunner

from labcli.cli import cli

SAMPLE = Path(__file__).resolve().parents[2] / "sample_runs"


def svg_text(args: list[str], out: Path) -> str:
    with matplotlib.rc_context({"svg.fonttype": "none"}):
        r = CliRunner().invoke(cli, [*args, "--plot", str(out)])
    assert r.exit_code == 0, r.output
    return html.unescape(out.read_text())


@pytest.fixture
def here(tmp_path: Path) -> Path:
    for name in ("pushes.h5", "stretch.h5", "joint.h5", "bent.h5", "force.model.json", "stretch.model.json"):
        shutil.copy(SAMPLE / name, tmp_path / name)
    return tmp_path


def test_figure9_names_the_method_and_what_a_known_category_is(here: Path) -> None:
    args = ["classify", str(here / "pushes.h5"), "--model", str(here / "force.model.json")]
    bands = svg_text([*args, "--method", "bands"], here / "bands.svg")
    assert "categories by the protocol's stiffness bands" in bands
    assert "given: soft" in bands and "given: hard" in bands and "reference (" not in bands
    assert "run pushes.h5 · protocol takuma2014-stiffness · model force.model.json" in bands
    refs = svg_text([*args, "--method", "reference"], here / "refs.svg")
    assert "nearest reference class" in refs and "reference (soft)" in refs and "given:" not in refs


def test_figure6_marks_the_fitted_range_and_the_default_held_constant(here: Path) -> None:
    text = svg_text(["fit", str(here / "stretch.h5"), "-o", str(here / "s.json")], here / "f6.svg")
    assert "cubic fit, fitted on" in text and "1.00–2.84" in text
    assert "protocol's default, made for" in text and "1.00–2.20" in text
    assert "default held at its end value" in text
    assert "run stretch.h5 · protocol rpam2015 · model s.json" in text


def test_figure8_is_model_against_measured_on_one_axis_and_a_residual_map(here: Path) -> None:
    text = svg_text(["validate", str(here / "joint.h5"), "--model", str(here / "stretch.model.json")], here / "f8.svg")
    assert "measured against the model" in text and "(b) residual: model with" in text
    assert "measured (deg)" in text  # the residual scale
    assert "run joint.h5 · protocol rpam2015 · model stretch.model.json" in text
    # Two panels now, not three.
    assert "(c) measured" not in text


def test_figure7_names_the_protocol_in_its_title(here: Path) -> None:
    text = svg_text(["validate", str(here / "bent.h5")], here / "f7.svg")
    assert "protocol takuma2014-bent" in text
    assert "run bent.h5 · protocol takuma2014-bent · model bent.h5:/models/takuma2014-bent" in text
