"""Write the trial plan of takuma2014.toml: 90 fit trials, then 18 validation trials.

    python protocols/make_plan.py                # rewrites protocols/takuma2014-plan.csv
    python protocols/make_plan.py --out plan.csv # somewhere else

The plan is the schedule the operator follows at the rig: which weight to hang
from the pulley and where the pulley pulls (direction counter-clockwise from +x
in the joint plane, degrees).  The design:

* Directions.  The arm stands upright, so a force along it (straight up or
  down) makes almost no torque and is barely observable from the pressures
  (det J = h2 h3 sin(theta2) -> 0).  The pulley therefore pulls on either side,
  from 60 deg below to 60 deg above the horizontal: right -60..60 deg, left
  120..240 deg (written -180..180, so 210 is -150).
* Fit (Section 3.2: 90 trials).  The full grid of 9 masses x 10 directions
  (5 per side, 30 deg apart), every pair once, so each mass meets each
  direction and the least squares sees the whole range evenly.
* Validation (18 trials).  Interleaved in the same ranges, never on the fit
  grid: masses between the fit masses, directions halfway between the fit
  directions (15 deg off the grid), each validation mass once per side.
* Order.  Moving the pulley is the slow step, so trials are grouped by pulley
  position; the order of positions and of masses within a position is
  shuffled (seeded) so slow drift of the rig (sleeve creep, temperature)
  does not line up with load size or direction.  Fit trials come first, then
  validation: the paper's sequential split.

The output is deterministic for a given --seed; a test regenerates it and
compares bytes with the shipped file.
"""

from __future__ import annotations

import argparse
import csv
import io
import random
from pathlib import Path

SEED = 2014
FIT_MASSES_G = (50, 100, 200, 300, 400, 500, 600, 800, 1000)
FIT_DIRECTIONS_DEG = {
    "right": (-60, -30, 0, 30, 60),
    "left": (120, 150, 180, -150, -120),
}
VALIDATION_MASSES_G = (75, 150, 250, 350, 450, 550, 700, 900, 950)
VALIDATION_DIRECTIONS_DEG = {
    "right": (-45, -15, 15, 45),
    "left": (135, 165, -165, -135),
}


def plan_rows(seed: int = SEED) -> list[tuple[int, str, int, int]]:
    """(trial, set, mass_g, direction_deg) for the whole plan, trial ids from 1."""
    rng = random.Random(seed)
    rows: list[tuple[str, int, int]] = []

    positions = [d for side in FIT_DIRECTIONS_DEG.values() for d in side]
    rng.shuffle(positions)
    for direction in positions:
        masses = list(FIT_MASSES_G)
        rng.shuffle(masses)
        rows += [("fit", m, direction) for m in masses]

    # Each validation mass once per side, spread over that side's directions
    # (3, 2, 2, 2 masses per direction), masses assigned at random.
    validation: dict[int, list[int]] = {}
    for directions in VALIDATION_DIRECTIONS_DEG.values():
        masses = list(VALIDATION_MASSES_G)
        rng.shuffle(masses)
        for i, m in enumerate(masses):
            validation.setdefault(directions[i % len(directions)], []).append(m)
    vpositions = list(validation)
    rng.shuffle(vpositions)
    for direction in vpositions:
        rows += [("validation", m, direction) for m in validation[direction]]

    return [(i, s, m, d) for i, (s, m, d) in enumerate(rows, start=1)]


def rows_csv(rows: list[tuple[int, str, int, int]]) -> str:
    """A plan's rows as the plan CSV's text."""
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(["trial", "set", "mass_g", "direction_deg"])
    w.writerows(rows)
    return buf.getvalue()


def write_rows(path: Path, rows: list[tuple[int, str, int, int]]) -> None:
    path.write_text(rows_csv(rows), encoding="utf-8")


def plan_csv(seed: int = SEED) -> str:
    return rows_csv(plan_rows(seed))


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=Path(__file__).with_name("takuma2014-plan.csv"))
    ap.add_argument("--seed", type=int, default=SEED)
    args = ap.parse_args(argv)
    args.out.write_text(plan_csv(args.seed), encoding="utf-8")
    print(f"wrote {args.out} ({len(plan_rows(args.seed))} trials)")


if __name__ == "__main__":
    main()
