"""The estimator's settings, as plain data (SI: s, MPa, MPa/s).

The defaults describe a McKibben rig like the paper's, and were tuned on the simulated rig's
seeds 1-10 (tests/benchmarks/sensing_online.py); ``labcli.sensing`` documents each in
the sensing page of the docs.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, fields
from typing import Any

from ..errors import ConfigError


@dataclass(frozen=True)
class EstimatorConfig:
    """How the estimator cuts, tracks, detects and fits (module docstring)."""

    # Blocks: one estimate and one detector step per block.  The muscles' lag (0.7 s) leaves
    # nothing faster than a few Hz in the pressures, so 10 estimates a second lose nothing, and
    # each costs one call of the model (about 1-2 ms for the posture form).
    block_s: float = 0.1
    # Baseline: seconds of data before the first estimate can be trusted; the trend's noise.
    warmup_s: float = 2.0
    level_q: float = 1e-12  # MPa^2/s: how far the level may wander beyond its slope (0.001 kPa/sqrt(s))
    slope_q: float = 1e-15  # MPa^2/s^3: how fast the leak's rate may change
    slope_sd: float = 5e-5  # MPa/s: a slope never seen (3 kPa/min)
    angle_level_q: float = 1e-10  # rad^2/s: the rest posture's wander
    # Detector (:mod:`.detector`).
    threshold: float = 30.0
    wander_MPa: float = 3e-5  # how far a tracked reference may be off for seconds at a time (0.03 kPa)
    windows: tuple[int, ...] = (1, 2, 4, 8, 16, 32, 64)
    # Transient model (:mod:`.transient`).
    tau_s: float = 0.7  # the muscles' lag
    tau_factors: tuple[float, ...] = (0.65, 0.72, 0.8, 0.89, 1.0, 1.11, 1.24, 1.38, 1.54)
    onset_shifts_blocks: tuple[float, ...] = (-1.0, -0.5, 0.0, 0.5, 1.0)
    thermal_tau_s: float = 3.0
    # B / A of the heat: kappa - 1 of air (0.4) for a change fast against thermal_tau, less for a slow one.
    thermal_kappas: tuple[float, ...] = (0.0, 0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8)
    shape_sd: float = (
        0.3  # share of what a change's shape still carries (lag to come, heat to leave) counted as uncertain
    )
    shape_error: float = 0.03  # share of a fitted change its shape may miss by (friction, lag, heat)
    fit_span_s: float = 12.0  # blocks after a change that the fit takes (later ones add little)
    history_s: float = 4.0  # blocks kept to place a change once it is detected
    # Settled: the transient's part of each pressure's uncertainty below settle_MPa for settle_hold_s.
    settle_MPa: float = 1e-4
    settle_hold_s: float = 0.25
    min_settle_s: float = 1.0
    # Release: a change seen this long after a load, pointing back to the baseline (the cosine of
    # the angle between the change and the way back at least release_cosine) and not larger than
    # release_overshoot times the load.
    release_guard_s: float = 0.5
    classify_s: float = 0.3  # blocks gathered after a change is seen before it is called a release or a load
    release_cosine: float = 0.7
    release_overshoot: float = 3.0
    # Or (:mod:`.release`) the pressures come back part of the way, give or take the pressure
    # sensors' new readings (how far a new reading may land from the last, rms), or the model
    # reads the force after the change within release_force_se standard errors of zero (0: not asked).
    reread_MPa: float = 5e-4
    release_force_se: float = 2.0
    # The first change after the air was seen supplied waits this long for the joints to move: a
    # load moves them, the valves' closing (the pressure sensors reading afresh) does not.
    closing_s: float = 1.0
    # A change on a load placed this long before it was found is no load or release (their lag
    # shows them within 2 s) but the reference creeping under the held load: the fitted heat's
    # error from the pressure sensors' new readings, the sleeves' friction.  It is folded into the load.
    creep_s: float = 2.5
    # A load whose pressures moved less than this may come off unseen (friction holds the arm): a
    # change on top of it starts afresh from where the rig stands.
    small_load_MPa: float = 5e-4
    # Under a load the model's standard error of a state quantity (a joint angle) under-reads the
    # rig's error: sleeve friction and backlash leave the arm a little elsewhere each time, and
    # the fit's trials average that out.  It is scaled by this factor while a load is on (tuned on
    # seeds 1-10 for 95 % intervals that hold the truth 90-98 % of the time, transients included).
    loaded_state_se_factor: float = 1.4

    def __post_init__(self) -> None:
        for f in fields(self):
            v = getattr(self, f.name)
            values = v if isinstance(v, tuple) else (v,)
            if not values or not all(isinstance(x, (int, float)) and math.isfinite(x) for x in values):
                raise ConfigError(f"Estimator setting {f.name} must be finite numbers, got {v!r}.")
        positive = (
            "block_s",
            "tau_s",
            "thermal_tau_s",
            "threshold",
            "settle_MPa",
            "fit_span_s",
            "history_s",
            "loaded_state_se_factor",
            "closing_s",
            "creep_s",
        )
        for name in positive:
            if not getattr(self, name) > 0:
                raise ConfigError(f"Estimator setting {name} must be greater than 0, got {getattr(self, name)!r}.")
        for name in ("reread_MPa", "release_force_se"):  # 0: that reading of a release is not made
            if not getattr(self, name) >= 0:
                raise ConfigError(f"Estimator setting {name} must be 0 or more, got {getattr(self, name)!r}.")

    def as_dict(self) -> dict[str, Any]:
        return asdict(self)

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> EstimatorConfig:
        known = {f.name for f in fields(cls)}
        unknown = sorted(set(data) - known)
        if unknown:
            raise ConfigError(f"Unknown estimator setting {unknown[0]!r}; known: {', '.join(sorted(known))}.")
        values: dict[str, Any] = {k: tuple(v) if isinstance(v, list) else v for k, v in data.items()}
        return cls(**values)
