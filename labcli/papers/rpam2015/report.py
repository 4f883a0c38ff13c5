"""What the rPAM paper prints: the stretch fit (Fig. 6, Eq. 7), the joint map against the
model (Fig. 8), the link optimisation (Section IV) and the demo's summary.

Each function prints one result of :mod:`.analyses` (or of the demo) with ``rich``; units
on every number.
"""

from __future__ import annotations

import contextlib
import math
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from ...core.report import cell, print_table, report_console


def print_stretch_fit(
    fit: Any, out: Path, run: Path, model_name: str, plot: Path | None, *, recorded: bool = True
) -> None:
    """The fitted cubic with its uncertainty, beside the protocol's default."""
    from rich import box
    from rich.table import Table

    m = fit.model
    con = report_console()
    table = Table(
        title="Eq. 7 stretch correction F_stretch = c0 + c1 lambda + c2 lambda^2 + c3 lambda^3 (N)",
        title_justify="left",
        box=box.SIMPLE_HEAD,
    )
    for col in ("coefficient", "fitted (N)", "std. error (N)", "95% interval (N)", "protocol's default (N)"):
        table.add_column(col, justify="left" if col == "coefficient" else "right")
    for k, (c, se, (lo, hi), d) in enumerate(
        zip(m.coefficients_N, m.std_errors_N, m.ci95_N, fit.default_coefficients_N, strict=False)
    ):
        table.add_row(f"c{k}", f"{c:+.4f}", f"{se:.4f}", f"[{lo:+.4f}, {hi:+.4f}]", f"{d:+.4g}")
    print_table(con, table)
    con.print(
        f"  {m.n_points} points ({m.dof} degrees of freedom), lambda {m.lambda_range[0]:.3f} to "
        f"{m.lambda_range[1]:.3f}; R^2 {m.r2:.5f}, RMSE {m.rmse_N:.3f} N",
        soft_wrap=True,
    )
    if fit.skipped_rows:
        con.print(
            f"  {len(fit.skipped_rows)} point(s) without a reading left out: " + ", ".join(map(str, fit.skipped_rows)),
            soft_wrap=True,
        )
    print_actuator_fit(con, fit)
    if plot is not None:
        con.print(f"Stretch-test figure (Fig. 6) written to {plot}.", soft_wrap=True)
    con.print(
        f"Model written to {out}"
        + (f" and recorded in {run} under /models/{model_name}" if recorded else "")
        + "; compare a joint map "
        f"with it: labcli validate JOINT.h5 --model {out}",
        soft_wrap=True,
    )


# How each fitted parameter of the actuator is printed: (label, unit, factor from SI, format).
_ACTUATOR_ROWS = {"L0_m": ("free length L0", "mm", 1e3, ".2f"), "radius_m": ("rest radius r", "mm", 1e3, ".3f")}


def print_actuator_fit(con: Any, fit: Any) -> None:
    """The lab's actuator fitted to the stretch test (Ogden moduli, L0, r), with standard errors."""
    from rich import box
    from rich.table import Table

    a = fit.actuator_fit
    if a is None:
        con.print(f"  The actuator itself is not fitted: {fit.actuator_note}", soft_wrap=True)
        return
    table = Table(
        title=f"The lab's actuator fitted to the same points ({a.force_reading} reading; the cubic refitted "
        "with it, in the model file)",
        title_justify="left",
        box=box.SIMPLE_HEAD,
    )
    for col in ("parameter", "fitted", "std. error", "protocol's", "determined"):
        table.add_column(col, justify="left" if col == "parameter" else "right")
    determined = a.determined
    for i, name in enumerate(a.moduli):
        exponent = fit_exponent(a, i)
        table.add_row(
            f"mu_{i + 1} (alpha {exponent:g}), MPa",
            f"{a.value(name):.5f}",
            f"{a.std_error(name):.5f}",
            f"{a.protocol_values[name]:.5f}",
            "yes" if determined[name] else "no",
        )
    for name, g in a.geometry.items():
        label, unit, k, fmt = _ACTUATOR_ROWS[name]
        table.add_row(
            f"{label}, {unit}",
            f"{g['value'] * k:{fmt}}" if g["fitted"] else f"{g['protocol'] * k:{fmt}} (kept)",
            f"{g['std_error'] * k:{fmt}}",
            f"{g['protocol'] * k:{fmt}}",
            "yes" if g["fitted"] else "no",
        )
    print_table(con, table)
    con.print(f"  RMSE {a.rmse_N:.3f} N over {a.n_points} points ({a.dof} degrees of freedom).", soft_wrap=True)
    for g in a.geometry.values():
        if not g["fitted"]:
            con.print(f"  {g['note']}", soft_wrap=True)
    for note in a.notes:
        con.print(f"  {note}", soft_wrap=True)


def fit_exponent(a: Any, i: int) -> float:
    """The i-th Ogden exponent of a fitted actuator (held at the protocol's by the fit)."""
    return float(a.actuator.ogden_alpha[i])


_SOURCE = {
    "protocol": "the protocol's [stretch_correction] (no --model given)",
    "fit": "the stretch fit in {model}",
    "given": "the coefficients given",
}


def print_joint_map(result: Any, run: Path, model_path: Path | None, plot: Path | None) -> None:
    """The joint map against the model without and with the stretch correction."""
    from rich import box
    from rich.table import Table

    con = report_console()
    table = Table(
        title=f"Joint map of {run.name} against the model (Fig. 8); errors are model - measured",
        title_justify="left",
        box=box.SIMPLE_HEAD,
    )
    for col in (
        "F_stretch",
        "points compared",
        "toggles",
        "on the stop",
        "RMSE (deg)",
        "max |error| (deg)",
        "at Pa, Pb (kPa)",
        "RMSE with toggles (deg)",
    ):
        table.add_column(col, justify="left" if col == "F_stretch" else "right")
    for name in ("without", "with"):
        s = result.summary[name]
        at = s["max_error_at_kPa"]
        where = "—" if not all(_finite(v) for v in at) else f"{at[0]:.0f}, {at[1]:.0f}"
        table.add_row(
            name,
            str(s["n_compared"]),
            str(s["n_toggle"]),
            str(s.get("n_on_stop", 0)),
            cell(s["rmse_deg"], ".2f"),
            cell(s["max_abs_error_deg"], ".2f"),
            where,
            cell(s["rmse_all_deg"], ".2f"),
        )
    print_table(con, table)
    c = ", ".join(f"{v:+.4g}" for v in result.actuator.stretch_coefficients_N)
    source = _SOURCE.get(result.correction_source, result.correction_source).format(model=model_path)
    con.print(f"  F_stretch coefficients c0..c3 = [{c}] N, from {source}.", soft_wrap=True)
    con.print(
        f"  'toggles': points where the model has no balance below the toggle angle "
        f"{result.toggle_deg:.1f} deg (the joint runs onto it); 'on the stop': points where the joint was "
        "measured on its stop although the model balances (it came from the stop and stayed, the paper's "
        "toggle). Both stay out of the RMSE; the last column counts every point, a toggle at the toggle "
        "angle.",
        soft_wrap=True,
    )
    if plot is not None:
        con.print(f"Figure 8 written to {plot}.", soft_wrap=True)


def _finite(v: Any) -> bool:
    return isinstance(v, (int, float)) and math.isfinite(v)


# --------------------------------------------------------------------------- optimize


@contextlib.contextmanager
def optimize_progress() -> Iterator[Any]:
    """A live line on stderr while the optimiser runs (a terminal only); yields its callback."""
    from rich.console import Console
    from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn

    err = Console(stderr=True)
    progress = Progress(
        TextColumn("[bold]optimising[/bold] gen {task.completed:>3.0f}"),
        BarColumn(bar_width=16),
        TextColumn("{task.fields[best]}"),
        TimeElapsedColumn(),
        console=err,
        transient=True,
        disable=not err.is_terminal,
    )
    task = progress.add_task("de", total=None, best="")

    def report(generation: int, best: dict[str, float]) -> None:
        alpha = best["alpha_deg"]
        text = (
            "no feasible design yet"
            if alpha != alpha
            else (
                f"best alpha {alpha:5.2f} deg at L1 {best['L1_m']:.4f}, L2 {best['L2_m']:.4f}, L3 {best['L3_m']:.4f} m"
            )
        )
        progress.update(task, completed=generation, total=best["maxiter"], best=text)

    with progress:
        yield report


_OPTIMUM_ROWS = (  # label, key, scale, format
    ("L1 (m)", "L1_m", 1.0, ".4f"),
    ("L2 (m)", "L2_m", 1.0, ".4f"),
    ("L3 (m)", "L3_m", 1.0, ".4f"),
    ("alpha (deg)", "alpha_deg", 1.0, ".2f"),
    ("toggle atan(L2/L3) (deg)", "toggle_deg", 1.0, ".2f"),
    ("margin to the toggle (deg)", "toggle_margin_deg", 1.0, ".2f"),
    ("stiffness -dtau/dalpha (N m/rad)", "stiffness_Nm_per_rad", 1.0, ".4f"),
    ("L_a (m)", "L_a_m", 1.0, ".4f"),
    ("L_b (m)", "L_b_m", 1.0, ".4f"),
    ("push of a, F_a (N)", "F_a_N", 1.0, ".2f"),
    ("push of b, F_b (N)", "F_b_N", 1.0, ".2f"),
    ("moment arm of a, m_a (mm)", "arm_a_m", 1e3, ".2f"),
    ("moment arm of b, m_b (mm)", "arm_b_m", 1e3, ".2f"),
)


def _design_cell(design: dict[str, Any], key: str, scale: float, spec: str) -> str:
    if key == "alpha_deg" and not design.get("balanced", True):
        return "toggles"
    v = design.get(key)
    return cell(None if v is None else v * scale, spec)


def print_optimum(d: dict[str, Any]) -> None:
    """The optimum (``OptimumResult.to_dict()``): its stiffness, margin to the toggle, forces, moment
    arms and active constraints, with the links as printed beside the paper's design."""
    rounded, paper = d["rounded"], d["paper"]
    lines = [
        f"Optimum at Pa = {d['Pa_kPa']:g} kPa, Pb = {d['Pb_kPa']:g} kPa (seed {d['seed']}, {d['generations']} "
        f"generations): alpha = {d['alpha_deg']:.2f} deg, stiffness {d['stiffness_Nm_per_rad']:.4f} N m/rad "
        f"(K_min {d['min_stiffness_Nm_per_rad']:g}), {d['toggle_margin_deg']:.2f} deg short of the toggle.",
        f"Links to {rounded['resolution_m'] * 1e3:g} mm as printed, beside the paper's design (Section IV) "
        f"with the same model (actuator force read as {d.get('force_reading', 'derived')}):",
        "",
        f"  {'':34s}{'labcli':>10s}{'paper' if paper else '':>10s}",
    ]
    for label, key, scale, spec in _OPTIMUM_ROWS:
        lines.append(
            f"  {label:34s}{_design_cell(rounded, key, scale, spec):>10s}"
            f"{_design_cell(paper, key, scale, spec) if paper else '':>10s}"
        )
    lines.append("")
    source, act = d.get("actuator_source", "protocol"), d.get("actuator")
    if source != "protocol" and act is not None:
        mu = ", ".join(f"{v:.4g}" for v in act["ogden_mu_MPa"])
        lines.append(
            f"Actuator: the lab's, fitted in {source}: Ogden moduli {mu} MPa, L0 = {act['L0_m'] * 1e3:.2f} mm, "
            f"thread {act['thread_length_m']:.4f} m in {act['n_turns']:g} turns, its own stretch correction."
        )
    active = d["active_constraints"]
    lines.append("Active at the optimum: " + ("; ".join(active) if active else "none (interior optimum)") + ".")
    if paper is not None:
        verdict = (
            "meets g1-g7, the toggle margin and K_min"
            if paper["feasible"]
            else "misses " + "; ".join(paper["violated_constraints"])
        )
        lines.append(f"The paper's design {verdict}.")
        if paper["reported_alpha_deg"] is not None:
            lines.append(
                f"The paper reports alpha = {paper['reported_alpha_deg']:g} deg for it, "
                "with its own, unpublished actuator constants."
            )
    print("\n".join(lines))


# --------------------------------------------------------------------------- demo


def _stretch_table(s: dict[str, Any]) -> Any:
    """The demo's Eq. 7 stretch correction, each coefficient beside the rig's truth."""
    from rich import box
    from rich.table import Table

    coef = Table(
        title=f"Eq. 7 stretch correction F_stretch(lambda) fitted on {s['n_points']} points "
        f"(lambda {s['lambda_range'][0]:.2f}-{s['lambda_range'][1]:.2f})",
        title_justify="left",
        box=box.SIMPLE_HEAD,
    )
    for col in (
        "coefficient",
        "fitted (N)",
        "std. error (N)",
        "rig's truth (N)",
        "fit - truth (s.e.)",
        "protocol default (N)",
    ):
        coef.add_column(col, justify="left" if col == "coefficient" else "right")
    for k in range(4):
        coef.add_row(
            f"c{k}",
            f"{s['coefficients_N'][k]:+.3f}",
            f"{s['std_errors_N'][k]:.3f}",
            f"{s['true_N'][k]:+.3f}",
            f"{s['deviation_in_se'][k]:+.2f}",
            f"{s['protocol_default_N'][k]:+.3g}",
        )
    return coef


def _joint_map_table(joint_map: dict[str, Any]) -> Any:
    """The demo's joint map against the model without, with the protocol's and with the fitted F_stretch."""
    from rich import box
    from rich.table import Table

    jm = Table(
        title=f"Joint map against the model (Fig. 8), errors model - measured; toggle angle "
        f"{joint_map['toggle_deg']:.1f} deg",
        title_justify="left",
        box=box.SIMPLE_HEAD,
    )
    for col in (
        "F_stretch",
        "points compared",
        "toggles",
        "RMSE (deg)",
        "max |error| (deg)",
        "RMSE with toggles (deg)",
    ):
        jm.add_column(col, justify="left" if col == "F_stretch" else "right", no_wrap=col == "F_stretch")
    for key, label in (("without", "none"), ("with_default", "protocol's"), ("with_fitted", "fitted")):
        r = joint_map[key]
        jm.add_row(
            label,
            str(r["n_compared"]),
            str(r["n_toggle"]),
            cell(r["rmse_deg"], ".2f"),
            cell(r["max_abs_error_deg"], ".2f"),
            cell(r["rmse_all_deg"], ".2f"),
        )
    return jm


def _print_by_stand(con: Any, by_stand: dict[str, Any]) -> None:
    """The joint-map check on a stand of each reading: each model against each stand's map."""
    from rich import box
    from rich.table import Table

    st = Table(
        title="The joint-map check on a stand of each reading (protocol's F_stretch): RMSE (deg), points compared",
        title_justify="left",
        box=box.SIMPLE_HEAD,
    )
    st.add_column("stand's force", justify="left")
    for reading in ("derived", "paper"):
        st.add_column(f"{reading} model", justify="right")
    for stand, row in by_stand.items():
        st.add_row(
            stand, *(f"{cell(row[r]['rmse_deg'], '.2f')} ({row[r]['n_compared']})" for r in ("derived", "paper"))
        )
    print_table(con, st)
    con.print(
        "Each model finds the map of the stand built on its own reading and misses the other's: the check "
        "tells the two forces apart, so it checks the model, not only the code.",
        soft_wrap=True,
    )


def print_demo(res: Any) -> None:
    """The demo's summary as tables (rich), units on every number."""
    from rich import box
    from rich.table import Table

    con = report_console(markup=True)
    s = res.stretch
    con.print(
        f"[bold]labcli demo --protocol rpam2015[/bold] on the simulated rPAM rig (seed {res.seed}): "
        f"{res.points['stretch']} stretch-test points, {res.points['joint_map']} joint-map points, "
        f"{res.timings_s['total']:.1f} s.",
        soft_wrap=True,
    )

    print_table(con, _stretch_table(s))
    con.print(
        f"R^2 {s['r2']:.5f}, RMSE {s['rmse_N']:.3f} N; chi^2 of the truth against the fit's covariance "
        f"{s['chi2_4dof']:.2f} (4 degrees of freedom; 18.5 is the 99.9 % limit).",
        soft_wrap=True,
    )

    print_table(con, _joint_map_table(res.joint_map))
    con.print(
        "Toggles: pressure pairs where the model has no balance below the toggle angle; they stay out "
        "of the RMSE and count at the toggle angle in the last column.",
        soft_wrap=True,
    )

    o = res.optimum
    con.print(
        f"Link optimisation (Section IV) at Pa = {o['Pa_kPa']:g} kPa, Pb = {o['Pb_kPa']:g} kPa with the "
        f"fitted F_stretch: alpha = {o['alpha_deg']:.2f} deg at L1 = {o['L1_m']:.4f} m, "
        f"L2 = {o['L2_m']:.4f} m, L3 = {o['L3_m']:.4f} m (toggle {o['toggle_deg']:.2f} deg; "
        f"{'; '.join(o['active_constraints']) or 'no constraint at its bound'}).",
        soft_wrap=True,
    )
    if res.readings:
        rd = Table(
            title="Both readings of the actuator force (--force): stretch fit, joint map with the fitted "
            "F_stretch, optimum (paper: 58.4 deg at 0.03 / 0.1048 / 0.06 m)",
            title_justify="left",
            box=box.SIMPLE_HEAD,
        )
        for col in ("reading", "F_stretch RMSE (N)", "map RMSE (deg)", "toggles", "K_min (N m/rad)", "alpha (deg)"):
            rd.add_column(col, justify="left" if col == "reading" else "right")
        rd.add_column("L1 / L2 / L3 (m)", justify="right", no_wrap=True)
        for name, r in res.readings.items():
            o, m = r["optimum"], r["joint_map_with_fitted"]
            rd.add_row(
                name,
                cell(r["stretch_rmse_N"], ".3f"),
                cell(m["rmse_deg"], ".2f"),
                str(m["n_toggle"]),
                f"{o['min_stiffness_Nm_per_rad']:g}",
                cell(o["alpha_deg"], ".2f"),
                f"{o['L1_m']:.4f} / {o['L2_m']:.4f} / {o['L3_m']:.4f}",
            )
        print_table(con, rd)
        con.print(
            "The simulated stand's actuators follow the derived force (computed another way): the paper "
            "reading's larger errors are the checks telling the two apart, and its F_stretch, fitted to this "
            "stand, absorbs part of the difference and moves its optimum towards the derived one. With the "
            "protocol's F_stretch, labcli optimize --force paper --min-stiffness 0.2 gives the paper's pattern.",
            soft_wrap=True,
        )
    if res.joint_map_by_stand:
        _print_by_stand(con, res.joint_map_by_stand)
    if res.actuator.get("fitted"):
        _print_demo_actuator(con, res.actuator)
    for note in res.notes:
        con.print(note, soft_wrap=True)
    con.print("Files:", soft_wrap=True)
    for path in res.files.values():
        con.print(f"  {path}", soft_wrap=True, markup=False)


_DEMO_ACTUATOR_ROWS = {
    "L0_m": ("free length L0", "mm", 1e3, ".2f"),
    "radius_m": ("rest radius r", "mm", 1e3, ".3f"),
}


def _print_demo_actuator(con: Any, a: dict[str, Any]) -> None:
    """The lab's actuator fitted to the demo's stretch test beside the stand's."""
    from rich import box
    from rich.table import Table

    t = Table(
        title="The actuator fitted to the stretch test (labcli fit), beside the stand's",
        title_justify="left",
        box=box.SIMPLE_HEAD,
    )
    for col in ("parameter", "fitted", "s.e.", "stand's", "off (s.e.)", "determined"):
        t.add_column(col, justify="left" if col == "parameter" else "right")
    for name, r in a["parameters"].items():
        label, unit, k, fmt = _DEMO_ACTUATOR_ROWS.get(name, (name, "MPa", 1.0, ".5f"))
        t.add_row(
            f"{label}, {unit}",
            f"{r['value'] * k:{fmt}}" + ("" if r["fitted"] else " (kept)"),
            f"{r['std_error'] * k:{fmt}}",
            f"{r['true'] * k:{fmt}}",
            cell(r["deviation_in_se"], "+.2f"),
            "yes" if r["determined"] else "no",
        )
    print_table(con, t)
    for note in a["notes"]:
        con.print(note, soft_wrap=True)
