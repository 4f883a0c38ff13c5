"""Protocol files: the rig, its channels, how a run is paced, what the paper published.

A protocol is a TOML file; the shipped ones live in ``protocols/`` and, as
package data, in ``labcli/data/``.  ``load_protocol("takuma2014")`` reads a
shipped one by name, ``load_protocol("my-rig.toml")`` reads a file as is.

The accepted keys are described by plain data (:data:`SECTIONS`, :data:`KINDS`),
so a new protocol kind is a new entry there, not new parsing code.  Every error
is one :class:`~labcli.errors.ConfigError` sentence naming the file and the key,
for example::

    my-rig.toml: key 'rig.h1_m' must be greater than 0, not -0.355.

Values are converted to the library's units on loading: lengths in m,
pressures in MPa, angles in rad (``angle_spread_deg`` becomes
``Settling.angle_spread_rad``).  Grams and degrees stay as typed only where
people enter them (``Protocol.force_limits``).
"""

from __future__ import annotations

import copy
import math
import re
import sys
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, NoReturn

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - exercised on 3.10 only
    import tomli as tomllib

from .calibration import UNIT_FACTORS, Calibration, Channel
from ..errors import ConfigError

DATA_DIR = Path(__file__).resolve().parents[1] / "data"

# ---------------------------------------------------------------------------
# Schema, as plain data.
#
# A key spec: {"type": ..., "unit": ..., "check": ..., "optional": bool, "help": ...}
#   type   "str" | "int" | "number" | "str-list" | "pair"   (pair: [low, high])
#   check  None | "positive" | "nonnegative" | "nonzero" | "unique" |
#          "increasing" | ["min", v] | ["one-of", [values]]
# A section spec is a dict of key specs, OPEN (any keys, kept as a plain dict),
# or one of the names in TABLE_OF (a table whose keys are free names, each value
# checked against another spec).
# ---------------------------------------------------------------------------

OPEN = "open"

TOP_LEVEL: dict[str, dict[str, Any]] = {
    "name": {"type": "str", "check": "identifier", "help": "the protocol's name"},
    "kind": {"type": "str", "help": "the protocol kind"},
    "title": {"type": "str", "optional": True},
    "source": {"type": "str", "optional": True},
    "paper": {"type": "str", "optional": True, "help": "the paper's file name under papers/"},
}

COEFFICIENT_NAMES: tuple[str, ...] = (
    "beta_theta1_L1", "beta_theta1_R1",
    "beta_theta2_L1", "beta_theta2_R1", "beta_theta2_L2", "beta_theta2_R2",
    *(f"beta_Fx{i}" for i in range(1, 7)),
    *(f"beta_Fy{i}" for i in range(1, 7)),
)

ACTUATORS: tuple[str, ...] = ("L1", "R1", "L2", "R2")
JOINTS: tuple[int, ...] = (1, 2)

SECTIONS: dict[str, Any] = {
    "device": {
        "name": {"type": "str", "help": "the device name the ID? reply carries"},
        "channels": {"type": "str-list", "check": "unique", "help": "the channel names in data-line order"},
        "adc_min_counts": {"type": "number", "unit": "counts"},
        "adc_max_counts": {"type": "number", "unit": "counts"},
    },
    "acquisition": {
        "rate_hz": {"type": "number", "unit": "Hz", "check": "positive"},
    },
    "rig.mckibben-2dof": {
        k: {"type": "number", "unit": "m", "check": "positive"} for k in ("h1_m", "h2_m", "h3_m", "r1_m", "r2_m")
    },
    "channel": {
        "quantity": {"type": "str", "check": ["one-of", list(UNIT_FACTORS)]},
        "actuator": {"type": "str", "check": ["one-of", list(ACTUATORS)], "optional": True,
                     "help": "the actuator of a pressure channel: L1, R1, L2 or R2"},
        "joint": {"type": "int", "check": ["one-of", list(JOINTS)], "optional": True,
                  "help": "the joint of an angle channel: 1 or 2"},
        "unit": {"type": "str"},
        "gain": {"type": "number", "unit": "unit per count", "check": "nonzero"},
        "zero_counts": {"type": "number", "unit": "counts"},
        "range": {"type": "pair", "check": "increasing", "help": "[low, high] in the channel's unit"},
    },
    "settling": {
        "window_s": {"type": "number", "unit": "s", "check": "positive"},
        "hold_s": {"type": "number", "unit": "s", "check": "nonnegative"},
        "pressure_spread_MPa": {"type": "number", "unit": "MPa", "check": "positive"},
        "angle_spread_deg": {"type": "number", "unit": "deg", "check": "positive"},
        "timeout_s": {"type": "number", "unit": "s", "check": "positive"},
        "capture_s": {"type": "number", "unit": "s", "check": "positive"},
    },
    "trials": {
        "fit": {"type": "int", "check": ["min", 1]},
        "validation": {"type": "int", "check": ["min", 0]},
        "plan": {"type": "str", "check": "nonempty", "help": "the plan CSV, relative to the protocol file"},
    },
    "force": {
        "mass_min_g": {"type": "number", "unit": "g", "check": "positive"},
        "mass_max_g": {"type": "number", "unit": "g", "check": "positive"},
        "direction_min_deg": {"type": "number", "unit": "deg", "check": ["min", -360]},
        "direction_max_deg": {"type": "number", "unit": "deg", "check": ["min", -360]},
    },
    "push": {
        "pushes_per_object": {"type": "int", "check": ["min", 1]},
        "distance_min_m": {"type": "number", "unit": "m", "check": "positive"},
        "distance_max_m": {"type": "number", "unit": "m", "check": "positive"},
    },
    "paper_coefficients.takuma2014": {name: {"type": "number"} for name in COEFFICIENT_NAMES},
    "stiffness_band": {"type": "pair", "check": "increasing", "help": "[low, high] in N/m"},
}

# Sections whose keys are free names (channel names, category names).
TABLE_OF: dict[str, str] = {
    "channel-map": "channel",
    "stiffness-bands": "stiffness_band",
}

_MCKIBBEN_COMMON: dict[str, tuple[str, str]] = {
    "device": ("required", "device"),
    "acquisition": ("required", "acquisition"),
    "rig": ("required", "rig.mckibben-2dof"),
    "channels": ("required", "channel-map"),
    "settling": ("required", "settling"),
}

_RPAM_COMMON: dict[str, tuple[str, str]] = {
    "device": ("optional", "device"),
    "acquisition": ("optional", "acquisition"),
    "rig": ("optional", OPEN),
    "channels": ("optional", "channel-map"),
    "settling": ("optional", "settling"),
}

# kind -> sections (name -> (required|optional, spec)); "extra_sections": other
# tables are accepted and kept as plain dicts in Protocol.sections.
KINDS: dict[str, dict[str, Any]] = {
    "force": {
        "sections": {
            **_MCKIBBEN_COMMON,
            "trials": ("required", "trials"),
            "force": ("required", "force"),
            "paper_coefficients": ("optional", "paper_coefficients.takuma2014"),
        },
        "extra_sections": False,
        "needs": {"actuators": ACTUATORS, "joints": JOINTS},
    },
    "push": {
        "sections": {
            **_MCKIBBEN_COMMON,
            "push": ("required", "push"),
            "stiffness_bands_N_per_m": ("optional", "stiffness-bands"),
            # Settings of the stiffness estimate (labcli.experiments.takuma2014.models.stiffness.StiffnessParams,
            # which checks its own keys).
            "stiffness": ("optional", OPEN),
            "paper_coefficients": ("optional", "paper_coefficients.takuma2014"),
        },
        "extra_sections": False,
        "needs": {"actuators": ACTUATORS, "joints": JOINTS},
    },
    "rpam": {"sections": dict(_RPAM_COMMON), "extra_sections": True, "needs": {}},
}

_TYPE_TEXT = {
    "str": "a string",
    "int": "an integer",
    "number": "a number",
    "str-list": "a list of strings",
    "pair": "a list of two numbers [low, high]",
    "table": "a table",
}


# ---------------------------------------------------------------------------
# Loaded form
# ---------------------------------------------------------------------------


@dataclass(frozen=True)
class DeviceSpec:
    """What ``ID?`` must answer."""

    name: str
    channels: tuple[str, ...]
    adc_min_counts: float = 0.0
    adc_max_counts: float = 4095.0

    def matches(self, device_name: str) -> bool:
        """True for the expected name or the same name with a ``-sim`` suffix."""
        return device_name in (self.name, self.name + "-sim")


@dataclass(frozen=True)
class Settling:
    """Equilibrium criteria: spreads over a rolling window, held for ``hold_s``."""

    window_s: float
    hold_s: float
    pressure_spread_MPa: float
    angle_spread_rad: float
    timeout_s: float
    capture_s: float


@dataclass(frozen=True)
class Trials:
    fit: int
    validation: int
    plan: Path | None  # resolved against the protocol file's folder

    @property
    def total(self) -> int:
        return self.fit + self.validation


@dataclass(frozen=True)
class ForceLimits:
    """Bounds for weights and directions typed by the operator (grams, degrees)."""

    mass_min_g: float
    mass_max_g: float
    direction_min_deg: float
    direction_max_deg: float


@dataclass(frozen=True)
class PushSettings:
    pushes_per_object: int
    distance_min_m: float
    distance_max_m: float
    stiffness_bands_N_per_m: dict[str, tuple[float, float]] = field(default_factory=dict)

    def category_of(self, stiffness_N_per_m: float) -> str | None:
        """The band containing a stiffness (low inclusive, high exclusive), or None."""
        for name, (lo, hi) in self.stiffness_bands_N_per_m.items():
            if lo <= stiffness_N_per_m < hi:
                return name
        return None


@dataclass(frozen=True)
class Protocol:
    name: str
    kind: str
    path: Path | None
    text: str  # the file verbatim, for the run file
    rig: dict[str, float]
    channels: tuple[str, ...]
    calibration: Calibration | None
    settling: Settling | None
    trials: Trials | None
    paper_coefficients: dict[str, float]
    rate_hz: float | None
    device: DeviceSpec | None
    force_limits: ForceLimits | None
    push: PushSettings | None
    sections: dict[str, Any]  # every table of the file as plain data, as written
    title: str = ""
    source: str = ""

    @property
    def source_label(self) -> str:
        return str(self.path) if self.path is not None else self.name

    def load_plan(self):
        """The plan named by ``trials.plan`` as a DataFrame, checked against this protocol."""
        from .tables import load_plan

        if self.trials is None or self.trials.plan is None:
            raise ConfigError(f"{self.source_label}: protocol '{self.name}' has no plan (key 'trials.plan').")
        if not self.trials.plan.is_file():
            raise ConfigError(
                f"{self.source_label}: key 'trials.plan' names {self.trials.plan}, which does not exist; "
                "put the plan next to the protocol file or fix the name."
            )
        limits = self.force_limits
        plan = load_plan(
            self.trials.plan,
            mass_range_g=(limits.mass_min_g, limits.mass_max_g) if limits else None,
            direction_range_deg=(limits.direction_min_deg, limits.direction_max_deg) if limits else None,
        )
        n_fit = int((plan["set"] == "fit").sum())
        n_val = int((plan["set"] == "validation").sum())
        if (n_fit, n_val) != (self.trials.fit, self.trials.validation):
            raise ConfigError(
                f"{self.trials.plan}: the plan has {n_fit} fit and {n_val} validation trials, but "
                f"{self.source_label} asks for {self.trials.fit} and {self.trials.validation} "
                "(keys 'trials.fit', 'trials.validation')."
            )
        return plan


# ---------------------------------------------------------------------------
# Loading
# ---------------------------------------------------------------------------


def shipped_protocols() -> tuple[str, ...]:
    """Names accepted by :func:`load_protocol` without a path."""
    return tuple(sorted(p.stem for p in DATA_DIR.glob("*.toml")))


def _looks_like_name(arg: str) -> bool:
    return not any(sep in arg for sep in ("/", "\\")) and not arg.endswith(".toml")


def load_protocol(path_or_name: str | Path) -> Protocol:
    """Read and check a protocol file; a bare name (``"takuma2014"``) means a shipped one."""
    arg = str(path_or_name)
    if isinstance(path_or_name, str) and _looks_like_name(arg):
        path = DATA_DIR / f"{arg}.toml"
        if not path.is_file():
            raise ConfigError(
                f"There is no shipped protocol named '{arg}'; shipped protocols are "
                f"{', '.join(shipped_protocols())}, or give the path of a .toml file."
            )
    else:
        path = Path(path_or_name)
        if not path.is_file():
            hint = ""
            if (DATA_DIR / path.name).is_file() and path.suffix == ".toml":
                hint = f" (the shipped protocol of that name is loaded with the bare name {path.stem})"
            raise ConfigError(f"Protocol file {arg} does not exist; check the path{hint}.")
    try:
        raw = path.read_bytes()
    except OSError as exc:
        raise ConfigError(f"Protocol file {arg} cannot be read ({exc.strerror or exc}).") from None
    label = str(path) if isinstance(path_or_name, str) and _looks_like_name(arg) else arg
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise ConfigError(f"{label}: not UTF-8 text (byte {exc.start}); save the file as UTF-8.") from None
    return loads_protocol(text, source=label, path=path)


def loads_protocol(text: str, *, source: str = "<protocol>", path: Path | None = None) -> Protocol:
    """Check protocol TOML given as text (e.g. the copy kept in a run file).

    ``source`` names the text in messages; ``trials.plan`` is resolved against
    ``path``'s folder when a path is given.
    """
    chk = _Checker(source)
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        chk.fail(_syntax_message(str(exc), text))
    return _build(data, text, chk, path)


def _syntax_message(msg: str, text: str) -> str:
    m = re.search(r"\(at line (\d+), column (\d+)\)\s*$", msg)
    if m:
        what = msg[: m.start()].strip()
        return f"TOML syntax error at line {m.group(1)}, column {m.group(2)}: {_sentence_body(what)}."
    m = re.search(r"\(at end of document\)\s*$", msg)
    if m:
        line = text.count("\n") + 1
        return f"TOML syntax error at line {line} (end of file): {_sentence_body(msg[: m.start()].strip())}."
    return f"TOML syntax error: {_sentence_body(msg)}."


def _sentence_body(s: str) -> str:
    # tomllib says "Expected '=' ..."; the sentence continues after a colon.
    s = s.rstrip(". ")
    return s[:1].lower() + s[1:] if s[:1].isupper() and not s[:2].isupper() else s


class _Checker:
    def __init__(self, source: str) -> None:
        self.source = source

    def fail(self, message: str) -> NoReturn:
        raise ConfigError(f"{self.source}: {message}")

    # one value against one key spec
    def value(self, v: Any, spec: dict[str, Any], key: str) -> Any:
        t = spec["type"]
        if t == "str":
            if not isinstance(v, str):
                self._wrong(v, spec, key)
        elif t == "int":
            if isinstance(v, bool) or not isinstance(v, int):
                self._wrong(v, spec, key)
        elif t == "number":
            if isinstance(v, bool) or not isinstance(v, (int, float)):
                self._wrong(v, spec, key)
            if not math.isfinite(v):
                self.fail(f"key '{key}' must be a finite number, not {_show(v)}.")
            v = float(v)
        elif t == "str-list":
            if not isinstance(v, list) or not all(isinstance(x, str) for x in v):
                self._wrong(v, spec, key)
            if not v:
                self.fail(f"key '{key}' must list at least one name.")
        elif t == "pair":
            if (
                not isinstance(v, list)
                or len(v) != 2
                or not all(isinstance(x, (int, float)) and not isinstance(x, bool) for x in v)
            ):
                self._wrong(v, spec, key)
            if any(math.isnan(x) for x in v):
                self.fail(f"key '{key}' must be two numbers, not {_show(v)}.")
            if v[0] == -math.inf:
                self.fail(f"key '{key}' must have a finite low end, not {_show(v)}.")
            v = [float(x) for x in v]
        self._check(v, spec.get("check"), key)
        return v

    def _wrong(self, v: Any, spec: dict[str, Any], key: str) -> NoReturn:
        self.fail(f"key '{key}' must be {_describe(spec)}, not {_kind_of(v)} {_show(v)}.")

    def _check(self, v: Any, check: Any, key: str) -> None:
        if check is None:
            return
        bad = None
        if check == "positive" and not v > 0:
            bad = "greater than 0"
        elif check == "nonnegative" and not v >= 0:
            bad = "at least 0"
        elif check == "nonzero" and v == 0:
            bad = "non-zero"
        elif check == "nonempty" and not v.strip():
            bad = "a non-empty string"
        elif check == "identifier" and not re.fullmatch(r"[A-Za-z0-9][A-Za-z0-9_.-]*", v):
            bad = "letters, digits, '-', '_' or '.'"
        elif check == "unique" and len(set(v)) != len(v):
            dup = sorted({x for x in v if v.count(x) > 1})
            self.fail(f"key '{key}' must list each name once, but {', '.join(dup)} repeats.")
        elif check == "increasing" and not v[0] < v[1]:
            bad = "[low, high] with low < high"
        elif isinstance(check, list) and check[0] == "min" and not v >= check[1]:
            bad = f"at least {check[1]}"
        elif isinstance(check, list) and check[0] == "one-of" and v not in check[1]:
            bad = f"one of {', '.join(str(x) for x in check[1])}"
        if bad is not None:
            self.fail(f"key '{key}' must be {bad}, not {_show(v)}.")

    # a table against a dict of key specs; returns the checked, converted values
    def table(self, data: Any, spec: dict[str, Any], prefix: str) -> dict[str, Any]:
        if not isinstance(data, dict):
            self.fail(f"key '{prefix.rstrip('.')}' must be a table, not {_kind_of(data)} {_show(data)}.")
        for k in data:
            if k not in spec:
                self.fail(
                    f"unknown key '{prefix}{k}'; the keys allowed there are {', '.join(spec)}."
                )
        out: dict[str, Any] = {}
        for k, kspec in spec.items():
            if k not in data:
                if not kspec.get("optional"):
                    self.fail(f"missing key '{prefix}{k}', expected {_describe(kspec)}.")
                continue
            out[k] = self.value(data[k], kspec, prefix + k)
        return out


def _describe(spec: dict[str, Any]) -> str:
    text = _TYPE_TEXT[spec["type"]]
    unit = spec.get("unit")
    if unit:
        text += f" in {unit}"
    if spec.get("help"):
        text += f" ({spec['help']})"
    return text


def _kind_of(v: Any) -> str:
    if isinstance(v, bool):
        return "the boolean"
    if isinstance(v, int):
        return "the integer"
    if isinstance(v, float):
        return "the number"
    if isinstance(v, str):
        return "the string"
    if isinstance(v, list):
        return "the list"
    if isinstance(v, dict):
        return "a table"
    return "the date/time"


def _show(v: Any) -> str:
    if isinstance(v, dict):
        return "{" + ", ".join(list(v)[:4]) + (", ..." if len(v) > 4 else "") + "}"
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, str):
        s = v if len(v) <= 40 else v[:37] + "..."
        return repr(s)
    if isinstance(v, float):
        return repr(v)
    if isinstance(v, list):
        s = "[" + ", ".join(_show(x) for x in v[:6]) + (", ..." if len(v) > 6 else "") + "]"
        return s
    return str(v)


def _build(data: dict[str, Any], text: str, chk: _Checker, path: Path | None) -> Protocol:
    # Top level: scalars first, so 'kind' is known before sections are judged.
    scalars = {k: v for k, v in data.items() if not isinstance(v, dict)}
    tables = {k: v for k, v in data.items() if isinstance(v, dict)}
    if "kind" in scalars:
        kind = chk.value(scalars["kind"], TOP_LEVEL["kind"], "kind")
        if kind not in KINDS:
            chk.fail(f"key 'kind' must be one of {', '.join(KINDS)}, not {_show(kind)}.")
    elif "kind" in tables:
        chk.fail(f"key 'kind' must be a string (the protocol kind), not a table {_show(tables['kind'])}.")
    else:
        chk.fail(f"missing key 'kind', expected a string (one of {', '.join(KINDS)}).")
    kind_spec = KINDS[kind]
    section_specs: dict[str, tuple[str, str]] = kind_spec["sections"]

    for k in scalars:
        if k in section_specs:
            chk.fail(f"key '{k}' must be a table [{k}], not {_kind_of(scalars[k])} {_show(scalars[k])}.")
        if k not in TOP_LEVEL:
            allowed = list(TOP_LEVEL) + [f"[{s}]" for s in section_specs]
            chk.fail(f"unknown key '{k}'; the keys allowed there are {', '.join(allowed)}.")
    top = chk.table(scalars, TOP_LEVEL, "")
    for k, v in tables.items():
        if k not in section_specs and k in TOP_LEVEL:
            chk.fail(f"key '{k}' must be {_describe(TOP_LEVEL[k])}, not a table {_show(v)}.")
        if k not in section_specs and not kind_spec["extra_sections"]:
            allowed = list(TOP_LEVEL) + [f"[{s}]" for s in section_specs]
            chk.fail(f"unknown key '{k}'; the keys allowed there are {', '.join(allowed)}.")

    checked: dict[str, Any] = {}
    for sec, (need, spec_name) in section_specs.items():
        if sec not in data:
            if need == "required":
                chk.fail(f"missing key '{sec}', expected a table [{sec}].")
            continue
        raw = data[sec]
        if not isinstance(raw, dict):
            chk.fail(f"key '{sec}' must be a table [{sec}], not {_kind_of(raw)} {_show(raw)}.")
        if spec_name == OPEN:
            checked[sec] = raw
        elif spec_name in TABLE_OF:
            item_spec = SECTIONS[TABLE_OF[spec_name]]
            checked[sec] = {
                name: (chk.table(v, item_spec, f"{sec}.{name}.") if "type" not in item_spec
                       else chk.value(v, item_spec, f"{sec}.{name}"))
                for name, v in raw.items()
            }
        else:
            checked[sec] = chk.table(raw, SECTIONS[spec_name], f"{sec}.")

    device = calibration = settling = trials = force_limits = push = None
    channels: tuple[str, ...] = ()
    if "device" in checked:
        d = checked["device"]
        if not d["adc_min_counts"] < d["adc_max_counts"]:
            chk.fail(
                f"key 'device.adc_max_counts' must be greater than device.adc_min_counts "
                f"({_show(d['adc_min_counts'])}), not {_show(d['adc_max_counts'])}."
            )
        device = DeviceSpec(d["name"], tuple(d["channels"]), d["adc_min_counts"], d["adc_max_counts"])
    if "channels" in checked:
        if device is None:
            chk.fail("missing key 'device', expected a table [device] listing the channel order.")
        calibration = _calibration(checked["channels"], device, kind_spec.get("needs", {}), chk)
        channels = calibration.names
    elif device is not None:
        chk.fail("missing key 'channels', expected one [channels.NAME] table per channel of device.channels.")

    if "settling" in checked:
        s = checked["settling"]
        if not s["timeout_s"] > s["window_s"] + s["hold_s"]:
            chk.fail(
                f"key 'settling.timeout_s' must be longer than window_s + hold_s "
                f"({_show(s['window_s'] + s['hold_s'])} s), not {_show(s['timeout_s'])}."
            )
        settling = Settling(
            window_s=s["window_s"],
            hold_s=s["hold_s"],
            pressure_spread_MPa=s["pressure_spread_MPa"],
            angle_spread_rad=math.radians(s["angle_spread_deg"]),
            timeout_s=s["timeout_s"],
            capture_s=s["capture_s"],
        )
    if "trials" in checked:
        t = checked["trials"]
        base = path.parent if path is not None else None
        plan = Path(t["plan"])
        if base is not None and not plan.is_absolute():
            plan = base / plan
        trials = Trials(t["fit"], t["validation"], plan if base is not None or plan.is_absolute() else None)
    if "force" in checked:
        f = checked["force"]
        if not f["mass_max_g"] > f["mass_min_g"]:
            chk.fail(
                f"key 'force.mass_max_g' must be greater than force.mass_min_g "
                f"({_show(f['mass_min_g'])}), not {_show(f['mass_max_g'])}."
            )
        if not f["direction_max_deg"] > f["direction_min_deg"]:
            chk.fail(
                f"key 'force.direction_max_deg' must be greater than force.direction_min_deg "
                f"({_show(f['direction_min_deg'])}), not {_show(f['direction_max_deg'])}."
            )
        if f["direction_max_deg"] - f["direction_min_deg"] > 360:
            chk.fail(
                "key 'force.direction_max_deg' must be at most 360 deg above force.direction_min_deg, "
                f"not {_show(f['direction_max_deg'])}."
            )
        force_limits = ForceLimits(**f)
    if "push" in checked:
        p = checked["push"]
        if not p["distance_max_m"] > p["distance_min_m"]:
            chk.fail(
                f"key 'push.distance_max_m' must be greater than push.distance_min_m "
                f"({_show(p['distance_min_m'])}), not {_show(p['distance_max_m'])}."
            )
        bands = {k: (v[0], v[1]) for k, v in checked.get("stiffness_bands_N_per_m", {}).items()}
        _check_bands(bands, chk)
        push = PushSettings(p["pushes_per_object"], p["distance_min_m"], p["distance_max_m"], bands)

    rate = checked.get("acquisition", {}).get("rate_hz")
    return Protocol(
        name=top["name"],
        kind=kind,
        path=path,
        text=text,
        rig=dict(checked.get("rig", {})),
        channels=channels,
        calibration=calibration,
        settling=settling,
        trials=trials,
        paper_coefficients=dict(checked.get("paper_coefficients", {})),
        rate_hz=rate,
        device=device,
        force_limits=force_limits,
        push=push,
        sections=copy.deepcopy(tables),
        title=top.get("title", ""),
        source=top.get("source", ""),
    )


def _calibration(
    chans: dict[str, dict[str, Any]], device: DeviceSpec, needs: dict[str, Any], chk: _Checker
) -> Calibration:
    listed = list(device.channels)
    missing = [c for c in listed if c not in chans]
    if missing:
        chk.fail(f"missing key 'channels.{missing[0]}', expected a table describing a channel of device.channels.")
    extra = [c for c in chans if c not in listed]
    if extra:
        chk.fail(
            f"unknown key 'channels.{extra[0]}'; the keys allowed there are the names in device.channels "
            f"({', '.join(listed)})."
        )
    lo_adc, hi_adc = device.adc_min_counts, device.adc_max_counts
    out: list[Channel] = []
    for name in listed:
        c = chans[name]
        q = c["quantity"]
        key = f"channels.{name}"
        if q == "pressure":
            if "actuator" not in c:
                chk.fail(f"missing key '{key}.actuator', expected {_describe(SECTIONS['channel']['actuator'])}.")
            if "joint" in c:
                chk.fail(f"unknown key '{key}.joint' for a pressure channel; the keys allowed there are "
                         "quantity, actuator, unit, gain, zero_counts, range.")
        else:
            if "joint" not in c:
                chk.fail(f"missing key '{key}.joint', expected {_describe(SECTIONS['channel']['joint'])}.")
            if "actuator" in c:
                chk.fail(f"unknown key '{key}.actuator' for an angle channel; the keys allowed there are "
                         "quantity, joint, unit, gain, zero_counts, range.")
        factors = UNIT_FACTORS[q]
        if c["unit"] not in factors:
            article = "an" if q[0] in "aeiou" else "a"
            chk.fail(
                f"key '{key}.unit' must be one of {', '.join(factors)} for {article} {q} channel, "
                f"not {_show(c['unit'])}."
            )
        lo, hi = c["range"]
        if q == "pressure" and lo < 0:
            chk.fail(f"key '{key}.range' must start at 0 or above (gauge pressure), not {_show(c['range'])}.")
        if not math.isfinite(hi):
            chk.fail(f"key '{key}.range' must have a finite high end, not {_show(c['range'])}.")
        # The sensor span must be representable: its ends, in counts, inside the ADC range.
        ends = sorted((lo / c["gain"] + c["zero_counts"], hi / c["gain"] + c["zero_counts"]))
        tol = 1e-6 * max(1.0, abs(hi_adc - lo_adc))
        if ends[0] < lo_adc - tol or ends[1] > hi_adc + tol:
            chk.fail(
                f"key '{key}.gain' with zero_counts {_show(c['zero_counts'])} maps the range "
                f"{_fmt_num(lo)} to {_fmt_num(hi)} {c['unit']} to counts {_fmt_num(ends[0])} to {_fmt_num(ends[1])}, "
                f"outside the ADC range {_fmt_num(lo_adc)} to {_fmt_num(hi_adc)}; check gain, zero_counts and range."
            )
        f = factors[c["unit"]]
        out.append(
            Channel(
                name=name,
                quantity=q,
                gain=c["gain"] * f,
                zero_counts=c["zero_counts"],
                range=(lo * f, hi * f),
                unit_in_file=c["unit"],
                actuator=c.get("actuator"),
                joint=c.get("joint"),
            )
        )
    for what, attr in (("actuator", "actuator"), ("joint", "joint")):
        seen: dict[Any, str] = {}
        for ch in out:
            v = getattr(ch, attr)
            if v is None:
                continue
            if v in seen:
                chk.fail(
                    f"key 'channels.{ch.name}.{attr}' repeats {_show(v)}, already the {what} of "
                    f"channels.{seen[v]}; each {what} has one channel."
                )
            seen[v] = ch.name
    for a in needs.get("actuators", ()):
        if not any(ch.actuator == a for ch in out):
            chk.fail(f"key 'channels' must give a pressure channel for actuator {a} (actuator = \"{a}\").")
    for j in needs.get("joints", ()):
        if not any(ch.joint == j for ch in out):
            chk.fail(f"key 'channels' must give an angle channel for joint {j} (joint = {j}).")
    return Calibration(tuple(out), (lo_adc, hi_adc))


def _check_bands(bands: dict[str, tuple[float, float]], chk: _Checker) -> None:
    for name, (lo, hi) in bands.items():
        if lo < 0:
            chk.fail(f"key 'stiffness_bands_N_per_m.{name}' must start at 0 or above, not {_show([lo, hi])}.")
    ordered = sorted(bands.items(), key=lambda kv: kv[1][0])
    for (n1, (_, h1)), (n2, (l2, _)) in zip(ordered, ordered[1:]):
        if l2 < h1:
            chk.fail(
                f"key 'stiffness_bands_N_per_m.{n2}' must not overlap band {n1} "
                f"(which ends at {_fmt_num(h1)} N/m), not start at {_fmt_num(l2)}."
            )


def _fmt_num(x: float) -> str:
    if math.isinf(x):
        return "inf" if x > 0 else "-inf"
    return f"{x:.6g}"
