"""The rPAM joint optimiser (Section IV) and ``labcli optimize``."""

from __future__ import annotations

import json
import math
import re

import numpy as np
import pytest
from click.testing import CliRunner

from labcli.cli import cli
from labcli.errors import ConfigError, ModelError
from labcli.experiments.rpam2015.models import rpam
from labcli.experiments.rpam2015.protocol import read_rpam_protocol
from labcli.experiments.rpam2015.models import rpam_optimize as ro

PATH, RAW = read_rpam_protocol("rpam2015")
ACT = rpam.actuator_from_protocol(RAW, PATH)
BOUNDS, SETTINGS = ro.settings_from_protocol(RAW, PATH)
QUICK = ("optimize.popsize=6", "optimize.maxiter=40")


@pytest.fixture(scope="module")
def shipped():
    """One optimisation with the shipped defaults (seed 2015)."""
    return ro.optimize_protocol("rpam2015")


def test_settings_read_the_papers_constants():
    assert (SETTINGS.Pa_MPa, SETTINGS.Pb_MPa) == pytest.approx((0.096, 0.041))
    assert BOUNDS.L1_m == (0.03, 0.06) and BOUNDS.L3_m == (0.03, 0.06)
    assert BOUNDS.actuator_length_m == (0.07, 0.14) and BOUNDS.alpha_deg == (0.0, 90.0)


def test_same_seed_same_optimum_other_seed_runs_independently():
    a = ro.optimize_protocol("rpam2015", overrides=QUICK, seed=7)
    b = ro.optimize_protocol("rpam2015", overrides=QUICK, seed=7)
    assert a.to_dict() == b.to_dict()
    assert [h["alpha_deg"] for h in a.history] == [h["alpha_deg"] for h in b.history]
    c = ro.optimize_protocol("rpam2015", overrides=QUICK, seed=8)
    assert c.to_dict()["seed"] == 8 and c.to_dict() != a.to_dict()


def test_shipped_optimum_is_balanced_on_the_valid_side_of_the_toggle(shipped):
    g = shipped.geometry
    assert 0 <= shipped.toggle_margin_deg
    assert shipped.alpha_rad < math.atan2(g.L2_m, g.L3_m)
    ma, mb = rpam.moment_arms(shipped.alpha_rad, g)
    assert ma > 0 and mb >= 0
    assert abs(float(rpam.joint_torque(shipped.alpha_rad, 0.096, 0.041, g, ACT))) < 1e-9
    # g2-g7 all hold.
    for v, (lo, hi) in ((g.L1_m, BOUNDS.L1_m), (g.L2_m, BOUNDS.L2_m), (g.L3_m, BOUNDS.L3_m),
                        (shipped.L_a_m, BOUNDS.actuator_length_m), (shipped.L_b_m, BOUNDS.actuator_length_m),
                        (shipped.alpha_deg, BOUNDS.alpha_deg)):
        assert lo - 1e-12 <= v <= hi + 1e-12


def test_shipped_optimum_puts_l1_at_its_lower_bound_and_beats_every_grid_design(shipped):
    assert shipped.geometry.L1_m == pytest.approx(0.03, abs=1e-5)
    assert "g2: L1 at lower bound 0.03 m" in shipped.active
    # No design on a 2 mm grid over g2-g4 does better.
    L1, L2, L3 = np.meshgrid(np.linspace(0.03, 0.06, 16), np.linspace(0.07, 0.14, 36),
                             np.linspace(0.03, 0.06, 16), indexing="ij")
    cost = ro.design_cost(np.stack([L1.ravel(), L2.ravel(), L3.ravel()]), ACT, BOUNDS, SETTINGS)
    assert -cost.min() <= shipped.alpha_deg + 1e-9
    # ...and it beats the paper's own optimum evaluated with the same actuator constants.
    paper = rpam.equilibrium_angle(0.096, 0.041, rpam.JointGeometry(0.03, 0.1048, 0.06), ACT)
    assert shipped.alpha_deg > math.degrees(paper)


def test_shipped_optimum_sits_where_actuator_a_reaches_its_free_length_at_the_toggle(shipped):
    # Why L3 ends inside its range: the joint turns until a is unloaded (its free length at
    # 96 kPa) just as b's line reaches the pivot; a larger L3 lowers atan(L2/L3).
    free = float(rpam.loaded_length(0.096, 0.0, ACT))
    assert shipped.L_a_m == pytest.approx(free, abs=2e-4)
    assert shipped.toggle_margin_deg < 0.05
    assert BOUNDS.L3_m[0] < shipped.geometry.L3_m < BOUNDS.L3_m[1]


def test_toggle_margin_option_keeps_the_optimum_away_from_the_toggle():
    r = ro.optimize_protocol("rpam2015", overrides=QUICK + ("optimize.min_toggle_margin_deg=3",), seed=1)
    assert r.toggle_margin_deg >= 3 - 1e-6


def test_design_cost_ranks_feasible_then_violating_then_toggling():
    X = np.array([[0.03, 0.1048, 0.06], [0.06, 0.14, 0.03], [0.03, 0.07, 0.06]]).T
    eq = rpam.solve_equilibrium(0.096, 0.041, rpam.JointGeometry(*X), ACT)
    cost = ro.design_cost(X, ACT, BOUNDS, SETTINGS)
    assert cost[0] == pytest.approx(-eq.alpha_deg[0])
    assert eq.L_a_m[1] > 0.14 and cost[1] == pytest.approx(100 + 1e3 * (eq.L_a_m[1] - 0.14))
    assert eq.status[2] == rpam.TOGGLE and cost[2] == 1000.0
    assert ro.design_cost(X[:, 0], ACT, BOUNDS, SETTINGS) == pytest.approx(cost[0])


def test_active_constraints_names_each_bound_met():
    g = rpam.JointGeometry(0.03, 0.1, 0.0599)
    act = ro.active_constraints(g, 45.0, 0.1400, 0.0701, BOUNDS, 0.005)
    assert act == ["g2: L1 at lower bound 0.03 m", "g4: L3 at upper bound 0.06 m",
                   "g5: L_a at upper bound 0.14 m", "g6: L_b at lower bound 0.07 m"]
    assert ro.active_constraints(g, 45.0, 0.1, 0.1, BOUNDS, 1e-6) == ["g2: L1 at lower bound 0.03 m"]


def test_impossible_pressures_are_reported():
    with pytest.raises(ModelError) as e:
        ro.optimize_protocol("rpam2015", overrides=QUICK, Pa_kPa=30, Pb_kPa=96)
    assert str(e.value) == ("No link lengths within g2-g4 give a balanced joint (g1) that also meets g5-g7 at "
                            "Pa = 30 kPa, Pb = 96 kPa; check the pressures and the actuator constants.")


def test_bad_optimizer_settings_are_one_sentence():
    with pytest.raises(ConfigError) as e:
        ro.optimize_protocol("rpam2015", overrides=("optimize.popsize=2.5",))
    assert str(e.value).startswith("Protocol key 'optimize.popsize' in ")
    assert str(e.value).endswith("must be a whole number, got 2.5.")


# --------------------------------------------------------------------------- command line


def test_cli_json_reports_the_optimum_and_honours_overrides():
    args = ["optimize", "--seed", "3", "--json", "--pa", "90", "--pb", "41", "--set", QUICK[0], "--set", QUICK[1]]
    result = CliRunner().invoke(cli, args)
    assert result.exit_code == 0, result.output
    d = json.loads(result.stdout)
    assert (d["Pa_kPa"], d["Pb_kPa"], d["seed"], d["popsize"]) == (90.0, 41.0, 3, 6)
    assert d["alpha_deg"] < d["toggle_deg"]
    g = rpam.JointGeometry(d["L1_m"], d["L2_m"], d["L3_m"])
    assert math.degrees(rpam.equilibrium_angle(0.090, 0.041, g, ACT)) == pytest.approx(d["alpha_deg"], abs=1e-9)


def test_cli_text_output_has_units():
    result = CliRunner().invoke(cli, ["optimize", "--seed", "1", "--set", QUICK[0], "--set", QUICK[1]])
    assert result.exit_code == 0, result.output
    lines = result.stdout.splitlines()
    assert lines[0] == "Optimum at Pa = 96 kPa, Pb = 41 kPa (seed 1, 40 generations):"
    for name, line in zip(("L1", "L2", "L3"), lines[1:4]):
        assert re.fullmatch(rf"  {name}    = 0\.\d{{4}} m", line)
    assert re.fullmatch(r"  alpha = \d+\.\d\d deg", lines[4])
    assert re.fullmatch(r"  L_a   = 0\.\d{4} m, L_b = 0\.\d{4} m", lines[5])
    assert re.fullmatch(r"  toggle angle atan\(L2/L3\) = \d+\.\d\d deg, \S+ deg beyond the optimum", lines[6])
    assert lines[7].startswith("  active constraints: ")


def test_cli_unknown_key_is_one_clear_line():
    result = CliRunner().invoke(cli, ["optimize", "--set", "actuator.L0=0.08"])
    assert result.exit_code == 1
    assert result.output == ("Error: Unknown protocol key 'actuator.L0' in --set; keys under actuator: "
                             "A0_m2, L0_m, n_turns, prestretch, thread_length_m.\n")


def test_cli_missing_protocol_is_one_clear_line():
    result = CliRunner().invoke(cli, ["optimize", "--protocol", "nosuch"])
    assert result.exit_code == 1
    assert result.output == "Error: No protocol named 'nosuch'; give a .toml path or a shipped name (rpam2015, takuma2014, takuma2014-stiffness).\n"
