"""The papers' figures, drawn from labcli results (one section per figure).

matplotlib is imported inside each function and drawn through the Agg canvas directly (no
pyplot, no global backend switch), so importing this module is cheap and works headless.
The file format follows the extension: ``.png`` (200 dpi), ``.pdf`` or ``.svg``.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

from .errors import ConfigError

FORMATS = (".png", ".pdf", ".svg")


def _check_path(path: str | Path, option: str = "The plot file") -> Path:
    p = Path(path)
    if p.suffix.lower() not in FORMATS:
        raise ConfigError(f"{option} {p} must end in .png, .pdf or .svg.")
    if not p.parent.exists():
        raise ConfigError(f"Cannot write {p}: the directory {p.parent} does not exist.")
    return p


def _new_figure(width_in: float, height_in: float) -> Any:
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(width_in, height_in))
    FigureCanvasAgg(fig)
    return fig


def _save(fig: Any, path: Path) -> None:
    try:
        fig.savefig(path, dpi=200 if path.suffix.lower() == ".png" else None)
    except OSError as e:
        raise ConfigError(f"Cannot write {path}: {e.strerror or e}.") from None


def _fmt(x: Any, digits: int = 3) -> str:
    if x is None or (isinstance(x, float) and not math.isfinite(x)):
        return "—"
    return f"{x:.{digits}g}"


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


def figure7(evaluation: dict[str, Any], path: str | Path, *, title: str | None = None) -> Path:
    """Draw the paper's Figure 7 from :func:`labcli.models.metrics.evaluate` and save it.

    Flagged trials (prediction not trustworthy, left out of the metrics) are drawn as open
    red markers at their stand-in values, pinned to the frame when they fall outside it.
    """
    import numpy as np

    p = _check_path(path)
    fig = _new_figure(8.0, 8.4)
    axes = fig.subplots(2, 2)
    mode = evaluation.get("mode", "pressure-only")
    how = ("forces from the calculated angles" if mode == "pressure-only"
           else "forces from the measured angles")
    for ax, (q, label, unit) in zip(axes.flat, FIGURE7_PANELS):
        obs = np.asarray(evaluation["observed"][q], dtype=float)
        calc = np.asarray(evaluation["calculated"][q], dtype=float)
        ok = np.asarray(evaluation["ok"][q], dtype=bool) & np.isfinite(obs) & np.isfinite(calc)
        bad = ~np.asarray(evaluation["ok"][q], dtype=bool) & np.isfinite(obs)
        shown = np.concatenate([obs[np.isfinite(obs)], calc[ok]])
        if shown.size:
            lo, hi = float(shown.min()), float(shown.max())
        else:
            lo, hi = -1.0, 1.0
        pad = 0.08 * (hi - lo) if hi > lo else max(abs(hi), 1.0) * 0.1
        lo, hi = lo - pad, hi + pad
        ax.plot([lo, hi], [lo, hi], color="0.35", lw=1.0, zorder=1, label="observed = calculated")
        ax.scatter(obs[ok], calc[ok], s=26, marker="o", facecolor="tab:blue", edgecolor="navy",
                   lw=0.6, zorder=3, label="validation trial")
        if bad.any():
            pinned = np.clip(np.nan_to_num(calc[bad], nan=lo), lo, hi)
            ax.scatter(obs[bad], pinned, s=40, marker="^", facecolor="none", edgecolor="tab:red",
                       lw=1.2, zorder=4, label="flagged (not in metrics)")
        ax.set_xlim(lo, hi)
        ax.set_ylim(lo, hi)
        ax.set_aspect("equal", adjustable="box")
        sym = FIGURE7_SYMBOLS[q]
        ax.set_xlabel(f"observed ${sym}$ [{unit}]")
        ax.set_ylabel(f"calculated ${sym}$ [{unit}]")
        ax.set_title(label, loc="left", fontsize=11)
        ax.grid(True, color="0.9", lw=0.6, zorder=0)
        m = evaluation["metrics"][q]
        text = (f"RMSE {_fmt(m.get('rmse'))} {unit}\n"
                f"max |err| {_fmt(m.get('max_abs'))} {unit}\n"
                f"bias {_fmt(m.get('bias'), 2)} {unit}\n"
                f"$R^2$ {'—' if m.get('r2') is None else format(m['r2'], '.4f')}   n = {m.get('n', 0)}")
        if m.get("n_flagged"):
            text += f"\nflagged {m['n_flagged']}"
        ax.text(0.03, 0.97, text, transform=ax.transAxes, va="top", ha="left", fontsize=8,
                bbox=dict(boxstyle="round,pad=0.3", facecolor="white", edgecolor="0.7", alpha=0.9))
        if bad.any():
            ax.legend(loc="lower right", fontsize=7, frameon=True)
    fig.suptitle(title or f"Accuracy of contact information (Figure 7): validation trials, {how}",
                 fontsize=11)
    fig.tight_layout()
    _save(fig, p)
    return p
