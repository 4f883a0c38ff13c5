"""The channel map: what ``ID?`` must answer and how each channel's counts become SI.

A protocol names its DAQ (the device name ``ID?`` carries, the channels in data-line order,
the ADC's range) and calibrates every channel in a table of its own: quantity, unit, gain,
zero count, range, and the role a paper gives it (the actuator of a pressure channel, the
joint of an angle channel; :class:`labcli.core.paper.ChannelRoles`).  The McKibben rig's
protocols write it as ``[device]`` and ``[channels.NAME]``; the rPAM stand's as
``[sensors]`` with its ``[sensors.NAME]`` tables: one map, checked here, wherever it lives
(``section`` names the tables in messages).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from .calibration import UNIT_FACTORS, Calibration, Channel
from .keyspecs import Checker, describe, fmt_num, or_list, show
from .paper import ChannelRoles

CHANNEL_MAP = "channel-map"  # the spec name of a table of [channels.NAME] tables
# A potentiometer turns less than this (ten-turn pots exist); a joint angle stays within a turn.
MAX_POT_SPAN_DEG = 3600.0
MAX_ANGLE_DEG = 360.0

DEVICE_KEYS: dict[str, Any] = {
    "name": {"type": "str", "help": "the device name the ID? reply carries"},
    "channels": {"type": "str-list", "check": "unique", "help": "the channel names in data-line order"},
    "adc_min_counts": {"type": "number", "unit": "counts"},
    "adc_max_counts": {"type": "number", "unit": "counts"},
}
# Which role a channel of each quantity may name (length channels name none).
_ROLE_OF = {"pressure": "actuator", "angle": "joint"}


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


def channel_spec(roles: ChannelRoles | None) -> dict[str, Any]:
    """The key specs of one channel's table under a kind's channel roles."""
    actuator: dict[str, Any] = {"type": "str", "optional": True}
    joint: dict[str, Any] = {"type": "int", "optional": True}
    if roles is not None and roles.actuators:
        actuator.update(
            check=["one-of", list(roles.actuators)],
            help=f"the actuator of a pressure channel: {or_list(roles.actuators)}",
        )
    if roles is not None and roles.joints:
        joint.update(
            check=["one-of", list(roles.joints)], help=f"the joint of an angle channel: {or_list(roles.joints)}"
        )
    return {
        "quantity": {"type": "str", "check": ["one-of", list(UNIT_FACTORS)]},
        "actuator": actuator,
        "joint": joint,
        "unit": {"type": "str"},
        "gain": {"type": "number", "unit": "unit per count", "check": "nonzero"},
        "zero_counts": {"type": "number", "unit": "counts"},
        "range": {"type": "pair", "check": "increasing", "help": "[low, high] in the channel's unit"},
    }


def device_spec(name: str, channels: list[str], adc: tuple[float, float], chk: Checker, section: str) -> DeviceSpec:
    """A checked device table as a :class:`DeviceSpec` (the ADC's range the right way round)."""
    lo, hi = adc
    if not lo < hi:
        chk.fail(
            f"key '{section}.adc_max_counts' must be greater than {section}.adc_min_counts ({show(lo)}), not {show(hi)}."
        )
    return DeviceSpec(name, tuple(channels), lo, hi)


def calibration(
    tables: dict[str, dict[str, Any]],
    device: DeviceSpec,
    roles: ChannelRoles | None,
    chk: Checker,
    *,
    section: str = "channels",
    listed_in: str = "device.channels",
) -> Calibration:
    """The calibration of every channel ``device`` lists, from their checked tables.

    ``tables`` maps channel names to their checked tables (``section.NAME`` in messages); each
    channel of the device has one and no other does; each role the kind lists is given once.
    """
    listed = list(device.channels)
    missing = [c for c in listed if c not in tables]
    if missing:
        chk.fail(f"missing key '{section}.{missing[0]}', expected a table describing a channel of {listed_in}.")
    extra = [c for c in tables if c not in listed]
    if extra:
        chk.fail(
            f"unknown key '{section}.{extra[0]}'; the keys allowed there are the names in {listed_in} "
            f"({', '.join(listed)})."
        )
    out = [_channel(name, tables[name], device, roles, chk, f"{section}.{name}") for name in listed]
    _check_roles(out, roles, chk, section)
    return Calibration(tuple(out), (device.adc_min_counts, device.adc_max_counts))


def _check_roles(out: list[Channel], roles: ChannelRoles | None, chk: Checker, section: str) -> None:
    """Each actuator and joint has one channel, and every one the kind lists has its channel."""
    for what in ("actuator", "joint"):
        seen: dict[Any, str] = {}
        for ch in out:
            v = getattr(ch, what)
            if v is None:
                continue
            if v in seen:
                chk.fail(
                    f"key '{section}.{ch.name}.{what}' repeats {show(v)}, already the {what} of "
                    f"{section}.{seen[v]}; each {what} has one channel."
                )
            seen[v] = ch.name
    for a in roles.actuators if roles is not None else ():
        if not any(ch.actuator == a for ch in out):
            chk.fail(f"key '{section}' must give a pressure channel for actuator {a} (actuator = \"{a}\").")
    for j in roles.joints if roles is not None else ():
        if not any(ch.joint == j for ch in out):
            chk.fail(f"key '{section}' must give an angle channel for joint {j} (joint = {j}).")


def _check_role_keys(c: dict[str, Any], roles: ChannelRoles | None, chk: Checker, key: str) -> None:
    """A pressure channel may name its actuator, an angle channel its joint; a kind that lists
    the roles needs them named.  A length channel names neither."""
    q = c["quantity"]
    own = _ROLE_OF.get(q)
    needed = (roles.actuators if own == "actuator" else roles.joints) if roles is not None and own else ()
    if own and needed and own not in c:
        chk.fail(f"missing key '{key}.{own}', expected {describe(channel_spec(roles)[own])}.")
    for role in ("actuator", "joint"):
        if role in c and role != own:
            article = "an" if q[0] in "aeiou" else "a"
            allowed = ", ".join(["quantity", *([own] if own else []), "unit", "gain", "zero_counts", "range"])
            chk.fail(f"unknown key '{key}.{role}' for {article} {q} channel; the keys allowed there are {allowed}.")


def _channel(
    name: str, c: dict[str, Any], device: DeviceSpec, roles: ChannelRoles | None, chk: Checker, key: str
) -> Channel:
    """One checked channel table: its role, unit, and a span the ADC can represent."""
    q = c["quantity"]
    _check_role_keys(c, roles, chk, key)
    factors = UNIT_FACTORS[q]
    if c["unit"] not in factors:
        article = "an" if q[0] in "aeiou" else "a"
        chk.fail(
            f"key '{key}.unit' must be one of {', '.join(factors)} for {article} {q} channel, not {show(c['unit'])}."
        )
    lo, hi = c["range"]
    if q == "pressure" and lo < 0:
        chk.fail(f"key '{key}.range' must start at 0 or above (gauge pressure), not {show(c['range'])}.")
    if not math.isfinite(hi):
        chk.fail(f"key '{key}.range' must have a finite high end, not {show(c['range'])}.")
    # The sensor span must be representable: its ends, in counts, inside the ADC range.
    lo_adc, hi_adc = device.adc_min_counts, device.adc_max_counts
    ends = sorted((lo / c["gain"] + c["zero_counts"], hi / c["gain"] + c["zero_counts"]))
    tol = 1e-6 * max(1.0, abs(hi_adc - lo_adc))
    if ends[0] < lo_adc - tol or ends[1] > hi_adc + tol:
        chk.fail(
            f"key '{key}.gain' with zero_counts {show(c['zero_counts'])} maps the range "
            f"{fmt_num(lo)} to {fmt_num(hi)} {c['unit']} to counts {fmt_num(ends[0])} to {fmt_num(ends[1])}, "
            f"outside the ADC range {fmt_num(lo_adc)} to {fmt_num(hi_adc)}; check gain, zero_counts and range."
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
        return (
            f"its gain makes the ADC's span {span:.6g} deg ({abs(math.degrees(gain_rad)):.3g} deg a count), "
            "beyond a ten-turn potentiometer"
        )
    return None
