"""``labcli classify``: object stiffness and material category from pushes (Section 4, Figure 9)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import click

from ..errors import LabcliError
from ..core.report import cell, report_console


def _print_report(data: dict[str, Any], plot: Path | None) -> None:
    from rich import box
    from rich.table import Table

    con = report_console(160)
    angles = ("angles and force from the pressures" if data["angles"] == "pressure-only"
              else "angles from the potentiometers, force from the pressures")
    pushes = Table(title=f"Pushes of {Path(data['pushes_file']).name}: {angles} (* = phi solved)",
                   title_justify="left", box=box.SIMPLE_HEAD)
    cols = ("push", "object", "theta1 [deg]", "theta2 [deg]", "Fx [N]", "Fy [N]", "C [mm]", "phi [deg]",
            "O2 [mm]", "delta_x [mm]", "k_o [N/m]", "")
    for c in cols:
        pushes.add_column(c, justify="left" if c in ("object", "") else "right")
    for p in data["pushes"]:
        phi = cell(p["phi_deg"], ".1f") + ("*" if p["phi_solved"] else "")
        pushes.add_row(
            str(p["push"]), p["object"], cell(p["theta1_deg"], ".3f"), cell(p["theta2_deg"], ".3f"),
            cell(p["Fx_N"], ".3f"), cell(p["Fy_N"], ".3f"),
            f"({cell(p['xc_mm'], '.1f')}, {cell(p['yc_mm'], '.1f')})", phi,
            f"({cell(p['xo_mm'], '.1f')}, {cell(p['yo_mm'], '.1f')})",
            cell(p["delta_x_mm"], ".3f"), cell(p["k_N_per_m"], ".0f"), "flagged" if p["flagged"] else "",
        )
    con.print(pushes)

    method = {"bands": "stiffness bands of the protocol",
              "reference": "nearest reference class in ln k"}[data["method"]]
    objects = Table(title=f"Objects: category by {method}", title_justify="left", box=box.SIMPLE_HEAD)
    has_true = any("true_k_N_per_m" in o for o in data["objects"])
    ocols = ["object", "role", "n", "flagged", "mean k_o [N/m]", "sd [N/m]", "sd [%]"]
    ocols += ["true k_o [N/m]"] if has_true else []
    ocols += ["category", "confidence", "method"]
    for c in ocols:
        objects.add_column(c, justify="left" if c in ("object", "role", "category", "method") else "right")
    for o in data["objects"]:
        mean, sd = o["k_mean_N_per_m"], o["k_sd_N_per_m"]
        rel = 100 * sd / mean if mean and sd is not None else None
        role = f"reference ({o['category_given']})" if o["role"] == "reference" else "unknown"
        row = [o["object"], role, str(o["n"]), str(o["n_flagged"]), cell(mean, ".0f"), cell(sd, ".0f"),
               cell(rel, ".1f")]
        row += [cell(o.get("true_k_N_per_m"), ".0f")] if has_true else []
        conf = o["confidence"]
        row += [o["category"] or "—", cell(None if conf is None else 100 * conf, ".0f") + (" %" if conf is not None else ""),
                o["method"]]
        objects.add_row(*row)
    con.print(objects)
    for o in data["objects"]:
        if o["note"]:
            con.print(f"  {o['object']}: {o['note']}", soft_wrap=True)
    flagged = [p for p in data["pushes"] if p["flagged"]]
    if flagged:
        con.print(f"{len(flagged)} push(es) flagged and kept out of the statistics:", soft_wrap=True)
        for p in flagged:
            con.print(f"  push {p['push']} ({p['object']}): {p['reason']}", soft_wrap=True)
    notes = sorted({p["note"] for p in data["pushes"] if p["note"] and not p["flagged"]})
    for note in notes:
        n = sum(1 for p in data["pushes"] if p["note"] == note and not p["flagged"])
        con.print(f"{n} push(es): {note}.", soft_wrap=True)
    if plot is not None:
        con.print(f"Figure 9 written to {plot}.")


@click.command("classify")
@click.argument("pushes", type=click.Path(dir_okay=False, path_type=Path))
@click.option("--model", "model_path", type=click.Path(dir_okay=False, path_type=Path), required=True,
              help="Model JSON from `labcli fit` on a force run of the same rig.")
@click.option("--reference", type=click.Path(dir_okay=False, path_type=Path), default=None,
              help="Push run or CSV whose labelled pushes (category column) are reference objects.")
@click.option("--method", type=click.Choice(["auto", "reference", "bands"]), default="auto", show_default=True,
              help="Categories from labelled reference objects, from the protocol's stiffness bands, "
                   "or reference objects when any push is labelled, else bands.")
@click.option("--angles", type=click.Choice(["pressure-only", "measured-angles"]), default="pressure-only",
              show_default=True,
              help="Joint angles from the pressures (Eqs. 34-35, the paper) or from the potentiometers.")
@click.option("--plot", type=click.Path(dir_okay=False, path_type=Path), default=None,
              help="Write Figure 9 (stiffness per object) to this .png, .pdf or .svg file.")
@click.option("--protocol", default=None,
              help="Protocol of a push CSV (name or .toml) [default: takuma2014-stiffness]; run files carry their own.")
@click.option("--json", "as_json", is_flag=True,
              help="Print every push's and every object's results as JSON (mm, deg, N, N/m).")
def classify(pushes: Path, model_path: Path, reference: Path | None, method: str, angles: str,
             plot: Path | None, protocol: str | None, as_json: bool) -> None:
    """Stiffness of each pushed object and its material category (Section 4, Figure 9).

    PUSHES is a push run file (.h5) or a push CSV.  Per push: joint angles and force from the
    pressures, contact point C, push direction phi (given, or solved), object centre O2,
    deformation delta_x and stiffness k_o = |F| / delta_x.  Per object: mean and standard
    deviation over the unflagged pushes, category and confidence.

    \b
    Example:
        labcli classify pushes.h5 --model force.model.json --plot fig9.png
        labcli classify unknown.csv --model force.model.json --reference refs.h5 --json
    """
    from ..experiments.takuma2014.models.classify import classify_file

    try:
        report = classify_file(pushes, model_path, reference=reference, protocol=protocol, method=method,
                               angles=angles)
        if plot is not None:
            from ..experiments.takuma2014.figures import figure9

            figure9(report.result, plot)
    except LabcliError as e:
        raise click.ClickException(str(e)) from None
    data = report.to_dict()
    if as_json:
        data["plot"] = str(plot) if plot else None
        click.echo(json.dumps(data, indent=2, allow_nan=False))
        return
    _print_report(data, plot)
