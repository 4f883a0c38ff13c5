"""The bent-rest protocol (protocols/takuma2014-bent.toml), its plan, and the [sensing] limits."""

from __future__ import annotations

import importlib.util
import math
import sys
from pathlib import Path

import pytest

from labcli.core.protocol import load_protocol
from labcli.errors import ConfigError
from labcli.papers.takuma2014.models.posture import DEFAULT_LIMITS, limits_from_protocol
from labcli.papers.takuma2014.protocol import load_plan

PROTOCOLS = Path(__file__).resolve().parents[3] / "protocols"


def _bent_plan_module():
    sys.path.insert(0, str(PROTOCOLS))  # make_bent_plan imports make_plan beside it
    try:
        spec = importlib.util.spec_from_file_location("make_bent_plan", PROTOCOLS / "make_bent_plan.py")
        mod = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(mod)
    finally:
        sys.path.remove(str(PROTOCOLS))
    return mod


def test_bent_plan_script_regenerates_the_shipped_plan_byte_for_byte(tmp_path: Path) -> None:
    mod = _bent_plan_module()
    out = tmp_path / "plan.csv"
    mod.main(["--out", str(out)])
    assert out.read_bytes() == (PROTOCOLS / "takuma2014-bent-plan.csv").read_bytes()


def test_bent_plan_loads_in_every_direction_along_the_arm_included() -> None:
    p = load_protocol("takuma2014-bent")
    plan = load_plan(p)
    fit, val = plan[plan["set"] == "fit"], plan[plan["set"] == "validation"]
    assert (len(fit), len(val)) == (90, 18)
    # every fit mass meets every fit direction once; 10 directions 36 deg apart, straight down first
    assert sorted(set(fit["direction_deg"])) == sorted(((-90 + 36 * k + 180) % 360) - 180 for k in range(10))
    assert len(set(zip(fit["mass_g"], fit["direction_deg"], strict=False))) == 90
    for along in (-90, 90):
        assert along in set(fit["direction_deg"]) and along in set(val["direction_deg"])
    assert not set(val["direction_deg"]) & {-54, -18, 18, 54, 126, 162, -162, -126}
    assert p.settings.rig == load_protocol("takuma2014").settings.rig


def test_sensing_limits_come_from_the_protocol(tmp_path: Path) -> None:
    limits = limits_from_protocol(load_protocol("takuma2014-bent"))
    assert limits["Fy"] == 1.0 and limits["theta2"] == pytest.approx(math.radians(0.5))
    assert limits_from_protocol(object()) == DEFAULT_LIMITS
    text = (PROTOCOLS / "takuma2014-bent.toml").read_text().replace("max_force_se_N = 1.0", "max_force_se_N = 0")
    (tmp_path / "bad.toml").write_text(text)
    (tmp_path / "takuma2014-bent-plan.csv").write_bytes((PROTOCOLS / "takuma2014-bent-plan.csv").read_bytes())
    with pytest.raises(ConfigError, match="max_force_se_N"):
        load_protocol(tmp_path / "bad.toml")


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_the_bent_supply_rests_the_arm_at_10_to_20_deg_with_the_outside_pair_below_the_paper(seed: int) -> None:
    from labcli.papers.takuma2014.demo import BENT_SUPPLY
    from labcli.papers.takuma2014.sim.options import parse_supply
    from labcli.papers.takuma2014.sim.rig import SimRig

    # The protocol file names the regulators the demo and benchmarks use.
    assert f"sim://?supply={BENT_SUPPLY}" in (PROTOCOLS / "takuma2014-bent.toml").read_text()
    supply = parse_supply(BENT_SUPPLY)
    # Sleeve friction scales with pressure: the outside pair (the bottom joint) below the
    # paper's 0.30 MPa, the inside pair unequal so the upper joint rests bent.
    assert supply[0] == supply[1] < 0.30 and supply[2] > supply[3]
    rig = SimRig(seed=seed, supply_MPa=supply)
    rig.supply_air()
    rig.advance(8.0)
    rig.close_valves()
    rig.advance(8.0)
    assert 10.0 <= math.degrees(rig.true_state()["theta_rad"][1]) <= 20.0
