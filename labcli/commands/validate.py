"""``labcli validate``: accuracy of a fitted model on a run's validation trials (Figure 7)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import click

from ..errors import LabcliError
from ..core.report import cell, report_console


def _print_report(ev: dict[str, Any], model_path: Path, run: Path, plot: Path | None) -> None:
    from rich import box
    from rich.table import Table

    from ..experiments.takuma2014.models.metrics import QUANTITIES
    from ..experiments.takuma2014.models.takuma import FLAG_TEXT

    con = report_console(110)
    how = ("forces from the calculated angles" if ev["mode"] == "pressure-only"
           else "forces from the measured angles")
    table = Table(title=f"Validation of {model_path.name} on {run.name}: {ev['mode']} ({how})",
                  title_justify="left", box=box.SIMPLE_HEAD)
    for col in ("quantity", "n", "RMSE", "MAE", "max|err|", "bias", "R^2", "RMSE/range", "flagged"):
        table.add_column(col, justify="left" if col == "quantity" else "right")
    for q, (_, unit, _) in QUANTITIES.items():
        m = ev["metrics"][q]
        table.add_row(f"{q} [{unit}]", str(m["n"]), cell(m["rmse"], ".3g"), cell(m["mae"], ".3g"),
                      cell(m["max_abs"], ".3g"), cell(m["bias"], "+.2g"), cell(m["r2"], ".4f"),
                      cell(m["pct_range"], ".2f") + (" %" if m["pct_range"] is not None else ""),
                      str(m["n_flagged"]))
    con.print(table)
    con.print("Errors are calculated - observed; RMSE/range is the RMSE as a share of the observed range.",
              soft_wrap=True)
    flagged = [(i, int(t), fl) for i, (t, fl) in enumerate(zip(ev["trial"], ev["flags"])) if fl]
    if flagged:
        con.print(f"{len(flagged)} trial(s) flagged; their values show as — and stay out of the metrics:",
                  soft_wrap=True)
        for i, t, fl in flagged:
            missing = [q for q in QUANTITIES if not ev["ok"][q][i]]
            reasons = "; ".join(FLAG_TEXT.get(f, f) for f in fl)
            con.print(f"  trial {t}: {', '.join(missing)} = — ({reasons})", soft_wrap=True)
    if plot is not None:
        con.print(f"Figure 7 written to {plot}.")


@click.command("validate")
@click.argument("run", type=click.Path(dir_okay=False, path_type=Path))
@click.option("--model", "model_path", type=click.Path(dir_okay=False, path_type=Path), default=None,
              help="Model JSON from `labcli fit` [default: RUN.model.json beside the run].")
@click.option("--mode", type=click.Choice(["pressure-only", "measured-angles"]), default="pressure-only",
              show_default=True,
              help="Angles for the force equations: from the pressures (Eqs. 34-35) or the potentiometers.")
@click.option("--plot", type=click.Path(dir_okay=False, path_type=Path), default=None,
              help="Write Figure 7 (observed vs calculated) to this .png, .pdf or .svg file.")
@click.option("--protocol", default=None,
              help="Protocol of a trial CSV (name or .toml) [default: takuma2014]; run files carry their own.")
@click.option("--json", "as_json", is_flag=True,
              help="Print the metrics and every validation trial's observed and calculated values as JSON.")
@click.option("--set", "overrides", multiple=True, metavar="KEY=VALUE",
              help="rPAM runs: override a protocol value for this analysis, e.g. --set actuator.A0_m2=2.2e-4 "
                   "(repeatable; the run file keeps its own).")
def validate(run: Path, model_path: Path | None, mode: str, plot: Path | None, protocol: str | None,
             as_json: bool, overrides: tuple[str, ...]) -> None:
    """Check a fitted model on the validation trials of RUN (the paper's Figure 7).

    RUN is a run file (.h5) or a trial CSV.  Reports RMSE, MAE, max |error|, bias, R^2 and
    RMSE as a share of the observed range for theta1, theta2 (deg) and Fx, Fy (N).
    On an rPAM joint-map run it compares the measured angles with the model without and
    with the stretch correction (--model: the stretch fit; default: the protocol's own),
    and --plot draws the rPAM paper's Figure 8.

    \b
    Example:
        labcli validate run.h5 --model run.model.json --plot fig7.png
        labcli validate trials.csv --mode measured-angles --json
        labcli validate joint.h5 --model stretch.model.json --plot fig8.png
    """
    from ..experiments.rpam2015.report import rpam_run_kind, validate_command

    if rpam_run_kind(run):  # an rPAM joint map (Fig. 8), not Eqs. 34-37
        validate_command(run, model_path=model_path, protocol=protocol, plot=plot, as_json=as_json,
                         overrides=overrides)
        return
    if overrides:
        raise click.ClickException("--set changes rPAM model constants (e.g. --set actuator.L0_m=0.08); a force "
                                   "run's model is fitted from its trials, so leave --set out.")
    from .fit import default_model_path
    from ..experiments.takuma2014.models.inputs import load_trial_source
    from ..experiments.takuma2014.models.metrics import evaluate, evaluation_to_dict
    from ..experiments.takuma2014.models.takuma import TakumaModel

    try:
        src = load_trial_source(run, protocol)
        mpath = model_path or default_model_path(run)
        model = TakumaModel.load(mpath)
        model.check_compatible(src.protocol.name, src.protocol.settings.rig,
                               model_name=f"the model file {mpath}", run_name=str(run))
        ev = evaluate(model, src.table, mode=mode, source=str(run))
        if plot is not None:
            from ..experiments.takuma2014.figures import figure7

            figure7(ev, plot)
    except LabcliError as e:
        raise click.ClickException(str(e)) from None
    if as_json:
        out = evaluation_to_dict(ev)
        out.update(run=str(run), model=str(mpath), plot=str(plot) if plot else None)
        click.echo(json.dumps(out, indent=2, allow_nan=False))
        return
    _print_report(ev, mpath, run, plot)
