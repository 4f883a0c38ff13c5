"""Protocol files, calibration and the shipped plan."""

from __future__ import annotations

import importlib.util
import itertools
import math
import re
from pathlib import Path

import numpy as np
import pytest

from labcli.core import protocol as protocol_mod
from labcli.core.calibration import format_value, from_display, to_display
from labcli.core.paper import ProtocolKind
from labcli.core.protocol import kinds, load_protocol, loads_protocol, shipped_protocols
from labcli.errors import ConfigError
from labcli.papers.takuma2014.protocol import COEFFICIENT_NAMES, load_plan

ROOT = Path(__file__).resolve().parents[2]
PROTOCOLS = ROOT / "protocols"
SHIPPED = protocol_mod.SHIPPED_DIR  # the protocols as installed (labcli.protocols)
FORCE_TEXT = (PROTOCOLS / "takuma2014.toml").read_text(encoding="utf-8")
PUSH_TEXT = (PROTOCOLS / "takuma2014-stiffness.toml").read_text(encoding="utf-8")


def write_variant(tmp_path: Path, old: str, new: str, text: str = FORCE_TEXT, name: str = "rig.toml") -> Path:
    assert old in text, old
    p = tmp_path / name
    p.write_text(text.replace(old, new, 1), encoding="utf-8")
    return p


def error_of(path: Path) -> str:
    with pytest.raises(ConfigError) as exc:
        load_protocol(path)
    return str(exc.value)


# ---------------------------------------------------------------- shipped files


def test_shipped_names() -> None:
    assert shipped_protocols() == tuple(sorted(p.stem for p in PROTOCOLS.glob("*.toml")))
    assert {"takuma2014", "takuma2014-stiffness"} <= set(shipped_protocols())


@pytest.mark.parametrize("name", sorted(p.stem for p in PROTOCOLS.glob("*.toml")))
def test_every_shipped_protocol_loads(name: str) -> None:
    by_name = load_protocol(name)
    by_path = load_protocol(PROTOCOLS / f"{name}.toml")
    assert by_name.name == by_path.name == name
    assert by_name.kind in kinds()
    assert by_name.text == (PROTOCOLS / f"{name}.toml").read_text(encoding="utf-8")


@pytest.mark.parametrize("name", ["takuma2014", "takuma2014-stiffness"])
def test_mckibben_protocols_by_name_and_by_path(name: str) -> None:
    by_name = load_protocol(name)
    by_path = load_protocol(PROTOCOLS / f"{name}.toml")
    assert by_name.name == by_path.name == name
    assert by_name.text == (PROTOCOLS / f"{name}.toml").read_text(encoding="utf-8")
    assert by_name.channels == ("P_L1", "P_R1", "P_L2", "P_R2", "POT1", "POT2")
    assert by_name.rate_hz == 200.0


@pytest.mark.parametrize("path", sorted(p for p in PROTOCOLS.iterdir() if p.suffix in (".toml", ".csv")), ids=str)
def test_installed_protocols_are_the_repository_files(path: Path) -> None:
    installed = SHIPPED / path.name
    assert installed.is_file(), f"{path} is not installed as package data of labcli.protocols"
    assert installed.read_bytes() == path.read_bytes()


def test_installed_protocols_hold_nothing_unshipped_and_git_holds_one_copy() -> None:
    assert sorted(p.name for p in SHIPPED.iterdir() if p.suffix in (".toml", ".csv")) == sorted(
        p.name for p in PROTOCOLS.iterdir() if p.suffix in (".toml", ".csv")
    )
    assert not (ROOT / "labcli" / "data").exists()


def test_force_protocol_values_from_the_paper() -> None:
    p = load_protocol("takuma2014")
    assert p.kind == "force"
    assert p.settings.rig == {"h1_m": 0.355, "h2_m": 0.130, "h3_m": 0.065, "r1_m": 0.075, "r2_m": 0.035}
    assert (p.settings.trials.fit, p.settings.trials.validation, p.settings.trials.total) == (90, 18, 108)
    assert p.settings.trials.plan == SHIPPED / "takuma2014-plan.csv"
    assert p.device.name == "mckibben-2dof"
    assert p.device.matches("mckibben-2dof") and p.device.matches("mckibben-2dof-sim")
    assert not p.device.matches("mckibben-2dof-v2") and not p.device.matches("rpam")
    assert p.settings.force_limits.mass_min_g == 1.0 and p.settings.force_limits.mass_max_g == 2000.0
    assert tuple(p.settings.paper_coefficients) == COEFFICIENT_NAMES
    # Section 3.3 as printed; Eq. 35's minus before beta_theta2_R2 is read as a misprint.
    printed = {
        "beta_theta1_L1": 0.136,
        "beta_theta1_R1": -1.587,
        "beta_theta2_L1": 1.359,
        "beta_theta2_R1": 1.094,
        "beta_theta2_L2": 0.766,
        "beta_theta2_R2": -2.972,
        "beta_Fx1": -75.906,
        "beta_Fx2": -5.538,
        "beta_Fx3": -2201.033,
        "beta_Fx4": -131.738,
        "beta_Fx5": 1.545,
        "beta_Fx6": -21.865,
        "beta_Fy1": 1.309,
        "beta_Fy2": -75.973,
        "beta_Fy3": -642.995,
        "beta_Fy4": -393.750,
        "beta_Fy5": 1.196,
        "beta_Fy6": -21.697,
    }
    for k, v in printed.items():
        assert p.settings.paper_coefficients[k] == v, k
    # L2 and R2 pull on opposite sides of the upper joint: opposite signs on theta2.
    assert p.settings.paper_coefficients["beta_theta2_L2"] * p.settings.paper_coefficients["beta_theta2_R2"] < 0


def test_settling_is_converted_and_consistent_with_the_rig() -> None:
    from labcli.core.settle import TAIL_WINDOWS

    s = load_protocol("takuma2014").settling
    assert s.angle_spread_rad == pytest.approx(math.radians(0.1), rel=1e-15)
    # at least three 1-s time constants before the earliest acceptance (the tail rule's
    # three windows of history, then the hold)
    earliest = TAIL_WINDOWS * s.window_s + s.hold_s
    assert earliest >= 3.0
    # each limit is one ADC count or a little more (0.305 kPa, 0.083 deg), never below one:
    # block means that sit on two neighbouring counts must count as still
    assert 1 <= s.pressure_spread_MPa / (5.0 / 4095 / 4.0) < 1.5
    assert 1 <= s.angle_spread_rad / math.radians(340 / 4095) < 1.5
    assert s.timeout_s > earliest + s.capture_s


def test_push_protocol_shares_the_rig_with_the_force_protocol() -> None:
    force, push = load_protocol("takuma2014"), load_protocol("takuma2014-stiffness")
    assert push.kind == "push"
    for sec in ("device", "acquisition", "rig", "channels", "settling"):
        assert push.sections[sec] == force.sections[sec], f"[{sec}] differs between the two files"
    assert push.calibration == force.calibration
    assert push.settings.trials is None and push.settings.paper_coefficients == {}
    assert push.settings.push.pushes_per_object == 10
    bands = push.settings.push.stiffness_bands_N_per_m
    assert list(bands) == ["soft", "medium", "hard"]
    assert push.settings.push.category_of(100.0) == "soft"
    assert push.settings.push.category_of(1500.0) == "medium"
    assert push.settings.push.category_of(1e9) == "hard"
    assert "assumed" in PUSH_TEXT.split("[stiffness_bands_N_per_m]")[1]


# ---------------------------------------------------------------- calibration


def test_reference_calibration_example_numbers() -> None:
    cal = load_protocol("takuma2014").calibration
    assert cal.units == ("MPa",) * 4 + ("rad",) * 2
    assert cal.display_units == ("MPa",) * 4 + ("deg",) * 2
    si = cal.to_si(np.array([[819, 819, 819, 819, 2048, 2048]]))
    assert np.all(si == 0.0)  # the documented zero points are exact
    # 0.3 MPa is 1801.8 counts: (0.3 * 4 + 1) V * 4095 / 5 V
    assert cal.to_counts([0.3, 0.3, 0.3, 0.3, 0.0, 0.0])[0] == pytest.approx(1801.8, abs=1e-9)
    assert cal.to_counts([0.3] * 4 + [0.0, 0.0], integer=True).tolist() == [1802] * 4 + [2048] * 2
    # top of the ADC is the top of the sensor span
    assert cal.to_si([4095] * 6)[0] == pytest.approx(1.0, abs=1e-12)
    # 340 deg over 4095 counts
    assert np.degrees(cal.to_si([0, 0, 0, 0, 4095, 0])[4]) == pytest.approx(340 * (4095 - 2048) / 4095, abs=1e-9)
    # the wire-protocol document's own example frame
    frame = cal.to_si([1556, 1560, 1549, 1551, 2048, 2047])
    wire_p = [(c * 5.0 / 4095 - 1.0) / 4.0 for c in (1556, 1560, 1549, 1551)]
    assert frame[:4] == pytest.approx(wire_p, abs=1e-15)
    assert frame[5] == pytest.approx(math.radians(-340 / 4095), rel=1e-12)


def test_calibration_round_trip_counts_si_counts() -> None:
    cal = load_protocol("takuma2014").calibration
    rng = np.random.default_rng(7)
    counts = rng.integers(0, 4096, size=(1000, 6))
    back = cal.to_counts(cal.to_si(counts))
    assert np.max(np.abs(back - counts)) < 1e-9
    assert np.array_equal(cal.to_counts(cal.to_si(counts), integer=True), counts)
    si = cal.to_si(counts)
    assert si.shape == (1000, 6) and si.dtype == np.float64


def test_calibration_clips_integer_counts_like_an_adc_and_rejects_wrong_width() -> None:
    cal = load_protocol("takuma2014").calibration
    assert cal.to_counts([2.0, -1.0, 0.5, 0.5, 0.0, 0.0], integer=True).tolist()[:2] == [4095, 0]
    with pytest.raises(ValueError, match="6 values per row"):
        cal.to_si(np.zeros((3, 5)))


def test_display_helpers() -> None:
    cal = load_protocol("takuma2014").calibration
    shown = cal.to_display([0.25, 0.25, 0.25, 0.25, math.pi / 2, -math.pi / 4])
    assert shown.tolist() == pytest.approx([0.25] * 4 + [90.0, -45.0])
    assert cal.from_display(shown) == pytest.approx([0.25] * 4 + [math.pi / 2, -math.pi / 4])
    assert to_display(math.pi, "angle") == pytest.approx(180.0)
    assert from_display(180.0, "angle") == pytest.approx(math.pi)
    assert format_value(0.30521, "pressure") == "0.3052 MPa"
    assert format_value(math.radians(-12.345), "angle") == "-12.35 deg"
    assert cal.pressure_index() == {"L1": 0, "R1": 1, "L2": 2, "R2": 3}
    assert cal.angle_index() == {1: 4, 2: 5}
    assert cal.in_range([0.5, 0.5, 1.1, 0.5, 0.0, 2.0]).tolist() == [True, True, False, True, True, False]


def test_other_units_convert_to_mpa_and_rad(tmp_path: Path) -> None:
    text = FORCE_TEXT.replace(
        'unit = "MPa"\ngain = 0.00030525030525030525\nzero_counts = 819.0\nrange = [0.0, 1.0]',
        'unit = "kPa"\ngain = 0.30525030525030525\nzero_counts = 819.0\nrange = [0.0, 1000.0]',
        1,
    ).replace(
        'unit = "deg"\ngain = 0.08302808302808302\nzero_counts = 2048.0\nrange = [-90.0, 90.0]',
        'unit = "rad"\ngain = 0.0014491134204592724\nzero_counts = 2048.0\nrange = [-1.5, 1.5]',
        1,
    )
    p = tmp_path / "kpa.toml"
    p.write_text(text, encoding="utf-8")
    cal = load_protocol(p).calibration
    ref = load_protocol("takuma2014").calibration
    counts = np.array([[1801.8, 1801.8, 1000, 1000, 3000, 3000]])
    assert cal.to_si(counts) == pytest.approx(ref.to_si(counts), rel=1e-12)
    assert cal.channels[0].unit_in_file == "kPa" and cal.channels[0].range == pytest.approx((0.0, 1.0))


# ---------------------------------------------------------------- errors, exact text


def test_unknown_key(tmp_path: Path) -> None:
    p = write_variant(tmp_path, "window_s = 1.0", "windw_s = 1.0")
    assert error_of(p) == (
        f"{p}: unknown key 'settling.windw_s'; the keys allowed there are window_s, hold_s, "
        "pressure_spread_MPa, angle_spread_deg, timeout_s, capture_s."
    )


def test_unknown_section(tmp_path: Path) -> None:
    p = write_variant(tmp_path, "[force]", "[forces]")
    assert error_of(p) == (
        f"{p}: unknown key 'forces'; the keys allowed there are name, kind, title, source, paper, [device], "
        "[acquisition], [rig], [channels], [settling], [trials], [force], [sensing], [paper_coefficients]."
    )


def test_missing_key(tmp_path: Path) -> None:
    p = write_variant(tmp_path, "hold_s = 12.0\n", "")
    assert error_of(p) == f"{p}: missing key 'settling.hold_s', expected a number in s."


def test_missing_section(tmp_path: Path) -> None:
    text = re.sub(r"\[trials\].*?(?=\[force\])", "", FORCE_TEXT, flags=re.S)
    p = tmp_path / "rig.toml"
    p.write_text(text, encoding="utf-8")
    assert error_of(p) == f"{p}: missing key 'trials', expected a table [trials]."


def test_wrong_type(tmp_path: Path) -> None:
    p = write_variant(tmp_path, "h1_m = 0.355", 'h1_m = "0.355"')
    assert error_of(p) == f"{p}: key 'rig.h1_m' must be a number in m, not the string '0.355'."
    p = write_variant(tmp_path, "fit = 90", "fit = 90.0")
    assert error_of(p) == f"{p}: key 'trials.fit' must be an integer, not the number 90.0."
    text = FORCE_TEXT.replace("[settling]", "[settling_old]").replace(
        'kind = "force"\n', 'kind = "force"\nsettling = 3\n'
    )
    p = tmp_path / "rig.toml"
    p.write_text(text, encoding="utf-8")
    assert error_of(p) == f"{p}: key 'settling' must be a table [settling], not the integer 3."
    p = write_variant(tmp_path, '"POT2"]', '"POT2", 7]')
    assert error_of(p) == (
        f"{p}: key 'device.channels' must be a list of strings (the channel names in data-line order), "
        "not the list ['P_L1', 'P_R1', 'P_L2', 'P_R2', 'POT1', 'POT2', ...]."
    )


def test_bad_values(tmp_path: Path) -> None:
    p = write_variant(tmp_path, "h1_m = 0.355", "h1_m = -0.355")
    assert error_of(p) == f"{p}: key 'rig.h1_m' must be greater than 0, not -0.355."
    p = write_variant(tmp_path, "fit = 90", "fit = 0")
    assert error_of(p) == f"{p}: key 'trials.fit' must be at least 1, not 0."
    p = write_variant(tmp_path, 'kind = "force"', 'kind = "forse"')
    assert error_of(p) == f"{p}: key 'kind' must be one of force, push, rpam, not 'forse'."
    p = write_variant(tmp_path, "timeout_s = 45.0", "timeout_s = 2.5")
    assert error_of(p) == f"{p}: key 'settling.timeout_s' must be longer than window_s + hold_s (13.0 s), not 2.5."
    p = write_variant(tmp_path, 'unit = "deg"', 'unit = "V"')
    assert error_of(p) == f"{p}: key 'channels.POT1.unit' must be one of rad, deg for an angle channel, not 'V'."
    p = write_variant(tmp_path, 'unit = "MPa"', 'unit = "deg"')
    assert error_of(p) == (
        f"{p}: key 'channels.P_L1.unit' must be one of MPa, kPa, Pa, bar, psi for a pressure channel, not 'deg'."
    )


def test_calibration_that_does_not_fit_the_adc(tmp_path: Path) -> None:
    p = write_variant(tmp_path, "gain = 0.00030525030525030525", "gain = 0.0002")
    assert error_of(p) == (
        f"{p}: key 'channels.P_L1.gain' with zero_counts 819.0 maps the range 0 to 1 MPa to counts "
        "819 to 5819, outside the ADC range 0 to 4095; check gain, zero_counts and range."
    )
    p = write_variant(tmp_path, "range = [-90.0, 90.0]", "range = [-180.0, 180.0]")
    assert "maps the range -180 to 180 deg to counts -119.941 to 4215.94" in error_of(p)


def test_channel_map_errors(tmp_path: Path) -> None:
    p = write_variant(tmp_path, 'actuator = "R2"', 'actuator = "R1"')
    assert error_of(p) == (
        f"{p}: key 'channels.P_R2.actuator' repeats 'R1', already the actuator of channels.P_R1; "
        "each actuator has one channel."
    )
    p = write_variant(tmp_path, '"POT2"]', '"POT2", "POT3"]')
    assert error_of(p) == f"{p}: missing key 'channels.POT3', expected a table describing a channel of device.channels."
    p = write_variant(tmp_path, 'quantity = "angle"\njoint = 1', 'quantity = "angle"\nactuator = "L1"')
    assert error_of(p) == (
        f"{p}: missing key 'channels.POT1.joint', expected an integer (the joint of an angle channel: 1 or 2)."
    )
    p = write_variant(tmp_path, 'quantity = "angle"\njoint = 1', 'quantity = "angle"\njoint = 3')
    assert error_of(p) == f"{p}: key 'channels.POT1.joint' must be one of 1, 2, not 3."


def test_syntax_error_names_line_and_column(tmp_path: Path) -> None:
    p = write_variant(tmp_path, "h1_m = 0.355", "h1_m 0.355")
    line = FORCE_TEXT.splitlines().index("h1_m = 0.355") + 1
    assert error_of(p) == (
        f"{p}: TOML syntax error at line {line}, column 6: expected '=' after a key in a key/value pair."
    )


def test_missing_file_and_unknown_name(tmp_path: Path) -> None:
    assert error_of(tmp_path / "nope.toml") == f"Protocol file {tmp_path / 'nope.toml'} does not exist; check the path."
    assert error_of(tmp_path / "takuma2014.toml") == (
        f"Protocol file {tmp_path / 'takuma2014.toml'} does not exist; check the path "
        "(the shipped protocol of that name is loaded with the bare name takuma2014)."
    )
    with pytest.raises(ConfigError) as exc:
        load_protocol("takuma2015")
    assert str(exc.value) == (
        "There is no shipped protocol named 'takuma2015'; shipped protocols are "
        f"{', '.join(shipped_protocols())}, or give the path of a .toml file."
    )


def test_not_utf8(tmp_path: Path) -> None:
    p = tmp_path / "latin.toml"
    p.write_bytes(FORCE_TEXT.replace("Takamine", "Tak\xe4mine").encode("latin-1"))
    assert error_of(p).startswith(f"{p}: not UTF-8 text (byte ")


def test_every_single_line_deletion_loads_or_raises_one_sentence(tmp_path: Path) -> None:
    # Removing any one line of the shipped file never escapes as a traceback.
    lines = FORCE_TEXT.splitlines(keepends=True)
    for i, line in enumerate(lines):
        if not line.strip() or line.lstrip().startswith("#"):
            continue
        text = "".join(lines[:i] + lines[i + 1 :])
        try:
            loads_protocol(text, source="cut.toml")
        except ConfigError as exc:
            msg = str(exc)
            assert msg.startswith("cut.toml: ") and msg.endswith(".") and "\n" not in msg, msg


# ---------------------------------------------------------------- text, extensibility


def test_loads_from_text_without_a_file() -> None:
    p = loads_protocol(FORCE_TEXT, source="run.h5:protocol")
    assert p.path is None and p.settings.trials.plan is None and p.text == FORCE_TEXT
    with pytest.raises(ConfigError) as exc:
        load_plan(p)
    assert str(exc.value) == "takuma2014: protocol 'takuma2014' has no plan (key 'trials.plan')."


def test_plan_must_exist_and_match_the_trial_counts(tmp_path: Path) -> None:
    p = write_variant(tmp_path, 'plan = "takuma2014-plan.csv"', 'plan = "missing.csv"')
    with pytest.raises(ConfigError) as exc:
        load_plan(load_protocol(p))
    assert str(exc.value) == (
        f"{p}: key 'trials.plan' names {tmp_path / 'missing.csv'}, which does not exist; "
        "put the plan next to the protocol file or fix the name."
    )
    p = write_variant(tmp_path, "validation = 18", "validation = 17")
    (tmp_path / "takuma2014-plan.csv").write_bytes((PROTOCOLS / "takuma2014-plan.csv").read_bytes())
    with pytest.raises(ConfigError) as exc:
        load_plan(load_protocol(p))
    assert str(exc.value) == (
        f"{tmp_path / 'takuma2014-plan.csv'}: the plan has 90 fit and 18 validation trials, but {p} asks for "
        "90 and 17 (keys 'trials.fit', 'trials.validation')."
    )


def test_a_new_kind_is_an_entry_in_the_schema_data(monkeypatch: pytest.MonkeyPatch) -> None:
    from labcli.core import registry

    kind = ProtocolKind(
        "demo-kind",
        {"rig": ("required", protocol_mod.OPEN)},
        extra_sections=True,
        build=lambda checked, chk, path: {"rig": checked["rig"]},
    )
    installed = registry.protocol_kinds
    monkeypatch.setattr(registry, "protocol_kinds", lambda: {**installed(), "demo-kind": kind})
    p = loads_protocol('name = "x"\nkind = "demo-kind"\n[rig]\nL2_m = 0.1048\n[stretch]\npayloads_kg = [0.1, 0.2]\n')
    assert p.kind == "demo-kind" and p.settings == {"rig": {"L2_m": 0.1048}}
    assert p.sections["stretch"] == {"payloads_kg": [0.1, 0.2]}
    assert p.calibration is None and p.channels == ()


def test_rpam_sections_are_declared_as_key_specs_like_every_kinds() -> None:
    # An rPAM protocol's tables are checked as the McKibben rig's are: no table or key unknown ...
    with pytest.raises(ConfigError) as e:
        loads_protocol('name = "rpam"\nkind = "rpam"\n[rig]\nL3_m = 0.06\n')
    assert str(e.value) == (
        "<protocol>: unknown key 'rig'; the keys allowed there are name, kind, title, source, paper, [joint], "
        "[actuator], [ogden], [stretch_correction], [pressure], [experiments], [optimize], [sensors], "
        "[acquisition], [settling]."
    )
    text = (PROTOCOLS / "rpam2015.toml").read_text(encoding="utf-8")
    with pytest.raises(ConfigError) as e:
        loads_protocol(text.replace("[optimize]\n", "[optimize]\nangle_deg = 58.4\n"))
    assert str(e.value).startswith("<protocol>: unknown key 'optimize.angle_deg'; the keys allowed there are Pa_kPa, ")
    # ... its DAQ's channels go through the core's channel map ...
    with pytest.raises(ConfigError) as e:
        loads_protocol(text.replace('unit = "mm"', 'unit = "deg"'))
    assert str(e.value) == "<protocol>: key 'sensors.LEN.unit' must be one of m, mm for a length channel, not 'deg'."
    with pytest.raises(ConfigError) as e:
        loads_protocol(text.replace("zero_counts = 2048.0", "zero_counts = 3500.0"))
    assert str(e.value) == (
        "<protocol>: key 'sensors.POT.gain' with zero_counts 3500.0 maps the range -90 to 90 deg to counts "
        "2416.03 to 4583.97, outside the ADC range 0 to 4095; check gain, zero_counts and range."
    )
    # ... and the file's tables are kept as written beside the typed settings they give.
    p = loads_protocol(text)
    assert p.sections["joint"]["L1_m"] == 0.03 and p.settings.geometry.L1_m == 0.03
    assert p.settings.sensors.calibration.names == ("P_A", "P_B", "POT", "LEN")
    assert p.settings.sensors.calibration.units == ("MPa", "MPa", "rad", "m")


# ---------------------------------------------------------------- the plan


def _plan_module():
    spec = importlib.util.spec_from_file_location("make_plan", PROTOCOLS / "make_plan.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_plan_script_regenerates_the_shipped_plan_byte_for_byte(tmp_path: Path) -> None:
    mod = _plan_module()
    out = tmp_path / "plan.csv"
    mod.main(["--out", str(out)])
    assert out.read_bytes() == (PROTOCOLS / "takuma2014-plan.csv").read_bytes()
    assert mod.plan_csv(seed=1) != mod.plan_csv()  # the seed matters


def test_plan_design() -> None:
    plan = load_plan(load_protocol("takuma2014"))
    assert len(plan) == 108
    assert plan["trial"].tolist() == list(range(1, 109))
    assert plan["set"].tolist() == ["fit"] * 90 + ["validation"] * 18  # sequential split
    fit, val = plan.iloc[:90], plan.iloc[90:]
    fit_pairs = set(zip(fit.mass_g, fit.direction_deg, strict=False))
    masses = sorted(set(fit.mass_g))
    directions = sorted(set(fit.direction_deg))
    # fit: the full 9 x 10 grid, every pair once
    assert len(masses) == 9 and len(directions) == 10
    assert fit_pairs == set(itertools.product(masses, directions))
    assert (min(masses), max(masses)) == (50.0, 1000.0)
    # both sides of the arm, within 60 deg of the horizontal, 30 deg apart
    right = sorted(d for d in directions if -90 < d < 90)
    left = sorted((d % 360) for d in directions if not -90 < d < 90)
    assert right == [-60, -30, 0, 30, 60] and left == [120, 150, 180, 210, 240]
    # validation: same ranges, never a fit mass, never a fit direction
    for m, d in zip(val.mass_g, val.direction_deg, strict=False):
        assert (m, d) not in fit_pairs
        assert 50 < m < 1000 and m not in masses
        assert d not in directions
        side = right if -90 < d < 90 else left
        dd = d if -90 < d < 90 else d % 360
        assert min(side) < dd < max(side)
    # each validation mass once per side
    for side_test in (lambda d: -90 < d < 90, lambda d: not -90 < d < 90):
        vm = sorted(m for m, d in zip(val.mass_g, val.direction_deg, strict=False) if side_test(d))
        assert len(vm) == 9 and len(set(vm)) == 9
    # grouped by pulley position: each direction is one contiguous block
    for block in (fit, val):
        runs = [k for k, _ in itertools.groupby(block.direction_deg)]
        assert len(runs) == len(set(runs))
    # weights are shuffled inside a block, not ascending
    assert fit.mass_g.iloc[:9].tolist() != sorted(fit.mass_g.iloc[:9])


# ---------------------------------------------------------------- fuzzing

from hypothesis import given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402

_VALUE_LINES = [i for i, line in enumerate(FORCE_TEXT.splitlines()) if re.match(r"^[A-Za-z_0-9]+ = ", line)]
_TOML_VALUES = st.one_of(
    st.sampled_from(
        [
            '"x"',
            '""',
            "0",
            "-1",
            "1e999",
            "nan",
            "-inf",
            "true",
            "[]",
            "[1, 2]",
            "[1, nan]",
            "[-inf, 1.0]",
            '["a", "a"]',
            "{a = 1}",
            "1979-05-27",
            "07:32:00",
            "0.0",
            "4095",
            "[0.0, 1.0, 2.0]",
        ]
    ),
    st.integers(-(10**20), 10**20).map(str),
    st.floats(allow_nan=False, allow_infinity=False).map(repr),
    st.text(alphabet="abcPL12_ -", max_size=8).map(lambda s: '"' + s + '"'),
)


@settings(max_examples=300, deadline=None)
@given(line=st.sampled_from(_VALUE_LINES), value=_TOML_VALUES)
def test_any_value_anywhere_loads_or_raises_one_sentence(line: int, value: str) -> None:
    lines = FORCE_TEXT.splitlines()
    key = lines[line].split(" = ")[0]
    lines[line] = f"{key} = {value}"
    try:
        p = loads_protocol("\n".join(lines) + "\n", source="fz.toml")
    except ConfigError as exc:
        msg = str(exc)
        assert msg.startswith("fz.toml: ") and msg.endswith(".") and "\n" not in msg, msg
        assert "key '" in msg or "TOML syntax error" in msg, msg
    else:
        # accepted: the calibration still covers its span inside the ADC range
        cal = p.calibration
        lo = np.array([c.range[0] for c in cal.channels])
        hi = np.array([c.range[1] for c in cal.channels])
        for ends in (cal.to_counts(lo), cal.to_counts(hi)):
            assert np.all(ends >= cal.adc_range[0] - 1e-3) and np.all(ends <= cal.adc_range[1] + 1e-3)
