"""Write the trial plan of takuma2014-bent.toml: 90 fit trials, then 18 validation trials.

    python protocols/make_bent_plan.py                # rewrites protocols/takuma2014-bent-plan.csv

The arm rests bent (theta2 about 18 deg; the inside pair supplied unequally, see the protocol),
so a force along the arm makes a torque and every direction can be sensed.  The pulley pulls
all the way round, along the arm (+-90 deg) included:

* Fit (90): 9 masses x 10 directions 36 deg apart starting straight down (-90, -54, ..., 126,
  162, -162, -126), every pair once.
* Validation (18): one direction every 20 deg (-170 .. 170, so +-90 and +-10 are among them),
  off the fit grid, with the 9 validation masses twice, assigned at random.
* Order: grouped by pulley position, positions and masses shuffled (seeded) as in make_plan.py.

The output is deterministic for a given --seed; a test regenerates it and compares bytes.
"""

from __future__ import annotations

import argparse
import random
from pathlib import Path

from make_plan import FIT_MASSES_G, VALIDATION_MASSES_G, write_rows  # type: ignore[import-not-found]

SEED = 2014
FIT_DIRECTIONS_DEG = tuple(((-90 + 36 * k + 180) % 360) - 180 for k in range(10))
VALIDATION_DIRECTIONS_DEG = tuple(range(-170, 171, 20))


def plan_rows(seed: int = SEED) -> list[tuple[int, str, int, int]]:
    """(trial, set, mass_g, direction_deg) for the whole bent-arm plan, trial ids from 1."""
    rng = random.Random(seed)
    rows: list[tuple[str, int, int]] = []
    positions = list(FIT_DIRECTIONS_DEG)
    rng.shuffle(positions)
    for direction in positions:
        masses = list(FIT_MASSES_G)
        rng.shuffle(masses)
        rows += [("fit", m, direction) for m in masses]
    masses = list(VALIDATION_MASSES_G) * 2
    rng.shuffle(masses)
    vpositions = list(zip(VALIDATION_DIRECTIONS_DEG, masses, strict=False))
    rng.shuffle(vpositions)
    rows += [("validation", m, d) for d, m in vpositions]
    return [(i, s, m, d) for i, (s, m, d) in enumerate(rows, start=1)]


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=Path(__file__).with_name("takuma2014-bent-plan.csv"))
    ap.add_argument("--seed", type=int, default=SEED)
    args = ap.parse_args(argv)
    write_rows(args.out, plan_rows(args.seed))
    print(f"wrote {args.out} ({len(plan_rows(args.seed))} trials)")


if __name__ == "__main__":
    main()
