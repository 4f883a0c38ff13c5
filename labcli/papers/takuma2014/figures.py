"""The paper's figures, drawn from labcli results (one section per figure): Figure 7, the
accuracy of the contact information, and Figure 9, the stiffness of the pushed objects.

Drawn headless through :mod:`labcli.core.figures`; the file format follows the extension:
``.png`` (200 dpi), ``.pdf`` or ``.svg``.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

from ...core.figures import caption, check_path, fmt, new_figure, save

# --------------------------------------------------------------------------------------
# Figure 7 (Takuma et al. 2014): accuracy of contact information on the validation trials.
# (a) theta1, (b) theta2 in degrees, (c) Fx, (d) Fy in newtons; observed on x, calculated on
# y, the diagonal where they agree.
# --------------------------------------------------------------------------------------

FIGURE7_PANELS = (
    ("theta1", "(a) angle $\\theta_1$", "deg"),
    ("theta2", "(b) angle $\\theta_2$", "deg"),
    ("Fx", "(c) force $F_x$", "N"),
    ("Fy", "(d) force $F_y$", "N"),
)
FIGURE7_SYMBOLS = {"theta1": "\\theta_1", "theta2": "\\theta_2", "Fx": "F_x", "Fy": "F_y"}


def figure7_title(
    evaluation: dict[str, Any], run: str | None = None, protocol: str | None = None, form: str | None = None
) -> str:
    """Figure 7's title: what it shows, the run, its protocol and the model form that made the estimates."""
    mode = evaluation.get("mode", "pressure-only")
    how = "forces from the calculated angles" if mode == "pressure-only" else "forces from the measured angles"
    about = [f"run {Path(str(run)).name}" if run else "", f"protocol {protocol}" if protocol else ""]
    about.append({"posture": "posture form", "paper": "the paper's Eqs. 34-37"}.get(str(form), str(form or "")))
    named = ", ".join(a for a in about if a)
    return f"Figure 7: validation trials, {how}" + (f"\n{named}" if named else "")


def figure7_panel(evaluation: dict[str, Any], q: str) -> dict[str, Any]:
    """One panel's data: the reported trials with their 95 % error bars, the flagged ones where their
    estimates lie (the frame holds every finite point; none is clipped), the frame, and a note when
    no trial is reported (on a straight arm Fy: the force along the arm makes no torque)."""
    import numpy as np

    obs = np.asarray(evaluation["observed"][q], dtype=float)
    calc = np.asarray(evaluation["calculated"][q], dtype=float)
    flag_ok = np.asarray(evaluation["ok"][q], dtype=bool)
    ok = flag_ok & np.isfinite(obs) & np.isfinite(calc)
    bad = ~flag_ok & np.isfinite(obs) & np.isfinite(calc)
    se = evaluation.get("se")
    err = 1.96 * np.asarray(se[q], dtype=float)[ok] if se is not None else None
    if err is not None:
        err = np.where(np.isfinite(err), err, 0.0)
    ends = [obs[ok | bad], calc[ok | bad]]
    if err is not None:
        ends += [calc[ok] - err, calc[ok] + err]
    shown = np.concatenate(ends) if ends else np.empty(0)
    lo, hi = (float(shown.min()), float(shown.max())) if shown.size else (-1.0, 1.0)
    pad = 0.08 * (hi - lo) if hi > lo else max(abs(hi), 1.0) * 0.1
    m = evaluation["metrics"][q]
    note = ""
    if not m.get("n") and m.get("n_flagged"):
        note = "none reported: every trial's standard error\nis over the protocol's limit"
        if q == "Fy":
            note += "\n(a straight arm: a force along it\nmakes no torque)"
    return {
        "observed": obs[ok],
        "calculated": calc[ok],
        "error_95": err,
        "flagged_observed": obs[bad],
        "flagged_calculated": calc[bad],
        "limits": (lo - pad, hi + pad),
        "note": note,
        "no_estimate": int((~flag_ok & np.isfinite(obs) & ~np.isfinite(calc)).sum()),
    }


def _figure7_points(ax: Any, panel: dict[str, Any]) -> bool:
    """One panel's validation trials with their 95 % intervals, and the flagged ones; whether any were."""
    if panel["error_95"] is not None and len(panel["observed"]):
        ax.errorbar(
            panel["observed"],
            panel["calculated"],
            yerr=panel["error_95"],
            fmt="none",
            ecolor="tab:blue",
            elinewidth=0.7,
            alpha=0.6,
            zorder=2,
            label="95 % interval",
        )
    ax.scatter(
        panel["observed"],
        panel["calculated"],
        s=26,
        marker="o",
        facecolor="tab:blue",
        edgecolor="navy",
        lw=0.6,
        zorder=3,
        label="validation trial",
    )
    flagged = len(panel["flagged_observed"]) > 0
    if flagged:
        ax.scatter(
            panel["flagged_observed"],
            panel["flagged_calculated"],
            s=40,
            marker="^",
            facecolor="none",
            edgecolor="tab:red",
            lw=1.2,
            zorder=4,
            label="flagged (not in metrics)",
        )
    return flagged


def _figure7_metrics(m: dict[str, Any], panel: dict[str, Any], unit: str) -> str:
    """The box of one Figure 7 panel: RMSE, max |err|, bias, R^2, n, and what was left out."""
    text = (
        f"RMSE {fmt(m.get('rmse'))} {unit}\n"
        f"max |err| {fmt(m.get('max_abs'))} {unit}\n"
        f"bias {fmt(m.get('bias'), 2)} {unit}\n"
        f"$R^2$ {'—' if m.get('r2') is None else format(m['r2'], '.4f')}   n = {m.get('n', 0)}"
    )
    if m.get("n_flagged"):
        text += f"\nflagged {m['n_flagged']}"
    if panel["no_estimate"]:
        text += f" ({panel['no_estimate']} without an estimate, not drawn)"
    if panel["note"]:
        text += "\n" + panel["note"]
    return text


def figure7(
    evaluation: dict[str, Any],
    path: str | Path,
    *,
    title: str | None = None,
    run: str | None = None,
    protocol: str | None = None,
    form: str | None = None,
    source: str = "",
) -> Path:
    """Draw the paper's Figure 7 from :func:`labcli.papers.takuma2014.models.metrics.evaluate` and save it.

    ``source``: what it was drawn from, the model included (:func:`labcli.core.figures.source_line`),
    written at its foot.  The title names the run, its protocol and the model form (:func:`figure7_title`); each reported
    trial carries its 95 % interval (1.96 standard errors) where the form gives them, and flagged
    trials (left out of the metrics) are open red markers where their estimates lie, inside the
    frame (:func:`figure7_panel`).
    """
    p = check_path(path)
    fig = new_figure(8.0, 8.6)
    axes = fig.subplots(2, 2)
    for ax, (q, label, unit) in zip(axes.flat, FIGURE7_PANELS, strict=False):
        panel = figure7_panel(evaluation, q)
        lo, hi = panel["limits"]
        ax.plot([lo, hi], [lo, hi], color="0.35", lw=1.0, zorder=1, label="observed = calculated")
        flagged = _figure7_points(ax, panel)
        ax.set_xlim(lo, hi)
        ax.set_ylim(lo, hi)
        ax.set_aspect("equal", adjustable="box")
        sym = FIGURE7_SYMBOLS[q]
        ax.set_xlabel(f"observed ${sym}$ ({unit})")
        ax.set_ylabel(f"calculated ${sym}$ ({unit})")
        ax.set_title(label, loc="left", fontsize=11)
        ax.grid(True, color="0.9", lw=0.6, zorder=0)
        ax.text(
            0.03,
            0.97,
            _figure7_metrics(evaluation["metrics"][q], panel, unit),
            transform=ax.transAxes,
            va="top",
            ha="left",
            fontsize=8,
            bbox=dict(boxstyle="round,pad=0.3", facecolor="white", edgecolor="0.7", alpha=0.9),
        )
        if flagged or panel["error_95"] is not None:
            ax.legend(loc="lower right", fontsize=7, frameon=True)
    fig.suptitle(title or figure7_title(evaluation, run, protocol, form), fontsize=11)
    fig.tight_layout(rect=(0, 0.02, 1, 1))
    caption(fig, source)
    save(fig, p)
    return p


# --------------------------------------------------------------------------------------
# Figure 9 (Takuma et al. 2014): acquired stiffness of the sample objects.  The objects on
# x, stiffness k_o on a log axis in N/m; every push a point (flagged pushes hollow), the
# mean +- standard deviation of the unflagged ones beside them, colour and marker by the
# category assigned, and the categories' bands or reference class means behind.
# --------------------------------------------------------------------------------------

FIGURE9_COLOURS = ("tab:green", "tab:orange", "tab:red", "tab:purple", "tab:brown", "tab:cyan")
FIGURE9_MARKERS = ("o", "s", "^", "D", "v", "P")


def _category_order(model: Any) -> list[str]:
    """Category names from soft to hard (bands by lower bound, classes by mean ln k)."""
    if model.method == "bands":
        return [n for n, _ in sorted(model.bands.items(), key=lambda kv: kv[1][0])]
    return [n for n, _ in sorted(model.classes.items(), key=lambda kv: kv[1]["mean_log_k"])]


def figure9(result: Any, path: str | Path, *, title: str | None = None, source: str = "") -> Path:
    """Draw the paper's Figure 9 from a classify result and save it.

    An object's tick names its known category as a reference object's (reference method) or
    as the category it was given (bands method, where it is compared with the bands, not
    used to place them).  ``source``: what it was drawn from, written at its foot.

    ``result`` is a :class:`labcli.papers.takuma2014.models.classify.ClassifyResult` (or a
    ``ClassifyReport``, whose ``result`` is used).
    """
    import numpy as np

    res = getattr(result, "result", result)
    p = check_path(path)
    pushes, objects, model = res.pushes, res.objects, res.model
    names = [str(o) for o in objects["object"]]
    order = _category_order(model)
    style = {
        c: (FIGURE9_COLOURS[i % len(FIGURE9_COLOURS)], FIGURE9_MARKERS[i % len(FIGURE9_MARKERS)])
        for i, c in enumerate(order)
    }
    fig = new_figure(max(6.5, 1.05 * len(names) + 2.5), 5.2)
    ax = fig.add_subplot(1, 1, 1)
    ax.set_yscale("log")
    k_all = np.asarray(pushes["k_N_per_m"], dtype=float)
    lo, hi = _stiffness_span(k_all, objects)
    y_lo, y_hi = lo / 2.2, hi * 2.2
    _draw_categories(ax, model, order, style, y_lo, y_hi)
    obj_col = pushes["object"].astype(str).to_numpy()
    flags = np.asarray(pushes["flag"], dtype=bool)
    used_labels: set[str] = set()
    ticks = []
    for i, row in enumerate(objects.to_dict("records")):
        sel = obj_col == str(row["object"])
        ticks.append(
            _draw_object(
                ax,
                i,
                row,
                k_all[sel],
                flags[sel],
                style,
                used_labels,
                (lo, y_lo, y_hi),
                many=len(names) > 8,
                method=model.method,
            )
        )
    ax.set_xticks(range(len(names)))
    ax.set_xticklabels(ticks, fontsize=8)
    ax.set_xlim(-0.6, len(names) - 0.4)
    ax.set_ylim(y_lo, y_hi)
    ax.set_ylabel("object stiffness $k_o$ (N/m)")
    ax.set_xlabel("sample object")
    ax.grid(True, which="major", axis="y", color="0.88", lw=0.6, zorder=0)
    ax.grid(True, which="minor", axis="y", color="0.94", lw=0.4, zorder=0)
    how = (
        "the protocol's stiffness bands (each object's given category under its name)"
        if model.method == "bands"
        else "nearest reference class in ln $k_o$"
    )
    handles, labels = ax.get_legend_handles_labels()
    rank = {c: i for i, c in enumerate(order)}
    pairs = sorted(zip(handles, labels, strict=False), key=lambda hl: rank.get(hl[1], len(rank)))
    ax.legend([h for h, _ in pairs], [lab for _, lab in pairs], loc="upper left", fontsize=8, frameon=True, ncol=2)
    fig.suptitle(title or f"Acquired stiffness of the sample objects (Figure 9)\ncategories by {how}", fontsize=11)
    fig.tight_layout(rect=(0, 0.025, 1, 1))
    caption(fig, source)
    save(fig, p)
    return p


def _stiffness_span(k_all: Any, objects: Any) -> tuple[float, float]:
    """The lowest and highest stiffness to show (N/m): the pushes' and the true values'."""
    import numpy as np

    shown = k_all[np.isfinite(k_all) & (k_all > 0)]
    lo, hi = (float(shown.min()), float(shown.max())) if shown.size else (100.0, 1e4)
    if "true_k_N_per_m" in objects.columns:
        true_k = np.asarray(objects["true_k_N_per_m"], dtype=float)
        ok_t = true_k[np.isfinite(true_k) & (true_k > 0)]
        if ok_t.size:
            lo, hi = min(lo, float(ok_t.min())), max(hi, float(ok_t.max()))
    return lo, hi


def _draw_categories(
    ax: Any, model: Any, order: list[str], style: dict[str, tuple[str, str]], y_lo: float, y_hi: float
) -> None:
    """What the categories mean, behind the data: the bands, or each reference class's mean ± sd."""
    if model.method == "bands":
        for cat in order:
            b_lo, b_hi = model.bands[cat]
            colour = style[cat][0]
            top = min(b_hi, y_hi)
            bottom = max(b_lo, y_lo)
            if top <= bottom:
                continue
            ax.axhspan(bottom, top, color=colour, alpha=0.07, lw=0, zorder=0)
            if math.isfinite(b_hi) and y_lo < b_hi < y_hi:
                ax.axhline(b_hi, color="0.6", lw=0.8, ls="--", zorder=1)
            ax.text(
                1.01,
                math.sqrt(bottom * top),
                f"{cat}\nband",
                transform=ax.get_yaxis_transform(),
                ha="left",
                va="center",
                fontsize=8,
                color=colour,
            )
        return
    sd = float(model.std_log_k)
    for cat in order:
        mu = model.classes[cat]["mean_log_k"]
        colour = style[cat][0]
        ax.axhspan(math.exp(mu - sd), math.exp(mu + sd), color=colour, alpha=0.08, lw=0, zorder=0)
        ax.axhline(math.exp(mu), color=colour, lw=0.9, ls=":", zorder=1)
        ax.text(
            1.01,
            math.exp(mu),
            f"{cat}\nreference\nmean ± sd",
            transform=ax.get_yaxis_transform(),
            ha="left",
            va="center",
            fontsize=8,
            color=colour,
        )


def _once(used: set[str], key: str, label: str) -> str | None:
    """``label`` the first time ``key`` is drawn (the legend names each kind of mark once)."""
    if key in used:
        return None
    used.add(key)
    return label


def _draw_interval(ax: Any, i: int, row: dict[str, Any], used: set[str]) -> None:
    """The object's 95 % interval of k from its standard error of ln k (the bands' confidence comes
    from it), beside the pushes: median x exp(+-1.96 se)."""
    se, median = row.get("log_k_se"), row.get("k_median_N_per_m")
    if se is None or median is None or not (math.isfinite(se) and math.isfinite(median) and median > 0):
        return
    lo, hi = median * math.exp(-1.96 * se), median * math.exp(1.96 * se)
    ax.plot([i + 0.42, i + 0.42], [lo, hi], color="0.15", lw=3.0, alpha=0.45, solid_capstyle="butt", zorder=4)
    ax.plot(
        [i + 0.42],
        [median],
        marker="o",
        ms=4,
        color="0.15",
        zorder=5,
        label=_once(used, "interval", "median, 95 % interval (standard error)"),
    )


def _draw_mean(ax: Any, i: int, row: dict[str, Any], used: set[str]) -> Any:
    """The object's mean stiffness ± sd beside its pushes; returns the mean (None when there is none)."""
    import numpy as np

    mean, sd = row.get("k_mean_N_per_m"), row.get("k_std_N_per_m")
    if mean is not None and np.isfinite(mean):
        err = sd if sd is not None and np.isfinite(sd) else 0.0
        lower = min(err, mean * 0.999)  # a log axis cannot show mean - sd <= 0
        ax.errorbar(
            [i + 0.3],
            [mean],
            yerr=[[lower], [err]],
            fmt="_",
            ms=14,
            mew=2.0,
            color="black",
            ecolor="black",
            elinewidth=1.3,
            capsize=4,
            zorder=4,
            label=_once(used, "mean", "mean ± sd"),
        )
    return mean


def _object_tick(name: str, row: dict[str, Any], n: int, *, many: bool, method: str) -> str:
    """An object's tick label: its name, the category it was given (as a reference's or not) and its pushes."""
    n_flag = int(row.get("n_flagged", 0))
    given = str(row.get("known_category") or "")
    if method == "reference":  # a reference object places its category's class
        ref_text = f"ref. {given}" if many else f"reference ({given})"  # room per tick
    else:  # bands: the category it was given, beside the one the bands gave it
        ref_text = f"given {given}" if many else f"given: {given}"
    return (
        f"{name}\n"
        + (f"{ref_text}\n" if given else "")
        + f"n = {int(row.get('n_pushes', n))}"
        + (f", {n_flag} flagged" if n_flag else "")
    )


def _draw_object(
    ax: Any,
    i: int,
    row: dict[str, Any],
    k: Any,
    fl: Any,
    style: dict[str, tuple[str, str]],
    used: set[str],
    span: tuple[float, float, float],
    *,
    many: bool,
    method: str = "reference",
) -> str:
    """One object's pushes, mean ± sd, true stiffness and category at x = ``i``; returns its tick label."""
    import numpy as np

    lo, y_lo, y_hi = span
    name = str(row["object"])
    cat = str(row.get("category") or "")
    colour, marker = style.get(cat, ("0.45", "X"))
    visible = np.isfinite(k) & (k > 0)
    # Deterministic spread so that repeated pushes do not hide each other.
    n = len(k)
    dx = (np.arange(n) - (n - 1) / 2) * (0.32 / max(n - 1, 1)) - 0.1
    good = visible & ~fl
    ax.scatter(
        i + dx[good],
        k[good],
        s=30,
        marker=marker,
        facecolor=colour,
        edgecolor="black",
        lw=0.5,
        zorder=3,
        label=_once(used, cat, cat) if cat else None,
    )
    bad = visible & fl
    if bad.any():
        ax.scatter(
            i + dx[bad],
            np.clip(k[bad], y_lo * 1.05, y_hi / 1.05),
            s=34,
            marker=marker,
            facecolor="none",
            edgecolor=colour,
            lw=1.2,
            zorder=3,
            label=_once(used, "flagged", "flagged push (not in mean)"),
        )
    mean = _draw_mean(ax, i, row, used)
    _draw_interval(ax, i, row, used)
    t = row.get("true_k_N_per_m")
    if t is not None and np.isfinite(t):
        ax.plot(
            [i - 0.32, i + 0.42],
            [t, t],
            color="0.25",
            lw=1.0,
            ls=(0, (4, 2)),
            zorder=2,
            label=_once(used, "true", "true k (simulated rig)"),
        )
    conf = row.get("confidence")
    evidence = str(row.get("evidence") or "")
    text = cat if cat else "no category"
    if cat and conf is not None and np.isfinite(conf):
        text += f"\n{100 * conf:.0f} %"
    if evidence:  # the report's evidence: "uncertain" (outside every class, or two close), "in-sample"
        text = f"uncertain\n({cat})" if evidence == "uncertain" and cat else text + f"\n{evidence}"
    top = np.nanmax(k[visible]) if visible.any() else (mean if mean is not None and np.isfinite(mean) else lo)
    ax.annotate(
        text,
        (i, min(top * 1.25, y_hi / 1.3)),
        ha="center",
        va="bottom",
        fontsize=8,
        color=colour if cat else "0.3",
        fontweight="bold",
    )
    return _object_tick(name, row, n, many=many, method=method)
