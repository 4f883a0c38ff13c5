"""monitor and a board that carries its own model: the board's estimates beside the readings.

The simulated board has no model of its own (the AVR firmware built with one does:
tests/core/test_firmware_model.py), so here the simulated link gains one at the wire: after each
read it hands back one ``$S`` estimate per data frame, of known values.  The monitor asks for them
(``EST 1``), keeps the latest and their statistics, shows them as rows of the live table and puts
them in the JSON summary.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from support.boards import BoardWithModel

from labcli.core.device import Device
from labcli.core.monitoring import channel_scale, watch
from labcli.core.protocol import load_protocol

NAMES = ("theta1", "theta2", "Fx", "Fy")


def values(seq: int) -> tuple[float, ...]:
    return (1e-4 * seq, -0.02, 0.5 + 1e-3 * seq, -1.0)  # rad, rad, N, N


def test_monitor_watches_the_boards_estimates_and_summarises_them():
    proto = load_protocol("takuma2014")
    snaps = []
    with Device.open("sim://?seed=3&clock=virtual") as raw:
        dev = BoardWithModel(raw, NAMES, values)
        scale = channel_scale(raw.info.channels, proto.calibration)
        summary = watch(dev, scale, rate_hz=200.0, seconds=0.3, on_update=snaps.append, refresh_s=0.05)
    assert dev.every == 1
    board = summary.to_json()["board_estimates"]
    n = board["n"]
    assert n > 0
    # Their mean is that of the values sent: one per frame, seq 0 .. n - 1.
    seqs = np.arange(n)
    assert board["theta1"]["mean"] == pytest.approx(1e-4 * seqs.mean(), rel=1e-9)
    assert board["theta2"] == {"mean": pytest.approx(-0.02), "std": pytest.approx(0.0, abs=1e-12), "unit": "rad"}
    assert board["Fx"]["unit"] == "N" and board["Fx"]["std"] == pytest.approx(1e-3 * seqs.std(ddof=1), rel=1e-6)
    assert snaps and snaps[-1].board is summary.board


def test_the_live_table_has_a_row_per_board_estimate():
    from rich.console import Console

    from labcli.commands.monitor import _render

    proto = load_protocol("takuma2014")
    snaps = []
    with Device.open("sim://?seed=3&clock=virtual") as raw:
        dev = BoardWithModel(raw, NAMES, values)
        scale = channel_scale(raw.info.channels, proto.calibration)
        watch(dev, scale, rate_hz=200.0, seconds=0.2, on_update=snaps.append, refresh_s=0.05)
        console = Console(width=200, record=True)
        console.print(_render(snaps[-1], scale, raw.info, plain=True))
    text = console.export_text()
    latest = snaps[-1].board.latest
    assert "theta1 (board)" in text and f"{math.degrees(latest[0]):.2f} deg" in text
    assert "Fy (board)" in text and "-1.00 N" in text


def test_a_board_without_a_model_adds_nothing():
    proto = load_protocol("takuma2014")
    with Device.open("sim://?seed=3&clock=virtual") as dev:
        summary = watch(dev, channel_scale(dev.info.channels, proto.calibration), rate_hz=200.0, seconds=0.1)
    assert summary.board is None and "board_estimates" not in summary.to_json()
