"""The rPAM joint optimiser (Section IV) and ``labcli optimize``."""

from __future__ import annotations

import json
import math
import re
from dataclasses import replace

import numpy as np
import pytest
from click.testing import CliRunner

from labcli.cli import cli
from labcli.core.protocol import check_document
from labcli.errors import ConfigError, ModelError
from labcli.papers.rpam2015.models import rpam
from labcli.papers.rpam2015.models import rpam_optimize as ro
from labcli.papers.rpam2015.protocol import load_rpam

PROTOCOL = load_rpam("rpam2015")
PATH, RAW = PROTOCOL.path, PROTOCOL.document
ACT = PROTOCOL.settings.actuator
BOUNDS, SETTINGS = ro.optimizer_settings(PROTOCOL.settings, str(PATH))
QUICK = ("optimize.popsize=6", "optimize.maxiter=40")


@pytest.fixture(scope="module")
def shipped():
    """One optimisation with the shipped constants and seed 1 (the shipped check)."""
    return ro.optimize_protocol("rpam2015", seed=1)


def test_settings_read_the_papers_constants():
    assert (SETTINGS.Pa_MPa, SETTINGS.Pb_MPa) == pytest.approx((0.096, 0.041))
    assert BOUNDS.L1_m == (0.03, 0.06) and BOUNDS.L3_m == (0.03, 0.06)
    assert BOUNDS.actuator_length_m == (0.07, 0.14) and BOUNDS.alpha_deg == (0.0, 90.0)
    assert SETTINGS.paper_links_m == (0.03, 0.1048, 0.06) and SETTINGS.paper_alpha_deg == 58.4
    # K_min is the weight torque gradient m g d of a 50 g link 0.14 m from the pivot, rounded up.
    assert SETTINGS.min_stiffness_Nm_per_rad == pytest.approx(0.05 * 9.80665 * 0.14, abs=0.002)
    assert SETTINGS.min_toggle_margin_deg == 1.0


def test_same_seed_same_optimum_other_seed_runs_independently():
    a = ro.optimize_protocol("rpam2015", overrides=QUICK, seed=7)
    b = ro.optimize_protocol("rpam2015", overrides=QUICK, seed=7)
    assert a.to_dict() == b.to_dict()
    assert [h["alpha_deg"] for h in a.history] == [h["alpha_deg"] for h in b.history]
    c = ro.optimize_protocol("rpam2015", overrides=QUICK, seed=8)
    assert c.to_dict()["seed"] == 8 and c.to_dict() != a.to_dict()


def test_shipped_optimum_is_a_joint_that_holds(shipped):
    g, d = shipped.geometry, shipped.to_dict()
    assert d["stiffness_Nm_per_rad"] >= SETTINGS.min_stiffness_Nm_per_rad > 0
    assert d["toggle_margin_deg"] >= 1.0
    assert abs(float(rpam.joint_torque(shipped.alpha_rad, 0.096, 0.041, g, ACT))) < 1e-9
    # The stiffness is what the torque does next to the balance, and both arms are positive.
    h = 1e-3
    assert float(rpam.joint_torque(shipped.alpha_rad + h, 0.096, 0.041, g, ACT)) == pytest.approx(
        -d["stiffness_Nm_per_rad"] * h, rel=0.02
    )
    ma, mb = rpam.moment_arms(shipped.alpha_rad, g)
    assert (d["arm_a_m"], d["arm_b_m"]) == pytest.approx((float(ma), float(mb)), rel=1e-12)
    assert ma > 0 and mb > 0 and d["F_a_N"] > 0 and d["F_b_N"] > 0
    assert d["F_a_N"] * d["arm_a_m"] == pytest.approx(d["F_b_N"] * d["arm_b_m"], rel=1e-9)  # g1
    # g2-g7 all hold.
    for v, (lo, hi) in (
        (g.L1_m, BOUNDS.L1_m),
        (g.L2_m, BOUNDS.L2_m),
        (g.L3_m, BOUNDS.L3_m),
        (d["L_a_m"], BOUNDS.actuator_length_m),
        (d["L_b_m"], BOUNDS.actuator_length_m),
        (d["alpha_deg"], BOUNDS.alpha_deg),
    ):
        assert lo - 1e-12 <= v <= hi + 1e-12


def test_shipped_optimum_is_held_by_g5_and_k_min_with_l3_at_its_lower_bound(shipped):
    assert shipped.active == [
        "g4: L3 at lower bound 0.03 m",
        "g5: L_a at upper bound 0.14 m",
        "K_min: stiffness at its minimum 0.07 N m/rad",
    ]
    # Actuator a still pushes at g5's 0.14 m: at 96 kPa it would extend to 0.145 m unloaded,
    # so g5, not the toggle, caps the angle.
    assert float(rpam.loaded_length(0.096, 0.0, ACT)) > 0.145
    assert shipped.optimum.F_a_N > 3.0
    # Every grid neighbour 0.1 mm away that turns further misses a constraint.
    x0 = np.array([shipped.geometry.L1_m, shipped.geometry.L2_m, shipped.geometry.L3_m])
    steps = np.array(np.meshgrid(*[[-1e-4, 0.0, 1e-4]] * 3, indexing="ij")).reshape(3, -1)
    X = np.clip(x0[:, None] + steps, [[0.03], [0.07], [0.03]], [[0.06], [0.14], [0.06]])
    for x in X.T:
        r = ro.evaluate_design(rpam.JointGeometry(*x), ACT, BOUNDS, SETTINGS)
        if r.balanced and r.alpha_deg > shipped.alpha_deg + 1e-6:
            assert r.violated, x


def test_no_design_on_a_grid_does_better(shipped):
    # A 2 mm grid over g2-g4, one L1 slice per call to keep the arrays small.
    best = -np.inf
    L2, L3 = np.meshgrid(np.linspace(0.07, 0.14, 36), np.linspace(0.03, 0.06, 16), indexing="ij")
    for L1 in np.linspace(0.03, 0.06, 16):
        cost = ro.design_cost(np.stack([np.full(L2.size, L1), L2.ravel(), L3.ravel()]), ACT, BOUNDS, SETTINGS)
        best = max(best, -cost.min())
    assert 0 < best <= shipped.alpha_deg + 1e-9


def test_the_printed_design_is_on_the_grid_feasible_and_balances_near_the_optimum(shipped):
    r = shipped.rounded
    for v in (r.geometry.L1_m, r.geometry.L2_m, r.geometry.L3_m):
        assert abs(v / ro.ROUND_M - round(v / ro.ROUND_M)) < 1e-9
    assert r.feasible
    assert abs(r.alpha_deg - shipped.alpha_deg) <= ro.ROUNDING_TOLERANCE_DEG
    # The numbers as printed, typed back in, give the same balance.
    typed = rpam.JointGeometry(*(float(f"{v:.4f}") for v in (r.geometry.L1_m, r.geometry.L2_m, r.geometry.L3_m)))
    assert math.degrees(rpam.equilibrium_angle(0.096, 0.041, typed, ACT)) == pytest.approx(r.alpha_deg, abs=1e-9)


def test_a_design_too_sensitive_to_print_is_refused():
    # A fake optimum whose angle no 0.1 mm grid point comes near.
    r = ro.evaluate_design(rpam.JointGeometry(0.0304, 0.1124, 0.0302), ACT, BOUNDS, SETTINGS)
    fake = ro.DesignReport(**{**r.__dict__, "alpha_rad": r.alpha_rad + math.radians(1.0)})
    with pytest.raises(ModelError) as e:
        ro.round_design(fake, ACT, BOUNDS, SETTINGS)
    assert str(e.value).startswith(
        f"The optimum (alpha = {fake.alpha_deg:.2f} deg) is too sensitive to build: "
        "on a 0.1 mm grid the best design balances at "
    )
    assert str(e.value).endswith("; raise optimize.min_stiffness_Nm_per_rad.")


def test_the_papers_design_is_evaluated_with_the_same_model(shipped):
    p = shipped.paper
    assert (p.geometry.L1_m, p.geometry.L2_m, p.geometry.L3_m) == (0.03, 0.1048, 0.06)
    # With the derived force actuator a still pushes at the toggle: the joint runs onto it.
    assert not p.balanced and not p.feasible
    assert p.violated == ["g1: no balance below the toggle angle, the joint runs onto it"]
    assert math.degrees(p.toggle_rad) == pytest.approx(60.21, abs=0.01)
    assert float(rpam.joint_torque(p.toggle_rad * (1 - 1e-6), 0.096, 0.041, p.geometry, ACT)) > 0
    d = shipped.to_dict()["paper"]
    assert d["reported_alpha_deg"] == 58.4 and d["alpha_deg"] is None and d["balanced"] is False
    # At a smaller pressure difference it balances, and the report fills in.
    low = ro.evaluate_design(p.geometry, ACT, BOUNDS, replace(SETTINGS, Pa_MPa=0.07))
    assert low.feasible and low.stiffness_Nm_per_rad > 0.07
    assert low.active == ["g2: L1 at lower bound 0.03 m", "g4: L3 at upper bound 0.06 m"]


def test_stiffness_and_margin_trade_against_the_angle():
    quick = QUICK + ("optimize.maxiter=80",)
    soft = ro.optimize_protocol("rpam2015", overrides=quick + ("optimize.min_stiffness_Nm_per_rad=0.02",), seed=1)
    stiff = ro.optimize_protocol("rpam2015", overrides=quick + ("optimize.min_stiffness_Nm_per_rad=0.3",), seed=1)
    assert stiff.optimum.stiffness_Nm_per_rad >= 0.3 and soft.optimum.stiffness_Nm_per_rad >= 0.02
    assert stiff.alpha_deg < soft.alpha_deg - 3


def test_toggle_margin_option_keeps_the_optimum_away_from_the_toggle():
    r = ro.optimize_protocol("rpam2015", overrides=QUICK + ("optimize.min_toggle_margin_deg=3",), seed=1)
    assert r.toggle_margin_deg >= 3 - 1e-6


def test_design_cost_ranks_feasible_then_violating_then_toggling():
    X = np.array(
        [
            [0.0304, 0.1124, 0.0302],  # the printed optimum: feasible
            [0.0304, 0.1122, 0.0300],  # turns further, but too soft: misses K_min only
            [0.0574, 0.1394, 0.0323],  # actuator a longer than g5's 0.14 m
            [0.03, 0.1048, 0.06],
        ]
    ).T  # the paper's design: runs onto the toggle
    cost = ro.design_cost(X, ACT, BOUNDS, SETTINGS)
    r = [ro.evaluate_design(rpam.JointGeometry(*x), ACT, BOUNDS, SETTINGS) for x in X.T]
    assert r[0].feasible and cost[0] == pytest.approx(-r[0].alpha_deg, abs=1e-12)
    assert r[1].alpha_deg > r[0].alpha_deg and 0 < r[1].stiffness_Nm_per_rad < 0.07
    assert r[1].violated == [f"K_min: stiffness {r[1].stiffness_Nm_per_rad:.4f} N m/rad below 0.07 N m/rad"]
    assert cost[1] == pytest.approx(100 + 10 * (0.07 - r[1].stiffness_Nm_per_rad) / 0.07)
    assert r[2].violated == [f"g5: L_a = {r[2].L_a_m:.4f} m outside 0.07-0.14 m"]
    assert cost[2] == pytest.approx(100 + 1e3 * (r[2].L_a_m - 0.14))
    assert not r[3].balanced and cost[3] == 1000.0
    assert ro.design_cost(X[:, 0], ACT, BOUNDS, SETTINGS) == pytest.approx(cost[0])


def test_active_constraints_names_each_bound_met():
    g = rpam.JointGeometry(0.03, 0.1, 0.0599)
    act = ro.active_constraints(g, 45.0, 0.1400, 0.0701, BOUNDS, 0.005)
    assert act == [
        "g2: L1 at lower bound 0.03 m",
        "g4: L3 at upper bound 0.06 m",
        "g5: L_a at upper bound 0.14 m",
        "g6: L_b at lower bound 0.07 m",
    ]
    assert ro.active_constraints(g, 45.0, 0.1, 0.1, BOUNDS, 1e-6) == ["g2: L1 at lower bound 0.03 m"]


def test_impossible_pressures_are_reported():
    with pytest.raises(ModelError) as e:
        ro.optimize_protocol("rpam2015", overrides=QUICK, Pa_kPa=30, Pb_kPa=96)
    assert str(e.value) == (
        "No link lengths within g2-g4 give a balanced joint (g1) that also meets g5-g7, a toggle "
        "margin of 1 deg and a stiffness of 0.07 N m/rad at Pa = 30 kPa, Pb = 96 kPa; check the "
        "pressures and the actuator constants."
    )


def test_bad_optimizer_settings_are_one_sentence():
    with pytest.raises(ConfigError) as e:
        ro.optimize_protocol("rpam2015", overrides=("optimize.popsize=2.5",))
    assert str(e.value) == (
        "Protocol rpam2015 with --set optimize.popsize=2.5: key 'optimize.popsize' must be an integer, "
        "not the number 2.5."
    )
    # A joint with no stiffness, or one allowed onto the toggle, holds nothing.
    for key in ("min_stiffness_Nm_per_rad", "min_toggle_margin_deg"):
        for value in ("0.0", "-0.1"):
            with pytest.raises(ConfigError) as e:
                ro.optimize_protocol("rpam2015", overrides=(f"optimize.{key}={value}",))
            assert str(e.value) == (
                f"Protocol rpam2015 with --set optimize.{key}={value}: key 'optimize.{key}' must be "
                f"greater than 0, not {float(value)!r}."
            )
    # A protocol from before the stiffness constraint loads, and the optimiser asks for it.
    older = load_rpam("rpam2015").document
    del older["optimize"]["min_stiffness_Nm_per_rad"]
    with pytest.raises(ConfigError) as e:
        ro.optimizer_settings(check_document(older, source="old.toml").settings, "old.toml")
    assert str(e.value) == (
        "old.toml: missing key 'optimize.min_stiffness_Nm_per_rad', expected a number in N m/rad "
        "(the least joint stiffness at the balance)."
    )


# --------------------------------------------------------------------------- command line


def test_cli_json_reports_the_optimum_and_honours_overrides():
    args = [
        "optimize",
        "--seed",
        "3",
        "--json",
        "--pa",
        "90",
        "--pb",
        "41",
        "--set",
        QUICK[0],
        "--set",
        QUICK[1],
        "--set",
        "optimize.min_stiffness_Nm_per_rad=0.1",
    ]
    result = CliRunner().invoke(cli, args)
    assert result.exit_code == 0, result.output
    d = json.loads(result.stdout)
    assert (d["Pa_kPa"], d["Pb_kPa"], d["seed"], d["popsize"]) == (90.0, 41.0, 3, 6)
    assert d["min_stiffness_Nm_per_rad"] == 0.1 and d["stiffness_Nm_per_rad"] >= 0.1
    assert d["alpha_deg"] < d["toggle_deg"] - 1
    g = rpam.JointGeometry(d["L1_m"], d["L2_m"], d["L3_m"])
    assert math.degrees(rpam.equilibrium_angle(0.090, 0.041, g, ACT)) == pytest.approx(d["alpha_deg"], abs=1e-9)
    assert set(d["paper"]) >= {"L1_m", "alpha_deg", "stiffness_Nm_per_rad", "F_a_N", "arm_b_m", "reported_alpha_deg"}


def test_cli_check_of_the_shipped_optimum():
    # The shipped check, on the command line as a person would run it.
    result = CliRunner().invoke(cli, ["optimize", "--protocol", "rpam2015", "--seed", "1", "--json"])
    assert result.exit_code == 0, result.output
    d = json.loads(result.stdout)
    assert d["stiffness_Nm_per_rad"] >= d["min_stiffness_Nm_per_rad"] > 0
    assert d["toggle_deg"] - d["alpha_deg"] >= 1.0
    for key in ("L_a_m", "L_b_m"):
        assert 0.07 <= d[key] <= 0.14 + 1e-12
    r = d["rounded"]
    typed = rpam.JointGeometry(round(r["L1_m"], 4), round(r["L2_m"], 4), round(r["L3_m"], 4))
    assert abs(math.degrees(rpam.equilibrium_angle(0.096, 0.041, typed, ACT)) - d["alpha_deg"]) <= 0.5
    assert r["feasible"] and r["stiffness_Nm_per_rad"] >= 0.07
    assert d["paper"]["balanced"] is False and d["paper"]["reported_alpha_deg"] == 58.4


def test_cli_text_output_has_units():
    result = CliRunner().invoke(cli, ["optimize", "--seed", "1", "--set", QUICK[0], "--set", QUICK[1]])
    assert result.exit_code == 0, result.output
    lines = result.stdout.splitlines()
    assert re.fullmatch(
        r"Optimum at Pa = 96 kPa, Pb = 41 kPa \(seed 1, 40 generations\): alpha = \d+\.\d\d deg, "
        r"stiffness 0\.\d{4} N m/rad \(K_min 0\.07\), \d+\.\d\d deg short of the toggle\.",
        lines[0],
    )
    assert lines[1] == (
        "Links to 0.1 mm as printed, beside the paper's design (Section IV) with the same model "
        "(actuator force read as derived):"
    )
    assert lines[3].split() == ["labcli", "paper"]
    rows = {line[:36].strip(): line[36:].split() for line in lines[4:17]}
    assert list(rows) == [
        "L1 (m)",
        "L2 (m)",
        "L3 (m)",
        "alpha (deg)",
        "toggle atan(L2/L3) (deg)",
        "margin to the toggle (deg)",
        "stiffness -dtau/dalpha (N m/rad)",
        "L_a (m)",
        "L_b (m)",
        "push of a, F_a (N)",
        "push of b, F_b (N)",
        "moment arm of a, m_a (mm)",
        "moment arm of b, m_b (mm)",
    ]
    assert rows["L2 (m)"][1] == "0.1048" and rows["alpha (deg)"][1] == "toggles"
    assert rows["toggle atan(L2/L3) (deg)"][1] == "60.21" and rows["push of a, F_a (N)"][1] == "—"
    for v in rows.values():
        float(v[0])
    assert lines[18].startswith("Active at the optimum: ") and lines[18].endswith(".")
    assert lines[19] == "The paper's design misses g1: no balance below the toggle angle, the joint runs onto it."
    assert lines[20] == "The paper reports alpha = 58.4 deg for it, with its own, unpublished actuator constants."


@pytest.fixture(scope="module")
def paper_reading():
    """The paper's reading of the force at K_min 0.2 N m/rad, on the command line (seed 1)."""
    args = ["optimize", "--force", "paper", "--min-stiffness", "0.2", "--seed", "1", "--json"]
    result = CliRunner().invoke(cli, args)
    assert result.exit_code == 0, result.output
    return json.loads(result.stdout)


def test_the_paper_reading_reproduces_the_papers_pattern(paper_reading):
    d = paper_reading
    assert d["force_reading"] == "paper" and d["min_stiffness_Nm_per_rad"] == 0.2
    # Section IV: alpha 58.4 deg with L1 at its lower bound and L3 at its upper bound.
    assert d["alpha_deg"] == pytest.approx(58.4, abs=1.5)
    assert d["L1_m"] == pytest.approx(0.03, abs=2e-3) and d["L3_m"] == pytest.approx(0.06, abs=2e-3)
    assert d["L2_m"] == pytest.approx(0.1048, abs=4e-3)
    assert "g2: L1 at lower bound 0.03 m" in d["active_constraints"]
    assert d["stiffness_Nm_per_rad"] >= 0.2
    # The balance it reports is the paper reading's, not the derived one's.
    g = rpam.JointGeometry(d["L1_m"], d["L2_m"], d["L3_m"])
    paper_act = ACT.with_force_reading("paper")
    assert math.degrees(rpam.equilibrium_angle(0.096, 0.041, g, paper_act)) == pytest.approx(d["alpha_deg"], abs=1e-9)
    # Under that reading the paper's own design balances and holds.
    assert d["paper"]["balanced"] and d["paper"]["feasible"]


def test_a_bad_min_stiffness_is_one_sentence():
    for value in ("0", "-1", "nan"):
        result = CliRunner().invoke(cli, ["optimize", "--min-stiffness", value])
        assert result.exit_code == 2
        assert "is not a stiffness a joint can hold with; give a number of N m/rad above 0." in result.output
    result = CliRunner().invoke(cli, ["optimize", "--force", "printed"])
    assert result.exit_code == 2 and "'printed' is not one of 'derived', 'paper'" in result.output


def test_cli_unknown_key_is_one_clear_line():
    result = CliRunner().invoke(cli, ["optimize", "--set", "actuator.L0=0.08"])
    assert result.exit_code == 1
    assert result.output == (
        "Error: Unknown protocol key 'actuator.L0' in --set; keys under actuator: "
        "A0_m2, L0_m, force_reading, n_turns, prestretch, thread_length_m.\n"
    )


def test_cli_missing_protocol_is_one_clear_line():
    result = CliRunner().invoke(cli, ["optimize", "--protocol", "nosuch"])
    assert result.exit_code == 1
    assert (
        result.output
        == "Error: There is no shipped protocol named 'nosuch'; shipped protocols are rpam2015, takuma2014, "
        "takuma2014-bent, takuma2014-stiffness, or give the path of a .toml file.\n"
    )
