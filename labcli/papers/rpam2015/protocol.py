"""The rPAM protocol kind, ``rpam``: its sections as key specs, and the typed settings they give.

An rPAM protocol (``protocols/rpam2015.toml``) holds the joint, its actuators and their
materials, the stretch correction, the grids of its two experiments, the optimiser's
settings and the ``[sensors]`` table of its DAQ.  The one loader
(:func:`labcli.core.protocol.load_protocol`) checks every key against :data:`SPECS` and the
DAQ's channels against the core's channel map (:mod:`labcli.core.channels`); :func:`build`
turns the checked tables into :class:`~.settings.RpamSettings` (``Protocol.settings``).

What only a command needs is judged when it runs: an actuator the model cannot build
(:func:`checked_actuator`), the optimiser's holding constraints
(:mod:`labcli.papers.rpam2015.models.rpam_optimize`), the tables ``labcli acquire`` needs.
So a protocol kept in an older run file still loads.

One protocol, two experiments: ``--experiment stretch`` records a run of kind
``rpam-stretch``, ``--experiment joint`` one of kind ``rpam-joint``.
"""

from __future__ import annotations

import copy
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import Any

from ...core.channels import calibration, channel_spec, device_spec
from ...core.keyspecs import OTHER_KEYS, Checker, show
from ...core.paper import ProtocolKind
from ...core.protocol import (
    SHIPPED_DIR,
    Protocol,
    ProtocolFileError,
    check_document,
    load_protocol,
    loads_protocol,
    tomllib,
)
from ...errors import ConfigError
from .actuator import FORCE_READINGS, STRETCH_TERMS, Actuator
from .joint import JointGeometry
from .settings import Bounds, JointMapGrid, OptimizeSettings, RpamSettings, Sensors, StretchTestGrid

# ``--experiment`` choices and the run kinds they record.
EXPERIMENTS: dict[str, str] = {"stretch": "rpam-stretch", "joint": "rpam-joint"}
# What an experiment takes once where --captures (acquisition.captures_per_load) takes a McKibben load
# several times, for the core's refusal: a point of its grid (a pressure with a payload, or two pressures),
# not a load (a stretch test's payload hangs on many points).
SINGLE_CAPTURES: dict[str, tuple[str, str]] = {
    kind: ("point", "an rPAM experiment takes each point of its grid once") for kind in EXPERIMENTS.values()
}
# The stand's channels, in the order of [sensors]: two pressures, the joint angle, actuator a's length.
CHANNELS = ("P_A", "P_B", "POT", "LEN")
_QUANTITIES = ("pressure", "pressure", "angle", "length")

# --------------------------------------------------------------------------- key specs

_LENGTH = {"type": "number", "unit": "m", "check": "positive"}
_SPAN_M = {"type": "pair", "unit": "m", "check": "increasing"}
_KPA = {"type": "number", "unit": "kPa", "check": "nonnegative"}
_COUNT = {"type": "int", "check": ["min", 1]}


def _grid_keys(*names: str) -> dict[str, Any]:
    keys: dict[str, Any] = {}
    for n in names:
        keys.update({f"{n}_start_kPa": _KPA, f"{n}_stop_kPa": _KPA, f"{n}_count": _COUNT})
    return keys


SENSOR_KEYS: dict[str, Any] = {
    "device": {"type": "str", "check": "nonempty", "help": "the device name the ID? reply carries"},
    "channels": {"type": "str-list", "check": "unique", "help": "the channel names in data-line order"},
    "adc_min_counts": {"type": "number", "unit": "counts", "default": 0.0},
    "adc_max_counts": {"type": "number", "unit": "counts", "default": 4095.0},
}

SPECS: dict[str, Any] = {
    "joint": {
        "L1_m": _LENGTH,
        "L2_m": _LENGTH,
        "L3_m": _LENGTH,
        "swivel_mounts": {"type": "bool", "optional": True},
        "bounds": {
            "type": "table",
            "optional": True,
            "keys": {
                "L1_m": _SPAN_M,
                "L2_m": _SPAN_M,
                "L3_m": _SPAN_M,
                "actuator_length_m": _SPAN_M,
                "alpha_deg": {"type": "pair", "unit": "deg", "check": "increasing"},
            },
        },
    },
    "actuator": {
        "L0_m": _LENGTH,
        "prestretch": {"type": "number", "check": "nonnegative", "optional": True},
        "A0_m2": {"type": "number", "unit": "m2", "check": "positive"},
        "n_turns": {"type": "number", "check": "positive"},
        "thread_length_m": _LENGTH,
        # A protocol written before the paper's reading existed is read as it was: derived.
        "force_reading": {
            "type": "str",
            "check": ["one-of", list(FORCE_READINGS)],
            "default": "derived",
            "help": "which reading of Eqs. 1-3 gives the actuator's force",
        },
    },
    "ogden": {
        "mu_MPa": {"type": "number-list", "unit": "MPa", "help": "Eq. 3's moduli"},
        "alpha": {"type": "number-list", "help": "Eq. 3's exponents"},
    },
    "stretch_correction": {
        "coefficients_N": {
            "type": "number-list",
            "length": STRETCH_TERMS,
            "unit": "N",
            "help": "c0..c3 of Eq. 7's cubic",
        },
        "lambda_range": {"type": "pair", "check": "increasing", "help": "the stretches the cubic holds for"},
    },
    # The paper's ranges, for people reading the file.
    "pressure": {
        "joint_map_kPa": {"type": "pair", "unit": "kPa", "optional": True},
        "stretch_test_kPa": {"type": "pair", "unit": "kPa", "optional": True},
        "payload_kg": {"type": "pair", "unit": "kg", "optional": True},
    },
    "experiments": {
        "stretch_test": {
            "type": "table",
            "optional": True,
            "keys": {
                "payloads_g": {"type": "number-list", "unit": "g", "check": "nonnegative"},
                **_grid_keys("pressure"),
            },
        },
        "joint_map": {"type": "table", "optional": True, "keys": _grid_keys("Pa", "Pb")},
    },
    "optimize": {
        "Pa_kPa": {"type": "number", "unit": "kPa"},
        "Pb_kPa": {"type": "number", "unit": "kPa"},
        # The range the search's random generator takes.
        "seed": {"type": "int", "check": ["min", 0], "max": 2**32 - 1},
        "popsize": _COUNT,
        "maxiter": _COUNT,
        "tol": {"type": "number", "check": "positive"},
        "mutation": {"type": "pair"},
        "recombination": {"type": "number", "check": "positive"},
        "active_tolerance": {"type": "number", "check": "positive"},
        "stretch_correction": {"type": "bool"},
        # Positive to optimise (the optimiser says so); a protocol that predates them still loads.
        "min_toggle_margin_deg": {"type": "number", "unit": "deg"},
        "min_stiffness_Nm_per_rad": {"type": "number", "unit": "N m/rad", "optional": True},
        "paper_links_m": {"type": "number-list", "length": 3, "unit": "m", "check": "positive", "optional": True},
        "paper_alpha_deg": {"type": "number", "unit": "deg", "check": "positive", "optional": True},
    },
    "sensors": {
        **SENSOR_KEYS,
        OTHER_KEYS: {
            **channel_spec(None),
            "settle_spread_mm": {
                "type": "number",
                "unit": "mm",
                "check": "positive",
                "optional": True,
                "help": "the settling limit of a length",
            },
        },
    },
}

# --------------------------------------------------------------------------- typed settings


def _bounds(b: dict[str, Any] | None, chk: Checker) -> Bounds | None:
    if b is None:
        return None
    for name in ("L1_m", "L2_m", "L3_m"):
        if not b[name][0] > 0:
            chk.fail(f"key 'joint.bounds.{name}' must start above 0 (a link has a length), not {show(b[name])}.")
    return Bounds(**{k: (v[0], v[1]) for k, v in b.items()})


def _optimize(o: dict[str, Any] | None) -> OptimizeSettings | None:
    if o is None:
        return None
    paper = o.get("paper_links_m")
    return OptimizeSettings(
        Pa_MPa=o["Pa_kPa"] / 1e3,
        Pb_MPa=o["Pb_kPa"] / 1e3,
        seed=o["seed"],
        popsize=o["popsize"],
        maxiter=o["maxiter"],
        tol=o["tol"],
        mutation=(o["mutation"][0], o["mutation"][1]),
        recombination=o["recombination"],
        active_tolerance=o["active_tolerance"],
        stretch_correction=o["stretch_correction"],
        min_toggle_margin_deg=o["min_toggle_margin_deg"],
        min_stiffness_Nm_per_rad=o.get("min_stiffness_Nm_per_rad"),
        paper_links_m=(paper[0], paper[1], paper[2]) if paper is not None else None,
        paper_alpha_deg=o.get("paper_alpha_deg"),
    )


def _steps(t: dict[str, Any], table: str, name: str, chk: Checker) -> tuple[float, ...]:
    """``{name}_count`` pressures from ``{name}_start_kPa`` to ``{name}_stop_kPa``, in MPa."""
    import numpy as np  # the grid as the model always spaced it (np.linspace), to the last bit

    start, stop = t[f"{name}_start_kPa"], t[f"{name}_stop_kPa"]
    if stop < start:
        chk.fail(f"key '{table}.{name}_stop_kPa' must be at least {name}_start_kPa ({show(start)}), not {show(stop)}.")
    return tuple(float(x) for x in np.linspace(start, stop, t[f"{name}_count"]) * 1e-3)


def _grids(e: dict[str, Any], chk: Checker) -> tuple[StretchTestGrid | None, JointMapGrid | None]:
    stretch = joint = None
    if "stretch_test" in e:
        s = e["stretch_test"]
        payloads = tuple(g * 1e-3 for g in s["payloads_g"])
        stretch = StretchTestGrid(payloads, _steps(s, "experiments.stretch_test", "pressure", chk))
    if "joint_map" in e:
        j = e["joint_map"]
        joint = JointMapGrid(
            _steps(j, "experiments.joint_map", "Pa", chk), _steps(j, "experiments.joint_map", "Pb", chk)
        )
    return stretch, joint


def _sensors(s: dict[str, Any] | None, chk: Checker) -> Sensors | None:
    """The DAQ through the core's channel map, then what the stand needs of it."""
    if s is None:
        return None
    device = device_spec(s["device"], s["channels"], (s["adc_min_counts"], s["adc_max_counts"]), chk, "sensors")
    tables = {k: v for k, v in s.items() if k not in SENSOR_KEYS}
    cal = calibration(tables, device, None, chk, section="sensors", listed_in="sensors.channels")
    missing = [c for c in CHANNELS if c not in device.channels]
    if missing:
        chk.fail(
            f"key 'sensors.channels' must include {', '.join(CHANNELS)}; "
            f"{', '.join(missing)} {'is' if len(missing) == 1 else 'are'} missing."
        )
    ours = [ch for ch in cal.channels if ch.name in CHANNELS]
    if [ch.name for ch in ours] != list(CHANNELS) or tuple(ch.quantity for ch in ours) != _QUANTITIES:
        chk.fail(
            f"key 'sensors.channels' must list {', '.join(CHANNELS)} in this order, "
            "two pressures, an angle and a length."
        )
    spreads = []
    for ch in cal.channels:
        if ch.quantity == "length":
            if "settle_spread_mm" not in tables[ch.name]:
                chk.fail(
                    f"missing key 'sensors.{ch.name}.settle_spread_mm', expected a number in mm "
                    "(the settling limit of a length)."
                )
            spreads.append(tables[ch.name]["settle_spread_mm"] * 1e-3)
    return Sensors(device, cal, min(spreads))


def build(checked: dict[str, Any], chk: Checker, path: Path | None) -> RpamSettings:
    """The typed settings of a checked ``rpam`` protocol."""
    j, a, o, c = checked["joint"], checked["actuator"], checked["ogden"], checked["stretch_correction"]
    actuator = Actuator(
        L0_m=a["L0_m"],
        A0_m2=a["A0_m2"],
        n_turns=a["n_turns"],
        thread_length_m=a["thread_length_m"],
        ogden_mu_MPa=tuple(o["mu_MPa"]),
        ogden_alpha=tuple(o["alpha"]),
        stretch_coefficients_N=tuple(c["coefficients_N"]),
        stretch_lambda_range=(c["lambda_range"][0], c["lambda_range"][1]),
        force_reading=a["force_reading"],
    )
    stretch, joint = _grids(checked.get("experiments", {}), chk)
    return RpamSettings(
        geometry=JointGeometry(j["L1_m"], j["L2_m"], j["L3_m"]),
        actuator=actuator,
        bounds=_bounds(j.get("bounds"), chk),
        optimize=_optimize(checked.get("optimize")),
        stretch_test=stretch,
        joint_map=joint,
        sensors=_sensors(checked.get("sensors"), chk),
    )


_REQUIRED = ("joint", "actuator", "ogden", "stretch_correction")

PROTOCOL_KINDS: dict[str, ProtocolKind] = {
    "rpam": ProtocolKind(
        name="rpam",
        sections={
            **{name: ("required" if name in _REQUIRED else "optional", name) for name in SPECS},
            "acquisition": ("optional", "acquisition"),
            "settling": ("optional", "settling"),
        },
        specs=SPECS,
        build=build,
        experiments=EXPERIMENTS,
        described_as="an rPAM protocol",
    ),
}


# --------------------------------------------------------------------------- reading


def named(path: str | Path | None) -> str:
    """How a sentence begins that names a protocol: ``Protocol rpam2015`` for a shipped one, else its path."""
    p = Path(path or "<protocol>")
    return f"Protocol {p.stem}" if p.parent == SHIPPED_DIR else str(p)


def load_rpam(path_or_name: str | Path) -> Protocol:
    """An rPAM protocol (``kind = "rpam"``), a shipped name or a path, read by the one loader.

    Its ``settings`` are an :class:`~.settings.RpamSettings`.
    """
    try:
        return load_protocol(path_or_name, kinds=tuple(PROTOCOL_KINDS))
    except ProtocolFileError as e:
        if e.problem != "kind":
            raise
        arg = str(path_or_name)
        bare = isinstance(path_or_name, str) and not any(sep in arg for sep in "/\\") and not arg.endswith(".toml")
        named = arg if bare else f"file {arg}"  # a shipped name, as the loader reads it, or a file
        raise ConfigError(f'Protocol {named} has kind = {e.detail!r}; the rPAM model needs kind = "rpam".') from None


def stored_protocol(text: str, run: str | Path) -> Protocol:
    """The protocol a run file keeps, read by the one loader (``{run} (protocol)`` in messages)."""
    try:
        return loads_protocol(text, source=f"{run} (protocol)")
    except ProtocolFileError as e:
        if e.problem == "syntax":
            raise ConfigError(f"{run}: the protocol stored in the run is not valid TOML ({e.detail}).") from None
        raise


def with_overrides(protocol: Protocol, assignments: Sequence[str], label: str, shown: Sequence[str] = ()) -> Protocol:
    """``protocol`` with ``key=value`` assignments applied (:func:`apply_overrides`) and checked
    again; ``label`` names it in messages, followed by ``with --set`` and the ``shown`` ones."""
    if not assignments:
        return protocol
    document = apply_overrides(protocol.document, assignments)
    source = f"{label} with --set {' '.join(shown)}" if shown else label
    return check_document(document, source=source, path=protocol.path, kinds=tuple(PROTOCOL_KINDS))


def checked_actuator(settings: RpamSettings, source: str) -> Actuator:
    """The protocol's actuator, refused in one sentence when the model cannot build it."""
    problems = settings.actuator.problems()
    if problems:
        raise ConfigError(f"{source}: {problems[0]}.")
    return settings.actuator


def actuator_of(protocol: str | Path | Protocol) -> Actuator:
    """The actuator of an rPAM protocol: a shipped name (``"rpam2015"``), a path, or a loaded
    protocol; refused in one sentence when the model cannot build it."""
    proto = protocol if isinstance(protocol, Protocol) else load_rpam(protocol)
    return checked_actuator(proto.settings, proto.source_label)


# --------------------------------------------------------------------------- --set


def _parse_value(text: str) -> Any:
    try:
        return tomllib.loads(f"v = {text}")["v"]
    except tomllib.TOMLDecodeError:
        return text


def apply_overrides(raw: dict[str, Any], assignments: Iterable[str]) -> dict[str, Any]:
    """Copy of a protocol document with ``key.path=value`` assignments applied (TOML literals).

    Only existing keys can be set, and a number can only replace a number (a list a list of
    the same length), so a typo is reported instead of silently ignored.
    """
    out = copy.deepcopy(raw)
    for item in assignments:
        if "=" not in item:
            raise ConfigError(f"--set needs key=value (for example actuator.L0_m=0.08), got '{item}'.")
        key, text = (s.strip() for s in item.split("=", 1))
        parts = key.split(".")
        node: Any = out
        for i, part in enumerate(parts):
            if not isinstance(node, dict) or part not in node:
                under = ".".join(parts[:i]) or "the top level"
                known = ", ".join(sorted(node)) if isinstance(node, dict) else "none (it is a value)"
                raise ConfigError(f"Unknown protocol key '{key}' in --set; keys under {under}: {known}.")
            if i < len(parts) - 1:
                node = node[part]
        old = node[parts[-1]]
        if isinstance(old, dict):
            raise ConfigError(f"Protocol key '{key}' is a table; --set one of its keys: {', '.join(sorted(old))}.")
        new = _parse_value(text)
        if not _same_kind(old, new):
            raise ConfigError(f"--set {key}={text}: expected {_kind_text(old)} like the protocol's {old!r}.")
        node[parts[-1]] = new
    return out


def _is_number(v: Any) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def _same_kind(old: Any, new: Any) -> bool:
    if _is_number(old):
        return _is_number(new)
    if isinstance(old, list):
        return (
            isinstance(new, list)
            and len(new) == len(old)
            and all(_same_kind(o, n) for o, n in zip(old, new, strict=True))
        )
    return type(old) is type(new)


def _kind_text(v: Any) -> str:
    if _is_number(v):
        return "a number"
    if isinstance(v, list):
        return f"a list of {len(v)} values"
    return f"a {type(v).__name__}"
