"""The friction relief by venting one side (acquisition.friction_relief_vent_s) and the posture form's
relieved friction terms (PostureModel(friction="relieved")): their physics on the simulated rig."""

from __future__ import annotations

import json
import math
import sys
from pathlib import Path

import numpy as np
import pytest

from labcli.errors import ModelError
from labcli.papers.takuma2014.analyses import friction_of
from labcli.papers.takuma2014.models.posture import (
    RELIEVED_BASELINES,
    RELIEVED_TERMS,
    TORQUE_TERMS,
    PostureModel,
    limits_from_protocol,
    relieved_columns,
    running_baseline,
    torque_features,
)
from labcli.papers.takuma2014.sim import physics as ph
from labcli.papers.takuma2014.sim.nonideal import NonIdeal, friction_forces
from labcli.papers.takuma2014.sim.rig import SimRig

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))

LOADS_DEG = (0.0, 180.0, 90.0, -90.0, 0.0, 180.0)  # opposite loads, one after the other
VENT_L = ("vent", "hold", "vent", "hold")


def _baselines(relief: tuple[str, ...] | None) -> np.ndarray:
    """The true posture (deg) and pressures (kPa) of each baseline after a 700 g load in each of
    LOADS_DEG, on the literature's rig (tuning seed 3), with the chambers ``relief`` (valve states)
    for 2 s, then supplied for 3 s and held, before each baseline; None: no relief."""
    rig = SimRig(seed=3, nonideal=NonIdeal(realism="literature"))
    rig.supply_air()
    rig.advance(8.0)
    rig.close_valves()
    rig.advance(8.0)
    out = []
    for d in LOADS_DEG:
        rig.hang_weight(0.7, math.radians(d))
        rig.advance(8.0)
        rig.remove_weight()
        if relief is not None:
            rig.set_valves(relief)
            rig.advance(2.0)
            rig.supply_air()
            rig.advance(3.0)
            rig.close_valves()
        rig.advance(8.0)
        state = rig.true_state()
        out.append([*np.degrees(state["theta_rad"]), *(np.asarray(state["pressures_MPa"]) * 1e3)])
    return np.array(out)


def test_venting_one_side_brings_every_baseline_back_from_that_side() -> None:
    """After opposite loads the baselines differ by friction's band; vented on one side and supplied
    again, they agree to within the pressure sensors' repeatability (0.33 kPa rms); venting all four
    chambers leaves the straight arm's band (its vented posture is close to its rest)."""
    none, one_side, all_four = _baselines(None), _baselines(VENT_L), _baselines(("vent",) * 4)
    spread = {k: np.ptp(v, axis=0) for k, v in (("none", none), ("one side", one_side), ("all", all_four))}
    assert spread["none"][:2].max() > 0.5 and spread["none"][2:].max() > 2.0  # deg, kPa
    assert spread["all"][:2].max() > 0.3
    assert spread["one side"][:2].max() < 0.05
    assert spread["one side"][2:].max() < 0.66  # two repeatability sd: the leak's drift over the run


def test_relieved_columns_are_the_load_motions_sign_and_a_constant() -> None:
    big = math.radians(2.0)
    cols = relieved_columns(np.array([[big, 0.0], [-big, 2 * big], [0.0, 0.0]]))
    np.testing.assert_allclose(cols, [[1, 1, 1], [-1, 1, 1], [0, 0, 1]], atol=1e-6)
    rng = np.random.default_rng(0)
    dP, dth = rng.normal(size=(5, 4)), rng.normal(size=(5, 2))
    both = torque_features(dP, dth, TORQUE_TERMS + RELIEVED_TERMS)
    assert np.array_equal(both[:, : len(TORQUE_TERMS)], torque_features(dP, dth))
    np.testing.assert_allclose(both[:, len(TORQUE_TERMS) :], relieved_columns(dth))


def test_a_protocol_that_vents_before_each_baseline_has_the_fit_offer_the_relieved_terms(tmp_path) -> None:
    from labcli.core.protocol import load_protocol

    shipped = load_protocol("takuma2014")
    assert friction_of(shipped) is False
    path = tmp_path / "p.toml"
    path.write_text(
        shipped.text.replace(
            "rate_hz = 200.0\n", "rate_hz = 200.0\nfriction_relief_s = 3.0\nfriction_relief_vent_s = 2.0\n"
        )
    )
    assert friction_of(load_protocol(str(path)), True) == "relieved"
    with pytest.raises(ModelError, match="Unknown friction terms 'sometimes'"):
        PostureModel(geometry=shipped.settings.rig, friction="sometimes").fit(None)


@pytest.fixture(scope="module")
def relieved_run():
    """The straight protocol on the literature's rig, tuning seed 3, vented on the L side for 2 s
    and supplied for 3 s before each baseline (108 trials)."""
    from sensing_accuracy import trials

    return trials(  # 8 s waits, the valves held between reliefs: the run the figures below were measured on
        "takuma2014",
        3,
        8.0,
        rig_kw={"nonideal": NonIdeal(realism="literature")},
        relief_s=3.0,
        relief_vent_s=2.0,
        repressurise_kPa=0.0,
    )


def test_the_fitted_friction_is_the_rigs(relieved_run) -> None:
    """The load term's torque on joint 2 is the inside pair's friction, the rig's FRICTION share of
    its pressure force at the supply over its pulley radius; the constant is minus the load term
    (every baseline approached from the same side: sign(now) - 1)."""
    proto, table = relieved_run
    model = PostureModel(geometry=proto.settings.rig, limits=limits_from_protocol(proto), friction="relieved")
    model.fit(table)
    kept = dict(zip(model.torque_terms, np.asarray(model.torque_coefficients), strict=True))
    assert "friction_rest" in kept and ("friction1_load" in kept or "friction2_load" in kept)
    load = kept.get("friction2_load", kept.get("friction1_load"))
    rig = SimRig(seed=3, nonideal=NonIdeal(realism="literature"))
    supplied = ph.Chambers.open(np.full(4, rig.params.supply_pa))
    rest = rig.true_state()["rest_theta_rad"]
    share = NonIdeal(realism="literature").magnitudes()["friction_fraction"]
    inside = rig.params.geometry.r2 * friction_forces(rest, rig.params, supplied, share)[2:].sum()
    assert load[1] / inside == pytest.approx(1.0, abs=0.5)
    # Within 30 %: the angle labels the terms are fitted with carry the play's correction, and the
    # relieved run, every baseline approached from one side, leaves the play's width loosely fitted
    # (this seed: the constant 1.25 times the load term on joint 1, 1.17 on joint 2).
    np.testing.assert_allclose(kept["friction_rest"], -load, rtol=0.3)


def test_the_relieved_terms_lower_the_force_error_and_survive_the_file(relieved_run) -> None:
    proto, table = relieved_run
    rig, limits = proto.settings.rig, limits_from_protocol(proto)
    plain = PostureModel(geometry=rig, limits=limits).fit(table)
    relieved = PostureModel(geometry=rig, limits=limits, friction="relieved").fit(table)
    assert not set(plain.torque_terms) & set(RELIEVED_TERMS)

    def rmse(model: PostureModel) -> float:
        val = table[table["set"] == "validation"]
        return float(np.sqrt(np.mean((model.predict_table(val)["Fx_N"] - val["Fx_N"].to_numpy()) ** 2)))

    # At least a tenth lower on this tuning seed (tests/benchmarks/friction_estimator.py: seeds 11-30).
    assert rmse(relieved) < 0.9 * rmse(plain)
    again = PostureModel.from_dict(relieved.to_dict())
    assert again.torque_terms == relieved.torque_terms and rmse(again) == pytest.approx(rmse(relieved))


def test_a_relieved_run_is_fitted_with_its_terms_by_labcli_fit_and_not_exported_to_the_board(
    relieved_run, tmp_path
) -> None:
    from click.testing import CliRunner

    from labcli.cli import cli
    from labcli.core.protocol import load_protocol

    proto, table = relieved_run
    toml = tmp_path / "relieved.toml"
    toml.write_text(
        load_protocol("takuma2014").text.replace(
            "rate_hz = 200.0\n", "rate_hz = 200.0\nfriction_relief_s = 3.0\nfriction_relief_vent_s = 2.0\n"
        )
    )
    csv = tmp_path / "trials.csv"
    table.to_csv(csv, index=False)
    model = tmp_path / "model.json"
    result = CliRunner().invoke(cli, ["fit", str(csv), "--protocol", str(toml), "-o", str(model)])
    assert result.exit_code == 0, result.output
    fitted = PostureModel.from_dict(json.loads(model.read_text()))
    assert "friction_rest" in fitted.torque_terms and fitted.baseline_mean == RELIEVED_BASELINES
    header = tmp_path / "model.h"
    result = CliRunner().invoke(cli, ["export-model", str(model), "--c", str(header), "--protocol", str(toml)])
    assert result.exit_code != 0 and "the board's estimator does not compute" in result.output
    assert not header.exists()


def test_the_running_baseline_is_the_mean_of_a_trials_own_and_the_ones_before_it() -> None:
    trial = np.array([3, 1, 4, 2])  # rows out of trial order
    P0 = np.array([[3.0, 30.0], [1.0, 10.0], [4.0, np.nan], [2.0, 20.0]])
    got = running_baseline(trial, P0, 2)
    # trial 1 alone; 2 with 1; 3 with 2; 4 with 3 (its own second chamber unknown: unknown).
    np.testing.assert_allclose(got, [[2.5, 25.0], [1.0, 10.0], [3.5, np.nan], [1.5, 15.0]])
    assert np.array_equal(running_baseline(trial, P0, 1), P0, equal_nan=True)


def test_a_relieved_runs_baselines_repeat_and_their_mean_lowers_the_angle_error(relieved_run) -> None:
    """Relieved, successive baselines differ by little more than the pressure sensors' repeatability
    (0.33 kPa rms per reading, so 0.47 kPa for a difference; the drift and the noise add a little):
    averaging them takes it out of P0."""
    proto, table = relieved_run
    p0 = table[["P_L10", "P_R10", "P_L20", "P_R20"]].to_numpy() * 1e3
    step = np.diff(p0, axis=0).std(axis=0)
    assert np.all((0.3 < step) & (step < 0.8)), step
    rig, limits = proto.settings.rig, limits_from_protocol(proto)
    own = PostureModel(geometry=rig, limits=limits, friction="relieved").fit(table)
    mean = PostureModel(geometry=rig, limits=limits, friction="relieved", baseline_mean=RELIEVED_BASELINES)
    mean.fit(table)
    val = table[table["set"] == "validation"]

    def rmse(model: PostureModel) -> float:
        return float(np.sqrt(np.mean((np.degrees(model.predict_table(val)["theta2_rad"]) - val["theta2_deg"]) ** 2)))

    assert rmse(mean) < 0.9 * rmse(own)
    again = PostureModel.from_dict(mean.to_dict())
    assert again.baseline_mean == RELIEVED_BASELINES and rmse(again) == pytest.approx(rmse(mean))
    with pytest.raises(ModelError, match="key 'baseline_mean' must be a whole number of baselines"):
        PostureModel.from_dict({**mean.to_dict(), "baseline_mean": 0.5})
