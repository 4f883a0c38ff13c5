"""The play's states on relieved runs read against the rig's own shafts: with the side vented, and without.

Each run is the shipped plan taken as ``labcli acquire --captures 3`` takes it (captures_acquired.py's
``relief3``: the relief, a 3 s supply pulse after a 2 s vent of the side each load pulls, before every
capture), the simulated rig's joints and potentiometer shafts read as each weight is hung and taken
off.  A capture's true state ``c`` (labels.play_states: the reading is ``d - b c``) is the shaft's
offset from its joint, in plays, before the load less the one under it.  The labels' rule is run on
the stored records (every capture, in trial order) with the rig's own play width and true deflections,
so that only the states are judged: the shafts' returns (labels.shaft_returns) with the side each
capture was relieved from (``relief_vent``), and without it (the returns alone, the rule before).  A
state is read wrong where the rule's ``c`` is more than half the play off the true one.

    nice python tests/benchmarks/relief_states.py --seeds 1-10 [--arms straight,bent]
"""

from __future__ import annotations

import sys
import tempfile
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

WRONG = 0.5  # plays: a state read more than half the play off


def _watched(folder: Path, arm: str, seed: int, realism: str) -> tuple[Any, list[tuple[np.ndarray, ...]], float]:
    """The run's records table and, per record, the rig's (joints, shafts) at its load and unload; the play (rad)."""
    from captures_acquired import acquired

    from labcli.core.store import RunFile
    from labcli.core.store.records import Records
    from labcli.papers.takuma2014.sim.rig import SimRig

    events: list[tuple[str, np.ndarray, np.ndarray]] = []
    widths: list[float] = []
    at_commit: list[int] = []
    real = {"hang": SimRig.hang_weight, "remove": SimRig.remove_weight, "write": Records.write}

    def seen(rig: Any, kind: str) -> None:
        st = rig.true_state()
        events.append((kind, np.asarray(st["theta_rad"], float), np.asarray(st["pot_shaft_rad"], float)))
        widths.append(float(rig._backlash))

    def hang(self: Any, *a: Any) -> None:
        seen(self, "hang")
        real["hang"](self, *a)

    def remove(self: Any) -> None:
        seen(self, "remove")
        real["remove"](self)

    def write(self: Any, record: Any) -> Any:
        at_commit.append(len(events))
        return real["write"](self, record)

    SimRig.hang_weight, SimRig.remove_weight, Records.write = hang, remove, write  # type: ignore[method-assign]
    try:
        path = acquired(arm, seed, "relief3", folder, realism)
    finally:
        SimRig.hang_weight, SimRig.remove_weight, Records.write = real["hang"], real["remove"], real["write"]  # type: ignore[method-assign]
    with RunFile.open(path) as run:
        table = run.records.table()
    states = []
    for n in at_commit:  # the last load and unload before each commit are the stored capture's
        hung = next(e for e in reversed(events[:n]) if e[0] == "hang")
        off = next(e for e in reversed(events[:n]) if e[0] == "remove")
        states.append((hung[1], hung[2], off[1], off[2]))
    return table, states, max(widths)


def wrong_states(table: Any, states: list[tuple[np.ndarray, ...]], play: float) -> dict[str, int]:
    """Per joint: the captures whose state the rule reads wrong, with the vented side and without it."""
    from labcli.papers.takuma2014.models.labels import play_states, shaft_returns

    order = np.argsort(np.asarray(table["trial"], dtype=int), kind="stable")
    th0, sh0, th1, sh1 = (np.array([s[i] for s in states]) for i in range(4))
    d_true = (th1 - th0)[order]
    c_true = (((sh0 - th0) - (sh1 - th1)) / play)[order]
    out: dict[str, int] = {"captures": len(table)}
    for rule, rows in (("with side", table), ("without", table.drop(columns=["relief_vent"]))):
        back = shaft_returns(rows, order)[order]
        for k, joint in enumerate(("theta1", "theta2")):
            c, _ = play_states(d_true[:, k], play, back[:, k])
            out[f"{joint} {rule}"] = int(np.sum(np.abs(c - c_true[:, k]) > WRONG))
    return out


def main(argv: list[str] | None = None) -> None:
    from rig_options import add_rig_options, bench_parser, seeds_text

    ap = bench_parser(__doc__)
    add_rig_options(ap, realism="literature", seeds="1-10")
    ap.add_argument("--arms", default="straight,bent", help="straight, bent or both (comma-separated)")
    args = ap.parse_args(argv)
    totals: dict[str, dict[str, int]] = {}
    for arm in args.arms.split(","):
        for seed in args.seeds:
            with tempfile.TemporaryDirectory() as tmp:
                table, states, play = _watched(Path(tmp), arm, seed, args.realism)
            got = wrong_states(table, states, play)
            total = totals.setdefault(arm, dict.fromkeys(got, 0))
            for k, v in got.items():
                total[k] += v
            print(f"{arm} seed {seed}: " + ", ".join(f"{k} {v}" for k, v in got.items()), flush=True)
    print(f"seeds {seeds_text(args.seeds)}, {args.realism} rig: states read wrong (more than half the play off)")
    for arm, t in totals.items():
        n = t["captures"]
        cells = [f"{j}: {t[f'{j} without']} -> {t[f'{j} with side']} of {n}" for j in ("theta1", "theta2")]
        print(f"{arm:8s} without the side -> with it: " + "; ".join(cells))


if __name__ == "__main__":
    main()
