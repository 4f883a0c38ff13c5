"""``labcli fit``: least squares of the paper's Eqs. 34-37 on a run's fit trials."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import click

from ..errors import LabcliError
from ..core.report import cell, report_console


def default_model_path(run: Path) -> Path:
    """``run.h5`` -> ``run.model.json`` beside it."""
    return run.with_name(run.stem + ".model.json")


def _write_model(path: Path, text: str) -> Any:
    """Replace ``path`` atomically with ``text``; returns a function that puts the old file back."""
    import os
    import tempfile

    old = path.read_bytes() if path.is_file() else None
    try:
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    except OSError as e:
        raise click.ClickException(f"Cannot write the model to {path}: {e.strerror or e} "
                                   "(check the folder exists and is writable).") from None
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as fh:
            fh.write(text)
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp, 0o666 & ~umask)  # mkstemp makes 0600; a model file is as readable as any other
        os.replace(tmp, path)
    except OSError as e:
        try:
            os.unlink(tmp)
        except OSError:
            pass
        raise click.ClickException(f"Cannot write the model to {path}: {e.strerror or e}.") from None

    def restore() -> None:
        if old is None:
            path.unlink(missing_ok=True)
        else:
            path.write_bytes(old)

    return restore


def _print_report(model: Any, paper: dict[str, float], out_path: Path, recorded: str) -> None:
    from rich import box
    from rich.table import Table

    from ..experiments.takuma2014.models.takuma import SIGN_NOTE, TERMS

    con = report_console(110)
    titles = {
        "theta1": ("Eq. 34  sin(theta1)", "1, dimensionless", "sin(theta1)"),
        "theta2": ("Eq. 35  sin(theta2)", "1, dimensionless", "sin(theta2)"),
        "Fx": ("Eq. 36  Fx", "N m/MPa", "N"),
        "Fy": ("Eq. 37  Fy", "N m/MPa", "N"),
    }
    for eq, names in TERMS.items():
        title, unit, space = titles[eq]
        st = model.fit_stats[eq]
        table = Table(title=f"{title}   (coefficients in {unit})", title_justify="left", box=box.SIMPLE_HEAD)
        table.add_column("coefficient")
        table.add_column("value", justify="right")
        table.add_column("std. error", justify="right")
        table.add_column("95% interval", justify="right")
        table.add_column("paper 3.3", justify="right")
        for name in names:
            lo, hi = model.ci95[name]
            table.add_row(name, f"{model.coefficients[name]:.5g}", f"{model.standard_errors[name]:.3g}",
                          f"[{lo:.5g}, {hi:.5g}]", cell(paper.get(name), ".6g"))
        con.print(table)
        if eq.startswith("theta"):
            fit_line = (f"R^2 {cell(st['r2'], '.5f')} ({space}), {cell(st['r2_native'], '.5f')} (deg); "
                        f"RMSE {cell(st['rmse'], '.3g')} ({space}) = {cell(st['rmse_native'], '.3g')} deg")
        else:
            fit_line = f"R^2 {cell(st['r2'], '.5f')}; RMSE {cell(st['rmse'], '.3g')} N"
        cond = st["design_cond"]
        warn = "  (ill-conditioned: coefficients poorly determined)" if st.get("ill_conditioned") else ""
        con.print(f"  {fit_line}; condition number {cell(cond, '.3g')}{warn}; "
                  f"{st['n']} trials ({st['dof']} degrees of freedom)", soft_wrap=True)
        excluded = model.excluded_trials.get(eq, [])
        if excluded:
            con.print(f"  excluded {len(excluded)} trial(s):")
            for item in excluded[:12]:
                con.print(f"    trial {item['trial']}: {item['reason']}", soft_wrap=True)
            if len(excluded) > 12:
                con.print(f"    ... and {len(excluded) - 12} more (see the model file)")
        con.print()
    con.print(f"Sign: {SIGN_NOTE}.", soft_wrap=True)
    con.print(f"Each force fit leaves out postures near the straight arm (theta2 = 0) where that "
              f"component's amplification ||row of (J^-1)^T|| ||J|| exceeds {model.max_amplification:g}.",
              soft_wrap=True)
    con.print(f"Model written to {out_path}{recorded}.", soft_wrap=True)


@click.command("fit")
@click.argument("run", type=click.Path(dir_okay=False, path_type=Path))
@click.option("-o", "--output", type=click.Path(dir_okay=False, path_type=Path), default=None,
              help="Model JSON to write [default: RUN.model.json beside the run].")
@click.option("--protocol", default=None,
              help="Protocol of a trial CSV (name or .toml) [default: takuma2014]; run files carry their own.")
@click.option("--max-amplification", type=click.FloatRange(min=1, min_open=True), default=100.0, show_default=True,
              help="Leave a posture out of the Fx (Fy) fit when that force's error amplification "
                   "near theta2 = 0 exceeds this.")
@click.option("--json", "as_json", is_flag=True, help="Print the model and the paper's values as JSON.")
@click.option("--plot", type=click.Path(dir_okay=False, path_type=Path), default=None,
              help="rPAM stretch-test runs: write the stretch test's figure (Fig. 6) to this .png, .pdf or .svg.")
@click.option("--set", "overrides", multiple=True, metavar="KEY=VALUE",
              help="rPAM runs: override a protocol value for this analysis, e.g. --set actuator.A0_m2=2.2e-4 "
                   "(repeatable; the run file keeps its own).")
def fit(run: Path, output: Path | None, protocol: str | None, max_amplification: float,
        as_json: bool, plot: Path | None, overrides: tuple[str, ...]) -> None:
    """Fit the paper's regression (Eqs. 34-37) to the fit trials of RUN.

    RUN is a run file (.h5) or a trial CSV.  Prints each equation's coefficients with standard
    errors, 95% intervals and the paper's values (Section 3.3), saves the model JSON and
    records it in the run file.  On an rPAM stretch-test run it fits the cubic stretch
    correction F_stretch(lambda) of the rPAM paper's Eq. 7 instead, with its uncertainty.

    \b
    Example:
        labcli fit run.h5                  # writes run.model.json
        labcli fit trials.csv --protocol takuma2014 -o model.json --json
        labcli fit stretch.h5 --plot fig6-stretch.png
    """
    from ..experiments.takuma2014.models.inputs import load_trial_source
    from ..experiments.takuma2014.models.takuma import TakumaModel
    from ..experiments.rpam2015.report import fit_command, rpam_run_kind

    if rpam_run_kind(run):  # an rPAM run: the stretch correction (Eq. 7), not Eqs. 34-37
        fit_command(run, output=output, protocol=protocol, plot=plot, as_json=as_json, overrides=overrides)
        return
    if overrides:
        raise click.ClickException("--set changes rPAM model constants (e.g. --set actuator.L0_m=0.08); a force "
                                   "run's model is fitted from its trials, so leave --set out.")
    if plot is not None:
        raise click.ClickException("--plot draws the stretch test (Fig. 6) of an rPAM stretch-test run; "
                                   "for a force run draw Figure 7 with labcli validate --plot.")

    try:
        src = load_trial_source(run, protocol)
        model = TakumaModel(geometry=src.protocol.settings.rig, protocol=src.protocol.name,
                            max_amplification=max_amplification).fit(src.table, source=str(run))
        out_path = output or default_model_path(run)
        text = model.to_json()
        recorded = ""
        if src.is_run:
            from ..core.store import RunFile

            # Open the run for writing before the model file is touched: a run that cannot take
            # the model (locked by a viewer, read-only) must leave both files as they were.
            with RunFile.open(run, "a") as rf:
                restore = _write_model(out_path, text)
                try:
                    rf.record_model(model.protocol, text)
                except BaseException:
                    restore()
                    raise
            recorded = f" and recorded in {run} under /models/{model.protocol}"
        else:
            _write_model(out_path, text)
    except LabcliError as e:
        raise click.ClickException(str(e)) from None
    paper = dict(src.protocol.settings.paper_coefficients or {})
    if as_json:
        click.echo(json.dumps({
            "model_path": str(out_path), "recorded_in_run": bool(recorded),
            "model": model.to_dict(), "paper_coefficients": paper,
        }, indent=2))
        return
    _print_report(model, paper, out_path, recorded)
