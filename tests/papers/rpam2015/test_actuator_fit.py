"""The lab's own actuator from its stretch test: Ogden moduli, free length and radius with their
standard errors, checked on a simulated stand whose actuator differs from the protocol's."""

from __future__ import annotations

import math
import re
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from labcli.errors import ModelError
from labcli.papers.rpam2015.models.rpam_actuator_fit import ActuatorFit, fit_actuator, resized
from labcli.papers.rpam2015.models.rpam_fit import StretchFit, analyse_stretch
from labcli.papers.rpam2015.protocol import actuator_of
from labcli.papers.rpam2015.sim.rig import RpamRig

ROOT = Path(__file__).resolve().parents[3]
ACT = actuator_of("rpam2015")
# The lab's actuator: other moduli (mu_1 +12 %, mu_2 -15 %, mu_3 +25 %), 2 mm longer, 0.3 mm wider.
LAB = resized(replace(ACT, ogden_mu_MPa=(0.075, 0.0035, 0.0028)), L0_m=0.072, radius_m=0.0128)
PAYLOADS_KG = (0.0, 0.1, 0.2, 0.3, 1.0, 1.3)  # the protocol's stretch test (Fig. 5)
PRESSURES_MPA = np.linspace(0.0, 0.19, 20)
LEN_NOISE_M = 0.05e-3  # the draw-wire potentiometer's noise after a capture's average


def lab_protocol(tmp_path: Path, act=LAB) -> Path:
    """The shipped protocol with the lab's actuator written in, as a lab would edit its copy."""
    text = (ROOT / "protocols" / "rpam2015.toml").read_text(encoding="utf-8")
    for key, value in (
        ("L0_m", act.L0_m),
        ("A0_m2", act.A0_m2),
        ("thread_length_m", act.thread_length_m),
        ("mu_MPa", list(act.ogden_mu_MPa)),
    ):
        text, n = re.subn(rf"^{key} = .*$", f"{key} = {value!r}", text, flags=re.M)
        assert n == 1, key
    path = tmp_path / "lab-rpam.toml"
    path.write_text(text, encoding="utf-8")
    return path


def stretch_run(protocol: Path, seed: int, reading: str | None = None) -> tuple[dict[str, list[float]], RpamRig]:
    """The stretch test on the seeded stand (its friction and per-actuator correction included)."""
    rig = RpamRig(seed=seed, protocol=protocol, experiment="stretch", force_reading=reading)
    noise = np.random.default_rng([seed, 7])
    table: dict[str, list[float]] = {"mass_g": [], "P_A": [], "L_m": []}
    for m in PAYLOADS_KG:
        rig.hang_payload(m)
        for p in PRESSURES_MPA:
            rig.set_pressures(float(p), 0.0)
            table["mass_g"].append(m * 1e3)
            table["P_A"].append(float(p))
            table["L_m"].append(rig.true_state()["target_length_m"] + LEN_NOISE_M * float(noise.standard_normal()))
    return table, rig


def truth(rig: RpamRig) -> dict[str, float]:
    t = {f"mu_{i + 1}": mu for i, mu in enumerate(rig.actuators[0].ogden_mu_MPa)}
    t.update({f"c{k}": c for k, c in enumerate(rig.true_stretch_coefficients_N["A"])})
    t.update(L0_m=rig.actuators[0].L0_m, radius_m=rig.actuators[0].rest_radius_m)
    return t


def test_resizing_keeps_the_turns_and_the_wall_thickness():
    def thickness(a):
        return a.rest_radius_m - math.sqrt(a.rest_radius_m**2 - a.A0_m2 / math.pi)

    assert LAB.rest_radius_m == pytest.approx(0.0128, rel=1e-12)
    assert LAB.L0_m == 0.072 and LAB.n_turns == ACT.n_turns
    assert thickness(LAB) == pytest.approx(thickness(ACT), rel=1e-12)  # 3 mm
    assert thickness(ACT) == pytest.approx(0.003, rel=1e-3)
    assert LAB.thread_length_m == pytest.approx(math.hypot(0.072, 2 * math.pi * 14 * 0.0128), rel=1e-12)
    assert resized(ACT) == ACT
    with pytest.raises(ModelError, match="cannot hold its wall"):
        resized(ACT, radius_m=0.002)


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_a_stretch_run_on_a_stand_with_known_moduli_returns_them_within_their_standard_errors(tmp_path, seed):
    table, rig = stretch_run(lab_protocol(tmp_path), seed)
    fit = analyse_stretch(table, "rpam2015")  # the protocol's actuator is only where the fit starts
    a = fit.actuator_fit
    assert a is not None and a.force_reading == "derived"
    true = truth(rig)
    # Both dimensions are determined (to 1.3 % and 0.2 %) and fitted.
    assert all(g["fitted"] for g in a.geometry.values())
    assert set(a.names) == {"mu_1", "mu_2", "mu_3", "c0", "c1", "c2", "c3", "L0_m", "radius_m"}
    # Every parameter within 3 standard errors of the stand's truth (on seeds 1-10 the largest
    # deviation is 1.9).  Jointly the linearised covariance is tighter than the truth along the
    # moduli-cubic trade in some runs (chi^2 38.6 on 9 degrees of freedom at seed 1), so the test
    # holds each error, not their product.
    for n in a.names:
        assert abs(a.value(n) - true[n]) < 3 * a.std_error(n), n
    # mu_1 carries the wall: determined to about 10 %, and far from the protocol's when it must be.
    assert a.determined["mu_1"] and a.std_error("mu_1") < 0.15 * a.value("mu_1")
    assert a.std_error("radius_m") < 5e-5 and abs(a.value("radius_m") - 0.0128) < 1e-4
    assert abs(a.value("radius_m") - ACT.rest_radius_m) > 5 * a.std_error("radius_m")
    # The fitted actuator is the one the model and the optimiser use.
    assert a.actuator.ogden_mu_MPa == tuple(a.value(f"mu_{i}") for i in (1, 2, 3))
    assert a.actuator.rest_radius_m == pytest.approx(a.value("radius_m"), rel=1e-12)
    assert a.actuator.L0_m == a.value("L0_m") and not a.actuator.problems()


def test_the_moduli_the_data_leave_loose_are_said_to_be_and_the_sum_is_given(tmp_path):
    table, _ = stretch_run(lab_protocol(tmp_path), 2)
    a = analyse_stretch(table, "rpam2015").actuator_fit
    assert a is not None
    loose = [n for n, ok in a.determined.items() if not ok]
    assert loose == ["mu_2", "mu_3"]
    assert any("does not determine mu_2, mu_3 (standard error above half the value)" in n for n in a.notes)
    assert any("the initial shear modulus, is 0.0" in note for note in a.notes)
    # Here the data ask for none of the two terms: both rest on their floor, and it is said.
    assert any(n.startswith("mu_2, mu_3 reached 0 MPa, the least a stable wall allows") for n in a.notes)


def test_under_the_papers_reading_the_radius_is_fitted_and_the_free_length_is_said_unsupported(tmp_path):
    # A stand built on the paper's reading, fitted under it: its pressure term fixes the cage,
    # while Eq. 3 and the cubic are both functions of the stretch, and trade.
    table, rig = stretch_run(lab_protocol(tmp_path), 2, reading="paper")
    fit = analyse_stretch(table, "rpam2015", force="paper")
    a = fit.actuator_fit
    assert a is not None and a.force_reading == "paper" and a.actuator.force_reading == "paper"
    r = a.geometry["radius_m"]
    assert r["fitted"] and abs(r["value"] - rig.actuators[0].rest_radius_m) < 3 * r["std_error"]
    g = a.geometry["L0_m"]
    assert not g["fitted"] and a.actuator.L0_m == ACT.L0_m
    assert g["note"].startswith("The data do not support fitting the free length: its standard error, ")
    assert not any(a.determined.values())
    assert any("the paper's wall force, Eq. 3, depends on the stretch alone" in n for n in a.notes)


def test_too_few_points_fit_the_cubic_but_not_the_actuator_and_say_why():
    table = {
        "mass_g": [0.0, 100.0, 200.0, 300.0, 1000.0, 1300.0],
        "P_A": [0.0] * 6,
        "L_m": [0.07, 0.0745, 0.079, 0.0835, 0.11, 0.12],
    }
    fit = analyse_stretch(table, "rpam2015")
    assert fit.model.fitted and fit.actuator_fit is None
    assert fit.actuator_note == (
        "Fitting the actuator (its 3 Ogden moduli, the cubic and its free length and radius) needs at least "
        "11 stretch-test points; the test gave 6."
    )
    with pytest.raises(ModelError, match="needs at least 11 stretch-test points"):
        fit_actuator([0.0], [0.0], [0.07], ACT)


def test_the_fitted_actuator_travels_with_the_stretch_fit_and_older_fits_read_without_one(tmp_path):
    table, _ = stretch_run(lab_protocol(tmp_path), 3)
    fit = analyse_stretch(table, "rpam2015")
    back = StretchFit.from_json(fit.to_json())
    assert back.actuator_fit is not None and fit.actuator_fit is not None
    assert back.actuator_fit.actuator == fit.actuator_fit.actuator
    assert back.actuator_fit.std_errors == pytest.approx(fit.actuator_fit.std_errors, rel=1e-12)
    assert ActuatorFit.from_dict(fit.actuator_fit.to_dict()).geometry == fit.actuator_fit.geometry
    old = fit.to_dict()
    del old["actuator_fit"], old["actuator_note"]
    assert StretchFit.from_dict(old).actuator_fit is None
    with pytest.raises(ModelError, match="Expected a fitted actuator"):
        ActuatorFit.from_dict({"kind": "rpam-stretch-fit"})
