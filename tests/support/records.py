"""Deterministic records and a stand-in protocol for the run-file tests.

Also the writer process of the kill tests:
``python tests/support/records.py RUN.h5 N_TRIALS N_SAMPLES [KILL_AT_WRITE]`` writes trials
0..N-1 of :func:`make_record`, resuming a file that exists, and prints
"ready" once the file is open and "stored N" after each trial (killed at its
KILL_AT_WRITE-th write to the file: :func:`kill_at_write`; with a fifth argument ``after-sync``,
killed just after its KILL_AT_WRITE-th ``fdatasync`` returns instead: :func:`kill_after_sync`).
"""

from __future__ import annotations

import math
import os
import sys
from dataclasses import dataclass, field

import numpy as np

from labcli.core.window import Window

CHANNELS = ("P_L1", "P_R1", "P_L2", "P_R2", "POT1", "POT2")


class LinearCalibration:
    """The reference rig's calibration (docs/wire-protocol.md), written out independently."""

    units = ("MPa", "MPa", "MPa", "MPa", "rad", "rad")

    def to_si(self, counts):
        c = np.asarray(counts, dtype=np.float64)
        out = np.empty_like(c)
        out[:, :4] = (c[:, :4] * 5.0 / 4095 - 1.0) / 4.0
        out[:, 4:] = np.radians((c[:, 4:] - 2048) * 340 / 4095)
        return out


@dataclass
class FakeProtocol:
    name: str = "bench"
    kind: str = "force"
    text: str = 'name = "bench"\nkind = "force"\n# verbatim, comments kept\n'
    channels: tuple = CHANNELS
    calibration: LinearCalibration = field(default_factory=LinearCalibration)
    path: str | None = None


@dataclass
class FakeDevice:
    device: str = "mckibben-2dof"
    firmware: str = "1.0"
    channels: tuple = CHANNELS
    port: str = "sim://?seed=1"


def make_window(rng: np.random.Generator, n: int, t0_us: int, seq0: int) -> Window:
    counts = rng.integers(1000, 3000, size=(n, len(CHANNELS))).astype(np.float64)
    t_us = (t0_us + 5000 * np.arange(n, dtype=np.int64)) % (1 << 32)
    seq = (seq0 + np.arange(n, dtype=np.int64)) % (1 << 32)
    return Window.of(seq, counts, LinearCalibration().to_si(counts), t_us=t_us)


def make_record(i: int, n: int = 50) -> dict:
    """Trial ``i``, the same every time; its windows cross the 32-bit clock and counter wraps."""
    rng = np.random.default_rng(1000 + i)
    t0 = (1 << 32) - 5000 * (n // 2) if i % 2 else 1_000_000 * i
    seq0 = (1 << 32) - n // 2 if i % 3 == 0 else 10 * i
    mass = 0.05 * (1 + i % 7)
    direction = math.radians(15.0 * (i % 24))
    return {
        "trial": i,
        "set": "fit" if i % 6 else "validation",
        "P0_MPa": rng.uniform(0.1, 0.3, 4),
        "P_MPa": rng.uniform(0.1, 0.3, 4),
        "pot0_rad": rng.uniform(-0.1, 0.1, 2),
        "theta_rad": rng.uniform(-0.3, 0.3, 2),
        "force_N": np.array([mass * 9.80665 * math.cos(direction), mass * 9.80665 * math.sin(direction)]),
        "mass_kg": mass,
        "direction_rad": direction,
        "started": f"2024-05-01T09:{i % 60:02d}:00Z",
        "ended": f"2024-05-01T09:{i % 60:02d}:30Z",
        "plan": {"mass_g": mass * 1e3, "direction_deg": 15.0 * (i % 24), "set": "fit" if i % 6 else "validation"},
        "settle": {
            "baseline": {
                "settled": True,
                "settle_time_s": 1.5 + i % 3,
                "waited_s": 3.0,
                "pressure_spread_MPa": 0.001,
                "angle_spread_rad": 0.002,
                "criterion": "spread < 1 kPa for 2 s",
            },
            "load": {
                "settled": i % 5 != 4,
                "settle_time_s": 2.0 + (i % 4),
                "waited_s": 6.0,
                "pressure_spread_MPa": 0.0015,
                "angle_spread_rad": 0.0025,
                "criterion": "spread < 1 kPa for 2 s",
            },
        },
        "raw": {"baseline": make_window(rng, n, t0, seq0), "load": make_window(rng, n, t0 + 10_000_000, seq0 + n)},
    }


def unwrap_s(t_us) -> np.ndarray:
    t = np.asarray(t_us, dtype=np.int64)
    return (t + np.concatenate([[0], np.cumsum(np.diff(t) < 0)]) * (1 << 32)) * 1e-6


def assert_record_stored(stored: dict, rec: dict) -> None:
    """``stored`` (RunFile.read) holds exactly what ``rec`` (make_record) gave."""
    assert stored["trial"] == rec["trial"]
    for key in ("P0_MPa", "P_MPa", "theta_rad", "force_N", "pot0_rad"):
        np.testing.assert_array_equal(stored[key], rec[key])
    assert stored["mass_kg"] == rec["mass_kg"]
    assert stored["direction_rad"] == rec["direction_rad"]
    assert stored["started"] == rec["started"] and stored["ended"] == rec["ended"]
    assert stored["plan"] == rec["plan"]
    assert stored["accepted"] == ("auto" if rec["settle"]["load"]["settled"] else "timeout")
    for key in ("baseline", "load"):
        w, r = stored["raw"][key], rec["raw"][key]
        np.testing.assert_array_equal(w.t_s, unwrap_s(r.t_us))
        np.testing.assert_array_equal(w.counts, r.counts)
        np.testing.assert_array_equal(w.si, r.si)
        np.testing.assert_array_equal(w.seq, r.seq)
        s = stored["settle"][key]
        for name, value in rec["settle"][key].items():
            assert s[name] == value, (key, name)
        assert s["accepted"] == ("auto" if rec["settle"][key]["settled"] else "timeout")


def stored_trials(path, attrs: bool = True) -> dict:
    """Every complete trial of a run file as comparable values, by trial id: arrays as (dtype, shape,
    bytes); with ``attrs``, under keys starting with "@", what may differ between two runs of one
    seed (times, order, settling, flags)."""
    from labcli.core.store import RunFile

    out: dict = {}
    with RunFile.open(path) as run:
        for t in run.records.ids():
            items: dict = {}
            for key, value in run.records.read(t).items():
                if key in ("started", "ended", "order", "settle", "accepted", "flags", "extra"):
                    if attrs:
                        items["@" + key] = repr(value)
                elif key == "raw":
                    for window, w in sorted(value.items()):
                        for name in ("counts", "seq", "si", "t_s"):
                            a = np.asarray(getattr(w, name))
                            items[f"raw/{window}/{name}"] = (a.dtype.str, a.shape, a.tobytes())
                elif isinstance(value, dict) or np.asarray(value).dtype == object:
                    items[key] = repr(value)
                else:
                    a = np.asarray(value)
                    items[key] = (a.dtype.str, a.shape, a.tobytes())
            out[int(t)] = items
    return out


def writer(path: str, n_trials: int, n_samples: int) -> None:
    from labcli.core.store import RunFile

    if os.path.exists(path):
        run = RunFile.open(path, "a")
    else:
        run = RunFile.create(path, protocol=FakeProtocol(), device_info=FakeDevice(), port="sim://", operator="kill")
    print("ready", flush=True)
    with run:
        while True:
            nxt = run.records.first_incomplete(range(n_trials))
            if nxt is None:
                break
            run.records.write(make_record(nxt, n_samples))
            print(f"stored {nxt}", flush=True)
    print("done", flush=True)


def kill_at_write(n: int) -> None:
    """SIGKILL this process at its ``n``-th ``os.pwrite`` (every byte a writer puts in a run file goes
    through one: :mod:`labcli.core.store.journal`), the way ``strace -e inject=pwrite64:signal=KILL``
    would; with ``n`` 0, print how many there were when the process ends."""
    import atexit
    import signal

    calls = [0]
    pwrite = os.pwrite

    def counted(fd, data, offset):
        calls[0] += 1
        if calls[0] == n:
            os.kill(os.getpid(), signal.SIGKILL)
        return pwrite(fd, data, offset)

    os.pwrite = counted
    if n == 0:
        atexit.register(lambda: print(f"writes {calls[0]}", flush=True))


def kill_after_sync(n: int) -> None:
    """SIGKILL this process just after its ``n``-th ``os.fdatasync`` returns (the journal's record of a
    checkpoint is durable, the pages it holds not yet copied into the run file); with ``n`` 0, print
    how many there were when the process ends."""
    import atexit
    import signal

    calls = [0]
    fdatasync = os.fdatasync

    def counted(fd):
        fdatasync(fd)
        calls[0] += 1
        if calls[0] == n:
            os.kill(os.getpid(), signal.SIGKILL)

    os.fdatasync = counted
    if n == 0:
        atexit.register(lambda: print(f"syncs {calls[0]}", flush=True))


if __name__ == "__main__":
    if len(sys.argv) > 5 and sys.argv[5] == "after-sync":
        kill_after_sync(int(sys.argv[4]))
    elif len(sys.argv) > 4:
        kill_at_write(int(sys.argv[4]))
    writer(sys.argv[1], int(sys.argv[2]), int(sys.argv[3]))
