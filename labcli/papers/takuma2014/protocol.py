"""The McKibben rig's protocol kinds, ``force`` and ``push``, as plain data for the loader.

:data:`PROTOCOL_KINDS` tells :mod:`labcli.core.protocol` which sections a ``takuma2014`` or
``takuma2014-stiffness`` protocol holds and how each key is checked; :func:`build`
turns the checked sections into :class:`McKibbenSettings` (``Protocol.settings``):
the rig's geometry (m), the trial counts and plan, the limits of typed loads (grams and
degrees, as people type them), the push settings and stiffness bands, and the paper's
Section 3.3 coefficients for comparison.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ...core.keyspecs import OPEN, fmt_num, show
from ...core.paper import ChannelRoles, ProtocolKind
from ...errors import ConfigError
from .tables import load_plan as read_plan

COEFFICIENT_NAMES: tuple[str, ...] = (
    "beta_theta1_L1",
    "beta_theta1_R1",
    "beta_theta2_L1",
    "beta_theta2_R1",
    "beta_theta2_L2",
    "beta_theta2_R2",
    *(f"beta_Fx{i}" for i in range(1, 7)),
    *(f"beta_Fy{i}" for i in range(1, 7)),
)

ACTUATORS: tuple[str, ...] = ("L1", "R1", "L2", "R2")
JOINTS: tuple[int, ...] = (1, 2)

SECTIONS: dict[str, Any] = {
    "rig.mckibben-2dof": {
        # a link or pulley of the arm: from a millimetre to the metre the trial tables allow
        k: {"type": "number", "unit": "m", "check": "positive", "least": 0.001, "max": 1.0}
        for k in ("h1_m", "h2_m", "h3_m", "r1_m", "r2_m")
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
    # The posture-aware form flags an estimate whose standard error exceeds these (models/posture.py).
    "sensing": {
        "max_angle_se_deg": {"type": "number", "unit": "deg", "check": "positive"},
        "max_force_se_N": {"type": "number", "unit": "N", "check": "positive"},
    },
    "stiffness_band": {"type": "pair", "check": "increasing", "help": "[low, high] in N/m"},
}

# Sections whose keys are free names (category names).
TABLES_OF: dict[str, str] = {"stiffness-bands": "stiffness_band"}

_COMMON: dict[str, tuple[str, str]] = {
    "device": ("required", "device"),
    "acquisition": ("required", "acquisition"),
    "rig": ("required", "rig.mckibben-2dof"),
    "channels": ("required", "channel-map"),
    "settling": ("required", "settling"),
}


# --------------------------------------------------------------------------- typed settings


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
class McKibbenSettings:
    """What a ``force`` or ``push`` protocol says beyond the core's sections."""

    rig: dict[str, float]  # h1_m, h2_m, h3_m, r1_m, r2_m
    paper_coefficients: dict[str, float] = field(default_factory=dict)
    trials: Trials | None = None  # force protocols
    force_limits: ForceLimits | None = None  # force protocols
    push: PushSettings | None = None  # push protocols
    sensing: dict[str, float] = field(default_factory=dict)  # max_angle_se_deg, max_force_se_N

    @property
    def default_split(self) -> tuple[int, int] | None:
        """The fit and validation counts ``labcli split`` uses when none are given."""
        return (self.trials.fit, self.trials.validation) if self.trials is not None else None


def _trials(t: dict[str, Any], path: Path | None) -> Trials:
    base = path.parent if path is not None else None
    plan = Path(t["plan"])
    if base is not None and not plan.is_absolute():
        plan = base / plan
    return Trials(t["fit"], t["validation"], plan if base is not None or plan.is_absolute() else None)


def _force_limits(f: dict[str, Any], chk: Any) -> ForceLimits:
    if not f["mass_max_g"] > f["mass_min_g"]:
        chk.fail(
            f"key 'force.mass_max_g' must be greater than force.mass_min_g "
            f"({show(f['mass_min_g'])}), not {show(f['mass_max_g'])}."
        )
    if not f["direction_max_deg"] > f["direction_min_deg"]:
        chk.fail(
            f"key 'force.direction_max_deg' must be greater than force.direction_min_deg "
            f"({show(f['direction_min_deg'])}), not {show(f['direction_max_deg'])}."
        )
    if f["direction_max_deg"] - f["direction_min_deg"] > 360:
        chk.fail(
            "key 'force.direction_max_deg' must be at most 360 deg above force.direction_min_deg, "
            f"not {show(f['direction_max_deg'])}."
        )
    return ForceLimits(**f)


def _push(p: dict[str, Any], bands_raw: dict[str, Any], chk: Any) -> PushSettings:
    if not p["distance_max_m"] > p["distance_min_m"]:
        chk.fail(
            f"key 'push.distance_max_m' must be greater than push.distance_min_m "
            f"({show(p['distance_min_m'])}), not {show(p['distance_max_m'])}."
        )
    bands = {k: (v[0], v[1]) for k, v in bands_raw.items()}
    for name, (lo, hi) in bands.items():
        if lo < 0:
            chk.fail(f"key 'stiffness_bands_N_per_m.{name}' must start at 0 or above, not {show([lo, hi])}.")
    ordered = sorted(bands.items(), key=lambda kv: kv[1][0])
    for (n1, (_, h1)), (n2, (l2, _)) in zip(ordered, ordered[1:], strict=False):
        if l2 < h1:
            chk.fail(
                f"key 'stiffness_bands_N_per_m.{n2}' must not overlap band {n1} "
                f"(which ends at {fmt_num(h1)} N/m), not start at {fmt_num(l2)}."
            )
    return PushSettings(p["pushes_per_object"], p["distance_min_m"], p["distance_max_m"], bands)


def build(checked: dict[str, Any], chk: Any, path: Path | None) -> McKibbenSettings:
    """The typed settings of a checked ``force`` or ``push`` protocol."""
    return McKibbenSettings(
        rig=dict(checked.get("rig", {})),
        paper_coefficients=dict(checked.get("paper_coefficients", {})),
        trials=_trials(checked["trials"], path) if "trials" in checked else None,
        force_limits=_force_limits(checked["force"], chk) if "force" in checked else None,
        push=_push(checked["push"], checked.get("stiffness_bands_N_per_m", {}), chk) if "push" in checked else None,
        sensing=dict(checked.get("sensing", {})),
    )


_ROLES = ChannelRoles(actuators=ACTUATORS, joints=JOINTS)

PROTOCOL_KINDS: dict[str, ProtocolKind] = {
    "force": ProtocolKind(
        name="force",
        sections={
            **_COMMON,
            "trials": ("required", "trials"),
            "force": ("required", "force"),
            "sensing": ("optional", "sensing"),
            "paper_coefficients": ("optional", "paper_coefficients.takuma2014"),
        },
        specs=SECTIONS,
        channel_roles=_ROLES,
        build=build,
    ),
    "push": ProtocolKind(
        name="push",
        sections={
            **_COMMON,
            "push": ("required", "push"),
            "stiffness_bands_N_per_m": ("optional", "stiffness-bands"),
            # Settings of the stiffness estimate (models.stiffness.StiffnessParams, which
            # checks its own keys).
            "stiffness": ("optional", OPEN),
            "paper_coefficients": ("optional", "paper_coefficients.takuma2014"),
        },
        specs=SECTIONS,
        tables_of=TABLES_OF,
        channel_roles=_ROLES,
        build=build,
    ),
}

# Run kinds that take each load several times (--captures, acquisition.captures_per_load), and for
# the others what the core's refusal says each takes once, and why (core.acquisition.check_captures).
CAPTURE_KINDS = ("force",)
SINGLE_CAPTURES: dict[str, tuple[str, str]] = {"push": ("push", "a push run records pushes, each its own")}


def load_plan(protocol: Any) -> Any:
    """The plan named by ``trials.plan`` as a DataFrame, checked against the protocol."""
    s = protocol.settings
    trials = s.trials if s is not None else None
    if trials is None or trials.plan is None:
        raise ConfigError(f"{protocol.source_label}: protocol '{protocol.name}' has no plan (key 'trials.plan').")
    if trials.plan.is_dir():
        raise ConfigError(
            f"{protocol.source_label}: key 'trials.plan' names {trials.plan}, a folder, not a plan file; "
            "give the name of the plan CSV (e.g. takuma2014-plan.csv)."
        )
    if not trials.plan.is_file():
        raise ConfigError(
            f"{protocol.source_label}: key 'trials.plan' names {trials.plan}, which does not exist; "
            "put the plan next to the protocol file or fix the name."
        )
    limits = s.force_limits
    plan = read_plan(
        trials.plan,
        mass_range_g=(limits.mass_min_g, limits.mass_max_g) if limits else None,
        direction_range_deg=(limits.direction_min_deg, limits.direction_max_deg) if limits else None,
    )
    n_fit = int((plan["set"] == "fit").sum())
    n_val = int((plan["set"] == "validation").sum())
    if (n_fit, n_val) != (trials.fit, trials.validation):
        raise ConfigError(
            f"{trials.plan}: the plan has {n_fit} fit and {n_val} validation trials, but "
            f"{protocol.source_label} asks for {trials.fit} and {trials.validation} "
            "(keys 'trials.fit', 'trials.validation')."
        )
    return plan
