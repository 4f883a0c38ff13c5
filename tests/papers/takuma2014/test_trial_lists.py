"""The fitted-trial lists of a model on a random split: written once however often they appear, the
validation trials told apart and the overlap found as before.

* One equation's ranges shared by the others stay one list through ``to_dict`` (the paper form's
  four equations, and the posture form's paper part), so the writer encodes them once; the
  file's value is the same as every list written out on its own.
* ``in_set`` picks the rows ``table["set"].astype(str) == name`` picks, missing and odd values
  included.
* ``overlap`` on a model whose trials are ranges as read (sorted, merged) finds the validation
  trials a merge of the same pairs finds.
"""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest

from labcli.core import idranges
from labcli.core.provenance import table_identity
from labcli.papers.takuma2014.analyses import in_set, overlap
from labcli.papers.takuma2014.models.posture import PostureModel, force_model_from_json
from labcli.papers.takuma2014.models.synthetic import PAPER_GEOMETRY, paper_trials
from labcli.papers.takuma2014.models.takuma import EQUATIONS, TakumaModel


@pytest.fixture(scope="module")
def random_split() -> pd.DataFrame:
    """1200 trials, every sixth in the validation set: 200 ranges of fit trials."""
    t = paper_trials(1200, seed=5, noise=True)
    t["set"] = np.where(np.arange(len(t)) % 6 == 5, "validation", "fit")
    return t


def test_the_paper_forms_shared_ranges_are_one_list_and_read_back_the_same(random_split):
    model = TakumaModel(geometry=PAPER_GEOMETRY).fit(random_split)
    ranges = model.fitted_trials
    assert len(ranges["theta1"]) == 200  # long enough for the writer's one-line form
    d = model.to_dict()
    shared = [d["fitted_trials"][eq] for eq in EQUATIONS]
    assert all(r is shared[0] for r in shared)  # one list, so encoded once
    # The file holds the same value as each list written on its own.
    written = json.loads(model.to_json())
    alone = json.loads(json.dumps({eq: [list(p) for p in ranges[eq]] for eq in EQUATIONS}))
    assert written["fitted_trials"] == alone
    fit_ids = random_split.loc[random_split["set"] == "fit", "trial"].to_numpy()
    assert idranges.count(written["fitted_trials"]["Fx"]) == len(fit_ids)
    again = TakumaModel.from_json(model.to_json())
    assert again.fitted_trials == ranges


def test_the_posture_forms_paper_part_writes_its_shared_ranges_once(random_split):
    model = PostureModel(geometry=PAPER_GEOMETRY).fit(random_split)
    if model.paper_model is None:
        pytest.skip("no quantity took the paper's route on this table")
    d = model.to_dict()
    part = d["paper_model"]["fitted_trials"]
    assert all(part[eq] is part[EQUATIONS[0]] for eq in EQUATIONS)
    # Fitted on the same trials as the posture form's own: the one list, written once.
    assert part["Fx"] == model.fitted_trials and part["Fx"] is d["fitted_trials"]
    # Its calibrated range is the posture form's, taken over: what a fit of its own on the same
    # labels (corrected for the pots' play here: 1200 trials) works out.
    labels = PostureModel(geometry=PAPER_GEOMETRY)._unplayed(random_split, "the table")
    own = TakumaModel(geometry=PAPER_GEOMETRY, label_play="none").fit(labels, record_trials=False)
    assert d["paper_model"]["calibrated_range"] == model.calibrated_range == own.calibrated_range
    assert model.play.get("play_deg")  # the labels were corrected: the range is theirs
    text = model.to_json()
    assert json.loads(text)["paper_model"]["fitted_trials"] == json.loads(json.dumps(part))
    assert force_model_from_json(text, name="the model").fitted_trials == model.fitted_trials


def test_in_set_picks_the_rows_a_comparison_as_strings_picks():
    rng = np.random.default_rng(3)
    pool = np.array(["fit", "validation", "", "Validation", " fit", "validation ", None, np.nan], dtype=object)
    table = pd.DataFrame({"set": pd.Series(pool[rng.integers(0, len(pool), 500)], dtype=object)})
    for name in ("fit", "validation", "", "Validation"):
        expected = (table["set"].astype(str) == name).to_numpy()
        assert expected.any() or name == ""
        np.testing.assert_array_equal(in_set(table, name), expected)


def test_overlap_on_ranges_as_read_is_the_merges(random_split, tmp_path):
    ids = random_split["trial"].to_numpy()
    val = ids[random_split["set"].to_numpy() == "validation"]
    # The model was fitted on the fit trials and, wrongly, on every third validation trial.
    fitted_ids = np.sort(np.r_[ids[random_split["set"].to_numpy() == "fit"], val[::3]])
    as_read = idranges.to_ranges(fitted_ids)
    scattered = [list(p) for p in reversed(as_read)]  # the same pairs, out of order: merged first
    identity = table_identity(tmp_path / "t.csv", None)

    class Source:
        table = random_split
        path = tmp_path / "t.csv"

    Source.identity = identity
    found = []
    for ft in (as_read, scattered):
        model = PostureModel(geometry=PAPER_GEOMETRY, fitted_trials=ft, fitted_on=identity)
        found.append(overlap(model, Source))
    assert found[0] == found[1] == sorted(val[::3].tolist())


def test_a_posture_model_read_back_writes_the_file_it_was_read_from(random_split, tmp_path):
    model = PostureModel(geometry=PAPER_GEOMETRY).fit(random_split)
    if model.paper_model is None:
        pytest.skip("no quantity took the paper's route on this table")
    path = tmp_path / "m.json"
    path.write_text(model.to_json())
    first = path.read_text()
    # 200 ranges: the fit writes each list on one line, not one number a line.
    assert len(first.splitlines()) < 1000
    again = force_model_from_json(first, name="the model")
    assert again.to_json() == first
    # Read back, the paper part's lists are the posture form's one list again (written once).
    d = again.to_dict()
    assert all(d["paper_model"]["fitted_trials"][eq] is d["fitted_trials"] for eq in EQUATIONS)
    # Twice round: the same text.
    assert force_model_from_json(again.to_json(), name="the model").to_json() == first


@pytest.mark.parametrize("baseline_mean", [1, 3])
def test_the_posture_forms_calibrated_range_is_the_tables_over_its_fit_rows(random_split, baseline_mean):
    """The fit's own columns stand in for the table's only where they are the table's: a running
    baseline's P0 is not, and its range is still the pressures as read."""
    from labcli.papers.takuma2014.models.calibrated import calibrated_range

    table = random_split.copy()
    table.loc[table.index[7], "P_L10"] += 0.05  # one baseline far from the rest: the mean moves it
    model = PostureModel(geometry=PAPER_GEOMETRY, label_play="none", baseline_mean=baseline_mean)
    model.fit(table, choose_routes=False)
    fit = (table["set"] == "fit").to_numpy()
    expected = calibrated_range(table, fit)
    assert model.calibrated_range == expected
    assert expected["P0_MPa"][0][1] == table.loc[fit, "P_L10"].max()
    # A table without force columns: no force range, the rest as before.
    bare = table.drop(columns=["Fx_N"])
    assert "F_N" not in calibrated_range(bare, fit)
