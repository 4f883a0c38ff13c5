"""Sensing sessions on the simulated rig, for the scenario test and ``tests/benchmarks/sensing_online.py``.

* :func:`calibrate`: the model ``labcli fit`` would write after ``labcli acquire`` of the
  protocol's plan on this rig (the trials simulated directly, :mod:`.drive`, each trial's
  rest posture its baseline potentiometer reading, as a run file stores it);
* :func:`random_script`: a session of random pulley loads (mass, direction, hold and gap drawn
  from a seed) and a stretch of idle rig at the end; :func:`stacked_script`: stacked weights;
* :func:`run_session`: the rig acts the script out (:class:`.scripted.ScriptedRig`) and the
  estimator takes the frames as a serial link delivers them, in batches of one read;
* :func:`offline_twin`: what ``acquire`` + ``validate`` would have measured for the same loads
  from the same stream: the baseline window just before each load, the loaded window after the
  protocol's settling rule said settled (:mod:`labcli.core.settle`), the model's prediction
  (with the friction terms, given each load's motion into its baseline from the one before, as
  ``labcli predict`` reads it from a run's rows).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import Any

import numpy as np

from ....core.settle import SettleCriteria, SettleDetector
from ....sensing import Estimator, EstimatorConfig
from ....sensing.scoring import Change
from .script import Script, parse_script

SESSION_START_S = 10.0  # the estimator starts once the rig is pressurised (air at 0 s, valves closed at 6 s)


def build(seed: int, rig_options: dict[str, Any] | None = None) -> Any:
    """The simulated rig of ``seed`` with the given ``sim://`` options (name -> parsed value)."""
    from ....core.options import build as build_options
    from .options import McKibbenRigOptions, build_rig

    return build_rig(seed=seed, options=build_options(McKibbenRigOptions, rig_options or {}))


class _Windows:
    """The rig with each sampled window's counts kept (drive.py samples baseline, loaded, ...)."""

    def __init__(self, rig: Any) -> None:
        self._rig = rig
        self.windows: list[tuple[np.ndarray, np.ndarray]] = []

    def __getattr__(self, name: str) -> Any:
        return getattr(self._rig, name)

    def samples(self, n: int, rate_hz: float) -> tuple[np.ndarray, np.ndarray]:
        out = self._rig.samples(n, rate_hz)
        self.windows.append(out)
        return out

    def supply_air(self) -> None:
        if len(self.windows) % 2:  # a baseline that drifted: taken again once the chambers are supplied
            self.windows.pop()
        self._rig.supply_air()


def calibrate(
    protocol: Any,
    seed: int,
    rig_options: dict[str, Any] | None = None,
    settle_s: float = 8.0,
    friction: bool | str = False,
    repressurise_kPa: float = 0.0,
) -> Any:
    """The posture-aware model fitted on the protocol's plan, simulated on the rig of ``seed``
    (``friction``: PostureModel's, True as ``labcli fit`` fits it; ``settle_s`` and
    ``repressurise_kPa``: each window's wait and the drift past which the chambers are supplied
    again, 15 s and the protocol's as ``labcli acquire`` takes a run, 8 s and 0 as they once were)."""
    from ..models.posture import PostureModel, limits_from_protocol
    from ..protocol import load_plan
    from .drive import simulate_weight_trials

    rig = _Windows(build(seed, rig_options))
    table = simulate_weight_trials(
        rig, load_plan(protocol), calibration=protocol.calibration, settle_s=settle_s, repressurise_kPa=repressurise_kPa
    )
    pots = [list(rig.channels).index(c) for c in ("POT1", "POT2")]
    base = np.array([protocol.calibration.to_si(c).mean(axis=0)[pots] for _, c in rig.windows[0::2]])
    table["theta1_0_deg"], table["theta2_0_deg"] = np.degrees(base[:, 0]), np.degrees(base[:, 1])
    model = PostureModel(
        geometry=protocol.settings.rig, protocol=protocol.name, limits=limits_from_protocol(protocol), friction=friction
    ).fit(table, source=f"simulated rig seed {seed}")
    t_base = np.array([t.mean() for t, _ in rig.windows[0::2]]) * 1e-6
    t_load = np.array([t.mean() for t, _ in rig.windows[1::2]]) * 1e-6
    model.baseline_gap_s = float(np.median(t_load - t_base))
    return model


def random_script(
    seed: int,
    *,
    loads: int = 40,
    idle_s: float = 600.0,
    hold_s: tuple[float, float] = (10.0, 25.0),
    gap_s: tuple[float, float] = (12.0, 25.0),
    mass_g: tuple[float, float] = (50.0, 1000.0),
) -> Script:
    """Random pulley loads (drawn from ``seed``), then ``idle_s`` of the idle rig."""
    rng = np.random.default_rng([int(seed), 27])
    t, rows = 30.0, []
    for _ in range(loads):
        hold = float(rng.uniform(*hold_s))
        rows.append(
            {
                "at_s": round(t, 3),
                "hold_s": round(hold, 3),
                "mass_g": round(float(rng.uniform(*mass_g)), 1),
                "direction_deg": round(float(rng.uniform(-180.0, 180.0)), 1),
            }
        )
        t += hold + float(rng.uniform(*gap_s))
    idle = [{"from_s": round(t, 3), "to_s": round(t + idle_s, 3)}] if idle_s > 0 else []
    return parse_script({"air": {"supply_s": 0.0, "close_s": 6.0}, "load": rows, "idle": idle}, f"random seed {seed}")


def stacked_script(
    seed: int,
    *,
    stacks: int = 4,
    hold_s: tuple[float, float] = (10.0, 15.0),
    gap_s: tuple[float, float] = (12.0, 25.0),
    mass_g: tuple[float, float] = (100.0, 300.0),
) -> Script:
    """Stacked weights (drawn from ``seed``): a weight hung, a second put on the same hanger while
    it hangs, then taken off one by one (the second first), each change held ``hold_s``.  They
    pull within 45 degrees of across the straight arm (+x or -x): along it a weight makes no torque
    (Fy is not observable there) and no pressure reading can tell one weight from two."""
    rng = np.random.default_rng([int(seed), 28])
    t, rows = 30.0, []
    for _ in range(stacks):
        holds = rng.uniform(*hold_s, size=3)
        across = float(rng.uniform(-45.0, 45.0)) + (180.0 if rng.uniform() < 0.5 else 0.0)
        direction = round((across + 180.0) % 360.0 - 180.0, 1)
        first, second = (round(float(m), 1) for m in rng.uniform(*mass_g, size=2))
        total = float(holds.sum())
        rows.append({"at_s": round(t, 3), "hold_s": round(total, 3), "mass_g": first, "direction_deg": direction})
        on2 = round(t + float(holds[0]), 3)
        rows.append({"at_s": on2, "hold_s": round(float(holds[1]), 3), "mass_g": second, "direction_deg": direction})
        t += total + float(rng.uniform(*gap_s))
    return parse_script({"air": {"supply_s": 0.0, "close_s": 6.0}, "load": rows}, f"stacked seed {seed}")


@dataclass
class Session:
    """One scripted session: the estimator's output, the stream it read (SI), the truth, timings."""

    items: list[Any]
    t_s: np.ndarray  # per frame
    si: np.ndarray  # per frame, the protocol's channel order
    truth_t: np.ndarray
    truth: np.ndarray  # (n, 4): deflections (rad), forces (N)
    changes: list[dict[str, Any]]
    wall_s: np.ndarray  # per update call
    cpu_s: np.ndarray
    estimates_per_call: np.ndarray
    frames: int


def run_session(
    model: Any,
    protocol: Any,
    script: Script,
    seed: int,
    *,
    rate_hz: float = 200.0,
    batch: int = 10,
    rig_options: dict[str, Any] | None = None,
    config: EstimatorConfig | None = None,
    keep_stream: bool = True,
    on_settled: Any = None,
) -> Session:
    """Act ``script`` out on the rig of ``seed`` and run the estimator on its frames (module docstring)."""
    from ....core.wire import FrameBatch
    from ..sensing import TakumaSensing
    from .scripted import ScriptedRig

    rig = ScriptedRig(build(seed, rig_options), script)
    rig.advance_to(SESSION_START_S)
    est = Estimator(
        TakumaSensing(model),
        calibration=protocol.calibration,
        channels=rig.channels,
        rate_hz=rate_hz,
        config=config,
        on_settled=on_settled,
    )
    items: list[Any] = []
    ts, sis, wall, cpu, per = [], [], [], [], []
    seq, end = 0, script.end_s + 5.0
    while rig.time_s < end:
        t_us, counts = rig.samples(batch, rate_hz)
        frames = FrameBatch(np.arange(seq, seq + batch, dtype=np.int64), t_us, counts.astype(float))
        seq += batch
        w0, c0 = time.perf_counter(), time.thread_time()
        out = est.update(frames)
        cpu.append(time.thread_time() - c0)
        wall.append(time.perf_counter() - w0)
        per.append(sum(1 for o in out if not hasattr(o, "kind")))
        items.extend(out)
        if keep_stream:
            ts.append(t_us * 1e-6)
            sis.append(protocol.calibration.to_si(counts))
    tr = rig.truth()
    truth = np.column_stack([tr["deflection_rad"], tr["force_N"]])
    return Session(
        items,
        np.concatenate(ts) if ts else np.empty(0),
        np.concatenate(sis) if sis else np.empty((0, len(rig.channels))),
        tr["t_s"],
        truth,
        tr["changes"],
        np.array(wall),
        np.array(cpu),
        np.array(per),
        seq,
    )


def offline_twin(
    sensing: Any, protocol: Any, session: Session, capture_s: float | None = None
) -> list[dict[str, Any] | None]:
    """Per change, what acquire + validate would have estimated (None when it would not have settled in time)."""
    crit = SettleCriteria.from_settling(protocol.settling)
    capture = float(capture_s or protocol.settling.capture_s)
    cal = protocol.calibration
    pc = [cal.index(n) for n in ("P_L1", "P_R1", "P_L2", "P_R2")]
    ac = [cal.index(n) for n in ("POT1", "POT2")]
    t, si = session.t_s, session.si
    out: list[dict[str, Any] | None] = []
    before = None  # the posture the previous load held the arm in (rad), for a model that reads it
    history = getattr(sensing, "uses_history", False)
    for c in session.changes:
        on, off = c["on_s"], c["off_s"]
        base = (t > on - capture) & (t <= on)
        det = SettleDetector(crit, pc, ac)
        k, decided = int(np.searchsorted(t, on, side="right")), None
        while k < len(t) and t[k] < off:
            status = det.update(t[k : k + 10], si[k : k + 10])
            if status.settled or status.timed_out:
                decided = float(t[min(k + 9, len(t) - 1)])
                break
            k += 10
        ok = decided is not None and decided + capture <= off and bool(base.any())
        # Not settled in time: the posture it left still from its last capture window before it came off.
        start = decided if ok and decided is not None else off - capture
        load = (t > start) & (t <= start + capture)
        if not base.any() or not load.any():
            out.append(None)
            continue
        P0, P, rest = si[base][:, pc].mean(axis=0), si[load][:, pc].mean(axis=0), si[base][:, ac].mean(axis=0)
        if sensing.p0_leak_corrected:
            slope = np.polyfit(t[base], si[base][:, pc], 1)[0]
            P0 = P0 + slope * (t[load].mean() - t[base].mean())
        moved = None if before is None or not history else (rest - before)[None]
        if history:
            before = rest + sensing.deflections(P0[None], P[None])[0]
        if not ok:
            out.append(None)
            continue
        if moved is None:
            pred = sensing.predict(P0[None], P[None], rest[None])
        else:
            pred = sensing.predict(P0[None], P[None], rest[None], motion_in=moved)
        mid = t[load].mean()
        i = min(int(np.searchsorted(session.truth_t, mid)), len(session.truth_t) - 1)
        out.append(
            {
                "values": pred.values[0],
                "se": pred.se[0],
                "flags": pred.flags[0],
                "truth": session.truth[i],
                "settle_s": start - on,
            }
        )
    return out


def true_changes(session: Session) -> list[Change]:
    """The scripted loads as :class:`labcli.sensing.scoring.Change` (size: the load's |F| in N)."""
    return [
        Change(
            float(c["on_s"]),
            float(c["off_s"] if math.isfinite(c["off_s"]) else np.inf),
            float(np.hypot(*c["force_N"])),
            extra={"kind": c["kind"], "force_N": c["force_N"]},
        )
        for c in session.changes
    ]
