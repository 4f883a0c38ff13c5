"""A board that carries its own model: its estimates beside the host's, frame by frame.

The simulated board has no model of its own (the AVR firmware built with one does:
tests/core/test_firmware_model.py), so the board here is the simulated rig's link with a model
added at the wire: after each read it hands back one ``$S`` estimate per data frame, of known
values.  The live loop asks the board for them (``EST 1``), pairs each host estimate with the
board's of the same frame (``seq``) in its JSON line, and the live view shows them in a column of
their own.
"""

from __future__ import annotations

import json
import math

from support.boards import BoardWithModel
from support.sensing import LinearModel

from labcli.core.device import Device
from labcli.core.protocol import load_protocol
from labcli.sensing import Estimator
from labcli.sensing.live import run
from labcli.sensing.view import LiveView

NAMES = ("x", "f")  # the board's model estimates the toy model's quantities


def board_value(seq: int) -> tuple[float, float]:
    return (seq * 1e-4, -seq * 1e-3)  # rad, N


class Sink:
    def __init__(self) -> None:
        self.lines: list[str] = []

    def publish(self, line: str) -> None:
        self.lines.append(line)

    def close(self) -> None:
        pass


def test_each_host_estimate_carries_the_boards_of_the_same_frame():
    sink, seen = Sink(), []
    with Device.open("sim://?seed=2&clock=virtual") as raw:
        dev = BoardWithModel(raw, NAMES, board_value)
        est = Estimator(LinearModel(), calibration=load_protocol("takuma2014").calibration, channels=raw.info.channels)
        summary = run(dev, est, [sink], seconds=5.0, on_board=seen.append)
    assert dev.every == 1  # the board was asked for an estimate line per frame
    estimates = [json.loads(line) for line in sink.lines if "state" in json.loads(line)]
    assert estimates and summary.paired == len(estimates) == summary.published
    for obj in estimates:
        x, f = board_value(obj["seq"])
        # Keyed as the host's own: the angle in degrees, the force in newtons.
        assert obj["board"] == {"x_deg": round(math.degrees(x), 6), "f_N": round(f, 6), "flags": []}
        assert "x_deg" in obj and "f_N" in obj
    # One per data frame, each seen (the last batch's beyond the 5 s are not counted as frames).
    assert summary.board == len(seen) >= summary.frames
    assert summary.to_json()["paired"] == len(estimates)


def test_a_board_without_a_model_adds_nothing():
    sink = Sink()
    with Device.open("sim://?seed=2&clock=virtual") as dev:
        est = Estimator(LinearModel(), calibration=load_protocol("takuma2014").calibration, channels=dev.info.channels)
        summary = run(dev, est, [sink], seconds=2.0)
    assert summary.board == summary.paired == 0
    assert not any("board" in json.loads(line) for line in sink.lines)


def test_the_live_view_shows_the_boards_estimate_in_a_column_of_its_own():
    from rich.console import Console

    with Device.open("sim://?seed=2&clock=virtual") as raw:
        est = Estimator(LinearModel(), calibration=load_protocol("takuma2014").calibration, channels=raw.info.channels)
        view = LiveView(est, "rig")
        view.board_names = NAMES
        run(BoardWithModel(raw, NAMES, board_value), est, [], seconds=2.0, on_batch=view.take, on_board=view.take_board)
    console = Console(width=200, record=True)
    console.print(view.render(plain=True))
    text = console.export_text()
    assert "board" in text.splitlines()[1] or any("board" in line for line in text.splitlines()[:4])
    x, f = view.board["x"], view.board["f"]
    assert f"{math.degrees(x):.2f} deg" in text and f"{f:.2f} N" in text
