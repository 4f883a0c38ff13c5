"""The estimator (labcli/sensing/estimator.py) on synthetic streams with closed-form answers.

The model is linear (support/sensing.py): its answer to a pressure vector is known exactly, so
the estimate can be held against the model's own prediction of the true pressures.
"""

from __future__ import annotations

import numpy as np
import pytest
from support.sensing import LinearModel, Load, stream

from labcli.core.calibration import Calibration, Channel
from labcli.core.wire import Frame, FrameBatch
from labcli.errors import ModelError
from labcli.sensing import IDLE, LOAD, LOADED, RELEASE, SETTLED, Estimate, Estimator, Event

LEAK = (-1.7e-5, -1.1e-5, -1.4e-5, -0.8e-5)  # MPa/s: 0.5-1 kPa/min, each chamber its own


def run(model, t, x, batch=100, **kw):
    est = Estimator(model, rate_hz=200.0, **kw)
    out = []
    for i in range(0, len(t), batch):
        out += est.update_si(t[i : i + batch], x[i : i + batch])
    return est, out


def events(out, kind=None):
    return [o for o in out if isinstance(o, Event) and (kind is None or o.kind == kind)]


def test_a_leaking_idle_rig_raises_no_event_for_five_minutes():
    t, x, _ = stream(300.0, leak_MPa_s=LEAK, seed=4)
    est, out = run(LinearModel(), t, x)
    assert events(out) == []
    assert est.state == IDLE
    ests = [o for o in out if isinstance(o, Estimate) and o.state == IDLE]
    f = np.array([e.values["f"] for e in ests])
    se = np.array([e.se["f"] for e in ests])
    # The leak is followed: 2.5-5 kPa lost over the five minutes, the load estimate stays at 0.
    assert np.mean(np.abs(f) <= 1.96 * se) > 0.93


def test_a_step_load_settles_on_the_models_answer_to_the_true_pressures_and_is_released():
    A = np.array([0.0, 0.0, 0.006, -0.005])  # the second pair: 5.5 N in the toy model
    t, x, drop = stream(60.0, loads=[Load(20.0, 40.0, A)], leak_MPa_s=LEAK, seed=5)
    model = LinearModel()
    est, out = run(model, t, x)
    kinds = [(e.kind, round(e.t_device_s, 1)) for e in events(out)]
    assert [k for k, _ in kinds] == [LOAD, SETTLED, RELEASE]
    load, settled, release = events(out)
    assert abs(load.t_device_s - 20.0) < 0.1 and load.t_detected_s - 20.0 < 0.5
    assert abs(release.t_device_s - 40.0) < 0.1 and release.t_detected_s - 40.0 < 0.5
    truth = model.truth(-A)  # x, f of the settled pressures: the model's offline answer
    last = [o for o in out if isinstance(o, Estimate) and o.state == LOADED][-1]
    assert last.values["f"] == pytest.approx(truth[1], abs=2 * last.se["f"])
    assert abs(last.values["f"] - truth[1]) < 0.02 * abs(truth[1])
    assert settled.estimate is not None and abs(settled.estimate.values["f"] - truth[1]) < 2 * settled.estimate.se["f"]
    assert est.state == IDLE  # back to rest after the release


def test_intervals_hold_the_truth_through_loads_and_releases():
    rng = np.random.default_rng(6)
    loads, t0 = [], 20.0
    for _ in range(8):
        A = np.array([1, -1, 0, 0]) * rng.uniform(-0.004, 0.004) + np.array([0, 0, 1, -0.9]) * rng.uniform(
            -0.008, 0.008
        )
        hold = rng.uniform(10, 20)
        loads.append(Load(t0, t0 + hold, A))
        t0 += hold + rng.uniform(15, 25)
    tau = 0.8
    t, x, drop = stream(t0, loads=loads, leak_MPa_s=LEAK, tau=tau, kappa=0.3, seed=7)
    model = LinearModel()
    est, out = run(model, t, x)
    ests = [o for o in out if isinstance(o, Estimate) and o.state != "starting"]
    te = np.array([e.t_device_s for e in ests])
    idx = np.searchsorted(t, te)
    # f is a load: from its start, the settled drop; x is a state: the isothermal drop now (the lag only).
    f_true = model.truth(drop[idx])[:, 1]
    lagged = np.zeros((len(te), 4))
    for ld in loads:
        for edge, sign in ((ld.on_s, 1.0), (ld.off_s, -1.0)):
            lagged -= sign * np.outer(1 - np.exp(-np.maximum(te - edge, 0) / tau), ld.A)
    x_true = model.truth(lagged)[:, 0]
    for q, truth in (("f", f_true), ("x", x_true)):
        v = np.array([e.values[q] for e in ests])
        s = np.array([e.se[q] for e in ests])
        cover = np.mean(np.abs(v - truth) <= 1.96 * s)
        assert 0.90 <= cover <= 0.995, (q, cover)
    assert len(events(out, LOAD)) == len(loads) == len(events(out, RELEASE))


def calibration(names=("P_L1", "P_R1", "P_L2", "P_R2", "POT1", "POT2")) -> Calibration:
    chans = []
    for n in names:
        if n.startswith("P_"):
            chans.append(Channel(n, "pressure", 5 / 16380, 819.0, (0.0, 1.0), "MPa", actuator=n[2:]))
        else:
            chans.append(Channel(n, "angle", np.radians(340 / 4095), 2048.0, (-1.5, 1.5), "deg", joint=int(n[-1])))
    return Calibration(tuple(chans))


def test_raw_frames_in_any_channel_order_give_the_same_estimates_as_si():
    cal = calibration()
    t, x, _ = stream(12.0, seed=8, noise_MPa=3e-4)
    counts = np.rint(cal.to_counts(x))  # the ADC's rounding: what the rig sends
    si = cal.to_si(counts)
    order = [5, 2, 0, 4, 1, 3]  # the rig sends POT2, P_L2, P_L1, POT1, P_R1, P_R2
    names = [cal.names[i] for i in order]
    seq = np.arange(len(t))
    est_raw = Estimator(LinearModel(), calibration=cal, channels=names, rate_hz=200.0)
    est_si = Estimator(LinearModel(), rate_hz=200.0)
    a = est_raw.update(FrameBatch(seq, np.rint(t * 1e6).astype(np.int64), counts[:, order]))
    b = est_si.update_si(np.rint(t * 1e6) * 1e-6, si, seq)
    assert len(a) == len(b) > 100
    for p, q in zip(a, b, strict=True):
        assert p.values == pytest.approx(q.values, rel=1e-9, abs=1e-12)
    frames = [Frame(int(s), int(round(ti * 1e6)), tuple(c)) for s, ti, c in zip(seq, t, counts[:, order], strict=True)]
    c = Estimator(LinearModel(), calibration=cal, channels=names, rate_hz=200.0).update(frames)
    assert [o.values for o in c] == [o.values for o in a]


def test_a_rig_without_a_channel_the_model_reads_is_refused_in_one_sentence():
    with pytest.raises(ModelError) as e:
        Estimator(LinearModel(), calibration=calibration(), channels=["P_L1", "P_R1", "P_L2", "POT1", "POT2"])
    assert str(e.value) == (
        "The rig sends the channels P_L1,P_R1,P_L2,POT1,POT2 but the model reads P_R2 too; "
        "connect the rig the model was fitted on, or fit a model for this one."
    )
    with pytest.raises(ModelError) as e:
        Estimator(LinearModel(), calibration=calibration(("P_L1", "P_R1", "P_L2", "POT1", "POT2")))
    assert str(e.value) == (
        "The protocol's calibration names no channel for actuator R2, which the model reads; "
        "use the protocol the model was fitted with."
    )


def test_a_restarted_device_clock_starts_a_new_baseline():
    t, x, _ = stream(8.0, seed=9)
    est, out = run(LinearModel(), t, x)
    assert est.state == IDLE
    assert est.update_si(t[:5], x[:5]) == []  # the clock went back: everything is learnt anew
    assert est.state == "starting"
    assert est.update_si(np.empty(0), np.empty((0, 6))) == []


def test_each_settled_load_calls_the_hook_once_with_its_estimate():
    seen = []

    class Hook:
        kind = "push"

        def __call__(self, estimate, rest):
            seen.append((estimate.state, rest.shape))
            return {"k_N_per_m": 500.0}

    A = np.array([0.0, 0.0, 0.006, -0.005])
    t, x, _ = stream(52.0, loads=[Load(10.0, 22.0, A), Load(34.0, 46.0, -A)], seed=10)
    _, out = run(LinearModel(), t, x, on_settled=Hook())
    pushes = events(out, "push")
    assert len(pushes) == 2 and len(seen) == 2
    assert pushes[0].data == {"k_N_per_m": 500.0} and pushes[0].as_json()["k_N_per_m"] == 500.0
    assert seen[0] == (LOADED, (2,))


def test_an_estimate_as_json_names_its_units():
    t, x, _ = stream(4.0, seed=11)
    _, out = run(LinearModel(), t, x)
    j = out[-1].as_json()
    assert set(j) == {"seq", "t_device_s", "state", "x_deg", "x_deg_se", "f_N", "f_N_se", "flags"}
    assert j["x_deg"] == pytest.approx(np.degrees(out[-1].values["x"]), abs=1e-6)


class HistoryModel(LinearModel):
    """The linear model, reading the history of loads: ``m1, m2`` are the motion into the baseline
    it was given (0 where none), its deflections a linear map of the pressure drops."""

    quantities = ("x", "f", "m1", "m2")
    units = ("rad", "N", "rad", "rad")
    kinds = ("state", "load", "state", "state")
    uses_history = True
    D = np.array([[10.0, -10.0, 0.0, 0.0], [0.0, 0.0, 10.0, -10.0]])  # 1 kPa: 0.01 rad

    def __init__(self) -> None:
        super().__init__(se=(0.002, 0.05))
        self.se = np.array([0.002, 0.05, 1e-3, 1e-3])

    def deflections(self, P0: np.ndarray, P: np.ndarray) -> np.ndarray:
        return (np.asarray(P0) - np.asarray(P)) @ self.D.T

    def predict(self, P0, P, rest, motion_in=None):
        base = super().predict(P0, P, rest)
        m = np.zeros((len(base.values), 2)) if motion_in is None else np.asarray(motion_in, dtype=float)
        return type(base)(np.column_stack([base.values, m]), np.tile(self.se, (len(m), 1)), base.flags)


def test_each_load_is_given_the_joints_motion_into_its_baseline_from_the_load_before():
    """The arm left 0.01, -0.02 rad off its old rest after the first load (friction holds it): the
    second load's motion into its baseline is that rest less the first load's posture (its rest
    plus the deflections of its pressures), in closed form; the first load and the idle rig have none."""
    A1, A2 = np.array([-0.004, 0.004, -0.002, 0.002]), np.array([0.0, 0.0, 0.005, -0.005])
    t, x, _ = stream(90.0, loads=[Load(20.0, 40.0, A1), Load(60.0, 80.0, A2)], seed=11)
    shift = np.array([0.01, -0.02])
    x[t >= 44.0, 4:] += shift
    model = HistoryModel()
    est, out = run(model, t, x)
    assert [e.kind for e in events(out)] == [LOAD, SETTLED, RELEASE] * 2
    ests = [o for o in out if isinstance(o, Estimate)]

    def motion(lo, hi):
        return np.array([[e.values["m1"], e.values["m2"]] for e in ests if lo < e.t_device_s <= hi])

    # The first load's posture: rest 0 plus D (P0 - P) = D (-A1) = (0.08, 0.04) rad.
    expected = shift - model.D @ (-A1)
    loaded = [e for e in ests if e.state == LOADED and 60.0 < e.t_device_s <= 80.0]
    got = motion(61.0, 80.0)
    assert len(loaded) > 50
    np.testing.assert_allclose(got, np.tile(expected, (len(got), 1)), atol=2e-3)
    assert np.all(motion(20.0, 40.0) == 0.0)  # the first load: no load before it
    idle = [e for e in ests if e.state == IDLE]
    assert len(idle) > 100 and all(e.values["m1"] == e.values["m2"] == 0.0 for e in idle)


def test_a_history_model_that_takes_no_deflections_is_still_given_its_motion():
    """``predict_rows`` passes a model's own deflections on only when it has them: a history model
    whose ``predict`` takes ``motion_in`` alone (as the protocol first had it) keeps working."""
    from labcli.sensing.offline import predict_rows

    m = HistoryModel()
    P0 = np.full((3, 4), 0.3)
    P = P0 - np.array([[1e-3, 0.0, 0.0, 0.0]])
    moved = np.array([[0.01, -0.02], [0.0, 0.0], [-0.03, 0.005]])
    out = predict_rows(m, P0, P, np.zeros((3, 2)), motion_in=moved)
    np.testing.assert_allclose(out.values[:, 2:], moved)
