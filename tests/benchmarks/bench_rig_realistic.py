"""What the realistic simulated rig costs: the unattended 108-trial run on it against the ideal rig.

Run:  python tests/benchmarks/bench_rig_realistic.py [--seeds N] [--realism kind] [--repeat R] [--parts]

Both runs are the library call ``labcli acquire RUN --port 'sim://?seed=N' --unattended``
makes (virtual clock, the shipped protocol and plan): setup, air, 108 trials of
baseline, load, settling, capture and review, the crash-safe writes, the split.  The
rig has sleeve friction, leak, heat, backlash and link weight at the levels of ``--realism``
(:mod:`labcli.papers.takuma2014.sim.nonideal`; kind by default, the rig the docs' figures were
measured on; rig_options.py); ``&ideal=1`` turns them off.  The two alternate, R times
each, in this one process, and the figures are medians:

* wall and CPU time of each run, and realistic / ideal;
* device time (frames / rate): the realistic rig's loads settle for longer (the air's
  heat relaxes over seconds and the detector waits it out), so it streams more frames;
* wall time per device second, realistic / ideal: the cost of the rig's physics per
  unit of simulated time;
* with ``--parts``, CPU seconds spent in the rig's operator actions (static equilibria
  with friction), in making frames (rig sampling and formatting), in the settle
  detector and in the run file's trial writes.
"""

from __future__ import annotations

import functools
import io
import statistics
import sys
import tempfile
import time
from collections import defaultdict
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from rich.console import Console  # noqa: E402
from rig_options import add_rig_options, bench_parser  # noqa: E402

from labcli.core.acquisition import acquire  # noqa: E402
from labcli.core.device import Device  # noqa: E402
from labcli.core.ui import UnattendedUI  # noqa: E402

PARTS = {  # label: (module, attribute path)
    "rig actions (equilibria)": ("labcli.papers.takuma2014.sim.rig", "SimRig._change"),
    "frames (rig samples)": ("labcli.papers.takuma2014.sim.rig", "SimRig.samples"),
    "frames (formatting)": ("labcli.core.sim.firmware", "format_frames"),
    "settle detector": ("labcli.core.settle", "SettleDetector.update"),
    "run file (trial writes)": ("labcli.core.store", "RunFile.write"),
}


class Meter:
    """CPU seconds per part, by wrapping the parts' functions (only while ``on``)."""

    def __init__(self) -> None:
        self.cpu: dict[str, float] = defaultdict(float)
        self.on = False
        self._undo = []

    def install(self) -> None:
        import importlib

        for label, (module, path) in PARTS.items():
            owner = importlib.import_module(module)
            *outer, name = path.split(".")
            for part in outer:
                owner = getattr(owner, part)
            original = getattr(owner, name)

            @functools.wraps(original)
            def timed(*a, _f=original, _label=label, **k):
                if not self.on:
                    return _f(*a, **k)
                t0 = time.process_time()
                try:
                    return _f(*a, **k)
                finally:
                    self.cpu[_label] += time.process_time() - t0

            setattr(owner, name, timed)
            self._undo.append((owner, name, original))

    def uninstall(self) -> None:
        for owner, name, original in reversed(self._undo):
            setattr(owner, name, original)


def one_run(port: str, meter: Meter | None) -> dict:
    frames = 0
    original_read = Device.read

    def counting_read(self, timeout=1.0):
        nonlocal frames
        batch = original_read(self, timeout)
        frames += len(batch)
        return batch

    Device.read = counting_read
    try:
        with tempfile.TemporaryDirectory() as tmp:
            ui = UnattendedUI(console=Console(file=io.StringIO()))
            if meter is not None:
                meter.cpu.clear()
                meter.on = True
            w0, c0 = time.perf_counter(), time.process_time()
            outcome = acquire(Path(tmp) / "run.h5", port, protocol="takuma2014", unattended=True, ui=ui)
            wall, cpu = time.perf_counter() - w0, time.process_time() - c0
            if meter is not None:
                meter.on = False
    finally:
        Device.read = original_read
    if outcome.stored != 108:
        raise SystemExit(f"{port}: {outcome.message}")
    return {"wall": wall, "cpu": cpu, "device": frames / 200.0, "parts": dict(meter.cpu) if meter else {}}


def main() -> None:
    ap = bench_parser(__doc__)
    add_rig_options(ap, realism="kind", seeds="1", one=True)
    ap.add_argument("--repeat", type=int, default=3, help="runs of each rig, alternating (default 3)")
    ap.add_argument("--parts", action="store_true", help="CPU time per part of the run (adds a little overhead)")
    args = ap.parse_args()
    seed = args.seeds[0]
    ports = {
        "realistic": f"sim://?seed={seed}&clock=virtual&realism={args.realism}",
        "ideal": f"sim://?seed={seed}&clock=virtual&realism={args.realism}&ideal=1",
    }
    meter = Meter() if args.parts else None
    if meter is not None:
        meter.install()
    one_run(ports["ideal"], None)  # imports and first-call costs out of the way
    runs: dict[str, list[dict]] = {k: [] for k in ports}
    for _ in range(args.repeat):
        for rig, port in ports.items():
            runs[rig].append(one_run(port, meter))
    if meter is not None:
        meter.uninstall()

    med = {rig: {k: statistics.median(r[k] for r in rs) for k in ("wall", "cpu", "device")} for rig, rs in runs.items()}
    real, ideal = med["realistic"], med["ideal"]
    print(
        f"unattended 108-trial run, {args.realism} rig, seed {seed}, median of {args.repeat} runs of each rig (alternating):"
    )
    print(f"{'rig':10s} {'wall (s)':>9s} {'CPU (s)':>9s} {'device (s)':>11s} {'wall per device s (ms)':>23s}")
    for rig in ports:
        m = med[rig]
        print(f"{rig:10s} {m['wall']:9.2f} {m['cpu']:9.2f} {m['device']:11.0f} {1e3 * m['wall'] / m['device']:23.2f}")
    print(
        f"realistic / ideal: wall {real['wall'] / ideal['wall']:.2f}, CPU {real['cpu'] / ideal['cpu']:.2f}, "
        f"device time {real['device'] / ideal['device']:.2f}, "
        f"wall per device second {(real['wall'] / real['device']) / (ideal['wall'] / ideal['device']):.2f}"
    )
    if meter is not None:
        print("CPU per part (s, median):")
        print(f"  {'part':28s} {'realistic':>10s} {'ideal':>10s}")
        for label in PARTS:
            r, i = (
                statistics.median(run["parts"].get(label, 0.0) for run in runs[rig]) for rig in ("realistic", "ideal")
            )
            print(f"  {label:28s} {r:10.2f} {i:10.2f}")


if __name__ == "__main__":
    main()
