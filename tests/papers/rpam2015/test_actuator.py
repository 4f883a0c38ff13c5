"""The one rPAM actuator type: what the model, the fits, the optimiser and the stand share."""

from __future__ import annotations

import json
import math
from dataclasses import FrozenInstanceError

import pytest

from labcli.errors import ModelError
from labcli.papers.rpam2015.actuator import Actuator
from labcli.papers.rpam2015.models import rpam, rpam_fit
from labcli.papers.rpam2015.protocol import actuator_of, load_rpam
from labcli.papers.rpam2015.sim.rig import RpamRig

PROTOCOL = load_rpam("rpam2015")
PATH, RAW = PROTOCOL.path, PROTOCOL.document
ACT = PROTOCOL.settings.actuator


def test_the_model_the_fits_and_the_stand_use_one_type():
    assert rpam.Actuator is Actuator
    rig = RpamRig(seed=1)
    assert all(type(a) is Actuator for a in (rig.nominal_actuator, *rig.actuators))
    # The stand is built from the protocol's actuator: only its true stretch correction differs.
    nominal = rig.nominal_actuator.with_stretch_correction(ACT.stretch_coefficients_N, ACT.stretch_lambda_range)
    assert nominal == ACT
    with pytest.raises(FrozenInstanceError):
        ACT.L0_m = 0.08  # type: ignore[misc]


def test_a_protocols_actuator_by_name_by_path_or_loaded():
    assert actuator_of("rpam2015") == actuator_of(PATH) == actuator_of(PROTOCOL) == ACT
    assert (ACT.L0_m, ACT.A0_m2, ACT.n_turns, ACT.thread_length_m) == (0.07, 2.0735e-4, 14.0, 1.10178)
    assert ACT.ogden_mu_MPa == (0.06707, 0.004111, 0.002247) and ACT.ogden_alpha == (1.3, 5.0, -2.0)
    assert ACT.stretch_coefficients_N == (8.0, -14.0, 4.0, 2.0) and ACT.stretch_lambda_range == (1.0, 2.2)


def test_rest_geometry_follows_from_the_cage():
    # r = sqrt(b^2 - L0^2) / (2 pi n): the shipped cage is the 25 mm tube's outer radius.
    assert ACT.rest_radius_m == pytest.approx(math.sqrt(1.10178**2 - 0.07**2) / (2 * math.pi * 14), rel=1e-15)
    assert ACT.rest_radius_m == pytest.approx(0.0125, rel=1e-4)
    assert math.cos(ACT.rest_helix_angle_rad) == pytest.approx(0.07 / 1.10178, rel=1e-15)


def test_a_model_files_record_round_trips_through_json():
    d = json.loads(json.dumps(ACT.to_dict()))
    assert d["ogden_mu_MPa"] == list(ACT.ogden_mu_MPa) and d["stretch_lambda_range"] == [1.0, 2.2]
    assert Actuator.from_dict(d) == ACT


def test_a_fitted_correction_goes_on_the_actuator_whole():
    fitted = ACT.with_stretch_correction([1.0, 2.0, 3.0, 4.0], (1.1, 1.9))
    assert fitted.stretch_coefficients_N == (1.0, 2.0, 3.0, 4.0) and fitted.stretch_lambda_range == (1.1, 1.9)
    assert fitted.L0_m == ACT.L0_m and fitted.ogden_mu_MPa == ACT.ogden_mu_MPa
    # Without a range the actuator keeps its own.
    assert ACT.with_stretch_correction([0, 0, 0, 1]).stretch_lambda_range == ACT.stretch_lambda_range
    # The model uses what it carries: at lambda = 1.5 the cubic c0 + c1 l + c2 l^2 + c3 l^3.
    assert float(rpam.stretch_force(1.5, fitted)) == pytest.approx(1 + 2 * 1.5 + 3 * 1.5**2 + 4 * 1.5**3)
    with pytest.raises(ModelError, match="4 coefficients c0..c3 in N, not 3"):
        ACT.with_stretch_correction([1.0, 2.0, 3.0])
    # A stretch fit puts its coefficients and range on the protocol's actuator.
    fit = rpam_fit.StretchCorrection().fit([1.0, 1.2, 1.4, 1.6, 1.8, 2.0], [0.0, 0.3, 1.1, 2.4, 4.4, 7.0])
    act, source = rpam_fit.correction_actuator(ACT, fit)
    assert source == "fit" and act.stretch_coefficients_N == fit.coefficients_N
    assert act.stretch_lambda_range == (1.0, 2.0)


def test_an_actuator_that_cannot_be_built_is_named():
    assert ACT.problems() == []
    thin = Actuator(0.07, 5e-4, 14.0, 1.10178, (0.1,), (2.0,))
    assert thin.problems() == [
        "key 'actuator.A0_m2' must be less than the cage's section at rest, pi r^2 = 0.0004909 m^2 "
        "(r from actuator.n_turns and thread_length_m): the wall lies inside the thread cage"
    ]
    short = Actuator(0.07, 1e-4, 14.0, 0.05, (0.1, 0.2), (2.0,))
    assert short.problems() == [
        "keys 'ogden.mu_MPa' and 'ogden.alpha' must be lists of the same length",
        "key 'actuator.thread_length_m' must exceed actuator.L0_m: a thread shorter than the actuator "
        "cannot wind round it",
    ]
    d = {**ACT.to_dict(), "ogden_mu_MPa": [0.1, 0.004, -0.03]}
    with pytest.raises(ModelError) as e:
        Actuator.from_dict(d)
    assert str(e.value) == (
        "The actuator record describes no actuator that can be built: the Ogden constants need mu_i > 0 and "
        "alpha_i != 0 for every term (Eq. 3's convention; a negative mu_i makes the wall unstable outside "
        "uniaxial tension)."
    )
    with pytest.raises(ModelError, match=r"^The actuator record is incomplete or malformed \('A0_m2'\)\.$"):
        Actuator.from_dict({k: v for k, v in ACT.to_dict().items() if k != "A0_m2"})
