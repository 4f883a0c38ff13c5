"""The chambers' air over a whole run: the baseline drift with and without re-pressurising, and what it does to the accuracy.

Run:  python tests/benchmarks/bench_air.py [--seeds 11,12,13] [--realism kind] [--leak 1] [--figures FILE]

For each held-out seed, the paper's 108-trial plan is acquired unattended on the simulated rig
(``sim://?seed=N&clock=virtual&leak=X&realism=R``, its 1.1 board driving the valves; ``--realism``
kind by default, the rig docs/air.md's figures were measured on) twice, through the real serial
code path:

* **with** re-pressurising: the shipped protocol, whose chambers are supplied and held again
  whenever a trial's baseline has drifted past ``acquisition.repressurise_kPa`` (its default,
  ten pressure floors: 3.1 kPa) since the last supply;
* **without** (the baseline of the comparison): the same protocol with ``valves = "hand"``, the
  chambers supplied once and held for the whole run, as the prompts of a 1.0 board have it;
* **with friction relief**: re-pressurising, and a supply pulse of ``--relief`` s before every
  baseline (``acquisition.friction_relief_s``).

Figures: the largest drift of any chamber's stored baseline from the first trial's (kPa) in each
run, the re-pressurisations made, and the posture form's RMSE on the 18 validation trials in each
(fitted on the 90 fit trials), as a ratio without/with.
"""

from __future__ import annotations

import json
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))

from rig_options import add_rig_options, bench_parser, seeds_text  # noqa: E402

from labcli.core.protocol import load_protocol  # noqa: E402
from labcli.papers.takuma2014.records import load_trials  # noqa: E402

QUANTITIES = ("theta1", "theta2", "Fx")


def labcli(*args: str, cwd: Path) -> str:
    proc = subprocess.run([sys.executable, "-m", "labcli", *args], cwd=cwd, capture_output=True, text=True)
    if proc.returncode != 0:
        raise SystemExit(f"labcli {' '.join(args)} failed:\n{proc.stdout}{proc.stderr}")
    return proc.stdout


def one_run(work: Path, name: str, protocol: Path, url: str) -> dict:
    run = work / f"{name}.h5"
    out = labcli("acquire", str(run), "--protocol", str(protocol), "--port", url, "--unattended", cwd=work)
    P0 = load_trials(run)[["P_L10", "P_R10", "P_L20", "P_R20"]].to_numpy()
    labcli("fit", str(run), "-o", str(work / f"{name}.json"), cwd=work)
    report = json.loads(labcli("validate", str(run), "--model", str(work / f"{name}.json"), "--json", cwd=work))
    rmse = {q: report["metrics"][q]["rmse"] for q in QUANTITIES}
    return {
        "drift kPa": float(np.abs(P0 - P0[0]).max() * 1e3),
        "supplies": out.count("supplying and holding again"),
        **{f"{q} rmse": float(v) for q, v in rmse.items()},
    }


def main() -> None:
    ap = bench_parser(__doc__)
    add_rig_options(ap, realism="kind", seeds="11,12,13")  # held-out seeds
    ap.add_argument("--leak", default="1", help="the rig's leak scale (1: about 1 kPa/min)")
    ap.add_argument(
        "--relief",
        default="0.5",
        help="the friction relief's supply pulse, s (a run per value and seed; comma-separated)",
    )
    ap.add_argument("--no-hand", action="store_true", help="leave out the runs without re-pressurising")
    ap.add_argument(
        "--rig",
        default="",
        help="more sim:// options of the rig, e.g. friction=0 (default: none; its realism is --realism's)",
    )
    ap.add_argument("--figures", help="also write the figures to this JSON file ({name: value})")
    args = ap.parse_args()
    if "realism=" in args.rig:
        ap.error("--rig takes the rig's other options; give its realism as --realism")
    seeds = args.seeds
    shipped = load_protocol("takuma2014")
    figures: dict = {
        "seeds": seeds_text(seeds),
        "realism": args.realism,
        "leak": float(args.leak),
        "limit kPa": shipped.air.repressurise_kPa,
    }
    if args.rig:
        figures["rig"] = args.rig
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        plan = ROOT / "protocols" / "takuma2014-plan.csv"
        (work / "takuma2014-plan.csv").write_bytes(plan.read_bytes())
        auto, hand = work / "auto.toml", work / "hand.toml"
        auto.write_text(shipped.text)
        hand.write_text(shipped.text.replace("rate_hz = 200.0\n", 'rate_hz = 200.0\nvalves = "hand"\n'))
        pulses = [float(x) for x in args.relief.split(",")] if args.relief not in ("", "none") else []
        reliefs = []
        for x in pulses:
            reliefs.append(work / f"relief{x:g}.toml")
            reliefs[-1].write_text(
                shipped.text.replace("rate_hz = 200.0\n", f"rate_hz = 200.0\nfriction_relief_s = {x}\n")
            )
        for seed in seeds:
            url = f"sim://?seed={seed}&clock=virtual&leak={args.leak}&realism={args.realism}"
            url += f"&{args.rig}" if args.rig else ""
            with_ = one_run(work, f"auto{seed}", auto, url)
            without = None if args.no_hand else one_run(work, f"hand{seed}", hand, url)
            relieved = [one_run(work, f"{r.stem}-{seed}", r, url) for r in reliefs]
            rows.append((seed, with_, without, relieved))
            print(
                f"seed {seed}: baseline drift {with_['drift kPa']:.2f} kPa with re-pressurising "
                f"({with_['supplies']} supplies)"
                + ("" if without is None else f", {without['drift kPa']:.2f} kPa without")
                + "; RMSE with "
                + ", ".join(f"{q} {with_[q + ' rmse']:.4g}" for q in QUANTITIES)
                + (
                    ""
                    if without is None
                    else "; without " + ", ".join(f"{q} {without[q + ' rmse']:.4g}" for q in QUANTITIES)
                )
                + "".join(
                    f"; relief {x:g} s " + ", ".join(f"{q} {r[q + ' rmse']:.4g}" for q in QUANTITIES)
                    for x, r in zip(pulses, relieved, strict=True)
                ),
                flush=True,
            )
    for key in ("drift kPa", "supplies", *(f"{q} rmse" for q in QUANTITIES)):
        a = [r[1][key] for r in rows]
        figures[f"with {key} max"] = float(max(a))
        figures[f"with {key} mean"] = float(np.mean(a))
        if not args.no_hand:
            b = [r[2][key] for r in rows]
            figures[f"without {key} min"] = float(min(b))
            figures[f"without {key} mean"] = float(np.mean(b))
        for i, x in enumerate(pulses):
            name = "relief" if i == 0 else f"relief {x:g} s"
            figures[f"{name} {key} mean"] = float(np.mean([r[3][i][key] for r in rows]))
    for q in QUANTITIES:
        if not args.no_hand:
            figures[f"{q} rmse ratio without/with"] = figures[f"without {q} rmse mean"] / figures[f"with {q} rmse mean"]
        for i, x in enumerate(pulses):
            name = "relief" if i == 0 else f"relief {x:g} s"
            figures[f"{q} rmse ratio {name}/with"] = figures[f"{name} {q} rmse mean"] / figures[f"with {q} rmse mean"]
    print(json.dumps(figures, indent=1))
    if args.figures:
        Path(args.figures).write_text(json.dumps(figures, indent=1) + "\n", encoding="utf-8")


if __name__ == "__main__":
    main()
