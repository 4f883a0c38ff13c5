"""The rPAM joint paper's two experiments as sessions of plain steps.

The rPAM protocol (``protocols/rpam2015.toml``, kind ``rpam``) holds two experiments, and a
run records one of them (``labcli acquire --experiment stretch|joint``); the run file's
kind says which:

* ``stretch`` (kind ``rpam-stretch``), Figs. 5-6: actuator A hangs on the stretch stand;
  for every payload (g) x pressure (kPa) of ``[experiments.stretch_test]`` the
  experimenter hangs the payload and sets ``P_A``, the session waits for equilibrium and
  records ``LEN`` and ``P_A`` averaged over the capture, with ``lambda = L / L0``::

      Point 7/120 (stretch): hang 100 g on actuator A, set P_A = 60 kPa, then press Enter

* ``joint`` (kind ``rpam-joint``), Fig. 8: both actuators drive the joint; for every
  ``Pa x Pb`` of ``[experiments.joint_map]`` the experimenter vents both actuators (the
  baseline: the potentiometer's reading of the rest posture), then sets the pair; the
  joint angle is the potentiometer's deflection from that baseline::

      Point 12/121 (joint map): set P_A = 50.7 kPa and P_B = 41 kPa, then press Enter

The steps are the core's (:mod:`labcli.core.steps`: ``Prompt``, ``WaitSettle``,
``Capture``, ...), so the run engine executes them as it does any other experiment's:
equilibrium judged from the data, one point written whole per ``Commit``, interrupt and
resume by point id.  The actions below are what the simulated rig acts out in unattended
runs (``act_on(rig)``).

The protocol's ``[sensors]`` table names the DAQ (``device``, ``channels``) and calibrates
its four channels (``P_A``, ``P_B`` pressures, ``POT`` the joint angle, ``LEN`` actuator
A's length), checked by the core's channel map when the protocol loads
(:mod:`labcli.papers.rpam2015.protocol`); :func:`acquisition_protocol` turns the protocol
into the one a run records with: its kind the run's (``rpam-stretch`` / ``rpam-joint``),
its calibration, channels and device from ``[sensors]``, the length's settling limit in
its settling, and the chosen experiment's grid in its settings (:class:`RpamRun`).
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Generator, Iterable
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, Any

import numpy as np

from ...core.steps import (
    Baseline,
    BeginTrial,
    Capture,
    Commit,
    Finish,
    Prompt,
    Review,
    SettleReport,
    SetupCheck,
    Step,
    WaitSettle,
    Window,
)
from ...errors import ConfigError
from .protocol import CHANNELS, EXPERIMENTS, checked_actuator
from .settings import RpamSettings, Sensors

if TYPE_CHECKING:
    from .records import PointRecord  # which imports this module

# The experiment each rPAM run kind records: rpam-stretch -> stretch.
EXPERIMENT_OF_RUN_KIND: dict[str, str] = {v: k for k, v in EXPERIMENTS.items()}
_TITLE = {"stretch": "stretch", "joint": "joint map"}


# --------------------------------------------------------------------------- actions


@dataclass(frozen=True)
class MountStretchStand:
    """Actuator A off the joint, hanging on the stretch stand, vented, no payload."""

    def act_on(self, rig: Any) -> None:
        rig.set_experiment("stretch")


@dataclass(frozen=True)
class MountJoint:
    """Both actuators on the joint's swivel plates, vented."""

    def act_on(self, rig: Any) -> None:
        rig.set_experiment("joint")


@dataclass(frozen=True)
class StretchLoad:
    """Payload on actuator A and its pressure set (P_B stays vented)."""

    mass_kg: float
    P_A_MPa: float

    def act_on(self, rig: Any) -> None:
        # Pressure first: between payloads the sweep drops to its lowest pressure with the
        # old payload on, then the new one is hung at that pressure.
        rig.set_pressures(self.P_A_MPa, 0.0)
        rig.hang_payload(self.mass_kg)


@dataclass(frozen=True)
class SetPressures:
    P_A_MPa: float
    P_B_MPa: float

    def act_on(self, rig: Any) -> None:
        rig.set_pressures(self.P_A_MPa, self.P_B_MPa)


@dataclass(frozen=True)
class Vent:
    def act_on(self, rig: Any) -> None:
        rig.vent()


@dataclass(frozen=True)
class UnloadStretchStand:
    def act_on(self, rig: Any) -> None:
        rig.remove_payload()
        rig.vent()


# --------------------------------------------------------------------------- protocol


@dataclass(frozen=True)
class PlannedPoint:
    """One point of an experiment's grid: SI set values (``mass_kg`` None on the joint)."""

    point: int  # 1-based, in the order the grid is run
    P_A_MPa: float
    P_B_MPa: float
    mass_kg: float | None = None

    def plan_row(self) -> dict[str, float]:
        row = {"P_A_kPa": _edge(self.P_A_MPa * 1e3), "P_B_kPa": _edge(self.P_B_MPa * 1e3)}
        if self.mass_kg is not None:
            row = {"mass_g": _edge(self.mass_kg * 1e3), **row}
        return row


def _edge(x: float) -> float:
    # Set values as people typed them (grams, kPa): 12 significant digits, like the store's tables.
    return float(f"{x:.12g}")


@dataclass(frozen=True)
class RpamRun:
    """What an rPAM run records (``Protocol.settings`` of :func:`acquisition_protocol`):
    the chosen experiment, its grid of points in the order they are run, and actuator A's
    undeformed length (the stretch is ``L / L0``)."""

    experiment: str  # "stretch" | "joint"
    points: tuple[PlannedPoint, ...]
    L0_m: float

    @property
    def title(self) -> str:
        """``stretch test`` or ``joint map``, for sentences."""
        return {"stretch": "stretch test", "joint": "joint map"}[self.experiment]


def experiment_of_kind(kind: str) -> str | None:
    """``rpam-stretch`` -> ``stretch``, ``rpam-joint`` -> ``joint``, else None."""
    return EXPERIMENT_OF_RUN_KIND.get(kind)


def acquisition_protocol(
    base: Any, experiment: str | None, *, stored_kind: str | None = None, run_path: str = ""
) -> Any:
    """Check the choice of experiment and build the protocol an rPAM run records with.

    ``stored_kind``: the kind of the run being resumed (its experiment is then fixed).
    Raises :class:`ConfigError` with one sentence for a missing or contradictory choice
    and for a protocol that lacks what acquisition needs.
    """
    name = getattr(base, "name", "the protocol")
    if getattr(base, "kind", "") != "rpam":
        raise ConfigError(
            f"--experiment picks one experiment of an rPAM protocol; {name} is of kind "
            f"'{getattr(base, 'kind', '')}', so leave --experiment out."
        )
    if experiment is not None and experiment not in EXPERIMENTS:
        raise ConfigError(f"--experiment must be stretch or joint, not '{experiment}'.")
    if stored_kind is not None:
        stored = experiment_of_kind(stored_kind)
        if stored is None:
            raise ConfigError(f"{run_path} is a run of kind '{stored_kind}', which protocol {name} cannot continue.")
        if experiment is not None and experiment != stored:
            raise ConfigError(
                f"{run_path} records the {stored} experiment, not {experiment}; drop --experiment to resume it."
            )
        experiment = stored
    if experiment is None:
        raise ConfigError(
            f"Protocol {name} holds two experiments: choose one with --experiment stretch "
            "(the stretch test, Figs. 5-6) or --experiment joint (the joint map, Fig. 8)."
        )
    label = str(getattr(base, "path", None) or name)
    settings, sensors = _needs(base, label)
    act = checked_actuator(settings, label)
    return replace(
        base,
        kind=EXPERIMENTS[experiment],
        calibration=sensors.calibration,
        channels=sensors.calibration.names,
        device=sensors.device,
        settling=replace(base.settling, length_spread_m=sensors.length_spread_m),
        settings=RpamRun(experiment, tuple(_points(settings, experiment, label)), act.L0_m),
    )


def _needs(base: Any, label: str) -> tuple[RpamSettings, Sensors]:
    """The settings of an rPAM protocol that acquisition needs: settling, rate and DAQ."""
    if getattr(base, "settling", None) is None:
        raise ConfigError(
            f"{label}: labcli acquire needs a [settling] table (window_s, hold_s, "
            "pressure_spread_MPa, angle_spread_deg, timeout_s, capture_s)."
        )
    if getattr(base, "rate_hz", None) is None:
        raise ConfigError(f"{label}: labcli acquire needs [acquisition] rate_hz.")
    settings: RpamSettings = base.settings
    if settings.sensors is None:
        raise ConfigError(
            f"{label}: labcli acquire needs a [sensors] table naming the DAQ (device, channels) "
            "and calibrating each channel."
        )
    return settings, settings.sensors


def _points(settings: RpamSettings, experiment: str, label: str) -> list[PlannedPoint]:
    """The experiment's grid, numbered in the order it is run: the first set value outermost."""
    if experiment == "stretch":
        if settings.stretch_test is None:
            raise ConfigError(
                f"{label}: the stretch test needs an [experiments.stretch_test] table "
                "(payloads_g, pressure_start_kPa, pressure_stop_kPa, pressure_count)."
            )
        grid = itertools.product(settings.stretch_test.payloads_kg, settings.stretch_test.pressures_MPa)
        return [PlannedPoint(i, p, 0.0, m) for i, (m, p) in enumerate(grid, start=1)]
    if settings.joint_map is None:
        raise ConfigError(
            f"{label}: the joint map needs an [experiments.joint_map] table "
            "(Pa_start_kPa, Pa_stop_kPa, Pa_count and the same for Pb)."
        )
    grid = itertools.product(settings.joint_map.Pa_MPa, settings.joint_map.Pb_MPa)
    return [PlannedPoint(i, a, b) for i, (a, b) in enumerate(grid, start=1)]


# --------------------------------------------------------------------------- text


def kpa(p_MPa: float) -> str:
    return f"{p_MPa * 1e3:.4g} kPa"


def point_label(point: int, total: int, experiment: str) -> str:
    return f"Point {point}/{total} ({_TITLE[experiment]})"


def stretch_prompt(label: str, p: PlannedPoint) -> str:
    grams = (p.mass_kg or 0.0) * 1e3
    load = f"hang {grams:.4g} g on actuator A" if grams > 0 else "leave actuator A without a payload"
    return f"{label}: {load}, set P_A = {kpa(p.P_A_MPa)}, then press Enter"


def joint_prompt(label: str, p: PlannedPoint) -> str:
    return f"{label}: set P_A = {kpa(p.P_A_MPa)} and P_B = {kpa(p.P_B_MPa)}, then press Enter"


def vent_prompt(label: str) -> str:
    return f"{label}: vent both actuators (P_A = P_B = 0 kPa) for the baseline, then press Enter"


MOUNT_STRETCH_TEXT = (
    "Take actuator A off the joint and hang it on the stretch stand, "
    "draw-wire sensor on its end caps, vented and without payload, then press Enter"
)
MOUNT_JOINT_TEXT = "Mount actuators A and B on the joint's swivel plates, both vented, then press Enter"
UNLOAD_STRETCH_TEXT = "Take the payload off actuator A and vent it, then press Enter"
VENT_TEXT = "Vent both actuators, then press Enter"


# --------------------------------------------------------------------------- records


def _cols(protocol: Any) -> dict[str, int]:
    names = list(protocol.channels)
    return {n: names.index(n) for n in CHANNELS}


def stretch_record(p: PlannedPoint, window: Window, settle: SettleReport, protocol: Any) -> PointRecord:
    """One stretch-test point, SI, with its raw window (what the store writes)."""
    c = _cols(protocol)
    m = window.mean()
    L = float(m[c["LEN"]])
    return {
        "point": int(p.point),
        "experiment": "stretch",
        "mass_kg": float(p.mass_kg or 0.0),
        "P_MPa": np.array([m[c["P_A"]], m[c["P_B"]]]),
        "L_m": L,
        "lambda": L / protocol.settings.L0_m,
        "plan": p.plan_row(),
        "settle": {"load": settle.as_dict()},
        "raw": {"load": window},
    }


def joint_record(
    p: PlannedPoint, baseline: Window, loaded: Window, settle_b: SettleReport, settle_l: SettleReport, protocol: Any
) -> PointRecord:
    """One joint-map point: pressures and the deflection from the vented baseline, SI."""
    c = _cols(protocol)
    b = baseline.mean()
    m = loaded.mean()
    return {
        "point": int(p.point),
        "experiment": "joint",
        "P0_MPa": np.array([b[c["P_A"]], b[c["P_B"]]]),
        "P_MPa": np.array([m[c["P_A"]], m[c["P_B"]]]),
        "pot0_rad": float(b[c["POT"]]),
        "alpha_rad": float(m[c["POT"]] - b[c["POT"]]),
        "L_m": float(m[c["LEN"]]),
        "plan": p.plan_row(),
        "settle": {"baseline": settle_b.as_dict(), "load": settle_l.as_dict()},
        "raw": {"baseline": baseline, "load": loaded},
    }


def point_row(record: PointRecord) -> dict[str, str]:
    """The point as people read it (kPa, g, mm, deg), for the review."""
    row = {"point": str(record["point"])}
    p = record["P_MPa"]
    if record["experiment"] == "stretch":
        row["payload (g)"] = f"{record['mass_kg'] * 1e3:.4g}"
        row["P_A (kPa)"] = f"{p[0] * 1e3:.2f}"
        row["L (mm)"] = f"{record['L_m'] * 1e3:.2f}"
        row["lambda"] = f"{record['lambda']:.4f}"
    else:
        row["P_A (kPa)"] = f"{p[0] * 1e3:.2f}"
        row["P_B (kPa)"] = f"{p[1] * 1e3:.2f}"
        row["alpha (deg)"] = f"{math.degrees(record['alpha_rad']):+.2f}"
    load = record["settle"]["load"]
    row["settled (s)"] = f"{load['settle_time_s']:.2f}" + ("" if load["settled"] else " timed out")
    return row


# --------------------------------------------------------------------------- sessions


def rpam_session(protocol: Any, *, completed: Iterable[int] = ()) -> Generator[Step, Any, None]:
    """The chosen experiment's grid, point by point; ``completed`` ids (resume) are skipped.

    ``protocol``: from :func:`acquisition_protocol`."""
    run: RpamRun = protocol.settings
    capture_s = float(protocol.settling.capture_s)
    done = set(int(t) for t in completed)
    total = len(run.points)
    remaining = [p for p in run.points if p.point not in done]
    stretch = run.experiment == "stretch"

    yield SetupCheck()
    yield Prompt(MOUNT_STRETCH_TEXT, MountStretchStand()) if stretch else Prompt(MOUNT_JOINT_TEXT, MountJoint())
    skipped: list[int] = []
    for p in remaining:
        label = point_label(p.point, total, run.experiment)
        yield BeginTrial(p.point, "", len(done) + 1, total, label)
        while True:  # until accepted or skipped
            if stretch:
                yield Prompt(stretch_prompt(label, p), StretchLoad(float(p.mass_kg or 0.0), p.P_A_MPa))
                wait = yield WaitSettle("point")
                if wait == "redo":
                    continue
                window = yield Capture(capture_s)
                record = stretch_record(p, window, wait, protocol)
            else:
                yield Prompt(vent_prompt(label), Vent())
                wait_b = yield WaitSettle("baseline")
                if wait_b == "redo":
                    continue
                base = yield Baseline(capture_s)
                yield Prompt(joint_prompt(label, p), SetPressures(p.P_A_MPa, p.P_B_MPa))
                wait = yield WaitSettle("pressures")
                if wait == "redo":
                    continue
                window = yield Capture(capture_s)
                record = joint_record(p, base, window, wait_b, wait, protocol)
            decision = yield Review(point_row(record))
            if decision == "redo":
                continue
            if decision == "skip":
                skipped.append(p.point)
                break
            yield Commit(record)
            done.add(p.point)
            break
    yield Prompt(UNLOAD_STRETCH_TEXT, UnloadStretchStand()) if stretch else Prompt(VENT_TEXT, Vent())
    yield Finish(None, tuple(skipped))
