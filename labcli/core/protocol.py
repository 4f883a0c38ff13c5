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
from typing import Any

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - exercised on 3.10 only
    import tomli as tomllib

from ..errors import ConfigError
from . import registry
from .air import ACQUISITION_KEYS as AIR_KEYS
from .air import AirSettings
from .calibration import Calibration
from .channels import CHANNEL_MAP, DEVICE_KEYS, DeviceSpec, calibration, channel_spec, device_spec
from .files import read_input
from .keyspecs import OPEN, Checker, describe, kind_of, show
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
# Schema, as plain data (the key-spec language: :mod:`labcli.core.keyspecs`).  A section
# spec is a table spec, OPEN (kept as written), or one of the names in a kind's
# ``tables_of`` (a table whose keys are free names, each value checked against another spec).
# ---------------------------------------------------------------------------


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
TOP_LEVEL: dict[str, dict[str, Any]] = {
    "name": {"type": "str", "check": "identifier", "help": "the protocol's name"},
    "kind": {"type": "str", "help": "the protocol kind"},
    "title": {"type": "str", "optional": True},
    "source": {"type": "str", "optional": True},
    "paper": {"type": "str", "optional": True, "help": "the paper's file name under papers/"},
}

SECTIONS: dict[str, Any] = {
    "device": DEVICE_KEYS,
    "acquisition": {
        "rate_hz": {"type": "number", "unit": "Hz", "check": "positive", "max": MAX_RATE_HZ},
        "supply_min_MPa": {
            "type": "number",
            "unit": "MPa",
            "check": "nonnegative",
            "optional": True,
            "help": "gauge pressure every actuator must reach once air is supplied",
        },
        **AIR_KEYS,
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


def kinds() -> dict[str, ProtocolKind]:
    """Every protocol kind the installed papers read (through the registry)."""
    return registry.protocol_kinds()


# ---------------------------------------------------------------------------
# Loaded form
# ---------------------------------------------------------------------------


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
    air: AirSettings = field(default_factory=AirSettings)  # the valves' use (labcli.core.air)
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
        if not path.exists():
            hint = ""
            if (SHIPPED_DIR / path.name).is_file() and path.suffix == ".toml":
                hint = f" (the shipped protocol of that name is loaded with the bare name {path.stem})"
            raise ProtocolFileError(f"Protocol file {arg} does not exist; check the path{hint}.", "missing", arg)
    try:
        raw = read_input(path, "a protocol file", label=f"Protocol file {arg}")
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
    return check_document(data, source=source, text=text, path=path, kinds=kinds)


def check_document(
    data: dict[str, Any],
    *,
    source: str = "<protocol>",
    text: str = "",
    path: Path | None = None,
    kinds: tuple[str, ...] | None = None,
) -> Protocol:
    """Check a protocol given as plain data (a TOML document as read, or one changed after
    reading: ``--set`` values), as :func:`loads_protocol` checks its text; ``text``: the file
    verbatim, when there is one."""
    chk = Checker(source)
    _check_values(data, chk)
    found = data.get("kind")
    if kinds is not None and found not in kinds:
        raise ProtocolFileError(
            f"{source}: key 'kind' must be one of {', '.join(kinds)}, not {show(found)}.", "kind", found
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


def _kind(
    scalars: dict[str, Any], tables: dict[str, Any], all_kinds: dict[str, ProtocolKind], chk: Checker
) -> ProtocolKind:
    """The file's kind, read first: it decides which sections are judged."""
    if "kind" in scalars:
        kind = chk.value(scalars["kind"], TOP_LEVEL["kind"], "kind")
        if kind not in all_kinds:
            chk.fail(f"key 'kind' must be one of {', '.join(all_kinds)}, not {show(kind)}.")
        return all_kinds[kind]
    if "kind" in tables:
        chk.fail(f"key 'kind' must be a string (the protocol kind), not a table {show(tables['kind'])}.")
    chk.fail(f"missing key 'kind', expected a string (one of {', '.join(all_kinds)}).")


def _check_top(scalars: dict[str, Any], tables: dict[str, Any], spec: ProtocolKind, chk: Checker) -> dict[str, Any]:
    """The top-level keys, and no table the kind does not know."""
    for k in scalars:
        if k in spec.sections:
            chk.fail(f"key '{k}' must be a table [{k}], not {kind_of(scalars[k])} {show(scalars[k])}.")
        if k not in TOP_LEVEL:
            allowed = list(TOP_LEVEL) + [f"[{s}]" for s in spec.sections]
            chk.fail(f"unknown key '{k}'; the keys allowed there are {', '.join(allowed)}.")
    top = chk.table(scalars, TOP_LEVEL, "")
    for k, v in tables.items():
        if k not in spec.sections and k in TOP_LEVEL:
            chk.fail(f"key '{k}' must be {describe(TOP_LEVEL[k])}, not a table {show(v)}.")
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
            chk.fail(f"key '{sec}' must be a table [{sec}], not {kind_of(raw)} {show(raw)}.")
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
    device = cal = None
    if "device" in checked:
        d = checked["device"]
        device = device_spec(d["name"], d["channels"], (d["adc_min_counts"], d["adc_max_counts"]), chk, "device")
    if "channels" in checked:
        if device is None:
            chk.fail("missing key 'device', expected a table [device] listing the channel order.")
        cal = calibration(checked["channels"], device, roles, chk)
    elif device is not None:
        chk.fail("missing key 'channels', expected one [channels.NAME] table per channel of device.channels.")
    return device, cal


def _settling(checked: dict[str, Any], chk: Checker) -> Settling | None:
    if "settling" not in checked:
        return None
    s = checked["settling"]
    if not s["timeout_s"] > s["window_s"] + s["hold_s"]:
        chk.fail(
            f"key 'settling.timeout_s' must be longer than window_s + hold_s "
            f"({show(s['window_s'] + s['hold_s'])} s), not {show(s['timeout_s'])}."
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
    device, cal = _device(checked, spec.channel_roles, chk)
    settling = _settling(checked, chk)
    settings = spec.build(checked, chk, path) if spec.build is not None else None
    acq = checked.get("acquisition", {})
    if acq.get("friction_relief_vent_s", 0.0) > 0 and not acq.get("friction_relief_s", 0.0) > 0:
        chk.fail(
            "key 'acquisition.friction_relief_vent_s' needs acquisition.friction_relief_s above 0: "
            "the supply pulse that fills the vented chambers again."
        )
    return Protocol(
        name=top["name"],
        kind=spec.name,
        path=path,
        text=text,
        channels=cal.names if cal is not None else (),
        calibration=cal,
        settling=settling,
        rate_hz=checked.get("acquisition", {}).get("rate_hz"),
        supply_min_MPa=checked.get("acquisition", {}).get("supply_min_MPa", DEFAULT_SUPPLY_MIN_MPA),
        air=AirSettings.of(checked.get("acquisition", {}), settling.pressure_spread_MPa if settling else None),
        device=device,
        sections=copy.deepcopy(tables),
        settings=settings,
        title=top.get("title", ""),
        source=top.get("source", ""),
        document=copy.deepcopy(data),
    )


# The [acquisition] header line (TOML allows blanks and quotes inside the brackets), its comment and
# its line end, LF or CRLF (the table holds rate_hz, so a line follows).
_ACQUISITION_HEADER = re.compile(r"^\[[ \t]*([\"']?)acquisition\1[ \t]*\][ \t]*(?:#[^\r\n]*)?\r?\n", flags=re.MULTILINE)


def with_captures(protocol: Protocol, captures: int, flag: str = "--captures") -> Protocol:
    """``protocol`` with ``acquisition.captures_per_load = captures`` written into its text (the copy a
    run stores, so the run says how many captures it took of each load and a resume takes as many).

    One capture, the default, leaves the protocol as it is: its text, and so the digest a model
    fitted on the run compares (:mod:`.provenance`), stays the file's.  The key goes into the
    file's own ``[acquisition]`` table, its line endings (LF or CRLF) kept.  A protocol that gives
    another number already is refused in one sentence (ConfigError)."""
    given = protocol.sections.get("acquisition", {}).get("captures_per_load")
    if given is not None:
        if int(given) == captures:
            return protocol
        raise ConfigError(
            f"{protocol.name} gives acquisition.captures_per_load = {given}, and {flag} {captures} asks for "
            f"{captures}; leave out {flag} or give a protocol without the key."
        )
    if captures == 1:
        return protocol
    return with_acquisition_key(
        protocol,
        f"captures_per_load = {captures}",
        f"{protocol.name} with {flag} {captures}",
        f"write captures_per_load = {captures} there instead of {flag} {captures}",
    )


def with_acquisition_key(protocol: Protocol, line: str, source: str, instead: str) -> Protocol:
    """``protocol`` with ``line`` (``key = value``) written at the top of its file's own ``[acquisition]``
    table, its line endings (LF or CRLF) kept, or a new table at the end where the file has none.  A
    file that gives its acquisition settings as dotted keys or an inline table has no header to write
    under: refused in one sentence ending with ``instead`` (what to write there by hand)."""
    text = protocol.text
    end = "\r\n" if "\r\n" in text else "\n"
    header = _ACQUISITION_HEADER.search(text)
    if header is not None:
        text = text[: header.end()] + line + end + text[header.end() :]
    elif "acquisition" in protocol.sections:
        raise ConfigError(
            f"{protocol.name} gives its acquisition settings without an [acquisition] table header; {instead}."
        )
    else:
        text = text.rstrip("\r\n") + f"{end}{end}[acquisition]{end}" + line + end
    return loads_protocol(text, source=source, path=protocol.path)


def run_captures(protocol_text: str, path: str) -> int:
    """The captures a run took of each load, from its embedded protocol (1 when it does not say or
    cannot be read): what ``labcli split`` and ``labcli inspect`` count a run's loads by."""
    if not protocol_text.strip():
        return 1
    try:
        protocol = loads_protocol(protocol_text, source=f"{path} (embedded protocol)")
    except ConfigError:
        return 1
    return int(protocol.air.captures_per_load)
