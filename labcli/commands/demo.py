"""``labcli demo``: the whole paper on the simulated rig, with no hardware and no questions."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import click


def _num(x: Any, spec: str) -> str:
    return "—" if x is None or (isinstance(x, float) and not math.isfinite(x)) else format(x, spec)


def _console() -> Any:
    from rich.console import Console

    con = Console(highlight=False)
    if not con.is_terminal:
        con.width = max(con.width, 100)  # a pipe or a log file: never truncate numbers
    return con


def _print_summary(res: Any) -> None:
    from rich import box
    from rich.table import Table

    con = _console()
    tr = res.trials
    con.print(f"[bold]labcli demo[/bold] on the simulated rig (seed {res.seed}): "
              f"{tr['fit'] + tr['validation']} force trials ({tr['fit']} fit, {tr['validation']} validation), "
              f"{tr['pushes']} pushes, {res.timings_s['total']:.1f} s.", soft_wrap=True)

    coef = Table(title="Eqs. 34-37 fitted vs paper (3.3)",
                 title_justify="left", box=box.SIMPLE_HEAD)
    for col, just in (("coefficient", "left"), ("fitted", "right"), ("std. error", "right"), ("paper", "right")):
        coef.add_column(col, justify=just)
    for c in res.coefficients:
        coef.add_row(c["name"], f"{c['value']:.4g}", f"{c['standard_error']:.2g}", _num(c["paper"], ".4g"))
    con.print(coef)
    con.print("Units: MPa, N, m, rad. " + " ".join(res.notes) + " The simulated rig's actuators "
              "differ from the paper's, so its coefficients differ too; the accuracy is what carries over.",
              soft_wrap=True)

    acc = Table(title="Accuracy on the validation trials, pressure-only (Figure 7)",
                title_justify="left", box=box.SIMPLE_HEAD)
    for col in ("quantity", "n", "RMSE", "max |error|", "R^2", "RMSE / range", "flagged"):
        acc.add_column(col, justify="left" if col == "quantity" else "right")
    for q, m in res.accuracy.items():
        unit = m["unit"]
        acc.add_row(f"{q} ({unit})", str(m["n"]), _num(m["rmse"], ".3g"), _num(m["max_abs"], ".3g"),
                    _num(m["r2"], ".4f"), _num(m["pct_range"], ".2f") + " %", str(m["n_flagged"]))
    con.print(acc)

    obj = Table(title=f"Object stiffness (Section 4, Figure 9); categories by the {res.classify_method} method, "
                      "true values from the simulated objects",
                title_justify="left", box=box.SIMPLE_HEAD)
    for col in ("object", "pushes used", "k mean [N/m]", "k sd [N/m]", "true k [N/m]", "category",
                "confidence", "true category"):
        obj.add_column(col, justify="left" if col in ("object", "category", "true category") else "right",
                       no_wrap=col == "object")
    for o in res.objects:
        obj.add_row(o["object"], f"{o['n_used']}/{o['n']}", _num(o["k_mean_N_per_m"], ".0f"),
                    _num(o["k_sd_N_per_m"], ".0f"), _num(o.get("true_k_N_per_m"), ".0f"), o["category"],
                    _num(o["confidence"], ".2f"), o["category_given"] or "—")
    con.print(obj)
    if res.classify_method == "bands":
        con.print("Stiffness bands come from the push protocol (protocols/takuma2014-stiffness.toml).",
                  soft_wrap=True)
    con.print("Files:", soft_wrap=True)
    for path in res.files.values():
        con.print(f"  {path}", soft_wrap=True, markup=False)


def _print_rpam_summary(res: Any) -> None:
    """The demo's summary as tables (rich), units on every number."""
    from rich import box
    from rich.table import Table

    con = _console()
    s = res.stretch
    con.print(f"[bold]labcli demo --protocol rpam2015[/bold] on the simulated rPAM rig (seed {res.seed}): "
              f"{res.points['stretch']} stretch-test points, {res.points['joint_map']} joint-map points, "
              f"{res.timings_s['total']:.1f} s.", soft_wrap=True)

    coef = Table(title=f"Eq. 7 stretch correction F_stretch(lambda) fitted on {s['n_points']} points "
                       f"(lambda {s['lambda_range'][0]:.2f}-{s['lambda_range'][1]:.2f})",
                 title_justify="left", box=box.SIMPLE_HEAD)
    for col in ("coefficient", "fitted (N)", "std. error (N)", "rig's truth (N)", "fit - truth (s.e.)",
                "protocol default (N)"):
        coef.add_column(col, justify="left" if col == "coefficient" else "right")
    for k in range(4):
        coef.add_row(f"c{k}", f"{s['coefficients_N'][k]:+.3f}", f"{s['std_errors_N'][k]:.3f}",
                     f"{s['true_N'][k]:+.3f}", f"{s['deviation_in_se'][k]:+.2f}",
                     f"{s['protocol_default_N'][k]:+.3g}")
    con.print(coef)
    con.print(f"R^2 {s['r2']:.5f}, RMSE {s['rmse_N']:.3f} N; chi^2 of the truth against the fit's covariance "
              f"{s['chi2_4dof']:.2f} (4 degrees of freedom; 18.5 is the 99.9 % limit).", soft_wrap=True)

    jm = Table(title=f"Joint map against the model (Fig. 8), errors model - measured; toggle angle "
                     f"{res.joint_map['toggle_deg']:.1f} deg",
               title_justify="left", box=box.SIMPLE_HEAD)
    for col in ("F_stretch", "points compared", "toggles", "RMSE (deg)", "max |error| (deg)",
                "RMSE with toggles (deg)"):
        jm.add_column(col, justify="left" if col == "F_stretch" else "right", no_wrap=col == "F_stretch")
    for key, label in (("without", "none"), ("with_default", "protocol's"), ("with_fitted", "fitted")):
        r = res.joint_map[key]
        jm.add_row(label, str(r["n_compared"]), str(r["n_toggle"]), _num(r["rmse_deg"], ".2f"),
                   _num(r["max_abs_error_deg"], ".2f"), _num(r["rmse_all_deg"], ".2f"))
    con.print(jm)
    con.print("Toggles: pressure pairs where the model has no balance below the toggle angle; they stay out "
              "of the RMSE and count at the toggle angle in the last column.", soft_wrap=True)

    o = res.optimum
    con.print(f"Link optimisation (Section IV) at Pa = {o['Pa_kPa']:g} kPa, Pb = {o['Pb_kPa']:g} kPa with the "
              f"fitted F_stretch: alpha = {o['alpha_deg']:.2f} deg at L1 = {o['L1_m']:.4f} m, "
              f"L2 = {o['L2_m']:.4f} m, L3 = {o['L3_m']:.4f} m (toggle {o['toggle_deg']:.2f} deg; "
              f"{'; '.join(o['active_constraints']) or 'no constraint at its bound'}).", soft_wrap=True)
    for note in res.notes:
        con.print(note, soft_wrap=True)
    con.print("Files:", soft_wrap=True)
    for path in res.files.values():
        con.print(f"  {path}", soft_wrap=True, markup=False)


@click.command("demo")
@click.argument("outdir", default="labcli-demo", type=click.Path(file_okay=False, path_type=Path))
@click.option("--seed", type=int, default=1, show_default=True, help="Seed of the simulated rig.")
@click.option("--force", is_flag=True, help="Overwrite earlier demo output in OUTDIR.")
@click.option("--json", "as_json", is_flag=True, help="Print the summary as JSON.")
@click.option("--protocol", type=click.Choice(["takuma2014", "rpam2015"]), default="takuma2014", show_default=True,
              help="Which paper: the McKibben joint (takuma2014) or the rPAM joint (rpam2015).")
def demo(outdir: Path, seed: int, force: bool, as_json: bool, protocol: str) -> None:
    """Run the whole paper on the simulated rig: no hardware, no questions.

    Acquires the 108 force trials of the shipped plan unattended, splits them
    90/18, fits Eqs. 34-37, validates them (Figure 7), pushes six simulated
    objects ten times each, classifies them (Figure 9) and prints one summary.
    Everything lands in OUTDIR (default ./labcli-demo).  With --protocol rpam2015:
    the rPAM paper's stretch test, the fitted stretch correction (Fig. 6), the joint
    map against the model without and with it (Fig. 8) and the link optimisation.

    \b
    Example:
        labcli demo out/
        labcli demo out/ --seed 7 --force --json
        labcli demo out/ --protocol rpam2015
    """
    import json
    import sys

    from ..experiments.takuma2014.demo import STAGES, run_demo
    from ..errors import LabcliError

    run, summarise = run_demo, _print_summary
    if protocol == "rpam2015":
        from ..experiments.rpam2015.demo import STAGES, run_rpam_demo  # noqa: F811

        run, summarise = run_rpam_demo, _print_rpam_summary

    show = sys.stderr.isatty() and not as_json

    def progress(stage: str, done: int, total: int) -> None:
        if not show:
            return
        n = STAGES.index(stage) + 1
        count = f" {done}/{total}" if total else ""
        click.echo(f"\r[{n}/{len(STAGES)}] {stage}{count}".ljust(60), nl=False, err=True)

    try:
        result = run(outdir, seed=seed, force=force, progress=progress)
    except LabcliError as e:
        raise click.ClickException(str(e)) from None
    if show:
        click.echo("\r" + " " * 60 + "\r", nl=False, err=True)
    if as_json:
        click.echo(json.dumps(result.to_dict(), indent=2))
        return
    summarise(result)
