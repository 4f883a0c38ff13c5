"""The ``sim://`` URL's grammar: its options, their defaults and checks, and the accepted form
every refusal shows.

Beside the core's options each paper declares its rigs' own (``Paper.sim_options``, options
declared as data: :mod:`labcli.core.options`, read through the registry); one given with a
``mode`` whose rig does not take it is refused.  ``labcli sim`` builds its command-line
options from the same declarations.

The firmware model's port (:mod:`.protocol_sim`, where each option's meaning is written) and
the compiled firmware on simavr (:mod:`.hil_port`, chosen by ``firmware=``) read the same URL.
"""

from __future__ import annotations

import math
import urllib.parse
from typing import Any

from serial.serialutil import SerialException

from .. import registry
from . import default_mode, modes
from .faults import FAULTS_FORM, FaultSpec, FaultSpecError
from .firmware import FACTOR_MAX, FACTOR_MIN, RATE_MAX, RATE_MIN


def accepted_form() -> str:
    own = "".join(f"[&{name}={opt.metavar}]" for name, opt in registry.sim_options().items())
    return (
        "sim://[?seed=N][&rate=HZ][&noise=X][&drift=X][&clock=virtual|wall][&tau=S][&ratefactor=X]"
        f"[&mode={'|'.join(modes())}][&faults=KIND:RATE[@X],...][&fw=1.0|1.1][&firmware=ELF]{own}"
    )


class SimURLError(SerialException, ValueError):
    """A malformed ``sim://`` URL (both a SerialException and a ValueError)."""


def _whole(text: str) -> int:
    v = int(text)
    if v < 0:
        raise ValueError
    return v


def _nonneg(text: str) -> float:
    v = float(text)
    if not (math.isfinite(v) and v >= 0):
        raise ValueError
    return v


def _rate(text: str) -> float:
    v = float(text)
    if not RATE_MIN <= v <= RATE_MAX:
        raise ValueError
    return v


def _factor(text: str) -> float:
    v = float(text)
    if not FACTOR_MIN <= v <= FACTOR_MAX:
        raise ValueError
    return v


def _positive(text: str) -> float:
    v = float(text)
    if not (math.isfinite(v) and v > 0):
        raise ValueError
    return v


def _clock(text: str) -> str:
    if text not in ("virtual", "wall"):
        raise ValueError
    return text


def _mode(text: str) -> str:
    if text not in modes():
        raise ValueError
    return text


def _faults(text: str) -> FaultSpec | None:
    spec = FaultSpec.parse(text)
    return spec if spec.active else None


def _fw(text: str) -> str:
    if text not in ("1.0", "1.1"):
        raise ValueError
    return text


def _firmware(text: str) -> str:
    if not text:
        raise ValueError
    return text


# option -> (parser, default, what a valid value is (text, or a function giving it))
OPTIONS = {
    "seed": (_whole, 0, "a whole number >= 0"),
    "rate": (_rate, 200.0, f"a number of Hz within {RATE_MIN:g}..{RATE_MAX:g}"),
    "noise": (_nonneg, 1.0, "a number >= 0"),
    "drift": (_nonneg, None, "a number >= 0"),  # None: the rig's own default
    "clock": (_clock, "virtual", "'virtual' or 'wall'"),
    "tau": (_positive, 0.7, "a number of seconds > 0"),
    "ratefactor": (_factor, 1.0, f"a number within {FACTOR_MIN:g}..{FACTOR_MAX:g}"),
    "mode": (_mode, None, lambda: "one of " + ", ".join(modes())),  # None: the default rig
    "faults": (_faults, None, "KIND:RATE[@X],..."),
    "fw": (_fw, "1.1", "the wire protocol version the board speaks, 1.0 or 1.1"),
    "firmware": (_firmware, None, "the path of a firmware ELF"),
}


def _query(url: str) -> dict[str, tuple[bool, str]]:
    """The URL's options as typed: key -> (``=`` given, raw text); malformed, unknown or repeated keys refused."""
    parts = urllib.parse.urlsplit(url)
    if parts.scheme != "sim":
        raise SimURLError(f"'{url}' is not a sim:// URL; expected {accepted_form()}")
    if parts.netloc or parts.path not in ("", "/") or parts.fragment:
        extra = parts.netloc + parts.path + ("#" + parts.fragment if parts.fragment else "")
        raise SimURLError(f"unexpected '{extra}' in sim:// URL; expected {accepted_form()}")
    known = set(OPTIONS) | set(registry.sim_options())
    typed: dict[str, tuple[bool, str]] = {}
    for item in filter(None, parts.query.split("&")):
        key, eq, raw = item.partition("=")
        key = urllib.parse.unquote(key)
        if key not in known:
            raise SimURLError(f"unknown option '{key}' in sim:// URL; expected {accepted_form()}")
        if key in typed:
            raise SimURLError(f"option '{key}' given twice in sim:// URL; expected {accepted_form()}")
        typed[key] = (bool(eq), urllib.parse.unquote(raw))
    return typed


def _value(key: str, parser: Any, what: Any, eq: bool, raw: str) -> Any:
    try:
        return parser(raw) if eq else parser("")
    except FaultSpecError as e:
        raise SimURLError(f"option 'faults' in sim:// URL: {e.detail}; expected faults={FAULTS_FORM}") from None
    except ValueError:
        raise SimURLError(
            f"option '{key}' in sim:// URL must be {what() if callable(what) else what}, got '{raw}'; "
            f"expected {accepted_form()}"
        ) from None


def parse_sim_url(url: str) -> dict:
    """Options of a ``sim://`` URL with defaults filled in; :class:`SimURLError` if malformed.

    The rig's own options are read with the declaration of the rig ``mode`` names (given in
    any order); one that rig does not take is refused.
    """
    typed = _query(url)
    opts: dict[str, Any] = {k: default for k, (_, default, _) in OPTIONS.items()}
    for key, (eq, raw) in typed.items():
        if key in OPTIONS:
            parser, _, what = OPTIONS[key]
            opts[key] = _value(key, parser, what, eq, raw)
    if opts["mode"] is None:
        opts["mode"] = default_mode()
    takes = registry.sim_options(opts["mode"])
    opts.update(dict.fromkeys(takes))
    for key, (eq, raw) in typed.items():
        if key in OPTIONS:
            continue
        if key not in takes:
            raise SimURLError(
                f"option '{key}' in sim:// URL applies to mode={'|'.join(registry.modes_taking(key))} "
                f"only; expected {accepted_form()}"
            )
        opts[key] = _value(key, takes[key].read, takes[key].accepted, eq, raw)
    return opts


def rig_options(opts: dict) -> dict:
    """The rig's own options (its paper's ``sim_options``) among parsed URL options, those given."""
    return {k: opts[k] for k in registry.sim_options(opts["mode"]) if opts.get(k) is not None}


NOT_WITH_FIRMWARE = {
    "rate": "the firmware powers up at its own rate and takes RATE from the host",
    "ratefactor": "the firmware's timer is what its code sets",
    "faults": "the firmware's link is what its UART makes",
    "fw": "the firmware's protocol version is what its code speaks",
}


def firmware_options(url: str) -> dict:
    """Options of a ``sim://?firmware=...`` URL; :class:`SimURLError` if malformed or not for firmware."""
    opts = parse_sim_url(url)
    for item in filter(None, urllib.parse.urlsplit(url).query.split("&")):
        key = urllib.parse.unquote(item.partition("=")[0])
        if key in NOT_WITH_FIRMWARE:
            raise SimURLError(
                f"option '{key}' in sim:// URL does not go with firmware=: {NOT_WITH_FIRMWARE[key]}; "
                f"expected {accepted_form()}"
            )
    return opts
