"""A fitted force model as C for the rig firmware: ``labcli export-model M.json --c model.h``.

The header holds everything ``firmware/src/model.c`` needs to compute what
:meth:`PostureModel.predict` (pressure-only, as ``labcli validate`` applies a model) computes,
in the chip's 32-bit floats, from one frame's counts and the baseline the chip took itself:

* the channels' calibration (counts to MPa and rad, the protocol's ``[channels]``), which
  channel is which actuator and joint, and the rig's geometry (h2, h3);
* the posture form: the angle terms kept and their coefficients, (X^T X)^-1 and residual
  covariance; theta1's own equation; the torque terms kept (indices into TORQUE_TERMS), their
  coefficients, (X^T X)^-1, residual covariance and the force prior, the variance the fit plan's
  directions add to each standard error (after the flags); with the sleeves' friction
  terms (``labcli fit``'s default, indices 14 and 15), each pair's fade
  (``MODEL_FRICTION_WIDTH``: sqrt(2 (sd^2 + FRICTION_MOTION_RAD^2)), sd the pair's motion's
  standard error from the pressures), the chip reading the motion into each baseline it keeps;
* the paper's Eqs. 34-37 where a quantity takes them (route ``paper`` or ``blend``): the 18
  coefficients, their covariances, the amplification bound and theta2's stand-in threshold,
  the held-out variances and each blend's weight and error correlation;
* the flags' limits (the standard errors above which an estimate is flagged uncertain), and
  the pressures below which the chip takes no baseline.

A model of the paper's form alone (``labcli fit --form paper``) exports its four equations with
every quantity on the paper's route and no standard errors (its file carries none).  Numbers are
written to 9 significant digits, which a 32-bit float keeps exactly.
"""

from __future__ import annotations

import hashlib
import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ....core.report import captures_warning
from ....errors import ModelError
from . import routes as rt
from .posture import (
    DEFAULT_LIMITS,
    FRICTION_TERMS,
    RELIEVED_TERMS,
    TORQUE_TERMS,
    PostureModel,
    friction_width,
    load_force_model,
)
from .takuma import TERMS, TakumaModel

ROUTE_CODES = {rt.POSTURE: 0, rt.PAPER: 1, rt.BLEND: 2}
ACTUATORS = ("L1", "R1", "L2", "R2")
BASELINE_MIN_MPA = 0.02  # the chip takes no baseline below this: u = P0/P - 1 needs air in the chambers
QUANTITIES = "theta1:theta2:Fx:Fy"


@dataclass(frozen=True)
class Export:
    """What ``export-model`` wrote: the header, the model it came from, its id and form."""

    header: Path
    model: Path
    model_id: str
    form: str
    routes: dict[str, str]
    protocol: str
    warnings: list[str] = field(default_factory=list)


# --------------------------------------------------------------------------- C text


def _f(x: float) -> str:
    x = float(x)
    if not math.isfinite(x):
        raise ModelError("The model holds a number that is not finite; refit it with `labcli fit`.")
    return f"{x:.9g}f" if ("." in f"{x:.9g}" or "e" in f"{x:.9g}") else f"{x:.9g}.0f"


def _array(ctype: str, name: str, values: Any, fmt: Any = _f) -> str:
    """``static const __flash ctype name[..][..] = {...};`` of a 1-D or 2-D array (never empty)."""
    a = np.asarray(values, dtype=float)
    if a.size == 0:
        a = np.zeros((1,) * max(a.ndim, 1))
    if not a.any():
        # avr-gcc 5 takes a table of zeros in flash for an uninitialised one: a last row of ones,
        # which no code reads, keeps it a table.
        a = np.concatenate([a, np.ones((1,) + a.shape[1:])])
    dims = "".join(f"[{n}]" for n in a.shape)

    def body(x: np.ndarray) -> str:
        if x.ndim == 1:
            return "{" + ", ".join(fmt(v) for v in x) + "}"
        return "{" + ", ".join(body(r) for r in x) + "}"

    return f"static const __flash {ctype} {name}{dims} = {body(a)};\n"


def _ints(values: Iterable[float]) -> str:
    return ", ".join(str(int(v)) for v in values)


def _angle_term_pairs(terms: Sequence[str]) -> list[list[int]]:
    """``u_L1`` -> [0, -1]; ``u_L1*u_R2`` -> [0, 3]."""
    out = []
    for t in terms:
        parts = [ACTUATORS.index(p[2:]) for p in t.split("*")]
        out.append(parts + [-1] * (2 - len(parts)))
    return out


# --------------------------------------------------------------------------- the parts


def _calibration_part(calibration: Any, channels: Sequence[str]) -> str:
    """Counts to SI per channel, and which channel is which actuator and joint."""
    by_name = {c.name: c for c in calibration.channels}
    missing = [c for c in channels if c not in by_name]
    if missing:
        raise ModelError(f"The protocol has no calibration for the channel(s) {', '.join(missing)}.")
    chans = [by_name[c] for c in channels]
    try:
        p_idx = [next(i for i, c in enumerate(chans) if c.actuator == a) for a in ACTUATORS]
        j_idx = [next(i for i, c in enumerate(chans) if c.joint == j) for j in (1, 2)]
    except StopIteration:
        raise ModelError(
            "The protocol's channels do not name the actuators L1, R1, L2, R2 and the joints 1, 2 the model needs."
        ) from None
    min_counts = [chans[i].zero_counts + BASELINE_MIN_MPA / chans[i].gain for i in p_idx]
    return (
        f'#define MODEL_CHANNEL_NAMES "{",".join(channels)}"\n'
        f"#define MODEL_N_CHANNELS {len(channels)}\n"
        "/* value = gain * (counts - zero): MPa for the pressures, rad for the angles */\n"
        + _array("float", "MODEL_GAIN", [c.gain for c in chans])
        + _array("float", "MODEL_ZERO", [c.zero_counts for c in chans])
        + f"static const __flash uint8_t MODEL_P_CHANNEL[4] = {{{_ints(p_idx)}}}; /* L1, R1, L2, R2 */\n"
        + f"static const __flash uint8_t MODEL_POT_CHANNEL[2] = {{{_ints(j_idx)}}}; /* joint 1, joint 2 */\n"
        + "/* no baseline below these counts (BASELINE_MIN_MPA) */\n"
        + _array("float", "MODEL_BASELINE_MIN_COUNTS", min_counts)
    )


def _posture_part(m: PostureModel) -> str:
    a_pairs = _angle_term_pairs(m.angle_terms)
    t1 = list(m.theta1_terms)
    has_prior = bool(m.force_prior_sd)
    known = TORQUE_TERMS + FRICTION_TERMS
    friction = m.uses_history
    width = friction_width(m.pair_motion_sd())
    return (
        "#define MODEL_HAS_POSTURE 1\n"
        f"#define MODEL_NA {len(a_pairs)} /* deflection terms: {', '.join(m.angle_terms)} */\n"
        + f"static const __flash int8_t MODEL_ANGLE_TERM[{len(a_pairs)}][2] = {{"
        + ", ".join("{" + _ints(p) + "}" for p in a_pairs)
        + "};\n"
        + _array("float", "MODEL_ANGLE_COEF", m.angle_coefficients)
        + _array("float", "MODEL_ANGLE_XTX", m.angle_xtx_inv)
        + _array("float", "MODEL_ANGLE_RESID", m.angle_resid_cov)
        + f"#define MODEL_N1 {len(t1)} /* theta1's own terms: {', '.join(t1) or 'none (the shared design)'} */\n"
        + (
            f"static const __flash int8_t MODEL_THETA1_TERM[{max(len(t1), 1)}][2] = {{"
            + ", ".join("{" + _ints(p) + "}" for p in (_angle_term_pairs(t1) or [[0, -1]]))
            + "};\n"
        )
        + _array("float", "MODEL_THETA1_COEF", m.theta1_coefficients or [0.0])
        + _array("float", "MODEL_THETA1_XTX", m.theta1_xtx_inv or [[0.0]])
        + f"#define MODEL_THETA1_VAR {_f(m.theta1_resid_var)}\n"
        + f"#define MODEL_NT {len(m.torque_terms)} /* torque terms: {', '.join(m.torque_terms)} */\n"
        + f"static const __flash uint8_t MODEL_TORQUE_TERM[{len(m.torque_terms)}] = "
        + f"{{{_ints(known.index(t) for t in m.torque_terms)}}};\n"
        + f"#define MODEL_HAS_FRICTION {int(friction)} /* torque terms 14, 15: the sleeves' friction */\n"
        + _array("float", "MODEL_FRICTION_WIDTH", width if friction else [0.0, 0.0])
        + _array("float", "MODEL_TORQUE_COEF", m.torque_coefficients)
        + _array("float", "MODEL_TORQUE_XTX", m.torque_xtx_inv)
        + _array("float", "MODEL_TORQUE_RESID", m.torque_resid_cov)
        + f"#define MODEL_HAS_PRIOR {int(has_prior)}\n"
        + _array("float", "MODEL_PRIOR_SD", m.force_prior_sd if has_prior else [0.0, 0.0])
        + "/* the variance the fit plan's directions add to each standard error (rad^2, N^2) */\n"
        + "#define MODEL_HAS_HELD_OUT 1\n"
        + _array("float", "MODEL_HELD_OUT_VAR", [m.held_out_variance.get(q, 0.0) for q in rt.QUANTITIES])
    )


def _paper_part(
    p: TakumaModel | None, variance: dict[str, float], blends: dict[str, dict[str, float]], alone: bool
) -> str:
    """Eqs. 34-37; their standard errors' parts only beside the posture form (``alone``: the paper's form only)."""
    if p is None:
        return "#define MODEL_HAS_PAPER 0\n"
    b = p.coefficients
    text = (
        "#define MODEL_HAS_PAPER 1\n"
        + "".join(_array("float", f"MODEL_PAPER_B_{eq.upper()}", [b[k] for k in TERMS[eq]]) for eq in TERMS)
        + f"#define MODEL_MAX_AMPLIFICATION {_f(p.max_amplification)}\n"
        + f"#define MODEL_THETA2_THRESHOLD {_f(p.theta2_threshold_rad)} /* rad: theta2 = 0's stand-in */\n"
    )
    if alone:
        return text
    covs = {eq: np.asarray(p.covariance.get(eq, np.zeros((len(TERMS[eq]),) * 2)), dtype=float) for eq in TERMS}
    return (
        text
        + "".join(_array("float", f"MODEL_PAPER_COV_{eq.upper()}", np.nan_to_num(covs[eq])) for eq in TERMS)
        + _array("float", "MODEL_PAPER_VAR", [variance.get(q, 0.0) for q in rt.QUANTITIES])
        + _array("float", "MODEL_BLEND_W", [blends.get(q, {}).get("posture_weight", 1.0) for q in rt.QUANTITIES])
        + _array("float", "MODEL_BLEND_RHO", [blends.get(q, {}).get("error_correlation", 0.0) for q in rt.QUANTITIES])
    )


def c_header(model: TakumaModel | PostureModel, calibration: Any, channels: Sequence[str], *, source: str) -> str:
    """The model as a C header for ``make -C firmware MODEL=...`` (module docstring)."""
    digest = hashlib.sha256(Path(source).read_bytes()).hexdigest() if Path(source).is_file() else ""
    model_id = digest[:8] or "00000000"
    if isinstance(model, PostureModel):
        routes = {q: model.route(q) for q in rt.QUANTITIES}
        paper = model.paper if set(routes.values()) - {rt.POSTURE} else None
        posture = _posture_part(model)
        limits = model.limits
        variance, blends = model.paper_variance, model.blends
    else:
        routes = dict.fromkeys(rt.QUANTITIES, rt.PAPER)
        paper, posture, limits, variance, blends = model, "#define MODEL_HAS_POSTURE 0\n", DEFAULT_LIMITS, {}, {}
    g = model.geometry
    return (
        f"/*\n * The force model {Path(source).name} for the rig firmware (make -C firmware MODEL=this file).\n"
        f" * Written by `labcli export-model`; sha256 of the model file {digest or 'unknown'}.\n"
        f" * Routes: {', '.join(f'{q} {r}' for q, r in routes.items())}.  Units: MPa, rad, m, N.\n */\n"
        "#ifndef LABCLI_MODEL_H\n#define LABCLI_MODEL_H\n\n#include <stdint.h>\n\n"
        "#ifndef __AVR__\n#define __flash /* the host's builds of the model: plain const */\n#endif\n\n"
        f'#define MODEL_ID "{model_id}"\n#define MODEL_QUANTITIES "{QUANTITIES}"\n'
        f"#define MODEL_H2 {_f(g['h2'])}\n#define MODEL_H3 {_f(g['h3'])}\n"
        + f"static const __flash uint8_t MODEL_ROUTE[4] = {{{_ints(ROUTE_CODES[routes[q]] for q in rt.QUANTITIES)}}};"
        + " /* theta1, theta2, Fx, Fy: 0 posture, 1 paper, 2 blend */\n"
        + "/* standard errors above these flag an estimate uncertain (rad, N) */\n"
        + _array("float", "MODEL_LIMIT", [limits.get(q, DEFAULT_LIMITS[q]) for q in rt.QUANTITIES])
        + _calibration_part(calibration, channels)
        + posture
        + _paper_part(paper, variance, blends, alone=not isinstance(model, PostureModel))
        + "\n#endif\n"
    )


# --------------------------------------------------------------------------- the analysis


def export(model: str | Path, *, c: str | Path, protocol: str | None = None, **_: Any) -> Export:
    """Write the model file ``model`` as the C header ``c`` (``protocol``: the calibration's, default the model's)."""
    from ....core.files import atomic_write
    from ....core.protocol import load_protocol

    m = load_force_model(model)
    if not m.is_fitted:
        raise ModelError(f"The model file {model} holds no fitted coefficients; fit one with `labcli fit`.")
    proto = load_protocol(protocol or m.protocol)
    if proto.calibration is None:
        raise ModelError(f"The protocol {proto.name} has no channel calibration for the board's counts.")
    beyond = [t for t in getattr(m, "torque_terms", ()) if t in RELIEVED_TERMS]
    if beyond:
        raise ModelError(
            f"The model file {model} uses the relieved run's friction terms ({', '.join(beyond)}), which the "
            "board's estimator does not compute (it keeps no friction relief); refit without them "
            f"(`labcli fit {m.source or 'RUN.h5'} --no-friction-terms`) and export that model."
        )
    channels = tuple(proto.channels)
    text = c_header(m, proto.calibration, channels, source=str(model))
    atomic_write(c, text.encode("ascii"), what="the C header to ")
    routes = {q: m.route(q) for q in rt.QUANTITIES} if isinstance(m, PostureModel) else {}
    model_id = text.split('#define MODEL_ID "', 1)[1][:8]
    # The board estimates each load from one capture of it.
    narrow = captures_warning(f"the model file {model}", m.captures_per_load, "the board's loads", 1)
    return Export(
        Path(c),
        Path(model),
        model_id,
        "posture" if isinstance(m, PostureModel) else "paper",
        routes,
        proto.name,
        [narrow] if narrow else [],
    )


def show(result: Export, **_: Any) -> None:
    import click

    routes = ", ".join(f"{q} {r}" for q, r in result.routes.items()) or "the paper's Eqs. 34-37"
    for w in result.warnings:
        click.echo(f"Warning: {w}", err=True)
    click.echo(
        f"Wrote {result.header}: the {result.form} model {result.model} (id {result.model_id}; {routes}), "
        f"calibration of protocol {result.protocol}."
    )
    click.echo(f"Build the firmware with it: make -C firmware MODEL={result.header.resolve()}")
