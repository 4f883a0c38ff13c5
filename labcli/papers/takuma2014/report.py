"""What the McKibben paper prints: the fit (Eqs. 34-37), the validation (Figure 7), the
classification (Figure 9) and the demo's summary, as tables with units on every number.

Each function prints one result of :mod:`.analyses` (or of the demo); ``--json`` output is
the result's own ``to_dict``.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from ...core.report import cell, ids_text, print_table, report_console
from .models.metrics import QUANTITIES
from .models.takuma import FLAG_TEXT, SIGN_NOTE, TERMS


def print_fit(model: Any, paper: dict[str, float], out_path: Path, recorded: str) -> None:
    from rich import box
    from rich.table import Table

    con = report_console()
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
            table.add_row(
                name,
                f"{model.coefficients[name]:.5g}",
                f"{model.standard_errors[name]:.3g}",
                f"[{lo:.5g}, {hi:.5g}]",
                cell(paper.get(name), ".6g"),
            )
        print_table(con, table)
        if eq.startswith("theta"):
            fit_line = (
                f"R^2 {cell(st['r2'], '.5f')} ({space}), {cell(st['r2_native'], '.5f')} (deg); "
                f"RMSE {cell(st['rmse'], '.3g')} ({space}) = {cell(st['rmse_native'], '.3g')} deg"
            )
        else:
            fit_line = f"R^2 {cell(st['r2'], '.5f')}; RMSE {cell(st['rmse'], '.3g')} N"
        cond = st["design_cond"]
        warn = "  (ill-conditioned: coefficients poorly determined)" if st.get("ill_conditioned") else ""
        con.print(
            f"  {fit_line}; condition number {cell(cond, '.3g')}{warn}; "
            f"{st['n']} trials ({st['dof']} degrees of freedom)",
            soft_wrap=True,
        )
        excluded = model.excluded_trials.get(eq, [])
        if excluded:
            con.print(f"  excluded {len(excluded)} trial(s):")
            for item in excluded[:12]:
                con.print(f"    trial {item['trial']}: {item['reason']}", soft_wrap=True)
            if len(excluded) > 12:
                con.print(f"    ... and {len(excluded) - 12} more (see the model file)")
        con.print()
    con.print(f"Sign: {SIGN_NOTE}.", soft_wrap=True)
    play = play_sentence(model)
    if play:
        con.print(play, soft_wrap=True)
    con.print(
        f"Each force fit leaves out postures near the straight arm (theta2 = 0) where that "
        f"component's amplification ||row of (J^-1)^T|| ||J|| exceeds {model.max_amplification:g}.",
        soft_wrap=True,
    )
    con.print(f"Model written to {out_path}{recorded}.", soft_wrap=True)


def play_sentence(model: Any) -> str:
    """What the fit estimated of the potentiometers' play (models/labels.py), in one sentence."""
    play = getattr(model, "play", None) or {}
    if not play.get("play_deg"):
        return "Angle labels taken as the potentiometers read them (no play fitted)."
    widths = ", ".join(
        f"theta{k + 1} {w:.3f} +- {se:.3f} deg"
        for k, (w, se) in enumerate(zip(play["play_deg"], play["se_deg"], strict=True))
    )
    inside = sum(len(v) for v in play.get("inside_play", {}).values())
    return (
        f"Potentiometer play fitted with Eqs. 34-35 (full width, standard error): {widths}; the angle labels "
        f"are corrected for it, and {inside} reading(s) inside the play are left out of the angle fits."
    )


def print_posture_fit(model: Any, out_path: Path, recorded: str) -> None:
    """The posture-aware form (models/posture.py): its terms and coefficients, fit residuals, limits."""
    import math

    from rich import box
    from rich.table import Table

    con = report_console()
    st = model.fit_stats
    angles = Table(
        title="Deflection  dtheta = sum beta u   (u = P0/P - 1; coefficients in rad)",
        title_justify="left",
        box=box.SIMPLE_HEAD,
    )
    torques = Table(
        title="Load torque  tau = J(theta0 + dtheta)^T F   (dP in MPa, dtheta in rad; N m per unit)",
        title_justify="left",
        box=box.SIMPLE_HEAD,
    )
    for table, terms, coef, cov in (
        (angles, model.angle_terms, model.angle_coefficients, model.angle_xtx_inv),
        (torques, model.torque_terms, model.torque_coefficients, model.torque_xtx_inv),
    ):
        res = model.angle_resid_cov if table is angles else model.torque_resid_cov
        names = ("dtheta1", "dtheta2") if table is angles else ("tau1", "tau2")
        table.add_column("term")
        for name in names:
            table.add_column(name, justify="right")
            table.add_column("std. error", justify="right")
        for i, term in enumerate(terms):
            row = [term]
            for k in range(2):
                row += [f"{coef[i][k]:.5g}", f"{math.sqrt(cov[i][i] * res[k][k]):.3g}"]
            table.add_row(*row)
        print_table(con, table)
    if model.theta1_terms:
        eq = " + ".join(f"{c:.5g} {t}" for t, c in zip(model.theta1_terms, model.theta1_coefficients, strict=False))
        con.print(
            f"theta1 as reported: its own equation from Eq. 34's terms, theta1 = {eq} rad "
            "(the table's dtheta1 feeds the forces).",
            soft_wrap=True,
        )
    con.print(
        f"Fit on {st['n']} trials; rest posture (median) theta0 = "
        f"({st['theta0_deg'][0]:.2f}, {st['theta0_deg'][1]:.2f}) deg; residual RMSE "
        f"dtheta {st['angle_rmse_deg'][0]:.3g}, {st['angle_rmse_deg'][1]:.3g} deg, "
        f"tau {st['torque_rmse_Nm'][0]:.3g}, {st['torque_rmse_Nm'][1]:.3g} N m.",
        soft_wrap=True,
    )
    lim = model.limits
    con.print(
        f"Forces F = (J^T)^-1 tau at theta0 + dtheta, each with its standard error; an estimate is "
        f"flagged above {math.degrees(lim['theta1']):.3g} deg (angles) or {lim['Fx']:.3g} N (forces) "
        "(protocol [sensing]). The paper's Eqs. 34-37: labcli fit --form paper.",
        soft_wrap=True,
    )
    con.print(route_text(model.routes, model.blends), soft_wrap=True)
    con.print(f"Model written to {out_path}{recorded}.", soft_wrap=True)


ROUTE_TEXT = {
    ("theta1", "posture"): "own equation",
    ("theta2", "posture"): "deflection fit",
    ("Fx", "posture"): "torques",
    ("Fy", "posture"): "torques",
    ("theta1", "paper"): "paper's Eq. 34",
    ("theta2", "paper"): "paper's Eq. 35",
    ("Fx", "paper"): "paper's Eq. 36",
    ("Fy", "paper"): "paper's Eq. 37",
}


def route_text(routes: dict[str, str], blends: dict[str, dict[str, float]] | None = None) -> str:
    """One sentence: which estimate each quantity takes (models/routes.py), a blend with its weights."""
    parts = []
    for q in QUANTITIES:
        route = routes.get(q, "posture")
        if route == "blend":
            w = (blends or {}).get(q, {}).get("posture_weight")
            own, paper = ROUTE_TEXT[q, "posture"], ROUTE_TEXT[q, "paper"]
            parts.append(
                f"{q} {w:.2f} x {own} + {1 - w:.2f} x {paper}" if w is not None else f"{q} a blend of {own} and {paper}"
            )
        else:
            parts.append(f"{q} {ROUTE_TEXT[q, route]}")
    return "Routes (chosen by cross-validation on the fit trials): " + ", ".join(parts) + "."


def print_forms(forms: dict[str, dict[str, Any]], where: str = "the same validation trials") -> None:
    """Validation RMSE of both forms side by side, reported trials and all trials."""
    from rich import box
    from rich.table import Table

    con = report_console()
    table = Table(
        title=f"Both forms on {where} (RMSE; all = flagged trials too)", title_justify="left", box=box.SIMPLE_HEAD
    )
    table.add_column("quantity")
    for form in forms:
        for col in ("n", "RMSE", "RMSE all"):
            table.add_column(f"{form} {col}", justify="right")
    table.add_column("posture 95% cover", justify="right")
    for q, (_, unit, _) in QUANTITIES.items():
        row = [f"{q} ({unit})"]
        for m in forms.values():
            row += [str(m[q]["n"]), cell(m[q]["rmse"], ".3g"), cell(m[q]["rmse_all"], ".3g")]
        cover = forms.get("posture", {}).get(q, {}).get("coverage95")
        row.append(cell(None if cover is None else 100 * cover, ".0f") + (" %" if cover is not None else ""))
        table.add_row(*row)
    print_table(con, table)


def print_validation(ev: dict[str, Any], model: str, run: Path, plot: Path | None) -> None:
    from rich import box
    from rich.table import Table

    con = report_console()
    how = "forces from the calculated angles" if ev["mode"] == "pressure-only" else "forces from the measured angles"
    con.print(f"model: {model}", soft_wrap=True)
    table = Table(title=f"Validation on {run.name}: {ev['mode']} ({how})", title_justify="left", box=box.SIMPLE_HEAD)
    for col in ("quantity", "n", "RMSE", "MAE", "max|err|", "bias", "R^2", "RMSE/range", "flagged"):
        table.add_column(col, justify="left" if col == "quantity" else "right")
    for q, (_, unit, _) in QUANTITIES.items():
        m = ev["metrics"][q]
        table.add_row(
            f"{q} ({unit})",
            str(m["n"]),
            cell(m["rmse"], ".3g"),
            cell(m["mae"], ".3g"),
            cell(m["max_abs"], ".3g"),
            cell(m["bias"], "+.2g"),
            cell(m["r2"], ".4f"),
            cell(m["pct_range"], ".2f") + (" %" if m["pct_range"] is not None else ""),
            str(m["n_flagged"]),
        )
    print_table(con, table)
    con.print(
        "Errors are calculated - observed; RMSE/range is the RMSE as a share of the observed range.", soft_wrap=True
    )
    if ev.get("routes"):
        con.print(route_text(ev["routes"], ev.get("blends")), soft_wrap=True)
    _print_flagged(con, ev)
    if len(ev.get("forms", {})) > 1:
        print_forms(ev["forms"])
    if plot is not None:
        con.print(f"Figure 7 written to {plot}.")


FLAGGED_LIST_LIMIT = 60  # flagged validation trials listed one by one up to this many; beyond, counted by reason


def _print_flagged(con: Any, ev: dict[str, Any]) -> None:
    """The flagged validation trials: each with its reasons when few, else counted by reason (--json lists all)."""
    flagged = [i for i, fl in enumerate(ev["flags"]) if fl]
    if not flagged:
        return
    if len(flagged) <= FLAGGED_LIST_LIMIT:
        con.print(
            f"{len(flagged)} trial(s) flagged; their values show as — and stay out of the metrics:", soft_wrap=True
        )
        for i in flagged:
            missing = [q for q in QUANTITIES if not ev["ok"][q][i]]
            reasons = "; ".join(FLAG_TEXT.get(f, f) for f in ev["flags"][i])
            con.print(f"  trial {int(ev['trial'][i])}: {', '.join(missing)} = — ({reasons})", soft_wrap=True)
        return
    by_reason: dict[str, list[int]] = {}
    for i in flagged:
        for f in ev["flags"][i]:
            by_reason.setdefault(f, []).append(i)
    con.print(
        f"{len(flagged)} of {len(ev['trial'])} trials flagged; their values stay out of the metrics "
        "(--json lists every trial):",
        soft_wrap=True,
    )
    for f, rows in sorted(by_reason.items(), key=lambda kv: -len(kv[1])):
        ids = np.asarray(ev["trial"])[rows].tolist()
        con.print(f"  {len(rows)} x {FLAG_TEXT.get(f, f)}: trials {ids_text(ids)}", soft_wrap=True)


def print_classification(
    data: dict[str, Any], plot: Path | None, pushes: list[dict[str, Any]] | None, flags: dict[str, Any]
) -> None:
    """The objects' summary, and the pushes one by one when ``pushes`` is given (few, or --pushes)."""
    from rich import box
    from rich.table import Table

    con = report_console()
    angles = (
        "angles and force from the pressures"
        if data["angles"] == "pressure-only"
        else "angles from the potentiometers, force from the pressures"
    )
    if pushes is not None:
        _print_pushes(con, pushes, f"Pushes of {Path(data['pushes_file']).name}: {angles} (* = phi solved)")
    else:
        con.print(
            f"{data['n_pushes']} pushes of {Path(data['pushes_file']).name} ({angles}) on "
            f"{len(data['objects'])} objects; list them with --pushes."
        )

    method = {"bands": "stiffness bands of the protocol", "reference": "nearest reference class in ln k"}[
        data["method"]
    ]
    objects = Table(title=f"Objects: category by {method}", title_justify="left", box=box.SIMPLE_HEAD)
    has_true = any("true_k_N_per_m" in o for o in data["objects"])
    ocols = ["object", "role", "n", "flagged", "mean k_o (N/m)", "sd (N/m)", "sd (%)"]
    ocols += ["true k_o (N/m)"] if has_true else []
    ocols += ["category", "confidence", "method"]
    for c in ocols:
        objects.add_column(c, justify="left" if c in ("object", "role", "category", "method") else "right")
    for o in data["objects"]:
        mean, sd = o["k_mean_N_per_m"], o["k_sd_N_per_m"]
        rel = 100 * sd / mean if mean and sd is not None else None
        role = {"reference": f"reference ({o['category_given']})", "given": f"given: {o['category_given']}"}.get(
            o["role"], "unknown"
        )
        row = [
            o["object"],
            role,
            str(o["n"]),
            str(o["n_flagged"]),
            cell(mean, ".0f"),
            cell(sd, ".0f"),
            cell(rel, ".1f"),
        ]
        row += [cell(o.get("true_k_N_per_m"), ".0f")] if has_true else []
        conf = o["confidence"]
        row += [
            category_text(o),
            cell(None if conf is None else 100 * conf, ".0f") + (" %" if conf is not None else ""),
            o["method"],
        ]
        objects.add_row(*row)
    print_table(con, objects)
    con.print(method_sentence(data), soft_wrap=True)
    unit = "class spreads of ln k" if data["method"] == "reference" else "the object's spread of ln k outside each band"
    con.print(f"Distance to each category (z, in {unit}):", soft_wrap=True)
    for o in data["objects"]:
        z = ", ".join(f"{c} {cell(v, '+.1f')}" for c, v in o.get("z_by_category", {}).items())
        note = f"; {o['note']}" if o["note"] else ""
        con.print(f"  {o['object']}: {z or '—'}{note}", soft_wrap=True)
    if flags["n_flagged"]:
        con.print(f"{flags['n_flagged']} push(es) flagged and kept out of the statistics:", soft_wrap=True)
        if pushes is not None:
            for p in pushes:
                if p["flagged"]:
                    con.print(f"  push {p['push']} ({p['object']}): {p['reason']}", soft_wrap=True)
        else:
            for reason, n in flags["reasons"].items():
                con.print(f"  {n} push(es): {reason}", soft_wrap=True)
    for note, n in sorted(flags["notes"].items()):
        con.print(f"{n} push(es): {note}.", soft_wrap=True)
    if plot is not None:
        con.print(f"Figure 9 written to {plot}.")


def _print_pushes(con: Any, pushes: list[dict[str, Any]], title: str) -> None:
    from rich import box
    from rich.table import Table

    table = Table(title=title, title_justify="left", box=box.SIMPLE_HEAD)
    cols = (
        "push",
        "object",
        "theta1 (deg)",
        "theta2 (deg)",
        "Fx (N)",
        "Fy (N)",
        "C (mm)",
        "phi (deg)",
        "O2 (mm)",
        "delta_x (mm)",
        "k_o (N/m)",
        "",
    )
    for c in cols:
        table.add_column(c, justify="left" if c in ("object", "") else "right")
    for p in pushes:
        phi = cell(p["phi_deg"], ".1f") + ("*" if p["phi_solved"] else "")
        table.add_row(
            str(p["push"]),
            p["object"],
            cell(p["theta1_deg"], ".3f"),
            cell(p["theta2_deg"], ".3f"),
            cell(p["Fx_N"], ".3f"),
            cell(p["Fy_N"], ".3f"),
            f"({cell(p['xc_mm'], '.1f')}, {cell(p['yc_mm'], '.1f')})",
            phi,
            f"({cell(p['xo_mm'], '.1f')}, {cell(p['yo_mm'], '.1f')})",
            cell(p["delta_x_mm"], ".3f"),
            cell(p["k_N_per_m"], ".0f"),
            "flagged" if p["flagged"] else "",
        )
    print_table(con, table)


def method_sentence(data: dict[str, Any]) -> str:
    """Which method made the categories and why, in one sentence (the same pushes classified by the
    other method can land elsewhere: the demo uses the protocol's bands)."""
    objects = data.get("objects", [])
    refs = [o for o in objects if o.get("role") == "reference"]
    if data.get("method") == "reference":
        given: dict[str, int] = {}
        for o in refs:
            given[str(o.get("category_given"))] = given.get(str(o.get("category_given")), 0) + 1
        alone = [c for c, n in given.items() if n == 1]
        why = (
            f"Categories by reference objects: {len(refs)} of the objects carry a category "
            f"({', '.join(f'{c} {n}' for c, n in sorted(given.items()))}), and auto takes them when any push does"
        )
        if refs and len(refs) == len(objects):
            why += "; every object is a reference, so each category largely repeats its own label"
        if alone:
            why += f" ({', '.join(sorted(alone))}: one reference, in-sample)"
        return why + ". --method bands judges each object by the protocol's stiffness bands instead, as the demo does."
    return (
        "Categories by the protocol's stiffness bands: each object's median k_o against fixed limits "
        "(no push carries a category, or --method bands); labelled reference objects (a category "
        "column, or --reference) would classify by them instead."
    )


def category_text(o: dict[str, Any]) -> str:
    """An object's category with its evidence: ``hard``, ``hard (in-sample)``, ``uncertain (medium)``."""
    cat, evidence = o.get("category") or "", o.get("evidence") or ""
    if evidence == "uncertain":
        return f"uncertain ({cat})" if cat else "uncertain"
    if evidence == "in-sample":
        return f"{cat} (in-sample)"
    return cat or "—"


def _accuracy_table(accuracy: dict[str, Any], ideal: dict[str, Any] | None) -> Any:
    """The demo's accuracy on the validation trials, the ideal rig's RMSE beside it when measured."""
    from rich import box
    from rich.table import Table

    acc = Table(
        title="Accuracy on the validation trials, pressure-only (Figure 7)", title_justify="left", box=box.SIMPLE_HEAD
    )
    cols = ("quantity", "n", "RMSE", "max |error|", "R^2", "RMSE / range", "flagged") + (
        ("ideal rig RMSE",) if ideal else ()
    )
    for col in cols:
        acc.add_column(col, justify="left" if col == "quantity" else "right")
    for q, m in accuracy.items():
        row = [
            f"{q} ({m['unit']})",
            str(m["n"]),
            cell(m["rmse"], ".3g"),
            cell(m["max_abs"], ".3g"),
            cell(m["r2"], ".4f"),
            cell(m["pct_range"], ".2f") + " %",
            str(m["n_flagged"]),
        ]
        if ideal:
            row.append(cell(ideal[q]["rmse"], ".3g") if q in ideal else "—")
        acc.add_row(*row)
    return acc


def print_demo(res: Any) -> None:
    """The demo's summary as tables (rich), units on every number."""
    from rich import box
    from rich.table import Table

    con = report_console(markup=True)
    tr = res.trials
    con.print(
        f"[bold]labcli demo[/bold] on the simulated rig (seed {res.seed}): "
        f"{tr['fit'] + tr['validation']} force trials ({tr['fit']} fit, {tr['validation']} validation), "
        f"{tr['pushes']} pushes, {res.timings_s['total']:.1f} s.",
        soft_wrap=True,
    )

    coef = Table(title="Eqs. 34-37 fitted vs paper (3.3)", title_justify="left", box=box.SIMPLE_HEAD)
    for col, just in (("coefficient", "left"), ("fitted", "right"), ("std. error", "right"), ("paper", "right")):
        coef.add_column(col, justify="left" if just == "left" else "right")
    for c in res.coefficients:
        coef.add_row(c["name"], f"{c['value']:.4g}", f"{c['standard_error']:.2g}", cell(c["paper"], ".4g"))
    print_table(con, coef)
    con.print(
        "Units: MPa, N, m, rad. " + " ".join(res.notes) + " The simulated rig's actuators "
        "differ from the paper's, so its coefficients differ too; the accuracy is what carries over.",
        soft_wrap=True,
    )

    ideal = res.accuracy_ideal
    print_table(con, _accuracy_table(res.accuracy, ideal))
    if ideal:
        con.print(
            "The default rig, at the literature's levels, has sleeve, contact and pulley friction, chamber "
            "leaks, thermal relaxation, potentiometer backlash, scale and linearity errors, the pressure "
            "sensors' repeatability and drift, and link weight; the ideal rig (the same seed with ideal=1) "
            "has none, so the two RMSE columns show what they cost.",
            soft_wrap=True,
        )
    for protocol, forms in getattr(res, "forms", {}).items():
        print_forms(forms, f"protocol {protocol}")

    obj = Table(
        title=f"Object stiffness (Section 4, Figure 9); categories by the {res.classify_method} method, "
        "true values from the simulated objects",
        title_justify="left",
        box=box.SIMPLE_HEAD,
    )
    for col in (
        "object",
        "pushes used",
        "k mean (N/m)",
        "k sd (N/m)",
        "true k (N/m)",
        "category",
        "confidence",
        "true category",
    ):
        obj.add_column(
            col, justify="left" if col in ("object", "category", "true category") else "right", no_wrap=col == "object"
        )
    for o in res.objects:
        obj.add_row(
            o["object"],
            f"{o['n_used']}/{o['n']}",
            cell(o["k_mean_N_per_m"], ".0f"),
            cell(o["k_sd_N_per_m"], ".0f"),
            cell(o.get("true_k_N_per_m"), ".0f"),
            category_text(o),
            cell(o["confidence"], ".2f"),
            o["category_given"] or "—",
        )
    print_table(con, obj)
    if res.classify_method == "bands":
        con.print("Stiffness bands come from the push protocol (protocols/takuma2014-stiffness.toml).", soft_wrap=True)
    con.print("Files:", soft_wrap=True)
    for path in res.files.values():
        con.print(f"  {path}", soft_wrap=True, markup=False)
