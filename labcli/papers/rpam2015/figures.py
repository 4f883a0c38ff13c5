"""The rPAM joint paper's figures, drawn from :mod:`labcli.papers.rpam2015.models.rpam_fit` results.

* :func:`figure8`: the joint map, Pa on x and Pb on y in kPa: (a) the measured angle's
  contours and the model's (with and without the stretch correction, drawn on a fine grid)
  at the same levels on one axis, hatched where the model runs onto the toggle; (b) the
  residual map, model minus measured at every point, blue to red about zero.
* :func:`figure_stretch`: the stretch test (Fig. 6): the empirical stretch force of every
  point against the stretch, the fitted cubic with its 95 % band over the range it was
  fitted on (marked), and the protocol's default, dotted where it is held at its end value
  outside its own range; beside it the residuals per payload.

Each figure names what it was drawn from (run, protocol, model) at its foot.

matplotlib is imported inside each function and drawn through the Agg canvas directly (no
pyplot, no global backend switch), through :mod:`labcli.core.figures`.  The file format follows
the extension: ``.png`` (200 dpi), ``.pdf`` or ``.svg``.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

from ...core.figures import caption, check_path, new_figure, save
from ...errors import ConfigError
from .models import rpam

_CMAP = "coolwarm"
_FINE = 81  # model grid points per axis


def _deg_label(v: float) -> str:
    return f"{v:.0f}°"


# --------------------------------------------------------------------------------------
# Figure 8: joint angle over (Pa, Pb), model without / with F_stretch and measured.
# --------------------------------------------------------------------------------------


def _legend_handles(result: Any, toggles: bool) -> list[Any]:
    """Panel (a)'s legend: measured and model contours, and the hatch where the model toggles."""
    from matplotlib.artist import Artist
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch

    handles: list[Artist] = [
        Line2D([], [], color="k", lw=1.0, label=f"measured ({result.Pa_MPa.size} points, labelled)"),
        Line2D([], [], color="tab:red", lw=1.0, ls="dashed", label="model with $F_{stretch}$"),
        Line2D([], [], color="tab:blue", lw=0.8, ls="dotted", label="model without $F_{stretch}$"),
    ]
    if toggles:
        handles.append(
            Patch(
                facecolor="0.93",
                hatch="/",
                edgecolor="0.4",
                label=f"model runs onto the toggle ({result.toggle_deg:.1f}°)",
            )
        )
    return handles


def _residual_map(fig: Any, ax: Any, result: Any) -> None:
    """Panel (b) of Fig. 8: the corrected model minus the measured angle at every point."""
    import numpy as np
    from matplotlib.colors import TwoSlopeNorm

    kpa = 1e3
    # (b) the residual map at the measured points.
    resid = np.asarray(result.model_deg["with"], dtype=float) - np.asarray(result.measured_deg, dtype=float)
    ok = np.isfinite(resid)
    # The scale covers 95 % of the residuals: one point far off does not grey out the rest (arrows say so).
    top = max(float(np.percentile(np.abs(resid[ok]), 95)) if ok.any() else 1.0, 1e-3)
    dots = ax.scatter(
        result.Pa_MPa[ok] * kpa,
        result.Pb_MPa[ok] * kpa,
        c=resid[ok],
        cmap=_CMAP,
        norm=TwoSlopeNorm(0.0, -top, top),
        s=46,
        marker="s",
        edgecolors="0.3",
        linewidths=0.3,
    )
    if (~ok).any():
        ax.plot(result.Pa_MPa[~ok] * kpa, result.Pb_MPa[~ok] * kpa, "x", color="0.4", markersize=5, label="toggles")
        ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.12), fontsize=8, frameon=False)
    ax.set_title("(b) residual: model with $F_{stretch}$ minus measured", fontsize=10)
    cax = fig.add_axes([0.94, 0.2, 0.012, 0.64])
    cb = fig.colorbar(dots, cax=cax, extend="both" if ok.any() and np.abs(resid[ok]).max() > top else "neither")
    cb.set_label("model $-$ measured (deg)")


def figure8(
    result: Any, path: str | Path, *, title: str | None = None, step_deg: float = 5.0, source: str = ""
) -> Path:
    """Draw Fig. 8 from a :class:`~labcli.papers.rpam2015.models.rpam_fit.JointMapResult`; returns the path.

    (a) The measured angle's contours (solid, labelled) and the model's at the same levels on
    the same axes, with the stretch correction (dashed) and without (dotted), every
    ``step_deg``; where the corrected model runs onto the toggle it is hatched.  (b) The
    residual map: the corrected model minus the measured angle at every point, on a scale
    symmetric about zero.  ``source``: what it was drawn from, written at its foot.
    """
    import numpy as np

    out = check_path(path)
    if result.Pa_MPa.size < 3:
        raise ConfigError("Figure 8 needs a joint map of at least 3 points.")
    pa_lo, pa_hi = float(result.Pa_MPa.min()), float(result.Pa_MPa.max())
    pb_lo, pb_hi = float(result.Pb_MPa.min()), float(result.Pb_MPa.max())
    if not (pa_hi > pa_lo and pb_hi > pb_lo):
        raise ConfigError("Figure 8 needs a joint map that spans a range of both Pa and Pb.")
    PA, PB = np.meshgrid(np.linspace(pa_lo, pa_hi, _FINE), np.linspace(pb_lo, pb_hi, _FINE))  # rows: Pb
    models = {
        name: rpam.solve_equilibrium(PA, PB, result.geometry, result.actuator, stretch=stretch).alpha_deg
        for name, stretch in (("without", False), ("with", True))
    }
    scale = _Scale(models, result, step_deg)
    kpa = 1e3
    fig = new_figure(13.0, 6.0)
    ax, ax2 = fig.subplots(1, 2)
    fig.subplots_adjust(left=0.06, right=0.93, bottom=0.2, top=0.84, wspace=0.28)

    # (a) one axis: measured and model contours at the same levels.
    _draw_measured_lines(ax, result, scale)
    ax.contour(
        PA * kpa, PB * kpa, models["with"], levels=scale.levels, colors="tab:red", linewidths=1.0, linestyles="dashed"
    )
    ax.contour(
        PA * kpa,
        PB * kpa,
        models["without"],
        levels=scale.levels,
        colors="tab:blue",
        linewidths=0.8,
        linestyles="dotted",
    )
    nan = ~np.isfinite(models["with"])
    if nan.any():
        ax.contourf(PA * kpa, PB * kpa, nan.astype(float), levels=[0.5, 1.5], colors=["0.93"], hatches=["/"], zorder=0)
    ax.plot(result.Pa_MPa * kpa, result.Pb_MPa * kpa, ".", color="k", markersize=2, alpha=0.4)
    s_with, s_without = result.summary["with"], result.summary["without"]
    ax.set_title(
        f"(a) joint angle $\\alpha$, contours every {step_deg:g}°: measured against the model\n"
        f"{_rmse_text('with $F_{stretch}$', s_with)}; {_rmse_text('without', s_without)}",
        fontsize=10,
    )
    handles = _legend_handles(result, bool(nan.any()))
    ax.legend(handles=handles, loc="upper center", bbox_to_anchor=(0.5, -0.12), ncol=2, fontsize=8, frameon=False)

    _residual_map(fig, ax2, result)
    for a in (ax, ax2):
        a.set_xlabel("$P_a$ (kPa)")
        a.set_ylabel("$P_b$ (kPa)")
        a.set_aspect("equal")
        a.set_xlim(pa_lo * kpa, pa_hi * kpa)
        a.set_ylim(pb_lo * kpa, pb_hi * kpa)
    fig.suptitle(
        title
        or "Joint angle over actuator pressures: the model, with and without the stretch correction, "
        "against the measured map (Fig. 8)",
        fontsize=11,
    )
    caption(fig, source)
    save(fig, out)
    return out


def _rmse_text(what: str, s: dict[str, Any]) -> str:
    rmse = s.get("rmse_deg")
    if rmse is None or not math.isfinite(rmse):
        return f"{what}: no point to compare"
    return f"{what}: RMSE {rmse:.1f}° over {s['n_compared']} points"


class _Scale:
    """Fig. 8's contour levels: every ``step_deg`` up to the largest angle (short of the toggle), labels every other."""

    def __init__(self, models: dict[str, Any], result: Any, step_deg: float) -> None:
        import numpy as np

        finite = [np.abs(v[np.isfinite(v)]) for v in (*models.values(), result.measured_deg)]
        top = max((float(v.max()) for v in finite if v.size), default=step_deg)
        # Angles near the toggle (and the stop) share the last level rather than crowding the map.
        top = min(math.ceil(top / step_deg) * step_deg, max(math.floor(result.toggle_deg / step_deg), 1) * step_deg)
        levels = np.arange(-top, top + step_deg / 2, step_deg)
        if levels.size < 3:
            levels = np.array([-step_deg, 0.0, step_deg])
        every_other = np.mod(levels, 2 * step_deg)
        self.levels = levels
        self.lines = levels[np.isclose(every_other, 0) | np.isclose(every_other, 2 * step_deg)]


def _draw_measured_lines(ax: Any, result: Any, scale: _Scale) -> None:
    """The measured angle's contour lines, on the grid the points make or on their triangulation;
    labelled every other level, spaced so that labels do not overlap."""
    import numpy as np
    from matplotlib.tri import Triangulation

    kpa = 1e3
    g = result.grid()
    if g is not None:
        gpa, gpb, cells = g
        GA, GB = np.meshgrid(gpa * kpa, gpb * kpa)
        cs = ax.contour(GA, GB, cells["measured"], levels=scale.levels, colors="k", linewidths=1.0, linestyles="solid")
    else:
        tri = Triangulation(result.Pa_MPa * kpa, result.Pb_MPa * kpa)
        cs = ax.tricontour(
            tri, result.measured_deg, levels=scale.levels, colors="k", linewidths=1.0, linestyles="solid"
        )
    labelled = [lv for lv in cs.levels if np.any(np.isclose(lv, scale.lines))]
    ax.clabel(cs, labelled, fmt=_deg_label, fontsize=8, inline=True, inline_spacing=4)


# --------------------------------------------------------------------------------------
# Figure 6: stretch force against stretch, cubic fit with its band.
# --------------------------------------------------------------------------------------


def _residuals_by_payload(ax: Any, lam: Any, res: Any, mass_g: Any) -> None:
    """Panel (b) of the stretch test: the fit's residuals, one colour per payload."""
    import numpy as np
    from matplotlib import colormaps

    cmap = colormaps["viridis"]
    masses = np.unique(mass_g)
    for k, mg in enumerate(masses):
        sel = mass_g == mg
        ax.plot(lam[sel], res[sel], "o", markersize=4, color=cmap(k / max(len(masses) - 1, 1)), label=f"{mg:g} g")
    ax.axhline(0.0, color="k", linewidth=0.8)
    ax.set_xlabel("stretch $\\lambda$")
    ax.set_ylabel("residual (N)")
    ax.grid(True, alpha=0.3)
    ax.legend(title="payload", fontsize=8, title_fontsize=8, loc="best")
    ax.set_title("(b) residuals of the fit by payload", fontsize=10)


def figure_stretch(fit: Any, path: str | Path, *, title: str | None = None, source: str = "") -> Path:
    """Draw the stretch test (Fig. 6) from a :class:`~labcli.papers.rpam2015.models.rpam_fit.StretchFit`.

    ``source``: what it was drawn from (:func:`labcli.core.figures.source_line`), at its foot.
    """
    import numpy as np

    out = check_path(path)
    m = fit.model
    p = fit.points
    lam = np.asarray(p["lambda"], dtype=float)
    F = np.asarray(p["F_stretch_N"], dtype=float)
    res = np.asarray(p["residual_N"], dtype=float)
    mass_g = np.round(np.asarray(p["mass_kg"], dtype=float) * 1e3, 3)
    lo, hi = m.lambda_range
    x = np.linspace(lo, hi, 300)
    band_lo, band_hi = m.band(x)

    fig = new_figure(12.5, 5.2)
    ax, ax2 = fig.subplots(1, 2, gridspec_kw={"width_ratios": [1.6, 1.0]})
    fig.subplots_adjust(left=0.07, right=0.98, bottom=0.14, top=0.84, wspace=0.25)
    ax.axvspan(lo, hi, color="tab:red", alpha=0.04, lw=0, zorder=0)
    for edge in (lo, hi):
        ax.axvline(edge, color="tab:red", lw=0.8, ls=(0, (2, 2)), zorder=1)
    ax.fill_between(x, band_lo, band_hi, color="tab:red", alpha=0.25, linewidth=0, label="95 % band of the fit")
    ax.plot(lam, F, "o", mfc="none", mec="tab:blue", markersize=5, label=f"stretch test ({m.n_points} points)")
    ax.plot(
        x, m.predict(x), "-", color="tab:red", linewidth=1.8, label=f"cubic fit, fitted on $\\lambda$ {lo:.2f}–{hi:.2f}"
    )
    # The protocol's default holds its end value outside the range it was made for: said, and dotted there.
    d_lo, d_hi = fit.default_lambda_range
    default = np.polynomial.polynomial.polyval(np.clip(x, d_lo, d_hi), fit.default_coefficients_N)
    inside = (x >= d_lo) & (x <= d_hi)
    ax.plot(
        np.where(inside, x, np.nan),
        default,
        "--",
        color="0.4",
        linewidth=1.0,
        label=f"protocol's default, made for $\\lambda$ {d_lo:.2f}–{d_hi:.2f}",
    )
    if (~inside).any():
        ax.plot(
            np.where(inside, np.nan, x), default, ":", color="0.4", linewidth=1.2, label="default held at its end value"
        )
    ax.set_xlabel("stretch $\\lambda = L / L_0$")
    ax.set_ylabel("stretch force $F_{stretch}$ (N)")
    ax.grid(True, alpha=0.3)
    ax.legend(loc="upper left", fontsize=9)
    c, se = m.coefficients_N, m.std_errors_N
    text = "\n".join(f"$c_{k}$ = {c[k]:+.3f} ± {se[k]:.3f} N" for k in range(len(c)))
    text += f"\n$R^2$ = {m.r2:.4f}, RMSE = {m.rmse_N:.3f} N"
    ax.text(
        0.98,
        0.03,
        text,
        transform=ax.transAxes,
        ha="right",
        va="bottom",
        fontsize=9,
        bbox={"boxstyle": "round", "facecolor": "white", "alpha": 0.85, "edgecolor": "0.7"},
    )
    ax.set_title("(a) stretch force against stretch (Eq. 7, Fig. 6)", fontsize=10)
    _residuals_by_payload(ax2, lam, res, mass_g)
    fig.suptitle(title or f"Stretch test: $L_0$ = {fit.L0_m * 1e3:.0f} mm, $\\lambda$ {lo:.2f}–{hi:.2f}", fontsize=11)
    caption(fig, source)
    save(fig, out)
    return out
