"""The load check's catches: the shipped plan's trial 1 (800 g) and trial 4 (300 g) done wrong
once, through the real serial code path, seed by seed on a rig.

Each mistake is made once by the scripted experimenter of
``tests/papers/takuma2014/test_guard_first_trial.py`` under the shipped 15 s settle: no weight hung
(trial 1), the weight taken off half a second into the settle, an Enter out of step (the weight
goes on at the next prompt).  A mistake is caught when any trial of the run is warned.  Tune on
seeds 1-10; report on held-out seeds (11-30)::

    python tests/benchmarks/guard_mistakes.py --seeds 11-20 --realism literature

``--realism`` and ``--seeds`` as every benchmark takes them (rig_options.py); the default rig is the
literature's, docs/load-check.md's first row (its kind row: ``--realism kind``).  ``--relief``
(``load``, the default side, or L or R): the shipped protocol with the friction relief before every
trial, venting the side each load pulls the arm towards or the side named (the relieved tables);
``--figures FILE`` also writes the counts as JSON::

    python tests/benchmarks/guard_mistakes.py --seeds 11-30 --relief --figures out.json
"""

from __future__ import annotations

import json
import sys
import tempfile
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent / "papers" / "takuma2014"))

import test_guard_first_trial as scripted  # noqa: E402
from rig_options import add_relief_option, add_rig_options, bench_parser, relieved, seeds_text  # noqa: E402
from test_valves_session import Person  # noqa: E402

from labcli.core.protocol import loads_protocol  # noqa: E402
from labcli.papers.takuma2014.session import HangWeight  # noqa: E402


def forget(action, slip) -> bool:
    """Enter at "hang" with no weight hung."""
    if isinstance(action, HangWeight):
        slip.done = True
        return True
    return False


# (name, trial, trials run, how): the trials run reach one past the slip, where an Enter out of
# step has the weight it left on met.
MISTAKES = (
    ("trial 1 no weight hung", 1, 2, forget),
    ("trial 1 taken off", 1, 2, scripted.lift),
    ("trial 1 out of step", 1, 2, scripted.late),
    ("trial 4 taken off", 4, 5, scripted.lift),
    ("trial 4 out of step", 4, 5, scripted.late),
)


def caught(url: str, trial: int, n: int, how, protocol=scripted.PROTOCOL) -> bool:
    """Whether the run of the shipped plan's first ``n`` trials warned of the slip at ``trial``."""
    with tempfile.TemporaryDirectory() as tmp:
        ui = scripted.Attended() if how is scripted.late else Person()
        ui, _, _ = scripted.session_with(Path(tmp), n, trial, how, ui=ui, url=url, protocol=protocol)
    return bool(scripted.warned(ui))


def main() -> None:
    ap = bench_parser(__doc__)
    add_rig_options(ap, realism="literature", seeds="1-10")  # 1-10: the tuning seeds
    add_relief_option(ap)
    ap.add_argument("--figures", help="also write the figures to this JSON file ({name: value})")
    args = ap.parse_args()
    seeds, protocol = args.seeds, scripted.PROTOCOL
    if args.relief:
        protocol = loads_protocol(
            relieved(protocol.text, args.relief), source=f"takuma2014, relief venting {args.relief}"
        )
    out: dict[str, list[int]] = {}
    for name, trial, n, how in MISTAKES:
        url = "sim://?seed={}&clock=virtual&realism=" + args.realism
        out[name] = [s for s in seeds if caught(url.format(s), trial, n, how, protocol)]
        print(f"{name}: caught on {len(out[name])}/{len(seeds)} seeds {out[name]}", flush=True)
    print(json.dumps({k: len(v) for k, v in out.items()}))
    if args.figures:
        figures = {"seeds": seeds_text(seeds), "relief": args.relief or "none", "runs": len(seeds)}
        figures.update({f"{k}.caught": len(v) for k, v in out.items()})
        Path(args.figures).write_text(json.dumps(figures, indent=1) + "\n", encoding="utf-8")


if __name__ == "__main__":
    main()
