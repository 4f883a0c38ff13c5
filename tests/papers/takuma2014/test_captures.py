"""Several relieved captures a load (``acquisition.captures_per_load``): every capture stored and
committed as it is taken, a run interrupted mid-load resumed at the capture it stopped at, and fit,
validate and predict reading one row per load, the mean of its captures."""

from __future__ import annotations

import io
import json
import os
import signal
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from rich.console import Console

from labcli.core.acquisition import acquire
from labcli.core.protocol import load_protocol, loads_protocol
from labcli.core.store import RunFile
from labcli.core.store.records import Records
from labcli.core.ui import UnattendedUI
from labcli.errors import ConfigError, ModelError
from labcli.papers.takuma2014.captures import AVERAGED, averaged, record_ids
from labcli.papers.takuma2014.models.inputs import load_trial_source
from labcli.papers.takuma2014.predict import read_rows
from labcli.papers.takuma2014.records import load_trials

PORT = "sim://?seed=21&clock=virtual"
N = 3
PLAN = "trial,set,mass_g,direction_deg\n1,fit,800,-90\n2,validation,500,30\n"


def quiet() -> UnattendedUI:
    return UnattendedUI(console=Console(file=io.StringIO()))


@pytest.fixture(scope="module")
def interrupted(tmp_path_factory):
    """A run of two loads, three captures each, interrupted (Ctrl-C) as load 2's second capture is
    written, then resumed: (path, the first outcome, the ids stored then, the resumed outcome)."""
    tmp = tmp_path_factory.mktemp("captures")
    proto = tmp / "p.toml"
    proto.write_text(
        load_protocol("takuma2014").text.replace("rate_hz = 200.0\n", f"rate_hz = 200.0\ncaptures_per_load = {N}\n")
    )
    plan = tmp / "plan.csv"
    plan.write_text(PLAN)
    path = tmp / "run.h5"
    real = Records.write
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)

    def pressed(self, record):
        if record["trial"] == 5:  # load 2, capture 2
            os.kill(os.getpid(), signal.SIGINT)
        return real(self, record)

    try:
        with pytest.MonkeyPatch.context() as mp:
            mp.setattr(Records, "write", pressed)
            first = acquire(path, PORT, protocol=str(proto), plan=plan, unattended=True, ui=quiet())
        with RunFile.open(path) as run:
            stored = run.records.ids()
        resumed = acquire(path, PORT, resume=True, unattended=True, ui=quiet())
    finally:
        signal.signal(signal.SIGINT, previous)
    return path, first, stored, resumed


def test_an_interrupted_load_resumes_at_its_next_capture_and_ends_with_n_captures_each(interrupted):
    path, first, stored, resumed = interrupted
    # The capture being written when Ctrl-C came is stored whole; nothing after it.
    assert first.exit_code == 130 and stored == [1, 2, 3, 4, 5]
    # The session's sentences count captures (records), not trials (loads): 5 of 2 loads' 6 captures.
    assert f"; 5 captures stored in {path} are safe. Resume with: " in first.message
    assert resumed.exit_code == 0, resumed.message
    assert resumed.message.startswith(f"Session complete: 6 captures stored in {path} (1 this session, ")
    with RunFile.open(path) as run:
        assert run.records.ids() == [1, 2, 3, 4, 5, 6] and run.records.incomplete_ids() == []
        split = run.split.get()
        assert split["fit"] == [1, 2, 3] and split["validation"] == [4, 5, 6]
        assert loads_protocol(run.protocol_text).air.captures_per_load == N  # the run's own protocol says how many
    df = load_trials(path)
    assert df.groupby(df["mass_g"]).size().to_dict() == {500.0: N, 800.0: N}
    assert df["mass_g"].tolist() == [800.0] * N + [500.0] * N  # each load's captures in a row
    # A resumed run asks for no capture already stored, and the finished one for nothing more.
    again = acquire(path, PORT, resume=True, unattended=True, ui=quiet())
    assert again.exit_code == 0
    assert again.message.startswith("All 6 captures of the 2 planned trials are already stored")


def test_fit_validate_and_predict_read_each_load_as_the_mean_of_its_captures(interrupted):
    path = interrupted[0]
    stored = load_trials(path)
    src = load_trial_source(path)
    assert src.captures == N and src.table["trial"].tolist() == [1, 2]
    assert src.table["set"].tolist() == ["fit", "validation"]
    for load, rows in ((0, slice(0, 3)), (1, slice(3, 6))):
        for c in AVERAGED:
            assert src.table[c].iloc[load] == pytest.approx(stored[c].iloc[rows].mean(), abs=1e-15), c
        assert src.table["Fx_N"].iloc[load] == stored["Fx_N"].iloc[rows.start]
    # The captures do differ (fresh readings): the mean is not any one of them.
    assert stored["P_L1"].iloc[:3].nunique() == 3
    pd.testing.assert_frame_equal(read_rows(Path(path)), src.table)


def test_a_skipped_capture_leaves_its_load_the_mean_of_the_others_and_one_capture_is_unchanged():
    table = pd.DataFrame(
        {
            "trial": [1, 2, 3, 5, 6],  # load 2's first capture (id 4) skipped
            "set": ["fit", "fit", "fit", "validation", "validation"],
            **{c: np.arange(5.0) * (i + 1) for i, c in enumerate(AVERAGED)},
            "Fx_N": [1.0, 1.0, 1.0, 2.0, 2.0],
        }
    )
    out = averaged(table, 3)
    assert out["trial"].tolist() == [1, 2] and out["set"].tolist() == ["fit", "validation"]
    assert out["P_L1"].tolist() == pytest.approx([table["P_L1"][:3].mean(), table["P_L1"][3:].mean()])
    assert out["Fx_N"].tolist() == [1.0, 2.0] and out["trial"].dtype == table["trial"].dtype
    assert averaged(table, 1) is table
    assert record_ids([1, 2], 3).tolist() == [1, 2, 3, 4, 5, 6] and record_ids([4], 1).tolist() == [4]


def test_the_leak_correction_is_refused_on_averaged_rows(interrupted, tmp_path):
    from labcli.papers.takuma2014.analyses import fit
    from labcli.papers.takuma2014.options import FitOptions

    with pytest.raises(ConfigError, match="averages 3 captures into each load's row"):
        fit(interrupted[0], FitOptions(), output=tmp_path / "m.json", leak_correct=True)


def labcli(*args: str):
    from click.testing import CliRunner

    from labcli.cli import cli

    return CliRunner().invoke(cli, list(args))


def test_acquire_captures_writes_the_number_into_the_runs_protocol_and_resume_keeps_it(tmp_path):
    plan = tmp_path / "plan.csv"
    plan.write_text(PLAN)
    run = tmp_path / "three.h5"
    res = labcli("acquire", str(run), "--port", PORT, "--unattended", "--plan", str(plan), "--captures", "3")
    assert res.exit_code == 0, res.output
    assert f"Session complete: 6 captures stored in {run} (6 this session, " in res.output.replace("\n", " ")
    with RunFile.open(run) as f:
        proto = loads_protocol(f.protocol_text)
        assert f.records.ids() == [1, 2, 3, 4, 5, 6]
    assert proto.air.captures_per_load == 3 and proto.air.friction_relief_vent_s == 2.0
    assert "captures_per_load = 3\n" in proto.text and proto.settings.rig == load_protocol("takuma2014").settings.rig
    res = labcli("acquire", str(run), "--port", PORT, "--unattended", "--resume", "--captures", "2")
    assert res.exit_code == 1 and "was recorded with 3 captures of each load, not 2" in res.output
    res = labcli("acquire", str(run), "--port", PORT, "--unattended", "--resume", "--captures", "3")
    # Two plan trials (loads) of three captures each: the trials counted as loads, the captures as captures.
    assert res.exit_code == 0 and f"All 6 captures of the 2 planned trials are already stored in {run}; nothing" in (
        res.output.replace("\n", " ")
    )
    once = tmp_path / "once.h5"
    assert labcli("acquire", str(once), "--port", PORT, "--unattended", "--plan", str(plan)).exit_code == 0
    res = labcli("acquire", str(once), "--port", PORT, "--unattended", "--resume", "--captures", "2")
    assert res.exit_code == 1 and "was recorded with 1 capture of each load, not 2" in res.output


@pytest.mark.parametrize(
    ("args", "said"),
    [
        (("--captures", "11"), "captures_per_load"),
        (("--captures", "0"), "0 is not in the range x>=1"),
    ],
)
def test_acquire_refuses_captures_it_cannot_take_in_one_sentence(tmp_path, args, said):
    res = labcli("acquire", str(tmp_path / "x.h5"), "--port", PORT, "--unattended", *args)
    assert res.exit_code != 0 and said in res.output and "Traceback" not in res.output, res.output
    assert not (tmp_path / "x.h5").exists()


ONCE = {  # run kinds taking each unit once: (their protocol's arguments, the unit, why), the papers' words
    "push": (("--protocol", "takuma2014-stiffness"), "push", "a push run records pushes, each its own"),
    "stretch": (
        ("--protocol", "rpam2015", "--experiment", "stretch"),
        "point",  # the rPAM paper's word: a stretch test's payload (load) hangs on many points
        "an rPAM experiment takes each point of its grid once",
    ),
    "joint": (
        ("--protocol", "rpam2015", "--experiment", "joint"),
        "point",
        "an rPAM experiment takes each point of its grid once",
    ),
}


@pytest.mark.parametrize("kind", sorted(ONCE))
def test_a_run_kind_taking_each_unit_once_refuses_captures_in_one_sentence_of_the_core(kind, tmp_path):
    """The core's check_captures is the one place the refusal is written, in the words of the paper's
    ``single_captures``: the option and the protocol's key above 1 refused before the rig is woken, and
    ``--captures 1`` (the default) taken as it is."""
    from labcli.core.acquisition import check_captures
    from labcli.core.paper import AcquireOptions
    from labcli.core.registry import run_protocol

    args, unit, why = ONCE[kind]
    port = PORT if kind == "push" else "sim://?mode=rpam&seed=1&clock=virtual"
    run = tmp_path / "x.h5"
    res = labcli("acquire", str(run), "--port", port, "--unattended", *args, "--captures", "2")
    assert res.exit_code == 1 and not run.exists()
    assert res.output == f"Error: --captures 2 asks for each {unit} 2 times, but {why}; leave it out.\n"
    name = args[1]
    proto = tmp_path / "three.toml"
    proto.write_text(load_protocol(name).text.replace("[acquisition]\n", "[acquisition]\ncaptures_per_load = 3\n"))
    res = labcli("acquire", str(run), "--port", port, "--unattended", "--protocol", str(proto), *args[2:])
    assert res.exit_code == 1 and not run.exists()
    assert res.output == (
        f"Error: Protocol {name} gives acquisition.captures_per_load = 3, but {why}: set the key to 1 or leave it out.\n"
    )
    paper, given = run_protocol(load_protocol(name), args[3] if len(args) > 2 else None)
    one = AcquireOptions(str(run), unattended=True, captures=1)
    check_captures(paper, given, one)
    assert paper.acquisition(given, one).protocol.text == given.text  # the protocol as written


def test_a_protocol_giving_another_number_of_captures_is_refused(tmp_path):
    from labcli.core.protocol import with_captures

    two = with_captures(load_protocol("takuma2014"), 2)
    assert two.air.captures_per_load == 2 and with_captures(two, 2) is two
    with pytest.raises(ConfigError, match="gives acquisition.captures_per_load = 2, and --captures 3"):
        with_captures(two, 3)
    # The key goes into the protocol's own [acquisition] table, a comment after its header kept.
    noted = loads_protocol(load_protocol("takuma2014").text.replace("[acquisition]\n", "[acquisition]  # air\n"))
    three = with_captures(noted, 3)
    assert three.air.captures_per_load == 3 and "[acquisition]  # air\ncaptures_per_load = 3\n" in three.text


def test_one_capture_keeps_the_protocol_as_written_so_a_model_sees_the_same_settings(tmp_path):
    """``--captures 1`` is the default: the run stores the file's own text, whose digest a model fitted
    on it compares, so a run acquired without the option shows no other settings."""
    from labcli.core.protocol import with_captures
    from labcli.core.provenance import rig_differences, run_identity

    base = load_protocol("takuma2014")
    assert with_captures(base, 1) is base
    given = loads_protocol(base.text.replace("rate_hz = 200.0\n", "rate_hz = 200.0\ncaptures_per_load = 1\n"))
    assert with_captures(given, 1) is given
    plan = tmp_path / "plan.csv"
    plan.write_text(PLAN)
    ids = []
    for name, extra in (("one_a.h5", ()), ("one_b.h5", ("--captures", "1"))):
        res = labcli("acquire", str(tmp_path / name), "--port", PORT, "--unattended", "--plan", str(plan), *extra)
        assert res.exit_code == 0, res.output
        with RunFile.open(tmp_path / name) as run:
            assert run.protocol_text == base.text and run.records.ids() == [1, 2]
            ids.append(run_identity(run, tmp_path / name))
    assert ids[0]["protocol_sha256"] == ids[1]["protocol_sha256"] and rig_differences(ids[1], ids[0]) == []


@pytest.mark.parametrize("end", ["\r\n", "\n"])
def test_captures_go_into_the_acquisition_table_of_a_file_with_either_line_end(end):
    from labcli.core.protocol import with_captures

    text = load_protocol("takuma2014").text.replace("\n", end)
    three = with_captures(loads_protocol(text), 3)
    assert three.air.captures_per_load == 3 and three.settings.rig == load_protocol("takuma2014").settings.rig
    assert f"[acquisition]{end}captures_per_load = 3{end}" in three.text
    assert three.text.count("\n") == text.count("\n") + 1 and three.text.count("\r\n") == text.count("\r\n") + (
        end == "\r\n"
    )


def test_captures_given_without_an_acquisition_header_are_refused_in_one_sentence():
    from labcli.core.protocol import with_captures

    bare = load_protocol("takuma2014").text.replace("[acquisition]\n", "").replace("rate_hz = 200.0\n", "")
    dotted = loads_protocol("acquisition.rate_hz = 200.0\n" + bare)
    assert dotted.rate_hz == 200.0
    with pytest.raises(ConfigError) as err:
        with_captures(dotted, 2)
    assert str(err.value) == (
        "takuma2014 gives its acquisition settings without an [acquisition] table header; "
        "write captures_per_load = 2 there instead of --captures 2."
    )


@pytest.fixture(scope="module")
def two(tmp_path_factory):
    """A run of two captures a load (the default relief vents before each) on 18 fit and 6
    validation loads of the plan, and the model `labcli fit` writes of it by default."""
    tmp = tmp_path_factory.mktemp("two")
    rows = pd.read_csv(Path(__file__).resolve().parents[3] / "protocols" / "takuma2014-plan.csv")
    plan = tmp / "plan.csv"
    pd.concat([rows[rows["set"] == "fit"].iloc[::3], rows[rows["set"] == "validation"].iloc[:6]]).to_csv(
        plan, index=False
    )
    run = tmp / "two.h5"
    res = labcli("acquire", str(run), "--port", PORT, "--unattended", "--plan", str(plan), "--captures", "2")
    assert res.exit_code == 0, res.output
    model = tmp / "two.model.json"
    res = labcli("fit", str(run), "-o", str(model))
    assert res.exit_code == 0, res.output
    assert "Each trial is the mean of its load's 2 captures" in res.output
    return run, model


def _fitted_as_by_hand(run: Path, model: Path, friction_terms: bool) -> dict:
    import json

    from labcli.papers.takuma2014.analyses import _fit_form

    src = load_trial_source(run)
    assert len(src.table) == 36 and len(load_trials(run)) == 72
    with np.errstate(all="ignore"):
        by_hand = _fit_form("posture", src, str(run), friction_terms=friction_terms).to_dict()
    written = json.loads(model.read_text())
    for key in ("angle_coefficients", "torque_coefficients", "angle_resid_cov"):
        np.testing.assert_allclose(written[key], by_hand[key], rtol=1e-12, err_msg=key)
    assert written["fitted_trials"] == by_hand["fitted_trials"]
    assert written["torque_terms"] == by_hand["torque_terms"]
    return written


def test_labcli_fit_of_a_run_of_two_captures_a_load_is_the_fit_of_its_averaged_rows(two):
    """The model ``labcli fit`` writes is the one fitted on the loads' means, said so in its report
    and in the model file."""
    from labcli.papers.takuma2014.analyses import _fit_form
    from labcli.papers.takuma2014.models.posture import FRICTION_TERMS, RELIEVED_TERMS, TORQUE_TERMS

    run, model = two
    written = _fitted_as_by_hand(run, model, friction_terms=True)
    # Relieved (the default relief vents): the relieved run's friction terms are offered, not the
    # history's (whether the forward selection keeps any depends on whether it cuts this small run's
    # cross-validated error, so the offer is what is asserted), and each row's P0 is its own, already
    # the mean of its captures' baselines, not the mean of five rows' as on a run of one relieved
    # capture a load.
    terms = set(written["torque_terms"])
    with np.errstate(all="ignore"):
        offered = _fit_form("posture", load_trial_source(run), str(run), friction_terms=True).friction
    assert offered == "relieved" and terms <= set(TORQUE_TERMS + RELIEVED_TERMS)
    assert not terms & set(FRICTION_TERMS) and written["baseline_mean"] == 1
    assert written["captures_per_load"] == 2


def test_predict_counts_loads_and_fit_counts_a_skipped_capture(two, tmp_path):
    run, model = two
    # predict counts loads, the means of the captures it read.
    res = labcli("predict", str(run), "--model", str(model))
    assert res.exit_code == 0 and "Estimated 36 loads (the means of 72 captures) with" in res.output, res.output
    # A capture skipped (here dropped from the run's export): its load is the mean of one, and fit says so.
    table = tmp_path / "two.csv"
    assert labcli("export", str(run), "-o", str(table)).exit_code == 0
    proto = tmp_path / "two.toml"
    proto.write_text(load_trial_source(run).protocol.text)
    # The export read with the run's protocol fits the run's model (not one of 72 single captures).
    res = labcli("fit", str(table), "--protocol", str(proto), "-o", str(tmp_path / "m3.json"))
    assert res.exit_code == 0, res.output
    from_csv, written = (json.loads(p.read_text()) for p in (tmp_path / "m3.json", model))
    assert from_csv["baseline_mean"] == written["baseline_mean"] == 1
    for key in ("angle_coefficients", "torque_coefficients"):
        np.testing.assert_allclose(from_csv[key], written[key], rtol=1e-6, err_msg=key)
    pd.read_csv(table).drop(index=5).to_csv(table, index=False)
    res = labcli("fit", str(table), "--protocol", str(proto), "-o", str(tmp_path / "m2.json"), "--no-friction-terms")
    assert res.exit_code == 0, res.output
    assert "Each trial is the mean of its load's captures, 2 a load" in res.output
    assert "or fewer where one was skipped (71 of 72 read)" in res.output


def test_predict_opens_the_run_once_and_reads_its_protocol_once(two, monkeypatch):
    """The rows, the captures they average and the rig check come from one opening of the run file and
    one reading of its embedded protocol (they were three openings and two readings)."""
    from labcli.core import protocol as core_protocol
    from labcli.core.store import RunFile as Run
    from labcli.papers.takuma2014 import predict

    run, model = two
    calls = {"open": 0, "protocol": 0}
    opened, parsed = Run.open.__func__, core_protocol.loads_protocol

    def counted_open(cls, *args, **kwargs):
        if Path(args[0]) == run:
            calls["open"] += 1
        return opened(cls, *args, **kwargs)

    def counted_protocol(*args, **kwargs):
        calls["protocol"] += 1
        return parsed(*args, **kwargs)

    monkeypatch.setattr(Run, "open", classmethod(counted_open))
    monkeypatch.setattr(core_protocol, "loads_protocol", counted_protocol)
    monkeypatch.setattr(predict, "loads_protocol", counted_protocol)
    result = predict.predict_file(run, model_path=model)
    assert (result.rows, result.records) == (36, 72)  # still one row per load, the means of its captures
    assert calls == {"open": 1, "protocol": 1}


def test_no_friction_terms_fits_the_plain_posture_form_on_a_relieved_run_and_exports_it(two, tmp_path):
    """--no-friction-terms is honoured on a relieved run (every run of several captures a load by
    default): the plain form, which export-model carries to the board; the refusal of the relieved
    terms names that route."""
    from labcli.papers.takuma2014.models.posture import RELIEVED_TERMS, TORQUE_TERMS

    run, relieved = two
    plain = tmp_path / "plain.json"
    res = labcli("fit", str(run), "-o", str(plain), "--no-friction-terms")
    assert res.exit_code == 0, res.output
    written = _fitted_as_by_hand(run, plain, friction_terms=False)
    # The plain form's terms (those its selection keeps), no friction term of either kind.
    assert set(written["torque_terms"]) <= set(TORQUE_TERMS) and not set(RELIEVED_TERMS) & set(written["torque_terms"])
    assert not [t for t in written["torque_terms"] if "friction" in t]
    assert written["baseline_mean"] == 1 and written["captures_per_load"] == 2

    # The refusal reads the kept terms' names; whether this small run's selection keeps a relieved
    # term depends on its noise, so a model that kept one is made by naming its last term so.
    data = json.loads(relieved.read_text())
    if not set(data["torque_terms"]) & set(RELIEVED_TERMS):
        data["torque_terms"][-1] = "friction_rest"
    relieved = tmp_path / "relieved.json"
    relieved.write_text(json.dumps(data))
    res = labcli("export-model", str(relieved), "--c", str(tmp_path / "relieved.h"))
    assert res.exit_code == 1 and not (tmp_path / "relieved.h").exists()
    assert f"refit without them (`labcli fit {run} --no-friction-terms`) and export that model." in res.output
    res = labcli("export-model", str(plain), "--c", str(tmp_path / "plain.h"))
    assert res.exit_code == 0, res.output
    assert (tmp_path / "plain.h").read_text().count("#define MODEL_ID") == 1
    assert res.stderr == (
        f"Warning: The model file {plain} was fitted on means of 2 captures a load (acquisition.captures_per_load) "
        "but the board's loads are single captures: its standard errors and 95 % intervals are too narrow for them.\n"
    )


def narrow(model: str, rows: str) -> str:
    return (
        f"Warning: {model} was fitted on means of 2 captures a load (acquisition.captures_per_load) "
        f"but {rows} are single captures: its standard errors and 95 % intervals are too narrow for them.\n"
    )


def test_commands_say_when_the_rows_average_another_number_of_captures_than_the_model(two, tmp_path):
    """validate, predict and sense warn (and go on) when a model of averaged rows estimates single captures."""
    run, model = two
    csv, proto = tmp_path / "two.csv", tmp_path / "cap2.toml"
    res = labcli("export", str(run), "-o", str(csv))
    assert res.exit_code == 0, res.output
    with RunFile.open(run) as rf:
        proto.write_text(rf.protocol_text)
    assert len(pd.read_csv(csv)) == 72  # every capture its own row

    # Read with the shipped protocol (one capture a load), each row is one capture.
    res = labcli("validate", str(csv), "--model", str(model))
    assert res.exit_code == 0, res.output
    assert narrow(f"The model {model}", f"the rows of {csv}") in res.stderr
    # Read with its own protocol, averaged as the run is: nothing to say.
    res = labcli("validate", str(csv), "--protocol", str(proto), "--model", str(model))
    assert res.exit_code == 0, res.output
    assert "captures" not in res.stderr
    res = labcli("predict", str(csv), "--model", str(model))
    assert res.exit_code == 0, res.output
    assert res.stderr == narrow(f"The model file {model}", f"the rows of {csv}")
    # The run itself is read as its loads' means, as the model was fitted: nothing to say.
    res = labcli("validate", str(run), "--model", str(model))
    assert res.exit_code == 0, res.output
    assert "captures" not in res.stderr
    res = labcli("predict", str(run), "--model", str(model))
    assert res.exit_code == 0 and res.stderr == "", res.output

    # Live, every estimate is of one capture.
    out = tmp_path / "live.jsonl"
    res = labcli("sense", "--port", PORT, "--model", str(model), "--seconds", "0.5", "--jsonl", str(out))
    assert res.exit_code == 0, res.output
    assert res.stderr.startswith(narrow(f"The model file {model}", "the live loads"))
    assert out.read_text().count("\n") > 0  # warned, not refused


def test_a_model_of_one_capture_a_load_on_averaged_rows_is_said_too_wide(two, tmp_path):
    run, _ = two
    single = tmp_path / "one.json"
    res = labcli("fit", str(Path(__file__).resolve().parents[3] / "sample_runs" / "force.h5"), "-o", str(single))
    assert res.exit_code == 0, res.output
    res = labcli("predict", str(run), "--model", str(single))
    assert res.exit_code == 0, res.output
    assert (
        f"Warning: The model file {single} was fitted on single captures (acquisition.captures_per_load) "
        f"but the rows of {run} are means of 2 captures a load: its standard errors and 95 % intervals are too "
        "wide for them.\n"
    ) in res.stderr
    # Nothing on a single-capture model applied live.
    res = labcli("sense", "--port", PORT, "--model", str(single), "--seconds", "0.2", "--jsonl", str(tmp_path / "o"))
    assert res.exit_code == 0 and "captures" not in res.stderr, res.output


@pytest.mark.parametrize("name", ["force.model.json", "bent.model.json", "force-paper.model.json"])
def test_model_files_of_one_capture_a_load_carry_no_captures_key_and_read_back_byte_for_byte(name, tmp_path):
    from labcli.papers.takuma2014.models.posture import force_model_from_json, load_force_model

    path = Path(__file__).resolve().parents[3] / "sample_runs" / name
    model = load_force_model(path)
    assert model.captures_per_load == 1 and "captures_per_load" not in path.read_text()
    assert model.to_json() == path.read_text()
    model.captures_per_load = 3
    again = force_model_from_json(model.to_json(), name="the model m.json")
    assert again.captures_per_load == 3 and '"captures_per_load": 3' in model.to_json()
    for bad in ("0", "2.5", "true", '"2"'):
        text = model.to_json().replace('"captures_per_load": 3', f'"captures_per_load": {bad}')
        with pytest.raises(ModelError, match="^The model m.json: key 'captures_per_load' must be a whole number"):
            force_model_from_json(text, name="the model m.json")


def test_inspect_and_runs_count_a_runs_captures_as_captures_against_its_plan_trials(interrupted, tmp_path):
    """A run of 2 plan trials of 3 captures holds 6 records: inspect and runs count 6 captures of 6
    planned (they said 6 trials complete of 2 planned), per capture where they count records."""
    import shutil

    run = tmp_path / "lab" / "run.h5"
    run.parent.mkdir()
    shutil.copy(interrupted[0], run)
    res = labcli("inspect", str(run))
    assert res.exit_code == 0, res.output
    lines = res.output.splitlines()
    assert "  captures    6 complete, 0 incomplete, 6 planned (2 plan trials, 3 captures each)" in lines
    assert "  split       3 fit, 3 validation, 0 unassigned captures (plan)" in lines
    assert any(ln.startswith("  settling    median ") and " over 6 captures; " in ln for ln in lines)
    assert "  baseline drift over 6 captures (recording order):" in lines
    assert sum("kPa/capture, max deviation" in ln for ln in lines) == 4
    shown = json.loads(labcli("inspect", str(run), "--json").output)
    assert (shown["records"], shown["complete"], shown["planned"], shown["captures_per_load"]) == ("captures", 6, 6, N)
    (row,) = json.loads(labcli("runs", str(run.parent), "--json").output)
    assert (row["records"], row["complete"], row["planned"]) == ("captures", 6, 6)
    res = labcli("export", str(run), "-o", str(run.with_suffix(".csv")))
    assert res.output == f"Wrote 6 captures from {run} to {run.with_suffix('.csv')}.\n"
    # Imported back with the run's protocol, the rows are captures still, as fit reads them.
    proto = tmp_path / "p.toml"
    with RunFile.open(run) as rf:
        proto.write_text(rf.protocol_text)
    back = tmp_path / "back.h5"
    res = labcli("import", str(run.with_suffix(".csv")), "-o", str(back), "--protocol", str(proto))
    assert (
        res.output == f"Imported 6 captures from {run.with_suffix('.csv')} into {back} (split: 3 fit, 3 validation).\n"
    )
    assert "  captures    6 complete, 0 incomplete" in labcli("inspect", str(back)).output.splitlines()
    # A note's record is a capture (record 5: trial 2's second), and so is one the run does not hold.
    res = labcli("note", str(run), "--trial", "5", "the weight swung")
    assert res.exit_code == 0 and res.output.startswith(f"{run}: note on capture 5 kept ("), res.output
    assert any(
        ln.startswith("  note        capture 5: the weight swung (")
        for ln in labcli("inspect", str(run)).output.splitlines()
    )
    res = labcli("note", str(run), "--trial", "7", "none")
    assert res.exit_code == 1 and res.output == f"Error: {run} has no complete capture 7, so the note was not added.\n"


def test_split_assigns_whole_loads_and_counts_loads(interrupted, tmp_path):
    """With N captures a load the counts given are loads and each set takes all of a load's captures;
    a split by record would put one load's captures in both sets (seed 3 did, on 6 loads x 3)."""
    import shutil

    from labcli.core.splitting import split

    run = tmp_path / "run.h5"
    shutil.copy(interrupted[0], run)
    for seed in range(6):
        done = split(run, 1, 1, "random", seed)
        with RunFile.open(run) as rf:
            s = rf.split.get()
        assert sorted((s["fit"], s["validation"])) == [[1, 2, 3], [4, 5, 6]], seed
        assert (done.fit, done.validation, done.total) == (1, 1, 2)
    # labcli split says it in one sentence of one bracket, captures beside the strategy.
    res = labcli("split", str(run), "--fit", "1", "--validation", "1", "--strategy", "random", "--seed", "5")
    assert res.exit_code == 0 and res.output == (
        f"{run}: 1 fit, 1 validation, 0 unassigned of 2 loads (6 captures, 3 a load; random, seed 5).\n"
    )
    # The protocol's 90 + 18 on 2 loads keeps its proportion over loads, not over the 6 captures.
    done = split(run)
    assert (done.fit, done.validation) == (1, 1)
    # A CSV of the run read with its captures protocol is split the same way.
    table = tmp_path / "run.csv"
    load_trials(run).assign(set="").to_csv(table, index=False)
    proto = tmp_path / "p.toml"
    with RunFile.open(run) as rf:
        proto.write_text(rf.protocol_text)
    split(table, 1, 1, "random", 2, protocol=str(proto))
    sets = pd.read_csv(table, keep_default_na=False)["set"].tolist()
    assert sets[:3] == [sets[0]] * 3 and sets[3:] == [sets[3]] * 3 and {sets[0], sets[3]} == {"fit", "validation"}
    with pytest.raises(ConfigError, match=r"has 2 loads \(6 captures, 3 a load\), fewer than the 3 loads asked for"):
        split(run, 2, 1)


@pytest.mark.parametrize("column", ["set", "mass_g", "direction_deg"])
def test_averaged_refuses_captures_of_one_load_that_differ_in_set_mass_or_direction(column):
    table = pd.DataFrame(
        {
            "trial": [1, 2, 3, 4],
            "set": ["fit"] * 4,
            "mass_g": [800.0] * 4,
            "direction_deg": [30.0] * 4,
            **{c: np.arange(4.0) for c in AVERAGED},
        }
    )
    assert averaged(table, 2)["trial"].tolist() == [1, 2]
    table.loc[3, column] = {"set": "validation", "mass_g": 500.0, "direction_deg": -90.0}[column]
    with pytest.raises(ConfigError, match=f"records 3, 4 would be the 2 captures of load 2 but differ in {column}"):
        averaged(table, 2)


def test_a_csv_read_with_a_captures_protocol_is_averaged_as_its_run_and_a_plain_run_is_refused(interrupted, tmp_path):
    """The export of a run of N captures a load, read with its protocol, gives the run's rows (so the same
    model); an ordinary run's table read or imported with such a protocol would merge two loads: refused."""
    run = interrupted[0]
    proto = tmp_path / "p.toml"
    with RunFile.open(run) as rf:
        proto.write_text(rf.protocol_text)
    table = tmp_path / "run.csv"
    assert labcli("export", str(run), "-o", str(table)).exit_code == 0
    from_csv, from_run = load_trial_source(table, str(proto)), load_trial_source(run)
    assert from_csv.captures == N and len(from_csv.table) == 2 and len(load_trials(table)) == 2 * N
    cols = ["trial", "set", *AVERAGED, "Fx_N"]
    pd.testing.assert_frame_equal(from_csv.table[cols], from_run.table[cols], check_dtype=False, atol=1e-9)
    # A run of one capture a load: its first two trials are two loads (800 g, 500 g), not two captures.
    plain = load_trials(run).iloc[[0, 3]].assign(trial=[1, 2])
    plain.to_csv(table, index=False)
    with pytest.raises(ConfigError, match="records 1, 2 would be the 3 captures of load 1 but differ in set"):
        load_trial_source(table, str(proto))
    res = labcli("import", str(table), "-o", str(tmp_path / "imported.h5"), "--protocol", str(proto))
    assert res.exit_code == 0, res.output
    res = labcli("fit", str(tmp_path / "imported.h5"), "-o", str(tmp_path / "m.json"))
    assert res.exit_code != 0 and "would be the 3 captures of load 1 but differ in set" in res.output
    assert "Traceback" not in res.output and not (tmp_path / "m.json").exists()
