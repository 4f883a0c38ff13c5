"""``labcli fit`` fits the lab's actuator on a stretch-test run, and ``labcli optimize --actuator``
designs with it (CliRunner, the simulated stand through the acquisition path)."""

from __future__ import annotations

import io
import json
from dataclasses import replace
from pathlib import Path

import pytest
from click.testing import CliRunner
from rich.console import Console

from labcli.cli import cli
from labcli.core.acquisition import acquire
from labcli.core.ui import UnattendedUI
from labcli.papers.rpam2015.protocol import actuator_of

ROOT = Path(__file__).resolve().parents[2]
ACT = actuator_of("rpam2015")
# A short search: the comparisons below are between runs of the same seed and settings.
QUICK = ("--seed", "1", "--set", "optimize.maxiter=30", "--json")


def invoke(*args: object):
    return CliRunner().invoke(cli, [str(a) for a in args])


@pytest.fixture(scope="module")
def fitted(tmp_path_factory) -> dict[str, object]:
    d = tmp_path_factory.mktemp("rpam-actuator")
    run = d / "stretch.h5"
    outcome = acquire(
        run,
        "sim://?mode=rpam&seed=4&clock=virtual",
        protocol="rpam2015",
        experiment="stretch",
        unattended=True,
        ui=UnattendedUI(console=Console(file=io.StringIO())),
    )
    assert outcome.status == "finished", outcome.message
    model = d / "stretch.model.json"
    r = invoke("fit", run, "-o", model, "--no-record")
    assert r.exit_code == 0, r.output
    return {"run": run, "model": model, "dir": d, "text": r.output}


def test_fit_records_the_labs_actuator_with_standard_errors(fitted):
    d = json.loads(fitted["model"].read_text())
    a = d["actuator_fit"]
    assert a["kind"] == "rpam-actuator-fit" and a["force_reading"] == "derived"
    assert set(a["names"]) == {"mu_1", "mu_2", "mu_3", "c0", "c1", "c2", "c3", "L0_m", "radius_m"}
    assert a["n_points"] == 120 and a["dof"] == 111
    # The stand's actuator is the protocol's (only its stretch correction is seeded), so through
    # the ADC, the settling and the capture the fit finds the protocol's radius and mu_1 again.
    r = a["parameters"]["radius_m"]
    assert abs(r["value"] - ACT.rest_radius_m) < 3 * r["std_error"] and r["std_error"] < 1e-4
    mu1 = a["parameters"]["mu_1"]
    assert abs(mu1["value"] - ACT.ogden_mu_MPa[0]) < 3 * mu1["std_error"] and a["determined"]["mu_1"]
    assert a["actuator"]["ogden_mu_MPa"] == [a["parameters"][f"mu_{i}"]["value"] for i in (1, 2, 3)]
    out = " ".join(fitted["text"].split())
    assert "The lab's actuator fitted to the same points (derived reading" in out
    assert "rest radius r, mm" in out and "mu_1 (alpha 1.3), MPa" in out


def _with_actuator(fitted, name: str, act) -> Path:
    """The stretch fit with its fitted actuator replaced by ``act``: a known answer for optimize."""
    d = json.loads(fitted["model"].read_text())
    d["actuator_fit"]["actuator"] = act.to_dict()
    path = fitted["dir"] / name
    path.write_text(json.dumps(d), encoding="utf-8")
    return path


def test_optimize_designs_with_the_fitted_actuator(fitted):
    # The protocol's own actuator given as the fitted one gives the protocol's optimum exactly ...
    same = _with_actuator(fitted, "same.model.json", ACT)
    base = json.loads(invoke("optimize", *QUICK).output)
    given = json.loads(invoke("optimize", "--actuator", same, *QUICK).output)
    for key in ("alpha_deg", "L1_m", "L2_m", "L3_m", "stiffness_Nm_per_rad"):
        assert given[key] == base[key], key
    assert base["actuator_source"] == "protocol" and given["actuator_source"] == str(same)
    # ... a stiffer wall gives what --set of the same moduli gives, and another optimum.
    path = _with_actuator(fitted, "stiff.model.json", replace(ACT, ogden_mu_MPa=(0.1, 0.006, 0.003)))
    via_file = json.loads(invoke("optimize", "--actuator", path, *QUICK).output)
    via_set = json.loads(invoke("optimize", "--set", "ogden.mu_MPa=[0.1,0.006,0.003]", *QUICK).output)
    assert via_file["alpha_deg"] == via_set["alpha_deg"] and via_file["L2_m"] == via_set["L2_m"]
    assert abs(via_file["alpha_deg"] - base["alpha_deg"]) > 0.1
    assert via_file["actuator"]["ogden_mu_MPa"] == [0.1, 0.006, 0.003]
    # The real fit is accepted and named in the report.
    r = invoke("optimize", "--actuator", fitted["model"], "--seed", "1", "--set", "optimize.maxiter=30")
    assert r.exit_code == 0, r.output
    assert f"Actuator: the lab's, fitted in {fitted['model']}: Ogden moduli" in " ".join(r.output.split())


def test_optimize_refuses_an_actuator_file_of_another_kind_in_one_sentence(fitted, tmp_path):
    def error(*args: object) -> str:
        r = invoke("optimize", *args)
        assert r.exit_code != 0
        return r.output.strip()

    force_model = ROOT / "sample_runs" / "force.model.json"
    assert error("--actuator", force_model) == (
        f"Error: Actuator file {force_model} is a force model of the McKibben paper (takuma2014), not a stretch "
        "fit of the rPAM paper; --actuator takes the file labcli fit writes for an rPAM stretch-test run."
    )
    joint = tmp_path / "joint.json"
    joint.write_text('{"kind": "rpam-joint-map"}', encoding="utf-8")
    assert error("--actuator", joint) == (
        f"Error: Actuator file {joint} is a joint-map analysis, not a stretch fit of the rPAM paper; --actuator "
        "takes the file labcli fit writes for an rPAM stretch-test run."
    )
    old = json.loads(fitted["model"].read_text())
    del old["actuator_fit"], old["actuator_note"]
    older = tmp_path / "older.model.json"
    older.write_text(json.dumps(old), encoding="utf-8")
    assert error("--actuator", older) == (
        f"Error: Actuator file {older} holds a stretch correction but no fitted actuator (written before labcli "
        "fit fitted one); fit the stretch-test run again with labcli fit."
    )
    text = tmp_path / "notes.txt"
    text.write_text("mu = 0.07", encoding="utf-8")
    assert error("--actuator", text) == (
        f"Error: Actuator file {text} is not a JSON stretch fit; give the file labcli fit wrote for an rPAM "
        "stretch-test run."
    )
    missing = tmp_path / "none.json"
    assert error("--actuator", missing) == (
        f"Error: Actuator file {missing} does not exist; fit the stretch test first with labcli fit STRETCH.h5, "
        "which writes STRETCH.model.json."
    )
    model = fitted["model"]
    assert error("--actuator", model, "--force", "paper") == (
        f"Error: The actuator of {model} was fitted with the derived force reading, so its moduli belong to it; "
        "optimise with --force derived, or fit the stretch test again with --force paper."
    )
    assert error("--actuator", model, "--set", "actuator.L0_m=0.08") == (
        f"Error: --set actuator.L0_m=0.08 changes the protocol's actuator, which the fitted actuator of {model} "
        "replaces; leave out one or the other."
    )
