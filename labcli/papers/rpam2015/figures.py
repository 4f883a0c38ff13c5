"""The rPAM joint paper's figures, drawn from :mod:`labcli.papers.rpam2015.models.rpam_fit` results.

* :func:`figure8`: the joint map as three contour plots side by side, (a) the model
  without the stretch correction, (b) the model with it, (c) the measured angles; Pa on x,
  Pb on y in kPa, angle contours labelled in degrees on one colour scale, blue to red.
  The model panels are drawn from the model on a fine grid; where the model has no balance
  below the toggle angle (the joint runs onto the toggle) the panel is hatched grey.
* :func:`figure_stretch`: the stretch test (Fig. 6): the empirical stretch force of every
  point against the stretch, the fitted cubic with its 95 % band and the protocol's
  default; beside it the residuals per payload.

matplotlib is imported inside each function and drawn through the Agg canvas directly (no
pyplot, no global backend switch), through :mod:`labcli.core.figures`.  The file format follows
the extension: ``.png`` (200 dpi), ``.pdf`` or ``.svg``.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

from ...core.figures import check_path, new_figure, save
from ...errors import ConfigError
from .models import rpam

_CMAP = "coolwarm"
_FINE = 81  # model grid points per axis


def _deg_label(v: float) -> str:
    return f"{v:.0f}°"


def _model_title(letter: str, what: str, s: dict[str, Any]) -> str:
    rmse = s.get("rmse_deg")
    if rmse is None or not math.isfinite(rmse):
        line = "no point to compare"
    else:
        line = f"RMSE {rmse:.1f}° over {s['n_compared']} points"
    total = s["n_compared"] + s["n_toggle"] + s.get("n_on_stop", 0)
    if s.get("n_toggle"):
        line += f"; toggles at {s['n_toggle']} of {total}"
    if s.get("n_on_stop"):
        line += f", on the stop at {s['n_on_stop']}"
    return f"({letter}) {what}\n{line}"


# --------------------------------------------------------------------------------------
# Figure 8: joint angle over (Pa, Pb), model without / with F_stretch and measured.
# --------------------------------------------------------------------------------------


def figure8(result: Any, path: str | Path, *, title: str | None = None, step_deg: float = 5.0) -> Path:
    """Draw Fig. 8 from a :class:`~labcli.papers.rpam2015.models.rpam_fit.JointMapResult`; returns the path.

    Filled contours every ``step_deg``, labelled lines every ``2 * step_deg``.
    """
    import numpy as np
    from matplotlib.patches import Patch

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
    fig = new_figure(15.5, 5.4)
    axes = fig.subplots(1, 3, sharex=True, sharey=True)
    fig.subplots_adjust(left=0.05, right=0.9, bottom=0.12, top=0.8, wspace=0.08)
    titles = {
        "without": _model_title("a", "model without $F_{stretch}$", result.summary["without"]),
        "with": _model_title("b", "model with $F_{stretch}$", result.summary["with"]),
    }
    filled = None
    for ax, name in zip(axes[:2], ("without", "with"), strict=False):
        filled = _draw_model(ax, PA, PB, models[name], scale)
        ax.set_title(titles[name], fontsize=10)
    _draw_measured(axes[2], result, scale)
    for ax in axes:
        ax.set_xlabel("$P_a$ (kPa)")
        ax.set_aspect("equal")
    axes[0].set_ylabel("$P_b$ (kPa)")
    cax = fig.add_axes([0.915, 0.12, 0.015, 0.68])
    cb = fig.colorbar(filled, cax=cax, ticks=scale.lines)
    cb.set_label("joint angle $\\alpha$ (deg)")
    fig.legend(
        handles=[
            Patch(
                facecolor="0.85",
                hatch="//",
                edgecolor="0.4",
                label=f"model runs onto the toggle (|$\\alpha$| → {result.toggle_deg:.1f}°)",
            )
        ],
        loc="lower center",
        ncol=1,
        frameon=False,
        fontsize=9,
    )
    fig.suptitle(
        title
        or "Joint angle over actuator pressures: model without and with the stretch "
        "correction against the measured map (Fig. 8)",
        fontsize=11,
    )
    fig.subplots_adjust(bottom=0.16)
    save(fig, out)
    return out


class _Scale:
    """Fig. 8's one colour scale: levels every ``step_deg`` up to the largest angle, lines every other."""

    def __init__(self, models: dict[str, Any], result: Any, step_deg: float) -> None:
        import numpy as np
        from matplotlib.colors import BoundaryNorm

        finite = [np.abs(v[np.isfinite(v)]) for v in (*models.values(), result.measured_deg)]
        top = max((float(v.max()) for v in finite if v.size), default=step_deg)
        # Angles near the toggle (and the stop) share the end colour rather than widening the scale.
        top = min(math.ceil(top / step_deg) * step_deg, max(math.floor(result.toggle_deg / step_deg), 1) * step_deg)
        levels = np.arange(-top, top + step_deg / 2, step_deg)
        if levels.size < 3:
            levels = np.array([-step_deg, 0.0, step_deg])
        every_other = np.mod(levels, 2 * step_deg)
        self.levels = levels
        self.lines = levels[np.isclose(every_other, 0) | np.isclose(every_other, 2 * step_deg)]
        self.norm = BoundaryNorm(levels, 256)
        self._eps = 1e-6 * step_deg

    def clip(self, z: Any) -> Any:
        import numpy as np

        return np.clip(z, self.levels[0] + self._eps, self.levels[-1] - self._eps)


def _draw_model(ax: Any, PA: Any, PB: Any, z: Any, scale: _Scale) -> Any:
    """One model panel: filled contours, labelled lines, the toggle region hatched; returns the fill."""
    import numpy as np

    kpa = 1e3
    filled = ax.contourf(PA * kpa, PB * kpa, scale.clip(z), levels=scale.levels, cmap=_CMAP, norm=scale.norm)
    cs = ax.contour(PA * kpa, PB * kpa, z, levels=scale.lines, colors="k", linewidths=0.7, linestyles="solid")
    ax.clabel(cs, fmt=_deg_label, fontsize=8, inline=True)
    nan = ~np.isfinite(z)
    if nan.any():
        ax.contourf(PA * kpa, PB * kpa, nan.astype(float), levels=[0.5, 1.5], colors=["0.85"], hatches=["//"])
        ax.contour(PA * kpa, PB * kpa, nan.astype(float), levels=[0.5], colors="0.4", linewidths=0.8)
    return filled


def _draw_measured(ax: Any, result: Any, scale: _Scale) -> None:
    """The measured panel: contours on the grid the points make, or on their triangulation."""
    import numpy as np
    from matplotlib.tri import Triangulation

    kpa = 1e3
    g = result.grid()
    if g is not None:
        gpa, gpb, cells = g
        GA, GB = np.meshgrid(gpa * kpa, gpb * kpa)
        ax.contourf(GA, GB, scale.clip(cells["measured"]), levels=scale.levels, cmap=_CMAP, norm=scale.norm)
        cs = ax.contour(GA, GB, cells["measured"], levels=scale.lines, colors="k", linewidths=0.7, linestyles="solid")
    else:
        tri = Triangulation(result.Pa_MPa * kpa, result.Pb_MPa * kpa)
        ax.tricontourf(tri, scale.clip(result.measured_deg), levels=scale.levels, cmap=_CMAP, norm=scale.norm)
        cs = ax.tricontour(tri, result.measured_deg, levels=scale.lines, colors="k", linewidths=0.7, linestyles="solid")
    ax.clabel(cs, fmt=_deg_label, fontsize=8, inline=True)
    ax.plot(result.Pa_MPa * kpa, result.Pb_MPa * kpa, ".", color="k", markersize=2, alpha=0.45)
    ax.set_title(f"(c) measured\n{result.Pa_MPa.size} points", fontsize=10)


# --------------------------------------------------------------------------------------
# Figure 6: stretch force against stretch, cubic fit with its band.
# --------------------------------------------------------------------------------------


def figure_stretch(fit: Any, path: str | Path, *, title: str | None = None) -> Path:
    """Draw the stretch test (Fig. 6) from a :class:`~labcli.papers.rpam2015.models.rpam_fit.StretchFit`."""
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

    fig = new_figure(12.5, 5.0)
    ax, ax2 = fig.subplots(1, 2, gridspec_kw={"width_ratios": [1.6, 1.0]})
    fig.subplots_adjust(left=0.07, right=0.98, bottom=0.12, top=0.84, wspace=0.25)
    ax.fill_between(x, band_lo, band_hi, color="tab:red", alpha=0.25, linewidth=0, label="95 % band of the fit")
    ax.plot(lam, F, "o", mfc="none", mec="tab:blue", markersize=5, label=f"stretch test ({m.n_points} points)")
    ax.plot(x, m.predict(x), "-", color="tab:red", linewidth=1.8, label="third-order polynomial fit")
    # The model holds the default's end value outside the range it was made for.
    d_lo, d_hi = fit.default_lambda_range
    default = np.polynomial.polynomial.polyval(np.clip(x, d_lo, d_hi), fit.default_coefficients_N)
    ax.plot(x, default, "--", color="0.4", linewidth=1.0, label="protocol's default correction")
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

    from matplotlib import colormaps

    cmap = colormaps["viridis"]
    masses = np.unique(mass_g)
    for k, mg in enumerate(masses):
        sel = mass_g == mg
        ax2.plot(lam[sel], res[sel], "o", markersize=4, color=cmap(k / max(len(masses) - 1, 1)), label=f"{mg:g} g")
    ax2.axhline(0.0, color="k", linewidth=0.8)
    ax2.set_xlabel("stretch $\\lambda$")
    ax2.set_ylabel("residual (N)")
    ax2.grid(True, alpha=0.3)
    ax2.legend(title="payload", fontsize=8, title_fontsize=8, loc="best")
    ax2.set_title("(b) residuals of the fit by payload", fontsize=10)
    fig.suptitle(title or f"Stretch test: $L_0$ = {fit.L0_m * 1e3:.0f} mm, $\\lambda$ {lo:.2f}–{hi:.2f}", fontsize=11)
    save(fig, out)
    return out
