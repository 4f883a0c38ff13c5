"""The interval's shares and the fit trials' errors by direction (interval_parts.py, captures_acquired.py
--diagnose), on a relieved run of the bent plan, and on the same run with a systematic error put into
one fit direction: the case of the literature rig's -90 deg loads, whose error the pooled residual
variance hands to every load."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))

import interval_parts as ip  # noqa: E402


@pytest.fixture(scope="module")
def relieved_bent():
    """The bent plan on the kind rig, relieved before each baseline (venting L), as a table."""
    from sensing_accuracy import BENT_SUPPLY_MPA

    from labcli.core.protocol import load_protocol
    from labcli.papers.takuma2014.protocol import load_plan
    from labcli.papers.takuma2014.sim.drive import simulate_weight_trials
    from labcli.papers.takuma2014.sim.nonideal import NonIdeal
    from labcli.papers.takuma2014.sim.rig import SimRig

    proto = load_protocol("takuma2014-bent")
    rig = SimRig(seed=1, nonideal=NonIdeal(realism="kind"), supply_MPa=BENT_SUPPLY_MPA)
    table = simulate_weight_trials(
        rig, load_plan(proto), calibration=proto.calibration, settle_s=15.0, relief_s=3.0, relief_vent_s=2.0
    )
    table["theta1_0_deg"], table["theta2_0_deg"] = 0.0, 0.0
    return proto, table


def _fit(proto, table):
    from labcli.papers.takuma2014.models.posture import PostureModel, limits_from_protocol

    model = PostureModel(geometry=proto.settings.rig, limits=limits_from_protocol(proto), friction="relieved")
    return model.fit(table)


def _offset(table, direction: float, newtons: float):
    """The table with the fit trials of one direction (200 g and more) reading ``newtons`` more Fx."""
    out = table.copy()
    at = (out["set"] == "fit") & (out["direction_deg"] == direction) & (out["mass_g"] >= 200)
    out.loc[at, "Fx_N"] += newtons
    return out


def test_the_shares_add_to_the_interval_and_the_direction_share_is_the_plans_term(relieved_bent):
    proto, table = relieved_bent
    model = _fit(proto, table)
    assert model.route("Fx") == "posture"
    parts = ip.variance_parts(model, table)["Fx"]
    # On the posture route the interval is the trial's own variance plus the plan's term, exactly.
    assert parts["direction"] == pytest.approx(model.held_out_variance["Fx"], rel=1e-9)
    assert parts["total"] == pytest.approx(parts["direction"] + parts["angle"] + parts["torque"], rel=1e-12)
    assert parts["torque"] > 0 and parts["angle"] >= 0
    # An angle has its route's own variance alone: no torque share.
    assert ip.variance_parts(model, table)["theta1"]["torque"] is None


def test_the_fit_trials_errors_by_direction_are_their_own_predictions(relieved_bent):
    proto, table = relieved_bent
    model = _fit(proto, table)
    got = ip.fit_direction_rmse(model, table)
    fit = table[table["set"] == "fit"]
    assert sorted(got) == sorted(set(fit["direction_deg"].astype(float)))
    rows = fit[fit["direction_deg"] == -90]
    err = np.asarray(model.predict_table(rows)["Fx_N"]) - np.asarray(rows["Fx_N"])
    assert got[-90.0] == pytest.approx(float(np.sqrt(np.mean(err**2))), rel=1e-9)


def test_one_directions_error_widens_every_interval_more_than_the_validation_errors_grow(relieved_bent):
    proto, table = relieved_bent
    plain = ip.variance_parts(_fit(proto, table), table)["Fx"]
    skewed = _offset(table, -90.0, 1.0)
    model = _fit(proto, skewed)
    by_direction = ip.fit_direction_rmse(model, skewed)
    others = [v for d, v in by_direction.items() if d != -90.0]
    # The diagnosis names the direction: it errs more than twice any other.
    assert by_direction[-90.0] > 2.0 * max(others)
    parts = ip.variance_parts(model, skewed)["Fx"]
    # The validation trials (no load of theirs carries the error) err a little more, through the
    # coefficients; the intervals' variance, pooled over the fit trials, grows far more.
    assert parts["torque"] > 3.0 * plain["torque"] and parts["direction"] > plain["direction"]
    assert parts["total"] / parts["mse"] > 1.5 * plain["total"] / plain["mse"]


def test_a_table_without_directions_has_no_errors_by_direction(relieved_bent):
    proto, table = relieved_bent
    model = _fit(proto, table)
    assert ip.fit_direction_rmse(model, table.drop(columns="direction_deg")) == {}
