"""N relieved captures of each load through ``labcli acquire --captures N`` and ``labcli fit``: accuracy and time.

tests/benchmarks/multi_capture.py measures the protocol on drive.py's trials; this one takes every run
as ``labcli acquire`` takes it (:func:`labcli.core.acquisition.acquire`: the session's steps on the
engine, the ``sim://`` rig in virtual time, every capture committed to a run file) and reads it as
``labcli fit`` and ``validate`` do (:func:`load_trial_source`, which averages a load's captures into
one row; ``labcli fit``'s posture form).  For each held-out rig seed (literature's rig) and arm
(straight: takuma2014; bent: takuma2014-bent with the bent arm's supply), three runs of the plan:

* ``ref``: one capture a load, no relief; the issue's estimator (the posture form without friction terms);
* ``relief3``: ``--captures 3`` (the relief before each capture: a 3 s supply pulse after a 2 s vent);
  ``labcli fit``'s form on the averaged rows (each row's P0 its own, the mean of its captures');
  ``relief3b5`` the same with each row's P0 the mean of five rows' (``RELIEVED_BASELINES``, the single
  relieved capture's choice), for comparison.

One relieved capture a load through the same path is multi_capture.py's ``relief1`` on drive.py's trials.

Reported: RMSE over every validation trial (a load's averaged row for ``relief3``), its ratio to ``ref``'s
with a 95 % paired bootstrap interval over seeds, Fy reported, the 95 % intervals' coverage, and
the rig's clock per plan load (the median gap between consecutive captures' baselines times the
captures a load, since a long run's stored device times restart part-way) with its ratio.

``--diagnose`` adds, per arm, where the ``relief3`` intervals' width comes from and where the fit
trials err (interval_parts.py: each share of the variance against the errors it stands for, and the
fit trials' Fx error per load direction); it reads what each seed's record keeps, measured with it.

    nice python tests/benchmarks/captures_acquired.py [--seeds 11-30] [--cache FILE] [--figures OUT] [--diagnose]
"""

from __future__ import annotations

import io
import sys
import tempfile
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

import interval_parts  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
ARMS = {"straight": "takuma2014", "bent": "takuma2014-bent"}
FORMS = {"relief3": 3}  # captures a load, each after the relief
RELIEF = "friction_relief_s = 3.0\nfriction_relief_vent_s = 2.0\n"


def _protocol(arm: str, relief: bool, folder: Path) -> str:
    """The arm's shipped protocol, or a copy of it with the relief before each capture."""
    from labcli.core.protocol import load_protocol

    if not relief:
        return ARMS[arm]
    text = load_protocol(ARMS[arm]).text
    path = folder / f"{arm}-relief.toml"
    path.write_text(text.replace("[acquisition]\n", "[acquisition]\n" + RELIEF, 1))
    return str(path)


def acquired(arm: str, seed: int, form: str, folder: Path, realism: str) -> Path:
    """A run of the arm's plan taken as ``labcli acquire`` takes it (its path)."""
    from rich.console import Console
    from sensing_accuracy import BENT_SUPPLY_MPA

    from labcli.core.acquisition import acquire
    from labcli.core.ui import UnattendedUI

    url = f"sim://?seed={seed}&clock=virtual&realism={realism}"
    if arm == "bent":
        url += "&supply=" + ",".join(f"{p:g}" for p in BENT_SUPPLY_MPA)
    path = folder / f"{arm}-{form}.h5"
    out = acquire(
        path,
        url,
        protocol=_protocol(arm, form != "ref", folder),
        plan=ROOT / "protocols" / f"{ARMS[arm]}-plan.csv",  # the shipped plan, beside the shipped protocol
        unattended=True,
        ui=UnattendedUI(console=Console(file=io.StringIO())),
        captures=FORMS.get(form),
    )
    if out.exit_code:
        raise RuntimeError(f"{arm} {form} seed {seed}: {out.message}")
    return path


def errors(path: Path, form: str, baseline_mean: int | None = None) -> dict[str, Any]:
    """Validation errors (deg, N), which are reported and whether the 95 % interval covers; the rig's
    seconds per plan load.  ``baseline_mean``: P0 the mean of that many baselines instead of ``labcli
    fit``'s choice."""
    from multi_capture import error_records

    from labcli.papers.takuma2014.analyses import _fit_form
    from labcli.papers.takuma2014.models.inputs import load_trial_source
    from labcli.papers.takuma2014.models.leak import window_times
    from labcli.papers.takuma2014.models.metrics import evaluate
    from labcli.papers.takuma2014.models.posture import PostureModel, limits_from_protocol

    src = load_trial_source(path)  # one row per load: its captures averaged
    proto = src.protocol
    with np.errstate(all="ignore"):
        if form == "ref":  # the estimator
            model = PostureModel(geometry=proto.settings.rig, limits=limits_from_protocol(proto), friction=False)
            model = model.fit(src.table)
        else:
            model = _fit_form("posture", src, str(path))
            if baseline_mean is not None:
                kw = {"geometry": proto.settings.rig, "limits": limits_from_protocol(proto), "friction": model.friction}
                model = PostureModel(**kw, baseline_mean=baseline_mean).fit(src.table)
        ev = evaluate(model, src.table)
    out = error_records(ev)
    if form != "ref" and baseline_mean is None:  # labcli fit's own: where its intervals' width comes from
        out.update(interval_parts.records(model, src.table))
    # The rig's clock from one capture's baseline to the next's (the median: the stored device times
    # start again part-way through a long run), times the captures of a load.
    starts = np.array([tb for tb, _ in window_times(path).values()])
    out["seconds"] = float(np.median(np.diff(starts)[np.diff(starts) > 0])) * src.captures
    return out


def measure(seed: int, realism: str = "literature") -> dict[str, Any]:
    """Per arm and form: the validation errors and the rig's seconds per plan load."""
    from labcli.papers.takuma2014.models.posture import RELIEVED_BASELINES

    out: dict[str, Any] = {}
    for arm in ARMS:
        for form in ("ref", *FORMS):
            with tempfile.TemporaryDirectory() as tmp:
                path = acquired(arm, seed, form, Path(tmp), realism)
                out.update({f"{arm}/{form}/{k}": v for k, v in errors(path, form).items()})
                if form == "relief3":  # P0 the mean of five rows' baselines, as one relieved capture a load has it
                    out.update({f"{arm}/relief3b5/{k}": v for k, v in errors(path, form, RELIEVED_BASELINES).items()})
    return out


def main(argv: list[str] | None = None) -> None:
    from figures_file import cached, git_head, write_figures
    from multi_capture import QUANTITIES, figures
    from rig_options import add_rig_options, bench_parser, seeds_text

    ap = bench_parser(__doc__)
    add_rig_options(ap, realism="literature", seeds="11-30")
    ap.add_argument("--cache", type=Path, default=None, help="JSON-lines file of measured seeds (resumable)")
    ap.add_argument(
        "--figures", "--json", dest="json", type=Path, default=ROOT / "docs" / "figures" / "captures-acquired.json"
    )
    ap.add_argument(
        "--diagnose", action="store_true", help="also where the intervals' width comes from (interval_parts.py)"
    )
    args = ap.parse_args(argv)
    commit = git_head()  # the code measured: the checkout's at the run's start
    raw = cached(args.cache, f"acquired {args.realism}", args.seeds, lambda s: measure(s, args.realism))
    forms = [*FORMS, "relief3b5"]
    figs = figures(raw, forms)
    print(f"seeds {seeds_text(args.seeds)}, {args.realism} rig: RMSE (deg, N), ratio to the issue's estimator [95 %]")
    for arm in ARMS:
        for form in ("ref", *forms):
            cells = []
            for q in QUANTITIES:
                k = f"{arm}/{form}/{q}"
                lo, hi = figs[f"{k}/ratio_ci95"]
                cov = figs[f"{k}/coverage"]
                cells.append(f"{q} {figs[f'{k}/rmse']:.3f} x{figs[f'{k}/ratio']:.2f} [{lo:.2f},{hi:.2f}] cov {cov:.3f}")
            cells.append(f"Fy reported {figs[f'{arm}/{form}/Fy/reported']}")
            t = figs[f"{arm}/{form}/seconds_per_trial"]
            cells.append(f"{t:.0f} s/load (x{figs[f'{arm}/{form}/time_ratio']:.2f})")
            print(f"{arm:8s} {form:8s} " + "; ".join(cells))
        if args.diagnose:
            for form in FORMS:
                interval_parts.show(raw, f"{arm}/{form}/")
    meta = {"meta/seeds": seeds_text(args.seeds), "meta/realism": args.realism}
    write_figures(args.json, meta, figs, commit=commit)


if __name__ == "__main__":
    main()
