"""``labcli classify`` says which method made its categories and why."""

from __future__ import annotations

from pathlib import Path

from click.testing import CliRunner

from labcli.cli import cli
from labcli.papers.takuma2014.report import method_sentence

ROOT = Path(__file__).resolve().parents[2]
PUSHES, MODEL = ROOT / "sample_runs" / "pushes.csv", ROOT / "sample_runs" / "force.model.json"


def test_labelled_pushes_say_they_are_their_own_references_and_name_the_bands() -> None:
    r = CliRunner().invoke(cli, ["classify", str(PUSHES), "--model", str(MODEL)])
    assert r.exit_code == 0, r.output
    line = next(x for x in r.output.splitlines() if x.startswith("Categories by"))
    assert line.startswith(
        "Categories by reference objects: 6 of the objects carry a category (hard 1, medium 2, soft 3)"
    )
    assert "every object is a reference" in line and "hard: one reference, in-sample" in line
    assert line.endswith(
        "--method bands judges each object by the protocol's stiffness bands instead, as the demo does."
    )


def test_bands_say_so() -> None:
    r = CliRunner().invoke(cli, ["classify", str(PUSHES), "--model", str(MODEL), "--method", "bands"])
    assert r.exit_code == 0, r.output
    assert "Categories by the protocol's stiffness bands: each object's median k_o against fixed limits" in r.output


def test_unknown_objects_beside_references_are_not_called_in_sample() -> None:
    data = {
        "method": "reference",
        "objects": [
            {"role": "reference", "category_given": "soft"},
            {"role": "reference", "category_given": "soft"},
            {"role": "unknown"},
        ],
    }
    s = method_sentence(data)
    assert "2 of the objects carry a category (soft 2)" in s
    assert "in-sample" not in s and "every object is a reference" not in s
