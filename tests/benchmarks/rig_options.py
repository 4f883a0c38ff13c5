"""The benchmarks' shared options: ``--realism`` (the simulated rig's levels) and ``--seeds``.

Every benchmark that runs the simulated McKibben rig takes them one way::

    ap = bench_parser(__doc__)
    add_rig_options(ap, realism="kind", seeds="1-10")
    args = ap.parse_args()  # args.realism == "kind", args.seeds == [1, 2, ..., 10]

* ``--realism``: ``kind`` or ``literature`` (labcli.papers.takuma2014.sim.nonideal.REALISMS); a
  benchmark that runs several takes a comma list (``several=True``: a list of names).  Each
  benchmark's default is the rig its docs figures were measured on, whatever the simulator's own
  default (``REALISM_DEFAULT``) is now, so that rerunning it without options remakes them.
* ``--seeds``: ``11-30``, ``1,4,7`` or ``1-3,7`` (whole numbers from 1, each once); a benchmark
  that runs one rig takes one (``one=True``).

A bad value is refused in one sentence on stderr (exit status 2), never a usage dump or a traceback.
The benchmarks of the rPAM joint run no McKibben rig and take ``--seeds`` alone (``add_seeds_option``).
The load check's benchmarks also take ``--relief`` (``add_relief_option``): the shipped protocol with the
friction relief before every trial, venting the side each load pulls the arm towards (load, the default)
or the side it names (L or R).
"""

from __future__ import annotations

import argparse
import re
from collections.abc import Sequence
from typing import NoReturn

from labcli.core.air import CAPTURE_RELIEF, RELIEF_VENTS
from labcli.papers.takuma2014.sim.nonideal import REALISMS

SEEDS_FORM = "a range such as 11-30, a list such as 1,4,7, or both (1-3,7)"


class BenchParser(argparse.ArgumentParser):
    """An ArgumentParser whose bad input is one sentence: ``prog: what was wrong.``"""

    def error(self, message: str) -> NoReturn:
        self.exit(2, f"{self.prog}: {message.rstrip('.')}.\n")


def bench_parser(doc: str | None, **kw: object) -> BenchParser:
    """The parser of a benchmark, its description the first line of its docstring."""
    return BenchParser(description=(doc or "").strip().split("\n")[0], **kw)  # type: ignore[arg-type]


def seeds_of(text: str) -> list[int]:
    """``"11-30"`` -> [11, ..., 30]; ``"1,4,7"``; ``"1-3,7"``.  ValueError (one sentence) otherwise."""
    out: list[int] = []
    for part in str(text).split(","):
        m = re.fullmatch(r"\s*(\d+)\s*(?:-\s*(\d+)\s*)?", part)
        lo, hi = (int(m.group(1)), int(m.group(2) or m.group(1))) if m else (0, -1)
        if not m or lo < 1 or hi < lo:
            raise ValueError(f"--seeds takes {SEEDS_FORM}, not {text!r}")
        out += range(lo, hi + 1)
    if len(set(out)) != len(out):
        raise ValueError(f"--seeds names a seed twice in {text!r}")
    return out


def seeds_text(seeds: Sequence[int]) -> str:
    """The seeds as ``seeds_of`` reads them, runs written as ranges: [11, ..., 30] -> ``"11-30"``."""
    parts: list[str] = []
    i = 0
    while i < len(seeds):
        j = i
        while j + 1 < len(seeds) and seeds[j + 1] == seeds[j] + 1:
            j += 1
        parts.append(str(seeds[i]) if j == i else f"{seeds[i]}-{seeds[j]}")
        i = j + 1
    return ",".join(parts)


def realisms_of(text: str) -> list[str]:
    """``"kind,literature"`` -> ["kind", "literature"]; ValueError (one sentence) on a name not in REALISMS."""
    names = [s.strip() for s in str(text).split(",")]
    if any(n not in REALISMS for n in names) or len(set(names)) != len(names):
        raise ValueError(f"--realism takes {', '.join(REALISMS)} or both, comma-separated, not {text!r}")
    return names


def realism_of(text: str) -> str:
    """``"kind"`` -> "kind"; ValueError (one sentence) unless it is one name of REALISMS."""
    if str(text).strip() not in REALISMS:
        raise ValueError(f"--realism takes {' or '.join(REALISMS)}, not {text!r}")
    return str(text).strip()


def _typed(read, what: str):  # type: ignore[no-untyped-def]
    def parse(text: str):  # type: ignore[no-untyped-def]
        try:
            return read(text)
        except ValueError as e:  # argparse names the option itself: "argument --seeds: takes ..."
            raise argparse.ArgumentTypeError(str(e).split(" ", 1)[1]) from None

    parse.__name__ = what
    return parse


def _one_seed(text: str) -> list[int]:
    seeds = seeds_of(text)
    if len(seeds) != 1:
        raise ValueError(f"--seeds takes one seed here (it runs one rig), not {text!r}")
    return seeds


def add_seeds_option(ap: argparse.ArgumentParser, seeds: str, *, one: bool = False, what: str = "rig seeds") -> None:
    """``--seeds`` (default ``seeds``), read into a list of ints; ``one``: exactly one seed."""
    ap.add_argument(
        "--seeds",
        type=_typed(_one_seed if one else seeds_of, "seeds"),
        default=seeds,
        help=f"{what}: {'one seed' if one else SEEDS_FORM} (default {seeds})",
    )


def add_rig_options(
    ap: argparse.ArgumentParser, *, realism: str, seeds: str, several: bool = False, one: bool = False
) -> None:
    """``--realism`` (default ``realism``: the rig of the benchmark's docs figures) and ``--seeds``."""
    read = realisms_of if several else realism_of
    read(realism)  # a default the benchmark itself got wrong fails here, not in a run
    ap.add_argument(
        "--realism",
        type=_typed(read, "realism"),
        default=realism,
        help=f"the simulated rig's levels, {' or '.join(REALISMS)}{' (comma-separated)' if several else ''} "
        f"(default {realism}: the rig its docs figures were measured on)",
    )
    add_seeds_option(ap, seeds, one=one)


def relieved(text: str, vent: str) -> str:
    """A protocol's text with the friction relief before every trial: the pulse and vent of a run of
    several captures a load (``labcli.core.air.CAPTURE_RELIEF``, what ``labcli acquire --captures 3``
    gives), here asked for explicitly so that one capture a load has it, venting the ``vent`` side."""
    if text.count("[acquisition]\n") != 1:
        raise ValueError("--relief needs a protocol with one [acquisition] table")
    pulse, vent_s = CAPTURE_RELIEF
    lines = f"friction_relief_s = {pulse}\nfriction_relief_vent_s = {vent_s}\nfriction_relief_vent = {vent!r}\n"
    return text.replace("[acquisition]\n", "[acquisition]\n" + lines.replace("'", '"'))


def add_relief_option(ap: argparse.ArgumentParser) -> None:
    """``--relief [load|L|R]``: the friction relief before every trial, venting the side each load
    pulls the arm towards (load, without a side) or that side; None without the option."""
    ap.add_argument(
        "--relief",
        nargs="?",
        const="load",
        choices=RELIEF_VENTS,
        help="the friction relief before every trial (a %g s pulse after a %g s vent), venting this side "
        "(default load: the side each load pulls the arm towards, as --captures gives it)" % CAPTURE_RELIEF,
    )
