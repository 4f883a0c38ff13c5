"""Protocol files: the rig, its channels, how a run is paced, what each paper adds.

A protocol is a TOML file; the shipped ones live in ``protocols/`` (installed as the
package ``labcli.protocols``, :data:`SHIPPED_DIR`).  ``load_protocol("takuma2014")`` reads a shipped one by
name, ``load_protocol("my-rig.toml")`` reads a file as is.  This is the one loader: every
paper reads its protocols through it.

The accepted keys are described by plain data.  The core's own sections are here
(:data:`SECTIONS`: ``[device]``, ``[acquisition]``, ``[channels.NAME]``, ``[settling]``
and the top-level keys); each paper contributes its protocol kinds and their
sections through the registry (:class:`labcli.core.paper.ProtocolKind`), so a new
protocol kind is new data there, not new parsing code here.  Every error is one
:class:`~labcli.errors.ConfigError` sentence naming the file and the key, for example::

    my-rig.toml: key 'rig.h1_m' must be greater than 0, not -0.355.

Values are converted to the library's units on loading: lengths in m, pressures in
MPa, angles in rad (``angle_spread_deg`` becomes ``Settling.angle_spread_rad``).  Grams
and degrees stay as typed only where people enter them.
"""

from __future__ import annotations

import copy
import importlib.resources
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

from ..errors import ConfigError
from . import registry
from .calibration import UNIT_FACTORS, Calibration, Channel
from .paper import ChannelRoles, ProtocolKind


def _shipped_dir() -> Path:
    # The package labcli.protocols is the folder protocols/ at the top of the repository
    # (pyproject.toml maps it), in an editable install and a built one alike.
    try:
        return Path(str(importlib.resources.files("labcli.protocols")))
    except ModuleNotFoundError:
        # labcli imported from a source checkout instead (``python -m pytest`` in the
        # repository puts it first on the path): the same folder, beside the package.
        return Path(__file__).resolve().parents[2] / "protocols"


SHIPPED_DIR = _shipped_dir()  # the shipped protocol files (names for load_protocol)

# ---------------------------------------------------------------------------
# Schema, as plain data.
#
# A key spec: {"type": ..., "unit": ..., "check": ..., "optional": bool, "help": ...}
#   type   "str" | "int" | "number" | "str-list" | "pair"   (pair: [low, high])
#   check  None | "positive" | "nonnegative" | "nonzero" | "unique" |
#          "increasing" | ["min", v] | ["one-of", [values]]
# A section spec is a dict of key specs, OPEN (any keys, kept as a plain dict),
# or one of the names in a kind's ``tables_of`` (a table whose keys are free names,
# each value checked against another spec).
# ---------------------------------------------------------------------------

OPEN = "open"

# A serial link of 1 Mbaud carries about 2,000 frames a second of six channels; no serial
# rig streams 10,000.
MAX_RATE_HZ = 10_000.0
# Gauge pressure every actuator must reach once air is supplied, unless the protocol says
# otherwise (acquisition.supply_min_MPa).  The paper's muscles work at about 0.3 MPa
# (Fig. 1c: 0.33 MPa) and the simulated rig's supply is 0.30 MPa; unsupplied, the sensors read
# within their offset of 0 (a few kPa).  A third of the working pressure is far above any
# offset and below any working supply: it catches a compressor off, a closed valve, a loose tube.
DEFAULT_SUPPLY_MIN_MPA = 0.1
# TOML integers are 64-bit; deeper nesting than this is no protocol file.
MAX_INT = 2**63 - 1
MAX_DEPTH = 16
# A potentiometer turns less than this (ten-turn pots exist); a joint angle stays within a turn.
MAX_POT_SPAN_DEG = 3600.0
MAX_ANGLE_DEG = 360.0

TOP_LEVEL: dict[str, dict[str, Any]] = {
    "name": {"type": "str", "check": "identifier", "help": "the protocol's name"},
    "kind": {"type": "str", "help": "the protocol kind"},
    "title": {"type": "str", "optional": True},
    "source": {"type": "str", "optional": True},
    "paper": {"type": "str", "optional": True, "help": "the paper's file name under papers/"},
}

SECTIONS: dict[str, Any] = {
    "device": {
        "name": {"type": "str", "help": "the device name the ID? reply carries"},
        "channels": {"type": "str-list", "check": "unique", "help": "the channel names in data-line order"},
        "adc_min_counts": {"type": "number", "unit": "counts"},
        "adc_max_counts": {"type": "number", "unit": "counts"},
    },
    "acquisition": {
        "rate_hz": {"type": "number", "unit": "Hz", "check": "positive", "max": MAX_RATE_HZ},
        "supply_min_MPa": {
            "type": "number",
            "unit": "MPa",
            "check": "nonnegative",
            "optional": True,
            "help": "gauge pressure every actuator must reach once air is supplied",
        },
    },
    # Times are bounded so that a window's samples fit in memory and a wait ends: at most
    # MAX_RATE_HZ x 60 s = 600,000 frames a window.
    "settling": {
        "window_s": {"type": "number", "unit": "s", "check": "positive", "max": 60},
        "hold_s": {"type": "number", "unit": "s", "check": "nonnegative", "max": 600},
        "pressure_spread_MPa": {"type": "number", "unit": "MPa", "check": "positive"},
        "angle_spread_deg": {"type": "number", "unit": "deg", "check": "positive"},
        "timeout_s": {"type": "number", "unit": "s", "check": "positive", "max": 3600},
        "capture_s": {"type": "number", "unit": "s", "check": "positive", "max": 60},
    },
}

# The [channels] section: a table per channel, keyed by channel name.
CHANNEL_MAP = "channel-map"


def _or(values: Any) -> str:
    items = [str(v) for v in values]
    return items[0] if len(items) == 1 else ", ".join(items[:-1]) + " or " + items[-1]


def channel_spec(roles: ChannelRoles | None) -> dict[str, Any]:
    """The key specs of one ``[channels.NAME]`` table under a kind's channel roles."""
    actuator: dict[str, Any] = {"type": "str", "optional": True}
    joint: dict[str, Any] = {"type": "int", "optional": True}
    if roles is not None and roles.actuators:
        actuator.update(
            check=["one-of", list(roles.actuators)], help=f"the actuator of a pressure channel: {_or(roles.actuators)}"
        )
    if roles is not None and roles.joints:
        joint.update(check=["one-of", list(roles.joints)], help=f"the joint of an angle channel: {_or(roles.joints)}")
    return {
        "quantity": {"type": "str", "check": ["one-of", list(UNIT_FACTORS)]},
        "actuator": actuator,
        "joint": joint,
        "unit": {"type": "str"},
        "gain": {"type": "number", "unit": "unit per count", "check": "nonzero"},
        "zero_counts": {"type": "number", "unit": "counts"},
        "range": {"type": "pair", "check": "increasing", "help": "[low, high] in the channel's unit"},
    }


def kinds() -> dict[str, ProtocolKind]:
    """Every protocol kind the installed papers read (through the registry)."""
    return registry.protocol_kinds()


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
    """Equilibrium criteria: spreads over a rolling window, held for ``hold_s``.

    ``length_spread_m``: the limit of length channels, where a protocol gives one (an
    paper's sensors table); without it length channels are not watched.
    """

    window_s: float
    hold_s: float
    pressure_spread_MPa: float
    angle_spread_rad: float
    timeout_s: float
    capture_s: float
    length_spread_m: float | None = None


@dataclass(frozen=True)
class Protocol:
    """A checked protocol.  ``settings`` holds what the paper of its kind made of its
    own sections (:attr:`labcli.core.paper.ProtocolKind.build`); ``sections`` every
    table of the file as plain data, as written, and ``document`` the whole file (top-level
    keys too), for a paper that reads its own tables.  Settings that define ``default_split``
    (fit and validation counts) give ``labcli split`` its defaults."""

    name: str
    kind: str
    path: Path | None
    text: str  # the file verbatim, for the run file
    channels: tuple[str, ...]
    calibration: Calibration | None
    settling: Settling | None
    rate_hz: float | None
    device: DeviceSpec | None
    sections: dict[str, Any]
    settings: Any = None
    title: str = ""
    source: str = ""
    supply_min_MPa: float = DEFAULT_SUPPLY_MIN_MPA
    document: dict[str, Any] = field(default_factory=dict, repr=False)  # the whole file as plain data

    @property
    def source_label(self) -> str:
        return str(self.path) if self.path is not None else self.name


# ---------------------------------------------------------------------------
# Loading
# ---------------------------------------------------------------------------


class ProtocolFileError(ConfigError):
    """A protocol file that is missing, unreadable, not TOML, or of a kind not asked for.

    ``problem`` is ``"missing"``, ``"unreadable"``, ``"syntax"`` or ``"kind"``; ``detail`` the
    reason (the path, the system's words, the TOML parser's, the kind found), so that a caller
    with sentences of its own (the rPAM optimiser's) can word the same failure its way.
    """

    def __init__(self, message: str, problem: str, detail: Any) -> None:
        super().__init__(message)
        self.problem = problem
        self.detail = detail


def shipped_protocols() -> tuple[str, ...]:
    """Names accepted by :func:`load_protocol` without a path."""
    return tuple(sorted(p.stem for p in SHIPPED_DIR.glob("*.toml")))


def _looks_like_name(arg: str) -> bool:
    return not any(sep in arg for sep in ("/", "\\")) and not arg.endswith(".toml")


def load_protocol(path_or_name: str | Path, *, kinds: tuple[str, ...] | None = None) -> Protocol:
    """Read and check a protocol file; a bare name (``"takuma2014"``) means a shipped one.

    ``kinds``: the protocol kinds the caller reads; a file of another kind is refused
    before its sections are judged.
    """
    arg = str(path_or_name)
    if isinstance(path_or_name, str) and _looks_like_name(arg):
        path = SHIPPED_DIR / f"{arg}.toml"
        if not path.is_file():
            raise ProtocolFileError(
                f"There is no shipped protocol named '{arg}'; shipped protocols are "
                f"{', '.join(shipped_protocols())}, or give the path of a .toml file.",
                "missing",
                arg,
            )
    else:
        path = Path(path_or_name)
        if not path.is_file():
            hint = ""
            if (SHIPPED_DIR / path.name).is_file() and path.suffix == ".toml":
                hint = f" (the shipped protocol of that name is loaded with the bare name {path.stem})"
            raise ProtocolFileError(f"Protocol file {arg} does not exist; check the path{hint}.", "missing", arg)
    try:
        raw = path.read_bytes()
    except OSError as exc:
        raise ProtocolFileError(
            f"Protocol file {arg} cannot be read ({exc.strerror or exc}).", "unreadable", exc.strerror or str(exc)
        ) from None
    label = str(path) if isinstance(path_or_name, str) and _looks_like_name(arg) else arg
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise ConfigError(f"{label}: not UTF-8 text (byte {exc.start}); save the file as UTF-8.") from None
    return loads_protocol(text, source=label, path=path, kinds=kinds)


def loads_protocol(
    text: str, *, source: str = "<protocol>", path: Path | None = None, kinds: tuple[str, ...] | None = None
) -> Protocol:
    """Check protocol TOML given as text (e.g. the copy kept in a run file).

    ``source`` names the text in messages; relative file names in the protocol (a plan)
    are resolved against ``path``'s folder when a path is given; ``kinds`` as for
    :func:`load_protocol`.
    """
    chk = Checker(source)
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ProtocolFileError(f"{source}: {_syntax_message(str(exc), text)}", "syntax", str(exc)) from None
    except RecursionError:
        raise ProtocolFileError(
            f"{source}: arrays or tables nested thousands of levels deep; a protocol file "
            f"nests at most {MAX_DEPTH} levels.",
            "syntax",
            "nesting",
        ) from None
    _check_values(data, chk)
    found = data.get("kind")
    if kinds is not None and found not in kinds:
        raise ProtocolFileError(
            f"{source}: key 'kind' must be one of {', '.join(kinds)}, not {_show(found)}.", "kind", found
        )
    return _build(data, text, chk, path)


def _check_values(data: Any, chk: Checker, key: str = "", depth: int = 0) -> None:
    """Every value of the document: nested at most MAX_DEPTH deep, integers within TOML's 64 bits."""
    if depth > MAX_DEPTH:
        chk.fail(f"key '{key}' nests more than {MAX_DEPTH} levels deep; a protocol file nests at most {MAX_DEPTH}.")
    if isinstance(data, dict):
        for k, v in data.items():
            _check_values(v, chk, f"{key}.{k}" if key else str(k), depth + 1)
    elif isinstance(data, list):
        for v in data:
            _check_values(v, chk, key, depth + 1)
    elif isinstance(data, int) and not isinstance(data, bool) and abs(data) > MAX_INT:
        chk.fail(
            f"key '{key}' holds an integer of {len(str(abs(data)))} digits; TOML integers are 64-bit "
            "(at most 19 digits)."
        )


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


class Checker:
    """Checks values against key specs; every failure is one ConfigError naming the source."""

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
        if "max" in spec and v > spec["max"]:
            unit = f" {spec['unit']}" if spec.get("unit") else ""
            self.fail(f"key '{key}' must be at most {spec['max']:g}{unit}, not {_show(v)}.")
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
                self.fail(f"unknown key '{prefix}{k}'; the keys allowed there are {', '.join(spec)}.")
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


def _kind(
    scalars: dict[str, Any], tables: dict[str, Any], all_kinds: dict[str, ProtocolKind], chk: Checker
) -> ProtocolKind:
    """The file's kind, read first: it decides which sections are judged."""
    if "kind" in scalars:
        kind = chk.value(scalars["kind"], TOP_LEVEL["kind"], "kind")
        if kind not in all_kinds:
            chk.fail(f"key 'kind' must be one of {', '.join(all_kinds)}, not {_show(kind)}.")
        return all_kinds[kind]
    if "kind" in tables:
        chk.fail(f"key 'kind' must be a string (the protocol kind), not a table {_show(tables['kind'])}.")
    chk.fail(f"missing key 'kind', expected a string (one of {', '.join(all_kinds)}).")


def _check_top(scalars: dict[str, Any], tables: dict[str, Any], spec: ProtocolKind, chk: Checker) -> dict[str, Any]:
    """The top-level keys, and no table the kind does not know."""
    for k in scalars:
        if k in spec.sections:
            chk.fail(f"key '{k}' must be a table [{k}], not {_kind_of(scalars[k])} {_show(scalars[k])}.")
        if k not in TOP_LEVEL:
            allowed = list(TOP_LEVEL) + [f"[{s}]" for s in spec.sections]
            chk.fail(f"unknown key '{k}'; the keys allowed there are {', '.join(allowed)}.")
    top = chk.table(scalars, TOP_LEVEL, "")
    for k, v in tables.items():
        if k not in spec.sections and k in TOP_LEVEL:
            chk.fail(f"key '{k}' must be {_describe(TOP_LEVEL[k])}, not a table {_show(v)}.")
        if k not in spec.sections and not spec.extra_sections:
            allowed = list(TOP_LEVEL) + [f"[{s}]" for s in spec.sections]
            chk.fail(f"unknown key '{k}'; the keys allowed there are {', '.join(allowed)}.")
    return top


def _check_sections(data: dict[str, Any], spec: ProtocolKind, chk: Checker) -> dict[str, Any]:
    """Every section of the kind, checked against its spec (converted values)."""
    specs = {**SECTIONS, **spec.specs, "channel": channel_spec(spec.channel_roles)}
    tables_of = {CHANNEL_MAP: "channel", **spec.tables_of}
    checked: dict[str, Any] = {}
    for sec, (need, spec_name) in spec.sections.items():
        if sec not in data:
            if need == "required":
                chk.fail(f"missing key '{sec}', expected a table [{sec}].")
            continue
        raw = data[sec]
        if not isinstance(raw, dict):
            chk.fail(f"key '{sec}' must be a table [{sec}], not {_kind_of(raw)} {_show(raw)}.")
        if spec_name == OPEN:
            checked[sec] = raw
        elif spec_name in tables_of:
            item_spec = specs[tables_of[spec_name]]
            checked[sec] = {
                name: (
                    chk.table(v, item_spec, f"{sec}.{name}.")
                    if "type" not in item_spec
                    else chk.value(v, item_spec, f"{sec}.{name}")
                )
                for name, v in raw.items()
            }
        else:
            checked[sec] = chk.table(raw, specs[spec_name], f"{sec}.")
    return checked


def _device(
    checked: dict[str, Any], roles: ChannelRoles | None, chk: Checker
) -> tuple[DeviceSpec | None, Calibration | None]:
    device = calibration = None
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
        calibration = _calibration(checked["channels"], device, roles, chk)
    elif device is not None:
        chk.fail("missing key 'channels', expected one [channels.NAME] table per channel of device.channels.")
    return device, calibration


def _settling(checked: dict[str, Any], chk: Checker) -> Settling | None:
    if "settling" not in checked:
        return None
    s = checked["settling"]
    if not s["timeout_s"] > s["window_s"] + s["hold_s"]:
        chk.fail(
            f"key 'settling.timeout_s' must be longer than window_s + hold_s "
            f"({_show(s['window_s'] + s['hold_s'])} s), not {_show(s['timeout_s'])}."
        )
    return Settling(
        window_s=s["window_s"],
        hold_s=s["hold_s"],
        pressure_spread_MPa=s["pressure_spread_MPa"],
        angle_spread_rad=math.radians(s["angle_spread_deg"]),
        timeout_s=s["timeout_s"],
        capture_s=s["capture_s"],
    )


def _build(data: dict[str, Any], text: str, chk: Checker, path: Path | None) -> Protocol:
    # Top level: scalars first, so 'kind' is known before sections are judged.
    scalars = {k: v for k, v in data.items() if not isinstance(v, dict)}
    tables = {k: v for k, v in data.items() if isinstance(v, dict)}
    spec = _kind(scalars, tables, kinds(), chk)
    top = _check_top(scalars, tables, spec, chk)
    checked = _check_sections(data, spec, chk)
    device, calibration = _device(checked, spec.channel_roles, chk)
    settling = _settling(checked, chk)
    settings = spec.build(checked, chk, path) if spec.build is not None else None
    return Protocol(
        name=top["name"],
        kind=spec.name,
        path=path,
        text=text,
        channels=calibration.names if calibration is not None else (),
        calibration=calibration,
        settling=settling,
        rate_hz=checked.get("acquisition", {}).get("rate_hz"),
        supply_min_MPa=checked.get("acquisition", {}).get("supply_min_MPa", DEFAULT_SUPPLY_MIN_MPA),
        device=device,
        sections=copy.deepcopy(tables),
        settings=settings,
        title=top.get("title", ""),
        source=top.get("source", ""),
        document=copy.deepcopy(data),
    )


def _calibration(
    chans: dict[str, dict[str, Any]], device: DeviceSpec, roles: ChannelRoles | None, chk: Checker
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
    out = [_channel(name, chans[name], device, roles, chk) for name in listed]
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
    for a in roles.actuators if roles is not None else ():
        if not any(ch.actuator == a for ch in out):
            chk.fail(f"key 'channels' must give a pressure channel for actuator {a} (actuator = \"{a}\").")
    for j in roles.joints if roles is not None else ():
        if not any(ch.joint == j for ch in out):
            chk.fail(f"key 'channels' must give an angle channel for joint {j} (joint = {j}).")
    return Calibration(tuple(out), (device.adc_min_counts, device.adc_max_counts))


def _channel(name: str, c: dict[str, Any], device: DeviceSpec, roles: ChannelRoles | None, chk: Checker) -> Channel:
    """One checked ``[channels.NAME]`` table: its role, unit, and a span the ADC can represent."""
    q = c["quantity"]
    key = f"channels.{name}"
    if q == "pressure":
        if "actuator" not in c:
            chk.fail(f"missing key '{key}.actuator', expected {_describe(channel_spec(roles)['actuator'])}.")
        if "joint" in c:
            chk.fail(
                f"unknown key '{key}.joint' for a pressure channel; the keys allowed there are "
                "quantity, actuator, unit, gain, zero_counts, range."
            )
    else:
        if "joint" not in c:
            chk.fail(f"missing key '{key}.joint', expected {_describe(channel_spec(roles)['joint'])}.")
        if "actuator" in c:
            chk.fail(
                f"unknown key '{key}.actuator' for an angle channel; the keys allowed there are "
                "quantity, joint, unit, gain, zero_counts, range."
            )
    factors = UNIT_FACTORS[q]
    if c["unit"] not in factors:
        article = "an" if q[0] in "aeiou" else "a"
        chk.fail(
            f"key '{key}.unit' must be one of {', '.join(factors)} for {article} {q} channel, not {_show(c['unit'])}."
        )
    lo, hi = c["range"]
    if q == "pressure" and lo < 0:
        chk.fail(f"key '{key}.range' must start at 0 or above (gauge pressure), not {_show(c['range'])}.")
    if not math.isfinite(hi):
        chk.fail(f"key '{key}.range' must have a finite high end, not {_show(c['range'])}.")
    # The sensor span must be representable: its ends, in counts, inside the ADC range.
    lo_adc, hi_adc = device.adc_min_counts, device.adc_max_counts
    ends = sorted((lo / c["gain"] + c["zero_counts"], hi / c["gain"] + c["zero_counts"]))
    tol = 1e-6 * max(1.0, abs(hi_adc - lo_adc))
    if ends[0] < lo_adc - tol or ends[1] > hi_adc + tol:
        chk.fail(
            f"key '{key}.gain' with zero_counts {_show(c['zero_counts'])} maps the range "
            f"{_fmt_num(lo)} to {_fmt_num(hi)} {c['unit']} to counts {_fmt_num(ends[0])} to {_fmt_num(ends[1])}, "
            f"outside the ADC range {_fmt_num(lo_adc)} to {_fmt_num(hi_adc)}; check gain, zero_counts and range."
        )
    f = factors[c["unit"]]
    if q == "angle":
        problem = angle_scale_problem(c["unit"], c["gain"] * f, (lo * f, hi * f), hi_adc - lo_adc)
        if problem:
            chk.fail(f"key '{key}.unit' is {c['unit']}, but {problem}; check the unit (deg or rad).")
    return Channel(
        name=name,
        quantity=q,
        gain=c["gain"] * f,
        zero_counts=c["zero_counts"],
        range=(lo * f, hi * f),
        unit_in_file=c["unit"],
        actuator=c.get("actuator"),
        joint=c.get("joint"),
    )


def angle_scale_problem(unit: str, gain_rad: float, range_rad: tuple[float, float], adc_span: float) -> str | None:
    """What makes an angle channel's calibration implausible (a unit of rad where deg was meant), or None."""
    lo, hi = (math.degrees(x) for x in range_rad)
    if max(abs(lo), abs(hi)) > MAX_ANGLE_DEG + 1e-9:
        return f"its range {lo:.6g} to {hi:.6g} deg goes beyond a full turn"
    span = abs(math.degrees(gain_rad)) * adc_span
    if span > MAX_POT_SPAN_DEG:
        return f"its gain makes the ADC's span {span:.6g} deg ({abs(math.degrees(gain_rad)):.3g} deg a count), beyond a ten-turn potentiometer"
    return None


def _fmt_num(x: float) -> str:
    if math.isinf(x):
        return "inf" if x > 0 else "-inf"
    return f"{x:.6g}"


# Helpers for the papers' own section checks (their ProtocolKind.build hooks).
show_value = _show
describe_spec = _describe
fmt_num = _fmt_num
