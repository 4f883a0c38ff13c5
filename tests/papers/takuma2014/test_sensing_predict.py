"""New data through a fitted model: the sensing adapter, ``labcli predict``, the model file's new keys."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from labcli.errors import ConfigError, ModelError
from labcli.papers.takuma2014.models.metrics import evaluate
from labcli.papers.takuma2014.models.posture import load_force_model
from labcli.papers.takuma2014.predict import SUMMARY_FLAGS, count_flags, estimate_table, predict_file
from labcli.papers.takuma2014.records import RECORD_TYPES, load_trials
from labcli.papers.takuma2014.sensing import TakumaSensing
from labcli.sensing import load_model

SAMPLES = Path(__file__).resolve().parents[3] / "sample_runs"


@pytest.fixture(scope="module")
def fitted(tmp_path_factory):
    """The sample force run's trials as a CSV and the posture model `labcli fit` writes for it."""
    from click.testing import CliRunner

    from labcli.cli import cli

    d = tmp_path_factory.mktemp("predict")
    table = load_trials(SAMPLES / "force.h5")
    csv = d / "trials.csv"
    RECORD_TYPES["force"].write_csv(table, csv)
    model = d / "trials.model.json"
    r = CliRunner().invoke(cli, ["fit", str(csv), "-o", str(model)])
    assert r.exit_code == 0, r.output
    return d, csv, model, table


def test_the_estimates_are_validates_predictions(fitted, invoke):
    d, csv, model_path, table = fitted
    new = table.drop(columns=["theta1_deg", "theta2_deg", "Fx_N", "Fy_N", "set", "mass_g", "direction_deg"])
    new.to_csv(d / "new.csv", index=False)
    out = d / "estimates.csv"
    r = invoke("predict", d / "new.csv", "--model", model_path, "-o", out)
    assert r.exit_code == 0, r.output
    assert r.output.startswith(f"Estimated 108 rows with {model_path} to {out}")
    got = pd.read_csv(out)
    model = load_force_model(model_path)
    ev = evaluate(model, table)  # validate's own path, on the validation trials
    val = got[table["set"] == "validation"]
    for q, col in (("theta1", "theta1_deg"), ("theta2", "theta2_deg"), ("Fx", "Fx_N"), ("Fy", "Fy_N")):
        np.testing.assert_allclose(val[col], ev["calculated"][q], rtol=1e-9, atol=1e-9)
        np.testing.assert_allclose(val[col + "_se"], ev["se"][q], rtol=1e-9, atol=1e-12)
    assert list(got["trial"]) == list(table["trial"])
    assert "Fx_N_true" not in got.columns


def test_truth_columns_are_carried_beside_the_estimates(fitted, invoke):
    d, csv, model_path, table = fitted
    out = d / "with-truth.csv"
    assert invoke("predict", csv, "--model", model_path, "-o", out).exit_code == 0
    got = pd.read_csv(out)
    np.testing.assert_allclose(got["Fx_N_true"], table["Fx_N"])
    assert got.columns.get_loc("Fx_N_true") < got.columns.get_loc("Fx_N")


def test_a_run_file_predicts_as_its_table(fitted, invoke, tmp_path):
    d, csv, model_path, table = fitted
    run = tmp_path / "force.h5"
    shutil.copy(SAMPLES / "force.h5", run)
    a, b = tmp_path / "a.csv", tmp_path / "b.csv"
    assert invoke("predict", run, "--model", model_path, "-o", a).exit_code == 0
    assert invoke("predict", csv, "--model", model_path, "-o", b).exit_code == 0
    pd.testing.assert_frame_equal(pd.read_csv(a)[["Fx_N", "Fx_N_se"]], pd.read_csv(b)[["Fx_N", "Fx_N_se"]])


def test_bad_inputs_are_one_sentence_each(fitted, invoke, tmp_path):
    d, csv, model_path, table = fitted
    r = invoke("predict", tmp_path / "none.csv", "--model", model_path)
    assert r.exit_code == 1
    assert (
        r.output
        == f"Error: {tmp_path / 'none.csv'} does not exist; pass a table (.csv) of pressures or a run file (.h5).\n"
    )
    r = invoke("predict", csv, "--model", tmp_path / "none.json")
    assert r.output == f"Error: The model file {tmp_path / 'none.json'} does not exist; write one with `labcli fit`.\n"
    table.drop(columns=["P_R2"]).to_csv(tmp_path / "short.csv", index=False)
    r = invoke("predict", tmp_path / "short.csv", "--model", model_path)
    assert r.exit_code == 1 and "P_R2" in r.output and "Traceback" not in r.output
    r = invoke("predict", csv, "--model", model_path, "-o", csv)
    assert r.exit_code == 1 and r.output.startswith(
        f"Error: Cannot write the estimates to {csv}: it is this command's input"
    )


def test_the_adapter_reports_unobservable_and_out_of_range(fitted):
    d, csv, model_path, table = fitted
    sens = load_model(model_path)
    assert isinstance(sens, TakumaSensing) and sens.kinds == ("state", "state", "load", "load")
    P0 = np.array([[0.3, 0.3, 0.3, 0.3]] * 3)
    P = P0 - np.array([[0.0, 0.0, 0.0, 0.0], [0.001, -0.001, 0.002, -0.002], [0.03, -0.03, 0.06, -0.06]])
    pred = sens.predict(P0, P, np.zeros((3, 2)))
    assert "unobservable:Fy" in pred.flags[0]  # a straight arm: the force along it makes no torque
    assert "out-of-range" in pred.flags[2]  # 30-60 kPa drops: far beyond the fit trials' loads
    assert not any(f.startswith("out-of-range") for f in pred.flags[1])
    bad = sens.predict(P0[:1], np.array([[0.3, -0.1, 0.3, 0.3]]), np.zeros((1, 2)))
    assert bad.flags[0] == ("bad-input",)


def test_model_files_say_how_their_baselines_were_taken(fitted, tmp_path):
    d, csv, model_path, table = fitted
    data = json.loads(model_path.read_text())
    assert data["baseline"] == {"p0_leak_corrected": False, "gap_s": None}  # a CSV carries no window times
    assert set(data["calibrated_range"]) == {"P0_MPa", "dP_MPa", "rest_deg", "theta_deg", "F_N"}
    old = {k: v for k, v in data.items() if k not in ("baseline", "calibrated_range")}
    (tmp_path / "old.json").write_text(json.dumps(old))
    m = load_model(tmp_path / "old.json")
    assert m.p0_leak_corrected is False and m.baseline_gap_s is None and m.calibrated_range == {}
    (tmp_path / "bad.json").write_text(json.dumps({**data, "baseline": {"p0_leak_corrected": "yes"}}))
    with pytest.raises(ModelError) as e:
        load_model(tmp_path / "bad.json")
    assert str(e.value) == (
        f"The model file {tmp_path / 'bad.json'}: key 'baseline' must hold p0_leak_corrected (true or false) and "
        "gap_s (seconds, or null); refit with `labcli fit`."
    )


def test_a_leak_corrected_fit_of_a_run_is_applied_with_corrected_baselines(tmp_path):
    from labcli.papers.takuma2014.analyses import fit, leak_handled
    from labcli.papers.takuma2014.models import leak
    from labcli.papers.takuma2014.models.inputs import load_trial_source
    from labcli.papers.takuma2014.options import FitOptions

    run = tmp_path / "force.h5"
    shutil.copy(SAMPLES / "force.h5", run)
    paper = FitOptions(form="paper")
    plain = fit(run, paper, output=tmp_path / "plain.json").model
    corrected = fit(run, paper, output=tmp_path / "corrected.json", leak_correct=True).model
    assert plain.p0_leak_corrected is False and corrected.p0_leak_corrected is True
    assert 5.0 < plain.baseline_gap_s < 30.0  # the protocol's wait for equilibrium and a capture
    assert corrected.baseline_gap_s == pytest.approx(plain.baseline_gap_s)
    moved = leak.corrected(load_trials(run), run, "test")
    times = leak.window_times(run)
    t = next(iter(times))
    row = load_trials(run).set_index("trial").loc[t]
    assert moved.set_index("trial").loc[t, "P_L10"] != pytest.approx(row["P_L10"], abs=1e-9)
    # validate applies the model to baselines moved the same way (and to the run's own otherwise).
    src = load_trial_source(run)
    assert leak_handled(plain, src, run) is src
    np.testing.assert_allclose(leak_handled(corrected, src, run).table["P_L10"], moved["P_L10"])
    csv = tmp_path / "trials.csv"
    RECORD_TYPES["force"].write_csv(load_trials(run), csv)
    with pytest.raises(ConfigError) as e:
        fit(csv, FitOptions(), output=tmp_path / "x.json", leak_correct=True)
    assert str(e.value).startswith("fit --leak-correct needs each trial's baseline and loaded window times")


def test_the_range_margin_is_the_share_of_the_calibrated_span_allowed_beyond_it(fitted, invoke, tmp_path):
    """``--range-margin`` (declared in the paper's options) moves the out-of-range edge: an
    estimate just past the fit trials' largest Fx is flagged with no margin, not with the default."""
    from labcli.core.options import Typed

    d, csv, model_path, table = fitted
    lo, hi = load_model(model_path).calibrated_range["F_N"][0]
    beyond = hi + 0.05 * (hi - lo)  # inside the default 10 % margin, outside a margin of 0
    for margin, flagged in ((0.0, True), (0.1, False)):
        sens = load_model(model_path, Typed({"range_margin": margin}, {}))
        assert sens.margin == margin
        got = sens._outside(np.zeros((1, 4)), np.zeros((1, 4)), np.zeros((1, 2)), np.array([[0, 0, beyond, 0]]))
        assert bool(got[1][0, 2]) is flagged
    counts = {}
    for margin in ("0", "0.1"):
        r = invoke("predict", csv, "--model", model_path, "--range-margin", margin, "--json")
        assert r.exit_code == 0, r.output
        counts[margin] = json.loads(r.output)["flagged"].get("out-of-range", 0)
    assert counts["0"] > counts["0.1"]  # the fit trials' own extremes sit on the span's edges
    r = invoke("predict", csv, "--model", model_path, "--range-margin", "-1")
    assert (
        r.exit_code == 2 and "Error: Invalid value for '--range-margin': -1.0 is not in the range 0<=x<=10." in r.output
    )


def test_a_friction_models_estimates_read_each_trials_history_as_validate_does(fitted, invoke, tmp_path):
    """With the friction terms each row's motion into its baseline comes from the row before it in
    trial order: ``labcli predict`` gives the validation trials what validate gives them (the first
    one's history from the last fit trial), and without that history its forces are others."""
    d, csv, _, table = fitted
    model_path = tmp_path / "friction.model.json"
    assert invoke("fit", csv, "--friction-terms", "-o", model_path).exit_code == 0
    model = load_force_model(model_path)
    assert model.uses_history
    out = tmp_path / "estimates.csv"
    shuffled = table.sample(frac=1.0, random_state=1)  # row order aside: the trial ids say which came before
    shuffled.to_csv(tmp_path / "shuffled.csv", index=False)
    assert invoke("predict", tmp_path / "shuffled.csv", "--model", model_path, "-o", out).exit_code == 0
    got = pd.read_csv(out).set_index("trial").loc[table["trial"]]
    ev = evaluate(model, table)
    val = got[(table["set"] == "validation").to_numpy()]
    for q, col in (("theta1", "theta1_deg"), ("theta2", "theta2_deg"), ("Fx", "Fx_N"), ("Fy", "Fy_N")):
        np.testing.assert_allclose(val[col], ev["calculated"][q], rtol=1e-9, atol=1e-9)
        np.testing.assert_allclose(val[col + "_se"], ev["se"][q], rtol=1e-9, atol=1e-12)
    sens = TakumaSensing(model)
    rows = table[table["set"] == "validation"]
    P0 = rows[["P_L10", "P_R10", "P_L20", "P_R20"]].to_numpy()
    P = rows[["P_L1", "P_R1", "P_L2", "P_R2"]].to_numpy()
    blind = sens.predict(P0, P, np.radians(rows[["theta1_0_deg", "theta2_0_deg"]].to_numpy()))
    assert np.min(np.abs(blind.values[:, 2] - val["Fx_N"].to_numpy())) > 0.1  # the history matters: 0.2-0.26 N


def _counted_row_by_row(column) -> dict[str, int]:
    """The summary's counts a row at a time: the plain formulation :func:`count_flags` must equal."""
    named = {f: sum(1 for v in column if isinstance(v, str) and f in v) for f in SUMMARY_FLAGS}
    return {f: n for f, n in named.items() if n}


def test_flag_counts_are_the_row_by_row_counts_and_the_summary_says_them(fitted, invoke, tmp_path):
    """Rows flagged out-of-range (pressures past the calibrated span) and not, and with missing
    truth or rest posture: the summary line names what a row-by-row count of the written flags
    gives, in the summary's order."""
    d, csv, model_path, table = fitted
    rows = table.drop(columns=["set", "mass_g", "direction_deg"]).reset_index(drop=True)
    rows.loc[[7, 8, 9], ["P_L1", "P_R1"]] *= 3.0
    rows.loc[[10, 11], "Fx_N"] = np.nan
    rows.loc[[12], ["theta1_0_deg", "theta2_0_deg"]] = np.nan
    rows.to_csv(tmp_path / "mixed.csv", index=False)
    out = tmp_path / "estimates.csv"
    r = invoke("predict", tmp_path / "mixed.csv", "--model", model_path, "-o", out)
    assert r.exit_code == 0, r.output
    written = pd.read_csv(out)["flags"]  # an unflagged row would read back as missing
    expected = _counted_row_by_row(written)
    assert 3 <= expected.get("out-of-range", 0) < len(rows)  # some rows flagged so, others not
    listed = ", ".join(f"{n} {f}" for f, n in expected.items())
    assert r.output == f"Estimated {len(rows)} rows with {model_path} to {out} ({listed}).\n"
    assert (
        json.loads(invoke("predict", tmp_path / "mixed.csv", "--model", model_path, "--json").output)["flagged"]
        == expected
    )


@pytest.mark.parametrize("dtype", [object, "str"])
def test_count_flags_matches_a_row_at_a_time_with_missing_values(dtype):
    values = ["", "unobservable:Fy", "unobservable:Fx;out-of-range:Fx", None, "bad-input", np.nan, "uncertain"]
    column = pd.Series(values * 5 + ["out-of-range:theta2"], dtype=dtype)
    assert count_flags(column) == _counted_row_by_row(column)
    assert count_flags(column) == {"unobservable": 10, "out-of-range": 6, "bad-input": 5}
    assert list(count_flags(column)) == list(SUMMARY_FLAGS)
    assert count_flags(pd.Series(["", "uncertain", None], dtype=dtype)) == {}


def test_a_carried_flags_column_is_not_counted(fitted, tmp_path):
    """A table that already holds a ``flags`` column (an earlier run's estimates) keeps it; the
    summary counts the new estimates' flags."""
    d, csv, model_path, table = fitted
    rows = table.drop(columns=["set", "mass_g", "direction_deg"]).assign(flags="bad-input")
    rows.loc[[1, 2], ["P_L1", "P_R1"]] *= 3.0
    rows.to_csv(tmp_path / "again.csv", index=False)
    result = predict_file(tmp_path / "again.csv", model_path=model_path)
    assert "bad-input" not in result.flagged and result.flagged.get("out-of-range", 0) >= 2
    assert result.flagged == _counted_row_by_row(result.table["flags"].iloc[:, -1])


def test_bad_input_rows_are_counted_as_a_row_at_a_time_counts_them(fitted):
    """A pressure of 0 (a run's record, not a checked table) flags its row bad-input."""
    d, csv, model_path, table = fitted
    rows = table.drop(columns=["set", "mass_g", "direction_deg"]).reset_index(drop=True)
    rows.loc[[3, 40], "P_L1"] = 0.0
    out = estimate_table(rows, TakumaSensing(load_force_model(model_path)))
    assert count_flags(out["flags"]) == _counted_row_by_row(out["flags"])
    assert count_flags(out["flags"])["bad-input"] == 2
