"""A third paper, defined here and nowhere else: the proof that the core knows no paper.

A 1-DoF rig with one pressure and one angle: a weight hung on its arm deflects the joint
and raises the actuator's pressure, both linearly in the mass.  A run is two trials (the
two masses of the protocol's ``[load]`` table), each with a baseline, the weight, the
equilibrium and a capture.  Everything a paper gives the core is here: the
protocol kind, the record type (what a trial holds, its table, its ``labcli inspect``
lines), the session, the simulated rig behind ``sim://?mode=toy`` with an option of its own
(``compliance``) and a console action (``hang``), an analysis for ``labcli fit`` with an
option of its own (``--through-origin``), and the registration.  Options are declared as
data (:mod:`labcli.core.options`); no line of the core or the commands names them.
"""

from __future__ import annotations

import json
import math
import threading
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from labcli.core.options import number, switch
from labcli.core.paper import AcquireOptions, Analysis, ChannelRoles, Column, Demo, ProtocolKind
from labcli.core.sim.clock import SimClock
from labcli.core.sim.console import ConsoleCommand, ConsoleError, numbers
from labcli.core.steps import (
    Baseline,
    BeginTrial,
    Capture,
    Commit,
    Finish,
    Prompt,
    Review,
    SetupCheck,
    WaitSettle,
)
from labcli.core.store.h5 import scalar, to_edge
from labcli.core.store.record_type import BaseRecordType
from labcli.core.tables import TableSpec

KIND = "toy"
MODE = "toy"
G = 9.80665
# The rig: 0.2 MPa at rest, +0.05 MPa and +10 deg per kg; a 12-bit ADC as the reference rig's.
P_REST_MPA = 0.2
P_PER_KG = 0.05
ANGLE_PER_KG_RAD = math.radians(10.0)
P_GAIN, P_ZERO = 1.0 / 4095.0, 0.0  # MPa per count: 0-1 MPa over the ADC
A_GAIN, A_ZERO = math.radians(0.1), 2048.0  # rad per count, centred

PROTOCOL_TEXT = f"""\
name = "toy"
kind = "{KIND}"
title = "A 1-DoF toy rig"

[device]
name = "toy-rig"
channels = ["P", "ANG"]
adc_min_counts = 0
adc_max_counts = 4095

[acquisition]
rate_hz = 100.0

[channels.P]
quantity = "pressure"
actuator = "A"
unit = "MPa"
gain = {P_GAIN!r}
zero_counts = {P_ZERO!r}
range = [0.0, 1.0]

[channels.ANG]
quantity = "angle"
joint = 1
unit = "deg"
gain = 0.1
zero_counts = {A_ZERO!r}
range = [-90.0, 90.0]

[settling]
window_s = 0.5
hold_s = 0.5
pressure_spread_MPa = 0.002
angle_spread_deg = 0.3
timeout_s = 10.0
capture_s = 0.5

[load]
masses_g = [200.0, 500.0]
"""


def write_protocol(folder: Path) -> Path:
    path = folder / "toy.toml"
    path.write_text(PROTOCOL_TEXT, encoding="utf-8")
    return path


# --------------------------------------------------------------------------- the rig


@dataclass(frozen=True)
class ToyRigOptions:
    """The toy rig's own option (``sim://?mode=toy&compliance=20``, ``labcli sim --mode toy --compliance 20``)."""

    compliance: float | None = number(
        help="How far the arm turns per kilogram hung.", units="deg/kg", minimum=0, above=True, default_text="10"
    )


def _hang(rig: Any, args: list[str]) -> str:
    (grams,) = numbers(args, ("mass",), "hang GRAMS")
    if grams < 0:
        raise ConsoleError(f"mass must be >= 0 g, got {grams:g}")
    rig.hang(grams / 1e3)
    return f"ok hang {grams:g} g (t={rig.time_s:.3f} s)"


class ToyRig(SimClock):
    """The simulated toy rig: what a weight does to the pressure and the angle, behind an ADC."""

    channels = ("P", "ANG")
    device = "toy-rig-sim"
    firmware = "1.0"
    console_commands = {"hang": ConsoleCommand("hang GRAMS", _hang)}

    def __init__(self, seed: int = 0, noise: float = 1.0, angle_per_kg_rad: float = ANGLE_PER_KG_RAD) -> None:
        self._t = 0.0
        self._lock = threading.RLock()
        self.mass_kg = 0.0
        self.noise = noise
        self.angle_per_kg_rad = angle_per_kg_rad
        self._rng = np.random.default_rng(seed)

    def hang(self, mass_kg: float) -> None:
        self.mass_kg = float(mass_kg)

    def samples(self, n: int, rate_hz: float) -> tuple[np.ndarray, np.ndarray]:
        with self._lock:
            t = self._t + np.arange(1, n + 1) / float(rate_hz)
            p = P_REST_MPA + P_PER_KG * self.mass_kg
            a = self.angle_per_kg_rad * self.mass_kg
            ideal = np.array([p / P_GAIN + P_ZERO, a / A_GAIN + A_ZERO])
            x = ideal + 0.3 * self.noise * self._rng.standard_normal((n, 2))
            self._t = float(t[-1]) if n else self._t
            return np.rint(t * 1e6).astype(np.int64), np.clip(np.rint(x), 0, 4095).astype(np.int64)


@dataclass(frozen=True)
class Hang:
    mass_kg: float

    def act_on(self, rig: Any) -> None:
        rig.hang(self.mass_kg)


# --------------------------------------------------------------------------- records


TOY_TABLE = TableSpec(
    label="trial",
    columns=(
        ("trial", "id", "required"),
        ("mass_g", "positive", "required"),
        ("P_MPa", "pressure", "required"),
        ("theta_deg", "float", "required"),
    ),
    id_column="trial",
)


class ToyTrials(BaseRecordType):
    kind = KIND
    collection = "trials"
    id_column = "trial"
    noun = "trial"
    plural = "trials"
    table_spec = TOY_TABLE
    columns = (
        Column("P", "MPa", bounds=(-1.0, 10.0), what="pressure under the load"),
        Column("theta", "rad", bounds=(-math.pi, math.pi), what="deflection"),
        Column("mass", "kg", bounds=(0.0, 100.0), what="mass hung"),
    )
    signal = "theta"

    def check(self, record: Mapping[str, Any], label: str, run: Any) -> dict[str, Any]:
        return {
            "P": scalar(record, "P_MPa", label),
            "theta": scalar(record, "theta_rad", label),
            "mass": scalar(record, "mass_kg", label),
        }

    def read(self, row: Mapping[str, Any]) -> dict[str, Any]:
        return {
            "trial": int(row["trial"]),
            "P_MPa": float(row["P"]),
            "theta_rad": float(row["theta"]),
            "mass_kg": float(row["mass"]),
        }

    def table(self, run: Any, ids: list[int], cols: Mapping[str, Any]) -> Any:
        import pandas as pd

        return pd.DataFrame(
            {
                "trial": pd.Series(ids, dtype="int64"),
                "mass_g": to_edge(np.asarray(cols["mass"], dtype=float) * 1e3),
                "P_MPa": np.asarray(cols["P"], dtype=float),
                "theta_deg": to_edge(np.degrees(np.asarray(cols["theta"], dtype=float))),
            }
        )

    def from_row(self, row: Mapping[str, Any], protocol: Any) -> dict[str, Any]:
        return {
            "trial": int(row["trial"]),
            "P_MPa": row["P_MPa"],
            "theta_rad": math.radians(row["theta_deg"]),
            "mass_kg": row["mass_g"] * 1e-3,
        }


# --------------------------------------------------------------------------- session


def toy_session(protocol: Any, completed: Any = ()) -> Any:
    capture_s = protocol.settling.capture_s
    masses = [m * 1e-3 for m in protocol.settings["masses_g"]]
    done = set(completed)
    yield SetupCheck()
    for trial, mass in enumerate(masses, start=1):
        if trial in done:
            continue
        label = f"Toy trial {trial}/{len(masses)}"
        yield BeginTrial(trial, "", len(done) + 1, len(masses), label)
        settle_b = yield WaitSettle("baseline")
        base = yield Baseline(capture_s)
        yield Prompt(f"{label}: hang {mass * 1e3:g} g, then press Enter", Hang(mass))
        settle_l = yield WaitSettle("load")
        loaded = yield Capture(capture_s)
        yield Prompt(f"{label}: take the weight off, then press Enter", Hang(0.0))
        b, m = base.mean(), loaded.mean()
        record = {
            "trial": trial,
            "P_MPa": float(m[0]),
            "theta_rad": float(m[1] - b[1]),
            "mass_kg": mass,
            "settle": {"baseline": settle_b.as_dict(), "load": settle_l.as_dict()},
            "raw": {"baseline": base, "load": loaded},
        }
        yield Review({"trial": str(trial), "P (MPa)": f"{record['P_MPa']:.4f}"})
        yield Commit(record)
        done.add(trial)
    yield Finish(None)


@dataclass
class ToyAcquisition:
    protocol: Any
    kind: str = KIND
    plan: Any = None

    def session(self, completed: Any) -> Any:
        return toy_session(self.protocol, completed)

    def already_done(self, run: Any, path: str) -> str | None:
        return None


# --------------------------------------------------------------------------- the analysis


@dataclass(frozen=True)
class ToyFitOptions:
    """``labcli fit`` on a toy run."""

    through_origin: bool = switch(help="Fit the deflection as a line through the origin (no offset).")


@dataclass(frozen=True)
class ToyFit:
    """The arm's compliance fitted on a toy run: deflection = slope * mass + offset."""

    slope_deg_per_kg: float
    offset_deg: float
    trials: int


def toy_fit(
    path: Path,
    options: ToyFitOptions,
    *,
    output: Path | None = None,
    protocol: str | None = None,
    record: bool | None = None,
) -> ToyFit:
    from labcli.core.store import RunFile

    with RunFile.open(path) as run:
        table = run.records.table()
    mass = table["mass_g"].to_numpy(dtype=float) / 1e3
    theta = table["theta_deg"].to_numpy(dtype=float)
    if options.through_origin:
        slope, offset = float(mass @ theta / (mass @ mass)), 0.0
    else:
        slope, offset = (float(v) for v in np.polyfit(mass, theta, 1))
    return ToyFit(slope, offset, len(mass))


def show_toy_fit(result: ToyFit, *, as_json: bool = False) -> None:
    import json
    from dataclasses import asdict

    if as_json:
        print(json.dumps(asdict(result)))
    else:
        print(f"deflection = {result.slope_deg_per_kg:.3f} deg/kg x mass + {result.offset_deg:.3f} deg")


# --------------------------------------------------------------------------- the sensing model

TOY_MODEL_SCHEMA = "toy-model"


@dataclass(frozen=True)
class ToySensingOptions:
    """``labcli sense`` with a toy model file."""

    weight_scale: float = number(1.0, help="Multiply every weight estimate by this.", minimum=0, above=True)


class ToySensing:
    """The weight on the arm from the pressure's rise over its baseline (the rig's 0.05 MPa per kg)."""

    quantities = ("W",)
    units = ("N",)
    kinds = ("load",)
    actuators = ("A",)
    joints = (1,)
    p0_leak_corrected = False
    baseline_gap_s = None
    record_kind = None

    def __init__(self, protocol: str, scale: float) -> None:
        self.protocol = protocol
        self.scale = scale

    def predict(self, P0: np.ndarray, P: np.ndarray, rest: np.ndarray) -> Any:
        from labcli.sensing.model import Prediction

        w = self.scale * (np.asarray(P, float) - np.asarray(P0, float)) / P_PER_KG * G
        return Prediction(w, np.full_like(w, 0.01), [() for _ in range(len(w))])


def write_model(folder: Path, protocol: Path) -> Path:
    path = folder / "toy.model.json"
    path.write_text(json.dumps({"schema": TOY_MODEL_SCHEMA, "protocol": str(protocol)}), encoding="utf-8")
    return path


def toy_sensing_model(text: str, name: str, options: ToySensingOptions | None = None) -> ToySensing | None:
    try:
        d = json.loads(text)
    except ValueError:
        return None
    if not isinstance(d, dict) or d.get("schema") != TOY_MODEL_SCHEMA:
        return None
    return ToySensing(str(d["protocol"]), (options or ToySensingOptions()).weight_scale)


# --------------------------------------------------------------------------- the paper


class ToyPaper:
    name = "toy"
    title = "A 1-DoF toy rig"
    paper = "none: defined in the tests"
    protocol_kinds = {
        KIND: ProtocolKind(
            name=KIND,
            sections={
                "device": ("required", "device"),
                "acquisition": ("required", "acquisition"),
                "channels": ("required", "channel-map"),
                "settling": ("required", "settling"),
                "load": ("required", "toy-load"),
            },
            specs={"toy-load": {"masses_g": {"type": "pair", "unit": "g", "help": "the two trials' masses"}}},
            channel_roles=ChannelRoles(actuators=("A",), joints=(1,)),
            build=lambda checked, chk, path: dict(checked["load"]),
        )
    }
    shipped_protocols = ()
    run_kinds = (KIND,)
    untagged_run_kind = None
    sim_modes = (MODE,)
    default_sim_mode = None
    sim_options = ToyRigOptions
    analysis_options = {"fit": ToyFitOptions}
    sensing_options = ToySensingOptions
    model_schemas = (TOY_MODEL_SCHEMA,)
    default_protocols: dict[str, str] = {}
    demo_protocol = None

    def record_type(self, run_kind: str) -> ToyTrials:
        return ToyTrials()

    def make_rig(
        self,
        mode: str,
        *,
        seed: int = 0,
        noise: float = 1.0,
        drift: float | None = None,
        tau_s: float = 0.7,
        options: ToyRigOptions | None = None,
    ) -> ToyRig:
        compliance = (options or ToyRigOptions()).compliance
        per_kg = ANGLE_PER_KG_RAD if compliance is None else math.radians(compliance)
        return ToyRig(seed=seed, noise=noise, angle_per_kg_rad=per_kg)

    def run_protocol(
        self, protocol: Any, choice: str | None, *, stored_kind: str | None = None, run_path: str = ""
    ) -> Any:
        return protocol

    def import_protocol(self, protocol: Any, choice: str | None, name: str) -> Any:
        return protocol

    def acquisition(self, protocol: Any, options: AcquireOptions) -> ToyAcquisition:
        return ToyAcquisition(protocol)

    def analysis(self, name: str) -> Analysis | None:
        return Analysis(toy_fit, show_toy_fit) if name == "fit" else None

    def demo(self) -> Demo | None:
        return None

    def sensing_model(self, text: str, name: str, options: ToySensingOptions | None = None) -> ToySensing | None:
        return toy_sensing_model(text, name, options)
