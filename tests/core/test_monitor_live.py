"""``labcli monitor``: statistics over the last seconds, a rolling plot, a plain recording, a
header that stays one line when piped; and the rolling pieces (labcli.core.rolling) alone."""

from __future__ import annotations

import json

import h5py
import numpy as np
import pytest
from click.testing import CliRunner

from labcli.cli import cli
from labcli.core.protocol import load_protocol
from labcli.core.rolling import Rolling, spark, trace_rows

# Long enough that a header naming it cannot fit 80 columns.
PORT = "sim://?seed=3&ideal=1&clock=virtual&noise=1"


def test_rolling_statistics_follow_the_last_seconds_only():
    r = Rolling(2, window_s=2.0)
    t = np.arange(0, 10, 0.005)  # 200 frames/s for 10 s
    x = np.where(t[:, None] < 6.0, [1.0, -1.0], [3.0, 5.0]) + np.c_[np.sin(t * 50), np.cos(t * 50)] * 0.1
    for a in range(0, t.size, 37):  # batches of any size
        r.add(t[a : a + 37], x[a : a + 37])
    last = t > 10 - 2.0 - 1e-9
    assert r.n == int(last.sum()) and r.span_s == pytest.approx(2.0)
    np.testing.assert_allclose(r.mean, x[last].mean(axis=0), rtol=1e-12)
    np.testing.assert_allclose(r.std, x[last].std(axis=0, ddof=1), rtol=1e-9)
    # The whole run's mean still carries the step; the window's does not.
    assert abs(r.mean[0] - 3.0) < 0.01 and abs(x[:, 0].mean() - 3.0) > 0.5
    assert r.trace(0).size == 20


def test_spark_draws_low_to_high_over_its_own_range():
    assert spark([0, 1, 2, 3, 4, 5, 6, 7], 8) == "▁▂▃▄▅▆▇█"
    assert spark([5, 5, 5], 4) == " ▁▁▁"  # flat: one level, right-aligned
    assert spark([], 3) == "   " and spark([np.nan, 1.0], 2) == " ▁"
    assert spark(np.arange(100), 10) == "▁▂▃▃▄▅▆▆▇█"  # thinned to the width: values 0, 11, ..., 99
    r = Rolling(1, 1.0)
    r.add(np.arange(0, 1, 0.01), np.arange(100.0)[:, None] / 100)
    ((name, rng, trace),) = trace_rows(r, ["P_L1"], ["MPa"], 10)
    assert name == "P_L1" and rng == "0.0450..0.9450 MPa" and trace == "▁▂▃▃▄▅▆▆▇█"


def test_monitor_records_every_frame_into_a_plain_file(tmp_path):
    rec = tmp_path / "stream.h5"
    r = CliRunner().invoke(cli, ["monitor", "--port", PORT, "--seconds", "0.5", "--json", "--record", str(rec)])
    assert r.exit_code == 0, r.output
    summary = json.loads(r.output)
    with h5py.File(rec, "r") as f:
        s = f["entry/stream"]
        assert f["entry"].attrs["kind"] == "stream" and s.attrs["axes"] == "time"
        assert s["seq"].shape == (summary["frames"],)
        assert np.all(np.diff(s["time"][:]) > 0) and s["time"].attrs["units"] == "s"
        assert list(f["entry"].attrs["channels"]) == list(summary["channels"])
        cal = load_protocol("takuma2014").calibration
        si = cal.to_si(s["counts"][:])
        for j, name in enumerate(summary["channels"]):
            assert s[name].attrs["units"] == summary["channels"][name]["unit"]
            np.testing.assert_allclose(s[name][:], si[:, j], rtol=1e-12, atol=1e-15)
            assert s[name][:].mean() == pytest.approx(summary["channels"][name]["mean"], rel=1e-9, abs=1e-12)
    again = CliRunner().invoke(cli, ["monitor", "--port", PORT, "--seconds", "0.2", "--record", str(rec)])
    assert again.exit_code == 1
    assert again.output == f"Error: {rec} already exists; record into a new file (labcli never overwrites data).\n"


def test_piped_the_header_and_status_stay_one_line_each_and_the_window_is_said():
    r = CliRunner(env={"COLUMNS": "80"}).invoke(
        cli, ["monitor", "--port", PORT, "--seconds", "0.5", "--window", "2", "--plot"]
    )
    assert r.exit_code == 0, r.output
    lines = r.output.splitlines()
    assert lines[0].startswith("mckibben-2dof-sim ") and lines[0].endswith(f" on {PORT} at 200 Hz")
    assert lines[1].split() == ["channel", "now", "mean", "(last", "2", "s)", "std", "(last", "2", "s)"]
    status = [line for line in lines if "frames/s" in line and "log lines" in line and line.endswith(" s")]
    assert len(status) == 1 and len(status[0]) > 80
    assert "last 2 s" in lines and any(line.startswith(" POT1 ") and "deg" in line for line in lines)
