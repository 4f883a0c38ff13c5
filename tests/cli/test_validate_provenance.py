"""Analysis that cannot fool itself: validation trials used in the fit are refused, a model of
another rig is named, and a run passed on without its model file is validated with its own model."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest
from click.testing import CliRunner
from support.trial_tables import write_small_trial_table

from labcli.cli import cli
from labcli.core.provenance import rig_differences, rig_warning, same_data

SIM3 = "sim://?seed=3&clock=virtual"


def run(*args, **kw):
    return CliRunner().invoke(cli, [str(a) for a in args], **kw)


@pytest.fixture(scope="module")
def fitted(tmp_path_factory) -> Path:
    """run.h5: 12 fit + 4 validation trials, its model fitted, beside it; acq3.h5 from sim seed 3."""
    d = tmp_path_factory.mktemp("prov")
    write_small_trial_table(d / "trials.csv")
    assert run("import", d / "trials.csv", "-o", d / "run.h5", "--protocol", "takuma2014").exit_code == 0
    assert run("fit", d / "run.h5", "--form", "paper").exit_code == 0
    (d / "plan.csv").write_text("trial,set,mass_g,direction_deg\n1,fit,500,-60\n2,fit,300,30\n3,validation,800,90\n")
    r = run("acquire", d / "acq3.h5", "--port", SIM3, "--plan", d / "plan.csv", "--unattended")
    assert r.exit_code == 0, r.output
    return d


@pytest.fixture()
def here(fitted: Path, tmp_path: Path) -> Path:
    for name in ("run.h5", "run.model.json", "acq3.h5"):
        shutil.copy(fitted / name, tmp_path / name)
    return tmp_path


def test_a_clean_split_validates_and_names_its_model(here: Path) -> None:
    r = run("validate", here / "run.h5")
    assert r.exit_code == 0, r.output
    # The model the run records is applied before the file beside it (the same JSON here).
    assert f"model: {here / 'run.h5'}:/models/takuma2014" in r.stdout and r.stderr == ""


def test_validation_trials_used_in_the_fit_are_refused(here: Path) -> None:
    assert (
        run(
            "split", here / "run.h5", "--fit", "8", "--validation", "8", "--strategy", "random", "--seed", "7"
        ).exit_code
        == 0
    )
    ranges = json.loads((here / "run.model.json").read_text())["fitted_trials"]["Fx"]
    fitted = {t for lo, hi in ranges for t in range(lo, hi + 1)}
    r = run("validate", here / "run.h5")
    assert r.exit_code == 1
    shared = ", ".join(str(t) for t in (3, 5, 6, 10, 12))
    assert {3, 5, 6, 10, 12} <= fitted  # the split put five of the model's own fit trials in validation
    assert r.stderr == (
        f"Error: 5 of the 8 validation trials of {here / 'run.h5'} ({shared}) were used to fit "
        f"{here / 'run.h5'}:/models/takuma2014, so the validation would test the model on its own data; "
        f"refit after the split (`labcli fit {here / 'run.h5'}`), or pass --allow-overlap to "
        "validate anyway.\n"
    )
    r = run("validate", here / "run.h5", "--allow-overlap")
    assert r.exit_code == 0
    assert r.stderr.startswith(f"Warning: 5 of the 8 validation trials of {here / 'run.h5'} ({shared}) were used")
    assert "(--allow-overlap)" in r.stderr
    # refitting after the split removes the overlap
    assert run("fit", here / "run.h5", "--form", "paper").exit_code == 0
    assert run("validate", here / "run.h5").exit_code == 0


def test_a_copy_of_the_run_without_its_model_file_uses_the_recorded_model(here: Path) -> None:
    shutil.copy(here / "run.h5", here / "sp.h5")
    with_file = run("validate", here / "run.h5", "--json")
    from_run = run("validate", here / "sp.h5", "--json")
    assert from_run.exit_code == 0, from_run.output
    a, b = json.loads(with_file.stdout), json.loads(from_run.stdout)
    assert b["model"] == f"{here / 'sp.h5'}:/models/takuma2014"
    assert a["metrics"] == b["metrics"]  # the same model, read from inside the run
    text = run("validate", here / "sp.h5").stdout
    assert f"model: {here / 'sp.h5'}:/models/takuma2014" in text


def test_a_copied_run_is_the_same_data_so_overlap_is_still_found(here: Path) -> None:
    assert (
        run(
            "split", here / "run.h5", "--fit", "8", "--validation", "8", "--strategy", "random", "--seed", "7"
        ).exit_code
        == 0
    )
    shutil.copy(here / "run.h5", here / "sp.h5")
    r = run("validate", here / "sp.h5")
    assert r.exit_code == 1 and "were used to fit " + str(here / "sp.h5") + ":/models/takuma2014" in r.stderr


def test_no_model_anywhere(here: Path) -> None:
    shutil.copy(here / "acq3.h5", here / "bare.h5")
    r = run("validate", here / "bare.h5")
    assert r.exit_code == 1
    assert r.stderr == (
        f"Error: {here / 'bare.h5'} records no model under /models/takuma2014 and the model file "
        f"{here / 'bare.model.json'} does not exist; write one with `labcli fit {here / 'bare.h5'}`.\n"
    )


def test_a_model_of_another_simulated_rig_gets_a_warning(here: Path) -> None:
    model = json.loads((here / "run.model.json").read_text())
    from labcli.papers.takuma2014.sim.rig import SimRig

    # The same simulated rig and firmware, another seed.
    model["fitted_on"].update(device="mckibben-2dof-sim", firmware=SimRig.firmware, sim_seed=1, run="force1.h5")
    (here / "m1.json").write_text(json.dumps(model))
    r = run("validate", here / "acq3.h5", "--model", here / "m1.json")
    assert r.exit_code == 0, r.output
    assert r.stderr == (
        f"Warning: {here / 'm1.json'} was fitted on force1.h5 (simulated rig seed 1, here seed 3): "
        f"its results on {here / 'acq3.h5'} may not hold; fit a model on a run of this rig.\n"
    )
    model["fitted_on"]["sim_seed"] = 3
    (here / "m3.json").write_text(json.dumps(model))
    assert run("validate", here / "acq3.h5", "--model", here / "m3.json").stderr == ""


def test_rig_differences_compare_only_what_both_sides_know() -> None:
    fit = {
        "run": "f.h5",
        "data": "a",
        "device": "rig",
        "firmware": "1.0",
        "sim_seed": None,
        "calibration": {"gain": [1.0, 2.0], "offset": [0.0, 0.0]},
        "protocol": "p",
        "protocol_sha256": "x",
    }
    assert rig_differences(fit, dict(fit)) == [] and same_data(fit, dict(fit))
    table = {
        "run": "t.csv",
        "data": "table:t.csv",
        "device": "",
        "firmware": "",
        "sim_seed": None,
        "calibration": {},
        "protocol": "p",
        "protocol_sha256": "x",
    }
    assert rig_differences(fit, table) == [] and not same_data(fit, table)
    other = dict(fit, firmware="1.1", calibration={"gain": [1.0, 2.5], "offset": [0.0, 0.0]}, protocol_sha256="y")
    assert rig_differences(fit, other) == [
        "device rig firmware 1.0, here rig firmware 1.1",
        "another channel calibration (gain or offset)",
        "protocol p with other settings than p here",
    ]
    assert rig_differences(fit, other, protocol_text=False)[-1] == "another channel calibration (gain or offset)"
    assert rig_warning("M", fit, "r.h5", dict(fit)) is None
