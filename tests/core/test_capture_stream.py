"""Capture windows streamed into the run file: flat memory, exact frames, only committed trials count.

The engine streams a trial's Baseline and Capture windows into the run file as they arrive
(:mod:`labcli.core.capture`, :class:`labcli.core.store.frames.WindowWriter`).  Checked here:

* the window writer stores exactly the frames given, in blocks of any size, with the
  checksum and the running mean and variance of the whole window;
* a trial recorded so stores the frames the rig sent, and the same record as the engine
  gathering every window in memory (``support.long_capture.InMemoryEngine``);
* memory does not grow with the window: a trial with windows 10x longer peaks within a
  small bound of the short one (Python's allocations by tracemalloc, the process's by its
  resident size), while gathering in memory grows with the frames;
* a window no record takes (a redo) is left in the file unreferenced and never read.
"""

from __future__ import annotations

import threading
import tracemalloc

import numpy as np
import pytest
from support.long_capture import CHANNELS, long_protocol, port, record_trial
from support.records import make_record, stored_trials

from labcli.core.capture import GapTally, WindowSink
from labcli.core.device import Device
from labcli.core.engine import RunEngine
from labcli.core.simoperator import operator_for
from labcli.core.steps import Baseline, BeginTrial, Capture, Commit, Finish, SettleReport, SetupCheck
from labcli.core.store import RunFile
from labcli.core.store.checksum import frames_checksum
from labcli.core.store.frames import MOD, window_parts
from labcli.core.window import Window
from labcli.errors import ConfigError, StoreError
from labcli.papers.takuma2014.session import ChannelMap, force_record

MiB = 1 << 20


def frames(rng: np.random.Generator, n: int, k: int = CHANNELS) -> tuple[np.ndarray, ...]:
    t = 12.5 + np.cumsum(rng.integers(900, 1100, n)) * 1e-6
    seq = np.arange(7, 7 + n, dtype=np.int64)
    counts = rng.integers(0, 4096, (n, k)).astype(float)
    return t, seq, counts, counts * 2.5e-4 - 0.1


# ---------------------------------------------------------------- the window writer


@pytest.mark.parametrize("blocks", [[1], [4095, 1, 4096, 3], [10_000], [333] * 40, [4096, 4096]])
def test_the_writer_stores_every_frame_given_in_blocks_of_any_size(tmp_path, fake_protocol, blocks):
    rng = np.random.default_rng(len(blocks))
    n = sum(blocks)
    t, seq, counts, si = frames(rng, n)
    with RunFile.create(tmp_path / "run.h5", protocol=fake_protocol) as run:
        chunk = run.tables.frames.chunk
        w = run.windows.begin("trial 1")
        at = 0
        for b in blocks:
            w.append(t[at : at + b], seq[at : at + b], counts[at : at + b], si[at : at + b])
            at += b
            # Whole chunks are in the file as soon as they fill; at most a chunk is held.
            assert w.stop - w.start == at // chunk * chunk and len(w) == at
        stored = w.finish()
        at = stored.stored
        assert (at.start, at.stop) == (0, n) and at.source is run.windows
        back = run.windows.frames(at.start, at.stop)
        np.testing.assert_array_equal(back.t_s, t)
        np.testing.assert_array_equal(back.seq, seq)
        np.testing.assert_array_equal(back.counts, counts)
        np.testing.assert_array_equal(back.si, si)
        assert at.checksum == int(frames_checksum(window_parts(t, seq.astype(np.uint64), counts, si), 0)) % MOD
        assert run.tables.frames.checksum(at.start, at.stop)[0] == at.checksum
        np.testing.assert_allclose(stored.mean(), si.mean(axis=0), rtol=1e-12)
        if n > 1:
            np.testing.assert_allclose(stored.var(ddof=1), si.var(axis=0, ddof=1), rtol=1e-9)
        else:
            assert np.isnan(stored.var(ddof=1)).all()
        assert len(stored) == n
        with pytest.raises(StoreError, match="this window is finished; begin another one to add frames"):
            w.append(t[:1], seq[:1], counts[:1], si[:1])
        # The next window starts at a fresh chunk, past every frame written.
        assert run.windows.begin().start == -(-n // chunk) * chunk


def test_the_gap_tally_gives_numpys_median_of_the_gaps_fed_in_blocks():
    rng = np.random.default_rng(3)
    t = np.cumsum(rng.choice([999, 1000, 1001, 2000, 15_321], 10_001, p=[0.2, 0.5, 0.2, 0.05, 0.05])) * 1e-6
    for cut in ([], [1], [5000], [17, 4000, 9999]):
        tally = GapTally()
        for part in np.split(t, cut):
            tally.add(part)
        assert tally.n == len(t) - 1
        assert tally.median_s() == pytest.approx(float(np.median(np.diff(t))), rel=1e-9)
    even = GapTally()
    even.add(np.array([0.0, 0.001, 0.003]))  # gaps 1 ms and 2 ms: numpy's median is their mean
    assert even.median_s() == pytest.approx(0.0015)
    assert np.isnan(GapTally().median_s())


def test_a_window_outside_a_trial_is_summarised_and_cannot_be_stored(tmp_path, fake_protocol):
    rng = np.random.default_rng(5)
    t, seq, counts, si = frames(rng, 5000)
    sink = WindowSink(CHANNELS)
    for a in range(0, 5000, 700):
        b = min(a + 700, 5000)
        sink.add(Window.of(seq[a:b], counts[a:b], si[a:b], t_s=t[a:b]))
    w = sink.finish()
    assert len(w) == 5000 and not w.kept and w.stored is None
    np.testing.assert_allclose(w.mean(), si.mean(axis=0), rtol=1e-12)
    np.testing.assert_allclose(w.std(), si.std(axis=0), rtol=1e-9)
    with pytest.raises(ConfigError, match="a window read outside a trial is not kept in the run file"):
        w.si
    record = make_record(1)
    record["raw"]["load"] = w
    with RunFile.create(tmp_path / "run.h5", protocol=fake_protocol) as run:
        with pytest.raises(ConfigError, match="a window read outside a trial is not kept in the run file"):
            run.records.write(record)
        assert run.records.ids() == [] and run.windows.extent == 0  # nothing written, not even the baseline


# ---------------------------------------------------------------- the engine


class Recording:
    """A device that keeps every frame it hands the engine (for the round trip)."""

    def __init__(self, dev: Device) -> None:
        self._dev = dev
        self.batches: list = []

    def read(self, timeout: float = 1.0):
        batch = self._dev.read(timeout=timeout)
        self.batches.append(batch)
        return batch

    def __getattr__(self, name: str):
        return getattr(self._dev, name)


def test_a_streamed_trial_stores_the_frames_the_rig_sent_and_verifies(tmp_path):
    protocol = long_protocol(6.0)  # 6000 frames a window: more than one chunk of 4096
    dev = Recording(Device.open(aired(port(4), tmp_path)))
    path = tmp_path / "run.h5"
    with RunFile.create(path, protocol=protocol, device_info=dev.info, port=port(4)) as run:
        engine = RunEngine(
            dev,
            run,
            protocol,
            _quiet(),
            run_path=str(path),
            resume_command="resume",
            simulated_operator=operator_for(dev),
        )
        outcome = engine.run(_two_window_trials(protocol, redo=False))
    dev.close()
    assert outcome.status == "finished" and outcome.stored == 1
    seq = np.concatenate([np.asarray(b.seq, dtype=np.int64) for b in dev.batches])
    t_us = np.concatenate([np.asarray(b.t_us, dtype=np.int64) for b in dev.batches])
    values = np.concatenate([np.asarray(b.values, dtype=float) for b in dev.batches])
    with RunFile.open(path) as run:
        assert run.verify() == {"ok": True, "records": 1, "windows": 2, "problems": []}
        rec = run.records.read(1)
    for name in ("baseline", "load"):
        w = rec["raw"][name]
        assert len(w.seq) == 6000
        # Where the rig sent this window's first frame (each streaming start restarts its counter).
        at = [
            i
            for i in np.flatnonzero(seq == w.seq[0])
            if np.array_equal(t_us[i : i + 6000] % (1 << 32), np.rint(w.t_s * 1e6).astype(np.int64) % (1 << 32))
        ]
        assert len(at) == 1, name
        i = at[0]
        np.testing.assert_array_equal(w.seq, seq[i : i + 6000])
        np.testing.assert_array_equal(w.counts, values[i : i + 6000])
        np.testing.assert_array_equal(w.si, protocol.calibration.to_si(values[i : i + 6000]))


def test_streamed_and_in_memory_capture_store_the_same_trial(tmp_path):
    a, b = tmp_path / "streamed.h5", tmp_path / "memory.h5"
    assert record_trial(a, 5.0, seed=2).stored == 1
    assert record_trial(b, 5.0, seed=2, in_memory=True).stored == 1
    sa, sb = stored_trials(a, attrs=False), stored_trials(b, attrs=False)
    assert sorted(sa) == sorted(sb) == [1]
    raw = [k for k in sa[1] if k.startswith("raw/")]
    assert len(raw) == 8 and all(sa[1][k] == sb[1][k] for k in raw)  # every frame, bit for bit
    for k in set(sa[1]) - set(raw):  # means of 5000 frames: summed in blocks or at once, to rounding
        if isinstance(sa[1][k], tuple):
            x, y = (np.frombuffer(s[2], dtype=s[0]) for s in (sa[1][k], sb[1][k]))
            np.testing.assert_allclose(x, y, rtol=1e-12, atol=1e-15, err_msg=k)
        else:
            assert sa[1][k] == sb[1][k], k
    with RunFile.open(a) as run:
        assert run.verify()["ok"]


def test_a_redone_window_stays_unreferenced_and_the_trial_takes_the_last(tmp_path):
    protocol = long_protocol(1.0)
    dev = Device.open(aired(port(6), tmp_path))
    path = tmp_path / "run.h5"
    with RunFile.create(path, protocol=protocol, device_info=dev.info, port=port(6)) as run:
        engine = RunEngine(
            dev,
            run,
            protocol,
            _quiet(),
            run_path=str(path),
            resume_command="resume",
            simulated_operator=operator_for(dev),
        )
        seen: list = []
        engine.subscribe(lambda step, reply: seen.append(reply) if isinstance(step, (Baseline, Capture)) else None)
        assert engine.run(_two_window_trials(protocol, redo=True)).stored == 1
        extent = run.windows.extent
    dev.close()
    first, second = seen[:2], seen[2:]
    assert [w.stored.start for w in first + second] == sorted(w.stored.start for w in first + second)
    with RunFile.open(path) as run:
        assert run.records.ids() == [1] and run.records.incomplete_ids() == []
        assert run.verify()["ok"]
        rec = run.records.read(1)
        for name, w in zip(("baseline", "load"), second, strict=False):
            np.testing.assert_array_equal(rec["raw"][name].t_s, run.windows.frames(w.stored.start, w.stored.stop).t_s)
        assert extent >= second[1].stored.stop > first[1].stored.stop  # the redone frames lie before, in no record


def aired(url: str, folder) -> str:
    """``url`` with air from the first frame (the rig starts vented; a row of no air is refused)."""
    script = folder / "air.toml"
    script.write_text("[air]\nsupply_s = 0.0\nclose_s = 1.0\n", encoding="utf-8")
    return f"{url}&script={script}"


def _two_window_trials(protocol, redo: bool):
    """Trial 1: a baseline and a loaded window (twice, the first pair dropped, with ``redo``), committed."""
    yield SetupCheck()
    yield BeginTrial(1, "fit", 1, 1, "Trial 1/1")
    settled = SettleReport(True, 0.0, 0.0, 0.0, 0.0, "fixed")
    for _ in range(2 if redo else 1):
        base = yield Baseline(protocol.settling.capture_s)
        loaded = yield Capture(protocol.settling.capture_s)
    cmap = ChannelMap.from_channels(protocol.channels)
    yield Commit(force_record(1, "fit", 0.2, 0.0, base, loaded, settled, settled, cmap))
    yield Finish(None)


def _quiet():
    import io

    from rich.console import Console

    from labcli.core.ui import UnattendedUI

    return UnattendedUI(console=Console(file=io.StringIO(), width=200))


# ---------------------------------------------------------------- memory


class PeakRSS:
    """The largest resident size of this process while in the block, sampled every 2 ms, over that before it."""

    def __init__(self) -> None:
        self.peak = 0

    @staticmethod
    def rss() -> int:
        import os

        with open("/proc/self/statm") as f:
            return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE")

    def __enter__(self) -> PeakRSS:
        self._before = self.rss()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._sample, daemon=True)
        self._thread.start()
        return self

    def _sample(self) -> None:
        while not self._stop.wait(0.002):
            self.peak = max(self.peak, self.rss() - self._before)

    def __exit__(self, *exc) -> None:
        self._stop.set()
        self._thread.join()
        self.peak = max(self.peak, self.rss() - self._before)


def peaks(tmp_path, capture_s: float, in_memory: bool) -> tuple[int, int]:
    """(tracemalloc peak, resident peak) over one trial with windows of ``capture_s``, bytes."""
    path = tmp_path / f"{capture_s:g}-{in_memory}.h5"
    tracemalloc.start()
    try:
        tracemalloc.reset_peak()
        base = tracemalloc.get_traced_memory()[0]
        with PeakRSS() as rss:
            assert record_trial(path, capture_s, in_memory=in_memory).stored == 1
        traced = tracemalloc.get_traced_memory()[1] - base
    finally:
        tracemalloc.stop()
    path.unlink()
    return traced, rss.peak


def test_memory_stays_flat_when_the_window_is_ten_times_longer(tmp_path):
    record_trial(tmp_path / "warm.h5", 1.0)  # imports and first-use setup, not counted
    record_trial(tmp_path / "warm-mem.h5", 1.0, in_memory=True)
    short, long = peaks(tmp_path, 5.0, False), peaks(tmp_path, 50.0, False)
    mem_short, mem_long = peaks(tmp_path, 5.0, True), peaks(tmp_path, 50.0, True)
    frames_added = 2 * 45_000  # the trial's two windows, 45 s more each at 1 kHz
    # Gathered in memory, each added frame costs its arrays (120 bytes of samples and more).
    assert mem_long[0] - mem_short[0] > 100 * frames_added
    # Streamed: the same trial with 10x the frames peaks within 1 MiB of Python allocations
    # and 4 MiB of resident memory (HDF5 keeps freed chunk buffers on its own free lists, up to
    # its limits: about 1 MiB more per 10 minutes of frames at 1 kHz) of the short one.
    print(
        f"peaks (traced, resident) MiB: streamed {[x / MiB for x in short]} -> {[x / MiB for x in long]}, "
        f"in memory {[x / MiB for x in mem_short]} -> {[x / MiB for x in mem_long]}"
    )
    assert long[0] - short[0] < 1 * MiB, (short, long)
    assert long[1] - short[1] < 4 * MiB, (short, long)
