"""The removal check on the McKibben rig: friction's bound from the physics, and acquisition that
completes with friction while a weight left hanging is still caught.

The bound (labcli.papers.takuma2014.friction): an unloaded baseline lies within ``mu P`` of the
frictionless rest on each chamber, so two baselines differ by at most ``2 mu P``; the simulated
rig must stay within it.  Then the session's guard on the rig itself: the unattended run that
stopped at trial 18 with "The readings have not returned since the last load" (the kind rig at
twice its friction) completes, and a weight left on the default rig is named.
"""

from __future__ import annotations

import io
import math
import sys
from pathlib import Path

import numpy as np
import pytest

from labcli.core.protocol import load_protocol
from labcli.papers.takuma2014.friction import SLEEVE_FRICTION_MAX, baseline_hold
from labcli.papers.takuma2014.protocol import load_plan
from labcli.papers.takuma2014.sim.drive import simulate_weight_trials
from labcli.papers.takuma2014.sim.nonideal import NonIdeal
from labcli.papers.takuma2014.sim.rig import SimRig

ROOT = Path(__file__).resolve().parents[3]
sys.path.insert(0, str(ROOT / "tests" / "benchmarks"))
from sensing_accuracy import _Recorder  # noqa: E402


def test_the_bound_is_twice_the_largest_friction_share_of_each_chambers_pressure():
    hold = baseline_hold(("MPa", "MPa", "MPa", "MPa", "rad", "rad"))
    got = hold(np.array([0.30, 0.15, 0.45, -0.001, 0.02, -0.03]))
    assert got == pytest.approx([2 * SLEEVE_FRICTION_MAX * p for p in (0.30, 0.15, 0.45, 0.0)] + [0.0, 0.0])
    assert SLEEVE_FRICTION_MAX == 0.05  # loops up to over 10 % of the force


@pytest.mark.parametrize("protocol,supply", [("takuma2014", None), ("takuma2014-bent", (0.15, 0.15, 0.45, 0.15))])
@pytest.mark.parametrize("scale", [0.25, 2.0])
def test_friction_moves_the_unloaded_baselines_by_less_than_the_bound(protocol, supply, scale):
    proto = load_protocol(protocol)
    plan = load_plan(proto).head(40)
    friction_only = NonIdeal(**{**NonIdeal.ideal().as_dict(), "friction": scale}, realism="literature")
    rig = _Recorder(SimRig(seed=1, noise=0, nonideal=friction_only, **({"supply_MPa": supply} if supply else {})))
    simulate_weight_trials(rig, plan, calibration=proto.calibration, settle_s=8.0)
    base = np.array([np.asarray(proto.calibration.to_si(w), float).mean(axis=0)[:4] for w in rig.windows[0::2]])
    mu = rig.nonideal.magnitudes()["friction_fraction"]
    share = np.abs(np.diff(base, axis=0)) / (mu * base[1:])
    # Friction does move them (a quarter of mu P at least somewhere), by less than mu P: half the bound.
    assert 0.25 < share.max() < 1.0, share.max()


def unattended(url: str) -> tuple[int, str]:
    import tempfile

    from rich.console import Console

    from labcli.core.acquisition import acquire
    from labcli.core.ui import UnattendedUI
    from labcli.errors import LabcliError

    with tempfile.TemporaryDirectory() as tmp:
        ui = UnattendedUI(console=Console(file=io.StringIO()))
        try:
            out = acquire(Path(tmp) / "run.h5", url, protocol="takuma2014", unattended=True, ui=ui)
        except LabcliError as e:
            return -1, str(e)
        return out.stored, out.message


def test_the_run_friction_stopped_at_trial_18_now_completes():
    # The kind rig at twice its sleeve friction (1 % of the pressure force): before the removal
    # check allowed for friction this run stopped at trial 18, its baseline "still 65% of the way
    # to the loaded ones (P_L2 -1.16 kPa from the baseline, -2.62 kPa under the load)".
    stored, message = unattended("sim://?seed=1&realism=kind&friction=2")
    assert stored == 108, message


def test_a_weight_left_on_the_literatures_rig_is_caught(tmp_path):
    """Twelve trials round the compass, then 1000 g left hanging: the next baseline is stopped."""
    from rich.console import Console

    from labcli.core.device import Device
    from labcli.core.engine import RunEngine
    from labcli.core.simoperator import operator_for
    from labcli.core.store import RunFile
    from labcli.core.ui import UnattendedUI
    from labcli.errors import DeviceError
    from labcli.papers.takuma2014.session import force_session
    from labcli.papers.takuma2014.tables import load_plan as read_plan

    loads = [(1000, d) for d in (-60, 30, 150, -150, 90, -90, 0, 180, -30, 60, 120, -120)] + [(1000, 45), (500, 0)]
    csv = tmp_path / "plan.csv"
    csv.write_text(
        "trial,set,mass_g,direction_deg\n" + "".join(f"{i},fit,{m},{d}\n" for i, (m, d) in enumerate(loads, 1))
    )
    protocol, url = load_protocol("takuma2014"), "sim://?seed=5&realism=literature"
    dev = Device.open(url)
    plan = read_plan(csv)
    store = RunFile.create(tmp_path / "run.h5", protocol=protocol, device_info=dev.info, port=url, plan=plan)
    ui = UnattendedUI(console=Console(file=io.StringIO()))
    engine = RunEngine(
        dev,
        store,
        protocol,
        ui,
        run_path=str(tmp_path / "run.h5"),
        resume_command="",
        simulated_operator=operator_for(dev),
    )
    rig, removals = dev.rig, []
    remove = rig.remove_weight

    def forgetful() -> None:  # the experimenter forgets the 13th weight
        removals.append(1)
        if len(removals) != 13:
            remove()

    rig.remove_weight = forgetful
    with pytest.raises(DeviceError) as e:
        engine.run(force_session(protocol, plan))
    store.close()
    dev.close()
    assert str(e.value).startswith("The readings have not returned since the last load: they are still ")
    assert "the last weight may still hang on the pulley; the 13 completed trials in " in str(e.value)
    assert math.isclose(rig.true_state()["load"]["mass_kg"], 1.0)


def test_the_simulated_trials_refuse_a_vent_side_they_cannot_take():
    """The session's per-load side is not simulated by the driver: it is refused, not vented as nothing."""
    proto = load_protocol("takuma2014")
    plan = load_plan(proto).head(2)
    rig = SimRig(seed=1, noise=0)
    with pytest.raises(ValueError, match="relief_vent must be 'L' or 'R' here, not 'load'"):
        simulate_weight_trials(rig, plan, calibration=proto.calibration, relief_vent_s=2.0, relief_vent="load")
