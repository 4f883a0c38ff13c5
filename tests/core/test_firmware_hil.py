"""Hardware in the loop: the compiled firmware on simavr behind the serial port and the link.

The ELF under test is built once per session (the fixture ``firmware_elf``,
``make -C firmware``, warnings refused) and runs on simavr's ATmega328P behind
the harness.  Here the toolkit talks to it through ``sim://?firmware=...``
(pyserial's API, :class:`labcli.core.device.Device`) and through
:class:`labcli.core.sim.hil.HilLink` directly: every command answered as the
protocol says, the ADC's oversampling against a rig of constant counts, the
32-bit counters across their wrap.  What the commands do with the board is
in ``tests/cli/test_firmware_cli.py``.
"""

from __future__ import annotations

import threading
import time
from pathlib import Path

import numpy as np
import serial
from support.firmware_build import make

from labcli.core.device import Device
from labcli.core.sim import register
from labcli.core.sim.hil import FIRMWARE_CHANNELS, HilLink
from labcli.core.wire import StreamReader


def test_the_firmware_answers_every_command_on_the_board(firmware_elf):
    register()
    with serial.serial_for_url(f"sim://?firmware={firmware_elf}", timeout=0.05) as port:
        lines = read_lines(port, 1)
        assert lines == ["# mckibben-2dof 1.1-avr ready, 6 channels, 115200 baud"]  # the power-up banner

        def ask(command: str, n: int = 1) -> list[str]:
            port.write(command.encode("latin-1") + b"\n")
            return read_lines(port, n)

        assert ask("ID?") == ["ID,mckibben-2dof,1.1-avr,P_L1,P_R1,P_L2,P_R2,POT1,POT2"]
        assert ask("RATE 1000") == ["ERR RATE must be within 1..202 Hz at 115200 baud, got 1000"]
        assert ask("RATE 12.5") == ["OK RATE 12.5"]
        assert ask("RATE 33.3333") == ["OK RATE 33.333"]
        assert ask("HELLO") == ["ERR unknown command 'HELLO'"]
        assert ask("x" * 300) == ["ERR command longer than 63 bytes"]
        assert ask("RATE 100\r") == ["OK RATE 100"]
        assert ask("START", 2) == [
            "OK START",
            "# streaming 6 channels at 100 Hz, ADC clock 250 kHz, 16 conversions per value",
        ]
        frames = read_lines(port, 20)
        assert all(line.startswith("$D,") for line in frames)
        stopped = ask("STOP", 1)
        while stopped[-1].startswith("$D,"):
            stopped += read_lines(port, 1)
        assert stopped[-1].startswith("# stopped: ") and " 0 dropped " in stopped[-1]
        assert read_lines(port, 1) == ["OK STOP"]


def read_lines(port, n: int, timeout: float = 20.0) -> list[str]:
    """The next n lines from the port, without their newlines."""
    buf = b""
    deadline = time.monotonic() + timeout
    while buf.count(b"\n") < n and time.monotonic() < deadline:
        buf += port.read(1)
    lines = buf.split(b"\n")
    assert len(lines) > n, f"only {buf!r} within {timeout} s"
    rest = b"\n".join(lines[n:])
    assert rest == b"", rest  # read one byte at a time: nothing past the n-th line
    return [line.decode("latin-1") for line in lines[:n]]


class StillRig:
    """Constant counts on the six inputs, no noise of its own: only the ADC's noise dithers."""

    channels = FIRMWARE_CHANNELS
    device = "still-rig"
    firmware = "0"
    counts = np.array([1000, 1001, 1002, 1003, 2047, 4000])

    def __init__(self) -> None:
        self.time_s = 0.0

    def samples(self, n: int, rate_hz: float):
        t = self.time_s + np.arange(1, n + 1) / rate_hz
        self.time_s = float(t[-1])
        return np.rint(t * 1e6).astype(np.int64), np.tile(self.counts, (n, 1))


def stream(elf: Path, rig, seconds: float, adc_noise_lsb: float) -> np.ndarray:
    """Frames' values for ``seconds`` of simulated time at 200 Hz."""
    got = bytearray()
    lock = threading.Lock()

    def take(data: bytes) -> None:
        with lock:
            got.extend(data)

    link = HilLink(rig, elf, pacing="demand", adc_noise_lsb=adc_noise_lsb, on_bytes=take)
    try:
        link.write(b"START\n")
        deadline = time.monotonic() + 60
        while link.avr_time_s < seconds and time.monotonic() < deadline:
            link.demand(0.1)
            time.sleep(0.01)
    finally:
        link.stop()
    reader = StreamReader(n_channels=6)
    batch = reader.feed(bytes(got))
    assert reader.counters["lost"] == 0 and reader.counters["bad_checksum"] == 0
    return batch.values


def test_oversampling_resolves_single_counts_only_with_noise(firmware_elf):
    """16 conversions give 12 bits when noise dithers the ADC, and 10 bits (steps of 4 counts) when none does."""
    dithered = stream(firmware_elf, StillRig(), 2.0, adc_noise_lsb=0.5)
    assert len(dithered) >= 390
    mean = dithered.mean(axis=0)
    # Rounding the 16-sample sum (quarter counts) to whole counts leaves up to 1/8 count of bias;
    # the mean of 400 frames adds about 0.03 count of noise.
    assert np.all(np.abs(mean - StillRig.counts) < 0.125 + 4 * 0.03), mean
    assert np.all(np.abs(np.diff(mean[:4]) - 1) < 0.3)  # neighbouring counts told apart
    quiet = stream(firmware_elf, StillRig(), 0.5, adc_noise_lsb=0.0)
    assert np.all(quiet.std(axis=0) == 0)  # every conversion the same code
    assert len(set(quiet[0, :4])) <= 2  # 1000..1003 V-steps fall on at most two 10-bit codes
    assert np.abs(quiet[0] - StillRig.counts).max() >= 1.5


def test_counters_wrap_at_32_bits_and_a_new_rate_keeps_the_device_clock(tmp_path_factory, firmware_elf):
    """Built to start 1 s before t_us and 1.5 s before seq wrap: nothing lost, no stall, periods exact."""
    build = tmp_path_factory.mktemp("firmware-wrap")
    make(build, "all", defs=f"-DSEQ_START={2**32 - 300}UL -DT_US_START={2**32 - 1_000_000}UL")
    with Device.open(f"sim://?firmware={build / 'labcli_rig.elf'}") as dev:
        dev.set_rate(200)
        dev.start()
        seqs, times = [], []
        while sum(map(len, seqs)) < 600:
            b = dev.read(timeout=1.0)
            seqs.append(b.seq)
            times.append(b.t_us)
        assert dev.set_rate(100) == 100.0
        while sum(map(len, seqs)) < 700:
            b = dev.read(timeout=1.0)
            seqs.append(b.seq)
            times.append(b.t_us)
        rest = dev.stop()
        assert dev.counters["lost"] == 0 and dev.counters["stalls"] == 0
    seq = np.concatenate(seqs + [rest.seq])
    t_us = np.concatenate(times + [rest.t_us])
    assert seq.max() > 2**32 - 10 and seq.min() < 300  # both sides of the wrap
    assert np.all((np.diff(seq) % 2**32) == 1)
    steps = np.diff(t_us) % 2**32
    switch = np.flatnonzero(steps == 10_000)[0]
    assert np.all(steps[:switch] == 5_000) and np.all(steps[switch:] == 10_000)
