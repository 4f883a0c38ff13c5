"""The monitor judges the link against physics and says so in warnings (issue campaign: it believed
anything): a confirmed rate the frames do not follow by the rig's own clock, counts outside the
ADC's range, a channel pinned at an ADC end, a ``seq`` jump larger than the frames the rig could
have sent.  A good link gives none.
"""

from __future__ import annotations

import json

import pytest
from click.testing import CliRunner
from support.firmware import REFERENCE_COUNTS, FakeFirmware

from labcli.cli import cli


def monitor(fw: FakeFirmware, *extra: str) -> dict:
    result = CliRunner().invoke(cli, ["monitor", "--port", fw.port, "--seconds", "1", "--json", *extra])
    assert result.exit_code == 0, result.output
    return json.loads(result.output)


def test_a_good_link_has_no_warning():
    with FakeFirmware(rate=200) as fw:
        assert monitor(fw)["warnings"] == []


def test_a_clock_ten_times_fast_is_not_the_confirmed_rate():
    with FakeFirmware(rate=200, clock_scale=0.1) as fw:
        (w,) = monitor(fw)["warnings"]
    assert w.startswith("the rig confirmed 200 Hz but sent ")
    rate = float(w.split("sent ")[1].split()[0])
    assert rate == pytest.approx(2000, rel=0.05)  # frames 5 ms apart on the wall, 0.5 ms on the rig's clock
    assert w.endswith(" frames/s by its own clock; its confirmation is not its rate")


def test_counts_outside_the_adc_range_are_not_readings():
    counts = (10**10, *REFERENCE_COUNTS[1:])
    with FakeFirmware(rate=200, counts=counts) as fw:
        summary = monitor(fw)
    (w,) = summary["warnings"]
    n = summary["frames"]
    assert w == f"P_L1 sent {n} of {n} frames with counts outside the ADC's range 0 to 4095: not readings"


def test_a_channel_pinned_at_the_rail_is_named():
    counts = (4095, *REFERENCE_COUNTS[1:])
    with FakeFirmware(rate=200, counts=counts) as fw:
        (w,) = monitor(fw)["warnings"]
    assert w == "P_L1 sat at an end of the ADC's range (0 or 4095 counts): a sensor at its rail"


def test_a_seq_jump_beyond_what_the_rig_could_send_is_a_corrupted_seq():
    with FakeFirmware(rate=200, faults={5: [("gap", 10**9)]}) as fw:
        summary = monitor(fw)
    assert summary["lost"] == 10**9
    (w,) = summary["warnings"]
    assert w.startswith("the frame numbers (seq) jumped by 1000000000 in ")
    assert w.endswith(" s, more than the rig could send; that is a corrupted seq, not lost frames")


def test_a_small_gap_is_lost_frames_and_no_warning():
    with FakeFirmware(rate=200, faults={5: [("gap", 3)]}) as fw:
        summary = monitor(fw)
    assert summary["lost"] == 3 and summary["warnings"] == []


def test_the_table_output_prints_each_warning_on_stderr():
    with FakeFirmware(rate=200, counts=(4095, *REFERENCE_COUNTS[1:])) as fw:
        result = CliRunner().invoke(cli, ["monitor", "--port", fw.port, "--seconds", "0.6"])
    assert result.exit_code == 0
    assert "Warning: P_L1 sat at an end of the ADC's range (0 or 4095 counts): a sensor at its rail.\n" in (
        result.stderr
    )
