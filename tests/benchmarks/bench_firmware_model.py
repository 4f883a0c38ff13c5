"""Estimates on the chip: cycles per estimate, the highest rate the chip keeps up with, flash and RAM,
and the agreement with the host, for models of each form, on simavr.

Run:  python tests/benchmarks/bench_firmware_model.py [--seconds 3] [--bauds 115200,1000000] [--models force,bent,paper,friction]
                                                       [--realism literature] [--seeds 3]

Models: ``force`` (the sample force run refitted: the posture form with three quantities blended
with the paper's: the heaviest), ``bent`` (the bent protocol's: the paper's angles, the posture
form's forces), ``paper`` (sample_runs/force-paper.model.json: Eqs. 34-37 alone) and ``friction``
(the sample force run refitted with ``--friction-terms``: ``labcli fit``'s default, as ``force`` and
``bent`` are fitted now).  For each:

* flash and RAM of the firmware built with the model (avr-size), beside the firmware without one
  (baseline, same run);
* cycles per estimate: ``model_predict`` on 8 inputs, timed by the harness's cycle counter
  between two port writes (firmware/test/model_bench.c), beside one float multiply and one sinf
  in the same run (the estimate in multiplies is the machine-independent figure); and with a
  motion into the baseline, which a model with the friction terms reads (one erf a pair per
  estimate either way: the baseline's erf once per baseline);
* the highest rate at which every frame gets its estimate (``EST 1``, the estimator skipping under
  1 % of the frames and no data line lost over ``--seconds`` of streaming), by bisection, at each baud:
  at 115200 the line carries a data and an estimate line per frame; at 1000000 the chip's time
  is the limit.  Baseline: one over the chip's own time per estimate (its STOP log);
* the agreement with the host: every estimate line of a run with a load (at 50 Hz), against
  ``predict`` on the same counts and the baseline the board reported: the largest difference in
  % of the quantity's range over the run, and the share of estimates whose flags agree; and the
  same over the estimates the chip does not flag singular, with how many it flags and the host's
  theta2 nearest to straight.  Near a straight arm the paper's forces grow as 1/sin(theta2), and the
  chip's float rounding of sin(theta2) (Eq. 35 on its pressure ratios P0/P - 1, each carried to
  about 6e-8) with them: there the two differ by a share of the force that grows as theta2 shrinks.

The board streams from the simulated rig of ``--realism`` and ``--seeds`` (rig_options.py; default the
literature's rig, seed 3, the one docs/hardware.md's figures were measured on).

Needs gcc-avr, avr-libc and simavr (firmware/README.md).
"""

from __future__ import annotations

import dataclasses
import functools
import json
import re
import shutil
import struct
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "tests"))

from rig_options import add_rig_options, bench_parser  # noqa: E402

from labcli.core.board import baseline_counts  # noqa: E402
from labcli.core.boardlines import ESTIMATE_FLAGS, Estimate, Event  # noqa: E402
from labcli.core.protocol import load_protocol  # noqa: E402
from labcli.core.sim.hil import HilLink  # noqa: E402
from labcli.core.wire import Frame, LogLine, parse_line  # noqa: E402
from labcli.papers.takuma2014.models.posture import PostureModel, load_force_model  # noqa: E402
from labcli.papers.takuma2014.sim.nonideal import NonIdeal  # noqa: E402
from labcli.papers.takuma2014.sim.rig import SimRig  # noqa: E402

QUANTITIES = ("theta1", "theta2", "Fx", "Fy")
STATS = re.compile(r"estimates: (\d+) made, (\d+) frames skipped while busy, (\d+) us mean, (\d+) us at most")
SINGULAR = next(bit for bit, name in ESTIMATE_FLAGS.items() if name == "singular-jacobian")
LOST = re.compile(r"stopped: (\d+) frames sent, (\d+) dropped")


def run(cmd: list[str], **kw) -> str:
    return subprocess.run(cmd, check=True, capture_output=True, text=True, **kw).stdout


def model_files(work: Path, names: list[str]) -> dict[str, Path]:
    out = {}
    for name in names:
        if name == "paper":
            out[name] = ROOT / "sample_runs" / "force-paper.model.json"
            continue
        source = "force" if name == "friction" else name
        shutil.copy(ROOT / "sample_runs" / f"{source}.h5", work / f"{name}.h5")
        extra = ["--friction-terms"] if name == "friction" else []
        run([sys.executable, "-m", "labcli", "fit", str(work / f"{name}.h5"), *extra, "-o", str(work / f"{name}.json")])
        out[name] = work / f"{name}.json"
    return out


def build(work: Path, model: Path | None, baud: int, extra: str = "") -> Path:
    build_dir = work / f"build-{model.stem if model else 'none'}-{baud}{extra.replace(' ', '')}"
    cmd = ["make", "-C", str(ROOT / "firmware"), f"BUILD={build_dir}", f"BAUD={baud}", "all"]
    if model is not None:
        header = build_dir.with_suffix(".h")
        run([sys.executable, "-m", "labcli", "export-model", str(model), "--c", str(header)])
        cmd.append(f"MODEL={header}")
    if extra:
        cmd.append(f"DEFS={extra}")
    run(cmd)
    return build_dir


def sizes(elf: Path) -> tuple[int, int]:
    text = run(["avr-size", "--format=avr", "--mcu=atmega328p", str(elf)])
    return int(re.search(r"Program:\s+(\d+)", text).group(1)), int(re.search(r"Data:\s+(\d+)", text).group(1))


def cycles(build_dir: Path, header: Path) -> dict[int, float]:
    """Median cycles per port-write pair of the model bench, by the value written first."""
    run(["make", "-C", str(ROOT / "firmware"), f"BUILD={build_dir}", f"MODEL={header}", "model-bench"])
    proc = subprocess.Popen(
        [str(build_dir / "labcli_hil"), str(build_dir / "model_bench.elf")],
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        stderr=subprocess.DEVNULL,
    )
    proc.stdin.write(struct.pack("<cI", b"V", 6 * 4 * 300) + np.zeros((300, 6), "<f4").tobytes())  # 0.3 s
    proc.stdin.flush()
    buf, writes = b"", []
    while True:
        chunk = proc.stdout.read1(65536)
        if not chunk:
            break
        buf += chunk
        done = False
        while len(buf) >= 5:
            kind, n = struct.unpack_from("<cI", buf)
            if len(buf) < 5 + n:
                break
            payload, buf = buf[5 : 5 + n], buf[5 + n :]
            if kind == b"P":
                writes.append(struct.unpack("<QcB", payload))
            done |= kind == b"T"
        if done:
            break
    proc.stdin.write(struct.pack("<cI", b"Q", 0))
    proc.stdin.close()
    proc.wait(10)
    spans: dict[int, list[int]] = {}
    start = None
    for cyc, port, value in writes:
        if port != b"B":
            continue
        if value:
            start = (value, cyc)
        elif start is not None:
            spans.setdefault(start[0], []).append(cyc - start[1])
            start = None
    return {k: float(np.median(v)) for k, v in spans.items()}


class Board:
    def __init__(self, elf: Path, rig: SimRig) -> None:
        self._lock = threading.Lock()
        self._bytes = bytearray()
        self.link = HilLink(rig, elf, pacing="demand", on_bytes=self._take)

    def _take(self, data: bytes) -> None:
        with self._lock:
            self._bytes += data

    def send(self, *commands: str) -> None:
        for c in commands:
            self.link.write(c.encode() + b"\n")

    def run(self, seconds: float) -> None:
        end = self.link.avr_time_s + seconds
        while self.link.avr_time_s < end:
            self.link.demand(0.05)
            time.sleep(0.002)

    def lines(self) -> list:
        with self._lock:
            return [parse_line(x, 6) for x in bytes(self._bytes).split(b"\n")[:-1]]


def pressurised(seed: int = 3, realism: str = "literature") -> SimRig:
    rig = SimRig(seed=seed, tau_s=0.3, nonideal=NonIdeal(realism=realism))
    rig.supply_air()
    rig.advance(3.0)
    rig.close_valves()
    rig.advance(1.0)
    return rig


def keeps_up(elf: Path, rate: float, seconds: float, rig_of=pressurised) -> tuple[bool, str]:
    """Stream at ``rate`` with an estimate line per frame: every frame estimated and sent?"""
    board = Board(elf, rig_of())
    try:
        board.send("RATE 20", "START")
        board.run(1.6)  # the baseline, at a rate the chip surely keeps up with
        board.send("STOP", f"RATE {rate:g}", "EST 1", "START")
        board.run(seconds)
        board.send("STOP")
        board.run(0.1)
        logs = [p.text for p in board.lines() if isinstance(p, LogLine)]
    finally:
        board.link.stop()
    stats, lost = STATS.search(logs[-1]), LOST.search(logs[-2])
    made, skipped = int(stats.group(1)), int(stats.group(2))
    # Keeping up: no data line lost, and no more estimates skipped than the stream's first
    # frames cost (an idle frame's estimate may still run when START comes): under 1 %.
    ok = int(lost.group(2)) == 0 and made > 0 and skipped <= 0.01 * (made + skipped)
    return ok, f"{logs[-2]} / {logs[-1]}"


def highest_rate(elf: Path, seconds: float, hi: float, rig_of=pressurised) -> tuple[float, str]:
    lo, why = 1.0, ""
    while hi - lo > 1.0:
        mid = round((lo + hi) / 2)
        ok, text = keeps_up(elf, mid, seconds, rig_of)
        lo, hi = (mid, hi) if ok else (lo, mid)
        why = text if not ok else why
    return lo, why


@dataclasses.dataclass(frozen=True)
class Agreement:
    pct: np.ndarray  # largest |chip - host| in % of each quantity's range, every estimate
    pct_not_singular: np.ndarray  # the same over the estimates the chip does not flag singular
    flags_alike: float  # share of the estimates whose flags agree (posture forms)
    n: int  # estimates compared
    singular: int  # of them flagged singular by the chip
    nearest_theta2_deg: float  # the host's |theta2| nearest to straight


def agreement(elf: Path, model_path: Path, rig_of=pressurised) -> Agreement:
    """The chip's estimates of a run with a load against the host's on the same counts and baselines."""
    model = load_force_model(model_path)
    rig = rig_of()
    board = Board(elf, rig)
    try:
        board.send("RATE 50", "EST 1", "START")
        board.run(1.6)
        rig.hang_weight(0.5, np.radians(20))
        board.run(2.0)
        rig.remove_weight()
        board.run(2.0)
        board.send("STOP")
        board.run(0.1)
        lines = board.lines()
    finally:
        board.link.stop()
    cal = load_protocol("takuma2014").calibration
    frames = {p.seq: p for p in lines if isinstance(p, Frame)}
    bases = [p for p in lines if isinstance(p, Event) and p.kind == "BASELINE"]
    got, want, alike, singular = [], [], [], []
    for e in (p for p in lines if isinstance(p, Estimate) and not p.flags & 256):
        base = [b for b in bases if b.t_us <= e.t_us][-1]
        si0 = cal.to_si(np.array([baseline_counts(base.fields)]))[0]
        si = cal.to_si(np.array([frames[e.seq].values]))[0]
        if isinstance(model, PostureModel):
            out = model.predict(si0[None, :4], si[None, :4], si0[None, 4:])
            se = np.array([out["se"][q][0] for q in QUANTITIES])
            bits = int((~(se <= np.array([model.limits[q] for q in QUANTITIES]))) @ np.array([1, 2, 4, 8]))
            alike.append((e.flags & 15) == bits)
        else:
            out = model.predict(si0[None, :4], si[None, :4])
        want.append([out[k][0] for k in ("theta1_rad", "theta2_rad", "Fx_N", "Fy_N")])
        got.append(e.values)
        singular.append(bool(e.flags & SINGULAR))
    got, want, kept = np.array(got), np.array(want), ~np.array(singular)

    def pct(rows: np.ndarray) -> np.ndarray:
        if not rows.any():
            return np.full(len(QUANTITIES), np.nan)
        return 100 * np.abs(got[rows] - want[rows]).max(axis=0) / np.ptp(want[rows], axis=0)

    return Agreement(
        pct=pct(np.ones(len(got), bool)),
        pct_not_singular=pct(kept),
        flags_alike=float(np.mean(alike) if alike else 1.0),
        n=len(got),
        singular=int(np.count_nonzero(~kept)),
        nearest_theta2_deg=float(np.degrees(np.abs(want[:, 1]).min())),
    )


def main() -> None:
    ap = bench_parser(__doc__)
    ap.add_argument("--seconds", type=float, default=3.0, help="simulated seconds each rate is held")
    ap.add_argument("--bauds", default="115200,1000000")
    ap.add_argument("--models", default="force,bent,paper")
    ap.add_argument("--figures", help="also write the figures to this JSON file ({name: value})")
    add_rig_options(ap, realism="literature", seeds="3", one=True)
    args = ap.parse_args()
    rig_of = functools.partial(pressurised, args.seeds[0], args.realism)
    figures: dict = {"simulated seconds per probe": args.seconds}
    if not (shutil.which("avr-gcc") and Path("/usr/include/simavr/sim_avr.h").exists()):
        sys.exit(
            "needs gcc-avr, avr-libc and simavr: apt-get install gcc-avr avr-libc binutils-avr simavr libsimavr-dev"
        )
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        plain = sizes(build(work, None, 115200) / "labcli_rig.elf")
        print(f"firmware without a model: flash {plain[0]} B, RAM {plain[1]} B (of 32768 and 2048)")
        figures.update({"none flash B": plain[0], "none RAM B": plain[1]})
        for name, path in model_files(work, args.models.split(",")).items():
            built = build(work, path, 115200)
            flash, ram = sizes(built / "labcli_rig.elf")
            c = cycles(built, built.with_suffix(".h"))
            est = c[1]
            print(
                f"\n{name} ({path.name}): flash {flash} B (+{flash - plain[0]}), RAM {ram} B (+{ram - plain[1]}); "
                f"{est:.0f} cycles per estimate ({est / 16e3:.2f} ms at 16 MHz) = {est / c[2]:.0f} float multiplies "
                f"({c[2]:.0f} cycles) or {est / c[16]:.0f} sinf ({c[16]:.0f}); add {c[4]:.0f}, divide {c[8]:.0f}, "
                f"sqrt {c[32]:.0f} cycles; with a motion into the baseline {c[64]:.0f} ({c[64] / 16e3:.2f} ms)"
            )
            figures.update(
                {
                    f"{name} flash B": flash,
                    f"{name} RAM B": ram,
                    f"{name} cycles": est,
                    f"{name} ms": est / 16e3,
                    f"{name} multiplies": est / c[2],
                    f"{name} cycles with history": c[64],
                    f"{name} ms with history": c[64] / 16e3,
                }
            )
            a = agreement(built / "labcli_rig.elf", path, rig_of)
            for q, v, w in zip(QUANTITIES, a.pct, a.pct_not_singular, strict=True):
                figures[f"{name} {q} difference %"] = float(v)
                figures[f"{name} {q} difference % not singular"] = float(w)
            figures.update(
                {
                    f"{name} flags alike %": 100 * a.flags_alike,
                    f"{name} estimates compared": a.n,
                    f"{name} estimates singular": a.singular,
                    f"{name} nearest theta2 deg": a.nearest_theta2_deg,
                }
            )
            print(
                f"  agreement over {a.n} estimates: largest difference "
                + ", ".join(f"{q} {v:.4f} %" for q, v in zip(QUANTITIES, a.pct, strict=True))
                + f" of the range; flags alike on {100 * a.flags_alike:.1f} %; over the {a.n - a.singular} "
                + "not flagged singular: "
                + ", ".join(f"{q} {v:.4f} %" for q, v in zip(QUANTITIES, a.pct_not_singular, strict=True))
                + f"; theta2 nearest to straight {a.nearest_theta2_deg:.4f} deg"
            )
            for baud in (int(b) for b in args.bauds.split(",")):
                elf = build(work, path, baud, "-DRATE_MAX_HZ=2000") / "labcli_rig.elf"
                rate, why = highest_rate(elf, args.seconds, 400.0, rig_of)
                figures[f"{name} {baud} max Hz"] = rate
                print(
                    f"  {baud} baud: every frame estimated and sent up to {rate:g} Hz "
                    f"(baseline 1 / estimate time: {16e6 / est:.0f} Hz); above: {why}"
                )
    if args.figures:
        Path(args.figures).write_text(json.dumps(figures, indent=1) + "\n", encoding="utf-8")


if __name__ == "__main__":
    main()
