"""What every paper's figures share: the output check, the headless canvas, the save.

matplotlib is imported inside each function and drawn through the Agg canvas directly (no
pyplot, no global backend switch), so importing a figures module is cheap and works
headless.  The file format follows the extension: ``.png`` (200 dpi), ``.pdf`` or ``.svg``.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

from ..errors import ConfigError
from .files import atomic_write, check_output

FORMATS = (".png", ".pdf", ".svg")


def check_path(path: str | Path, option: str = "The plot file") -> Path:
    """The figure's path, once it ends in a known format and its folder exists (ConfigError otherwise)."""
    p = Path(path)
    if p.suffix.lower() not in FORMATS:
        raise ConfigError(f"{option} {p} must end in .png, .pdf or .svg.")
    if not p.parent.exists():
        raise ConfigError(f"Cannot write {p}: the directory {p.parent} does not exist.")
    check_output(p)
    return p


def new_figure(width_in: float, height_in: float) -> Any:
    """A matplotlib Figure on the Agg canvas (no pyplot, no global state)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(width_in, height_in))
    FigureCanvasAgg(fig)
    return fig


def save(fig: Any, path: Path) -> None:
    """Write the figure, whole, in the format of its extension (ConfigError naming the path if it cannot)."""
    import io

    buf = io.BytesIO()
    suffix = path.suffix.lower()
    fig.savefig(buf, format=suffix[1:], dpi=200 if suffix == ".png" else None)
    atomic_write(path, buf.getvalue())


def fmt(x: Any, digits: int = 3) -> str:
    """A number for a figure's annotation, or a dash where there is none."""
    if x is None or (isinstance(x, float) and not math.isfinite(x)):
        return "—"
    return f"{x:.{digits}g}"


def source_line(run: Any = None, protocol: Any = None, model: Any = None) -> str:
    """``run force.h5 · protocol takuma2014 · model force.model.json``: what a figure was drawn from."""
    parts = []
    for what, value in (("run", run), ("protocol", protocol), ("model", model)):
        if value is not None and str(value):
            text = str(value)
            # A path is named by its file name (a run inside: force.h5:/models/takuma2014).
            parts.append(f"{what} {Path(text).name if '/' in text and ':/' not in text else _short(text)}")
    return " · ".join(parts)


def _short(text: str) -> str:
    head, sep, tail = text.partition(":/")
    return f"{Path(head).name}{sep}{tail}" if sep else text


def caption(fig: Any, text: str) -> None:
    """Write ``text`` (a :func:`source_line`) small at the figure's bottom left, so a figure names its origin."""
    if text:
        fig.text(0.005, 0.004, text, ha="left", va="bottom", fontsize=7, color="0.35")
