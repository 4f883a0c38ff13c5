"""``labcli fit`` and ``labcli validate`` on rPAM runs (the rPAM joint paper, Figs. 6 and 8).

The commands dispatch on the run file's kind: a stretch-test run (``rpam-stretch``) is
fitted here (the cubic ``F_stretch(lambda)`` of Eq. 7 with its uncertainty), a joint-map
run (``rpam-joint``) is compared here with the model without and with that correction;
every other run goes on to the McKibben path unchanged.

Each function parses nothing and prints through ``rich``; it raises
:class:`~labcli.errors.LabcliError` with one sentence for anything a person can fix.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

from ...errors import ConfigError, ModelError
from .protocol import stored_protocol

RUN_SUFFIXES = (".h5", ".hdf5")


def rpam_run_kind(path: str | Path) -> str | None:
    """``rpam-stretch`` / ``rpam-joint`` for an rPAM run file; None for anything else.

    Unreadable or missing files give None too: the McKibben path reports them in its words.
    """
    from ...errors import LabcliError

    p = Path(path)
    if p.suffix.lower() not in RUN_SUFFIXES or not p.is_file():
        return None
    from ...core.store import RunFile

    try:
        with RunFile.open(p) as run:
            kind = run.kind
    except LabcliError:
        return None
    return kind if kind.startswith("rpam") else None


def _read_run(path: Path, protocol: str | None,
              overrides: tuple[str, ...] = ()) -> tuple[str, Any, dict[str, Any], str, str]:
    """(kind, point table, raw protocol TOML, protocol name, where) of an rPAM run.

    ``overrides`` (``--set key=value``) change the run's stored protocol for this analysis only;
    ``where`` names the protocol in messages, with the overrides when there are any.
    """
    from ...core.store import RunFile

    with RunFile.open(path) as run:
        kind = run.kind
        name = str(run.attrs.get("protocol", ""))
        text = run.protocol_text
        table = run.table()
    if protocol is not None and protocol != name:
        raise ConfigError(f"{path} was recorded with protocol '{name}'; --protocol applies to "
                          "trial CSV files only, so leave it out for a run file.")
    raw = stored_protocol(text, path)
    where = f"{path} (protocol)"
    if overrides:
        from .models import rpam

        raw = rpam.apply_overrides(raw, overrides)
        where += f" with --set {' '.join(overrides)}"
    return kind, table, raw, name, where


def _console() -> Any:
    from rich.console import Console

    con = Console(highlight=False, markup=False)
    if not con.is_terminal:
        con.width = max(con.width, 110)  # a pipe or a log file: never truncate numbers
    return con


# --------------------------------------------------------------------------- fit


def fit_stretch_run(run: Path, *, output: Path | None = None, protocol: str | None = None,
                    plot: Path | None = None, overrides: tuple[str, ...] = ()) -> tuple[Any, Path, str]:
    """Fit the stretch correction to a stretch-test run; write and record the fit.

    Returns ``(StretchFit, model path, model name in the run)``.
    """
    from ...commands.fit import _write_model, default_model_path
    from .models.rpam_fit import analyse_stretch
    from ...core.store import RunFile

    kind, table, raw, name, where = _read_run(run, protocol, overrides)
    if kind != "rpam-stretch":
        raise ConfigError(
            f"{run} is a joint-map run (kind {kind}); labcli fit fits the stretch correction to a stretch-test "
            "run (labcli acquire --experiment stretch), and labcli validate compares a joint map with the model."
        )
    fit = analyse_stretch(table, (where, raw))
    if plot is not None:
        from .figures import figure_stretch

        figure_stretch(fit, plot)
    out = output or default_model_path(run)
    text = fit.to_json()
    model_name = f"{name or 'rpam'}-stretch"
    with RunFile.open(run, "a") as rf:
        restore = _write_model(out, text)
        try:
            rf.record_model(model_name, text)
        except BaseException:
            restore()
            raise
    return fit, out, model_name


def print_stretch_fit(fit: Any, out: Path, run: Path, model_name: str, plot: Path | None) -> None:
    from rich import box
    from rich.table import Table

    m = fit.model
    con = _console()
    table = Table(title="Eq. 7 stretch correction F_stretch = c0 + c1 lambda + c2 lambda^2 + c3 lambda^3 (N)",
                  title_justify="left", box=box.SIMPLE_HEAD)
    for col in ("coefficient", "fitted (N)", "std. error (N)", "95% interval (N)", "protocol's default (N)"):
        table.add_column(col, justify="left" if col == "coefficient" else "right")
    for k, (c, se, (lo, hi), d) in enumerate(zip(m.coefficients_N, m.std_errors_N, m.ci95_N,
                                                   fit.default_coefficients_N)):
        table.add_row(f"c{k}", f"{c:+.4f}", f"{se:.4f}", f"[{lo:+.4f}, {hi:+.4f}]", f"{d:+.4g}")
    con.print(table)
    con.print(f"  {m.n_points} points ({m.dof} degrees of freedom), lambda {m.lambda_range[0]:.3f} to "
              f"{m.lambda_range[1]:.3f}; R^2 {m.r2:.5f}, RMSE {m.rmse_N:.3f} N", soft_wrap=True)
    if fit.skipped_rows:
        con.print(f"  {len(fit.skipped_rows)} point(s) without a reading left out: "
                  + ", ".join(map(str, fit.skipped_rows)), soft_wrap=True)
    if plot is not None:
        con.print(f"Stretch-test figure (Fig. 6) written to {plot}.", soft_wrap=True)
    con.print(f"Model written to {out} and recorded in {run} under /models/{model_name}; compare a joint map "
              f"with it: labcli validate JOINT.h5 --model {out}", soft_wrap=True)


# --------------------------------------------------------------------------- validate


def load_stretch_model(path: Path) -> Any:
    """A stretch fit (``labcli fit`` on a stretch-test run) or a bare stretch correction, from JSON."""
    from .models.rpam_fit import StretchCorrection, StretchFit

    if not path.is_file():
        raise ConfigError(f"Model file {path} does not exist; fit the stretch test first with "
                          "labcli fit STRETCH.h5, which writes STRETCH.model.json.")
    try:
        text = path.read_text(encoding="utf-8")
        d = json.loads(text)
    except (OSError, UnicodeDecodeError, json.JSONDecodeError):
        raise ConfigError(f"Model file {path} is not a JSON stretch fit; give the file labcli fit wrote "
                          "for a stretch-test run.") from None
    kind = d.get("kind") if isinstance(d, dict) else None
    if kind == "rpam-stretch-fit":
        return StretchFit.from_dict(d)
    if kind == "rpam-stretch-correction":
        return StretchCorrection.from_dict(d)
    raise ConfigError(f"Model file {path} is not a stretch fit (kind {kind!r}); a joint map is compared with "
                      "the stretch correction labcli fit writes for a stretch-test run.")


def validate_joint_run(run: Path, *, model_path: Path | None = None, protocol: str | None = None,
                       plot: Path | None = None, overrides: tuple[str, ...] = ()) -> Any:
    """Compare a joint-map run with the model without and with the stretch correction (Fig. 8).

    The correction is the fit in ``model_path`` or, without one, the protocol's own
    ``[stretch_correction]``; a protocol whose correction is zero needs a fit.
    """
    from .models import rpam
    from .models.rpam_fit import analyse_joint_map

    kind, table, raw, _, where = _read_run(run, protocol, overrides)
    if kind != "rpam-joint":
        raise ConfigError(
            f"{run} is a stretch-test run (kind {kind}); labcli validate compares a joint-map run with the model: "
            f"fit this one with labcli fit {run} and pass the model it writes to labcli validate JOINT.h5 --model."
        )
    correction = None
    if model_path is not None:
        correction = load_stretch_model(model_path)
    else:
        act = rpam.actuator_from_protocol(raw, where)
        if not any(act.stretch_coefficients_N):
            raise ConfigError(
                f"{run}'s protocol has no stretch correction (its coefficients are all 0 N), so the model with "
                "and without it would agree; fit one to a stretch-test run with labcli fit STRETCH.h5 and pass "
                "it with --model STRETCH.model.json."
            )
    result = analyse_joint_map(table, (where, raw), correction)
    if plot is not None:
        from .figures import figure8

        figure8(result, plot)
    return result


_SOURCE = {"protocol": "the protocol's [stretch_correction] (no --model given)",
           "fit": "the stretch fit in {model}", "given": "the coefficients given"}


def print_joint_map(result: Any, run: Path, model_path: Path | None, plot: Path | None) -> None:
    from rich import box
    from rich.table import Table

    con = _console()
    table = Table(title=f"Joint map of {run.name} against the model (Fig. 8); errors are model - measured",
                  title_justify="left", box=box.SIMPLE_HEAD)
    for col in ("F_stretch", "points compared", "toggles", "RMSE (deg)", "max |error| (deg)", "at Pa, Pb (kPa)",
                "RMSE with toggles (deg)"):
        table.add_column(col, justify="left" if col == "F_stretch" else "right")
    for name in ("without", "with"):
        s = result.summary[name]
        at = s["max_error_at_kPa"]
        where = "—" if not all(_finite(v) for v in at) else f"{at[0]:.0f}, {at[1]:.0f}"
        table.add_row(name, str(s["n_compared"]), str(s["n_toggle"]), _f(s["rmse_deg"], ".2f"),
                      _f(s["max_abs_error_deg"], ".2f"), where, _f(s["rmse_all_deg"], ".2f"))
    con.print(table)
    c = ", ".join(f"{v:+.4g}" for v in result.actuator.stretch_coefficients_N)
    source = _SOURCE.get(result.correction_source, result.correction_source).format(model=model_path)
    con.print(f"  F_stretch coefficients c0..c3 = [{c}] N, from {source}.", soft_wrap=True)
    con.print(f"  'toggles': points where the model has no balance below the toggle angle "
              f"{result.toggle_deg:.1f} deg (the joint runs onto it); they stay out of the RMSE and count at "
              "the toggle angle in the last column.", soft_wrap=True)
    if plot is not None:
        con.print(f"Figure 8 written to {plot}.", soft_wrap=True)


def _finite(v: Any) -> bool:
    return isinstance(v, (int, float)) and math.isfinite(v)


def _f(v: Any, spec: str) -> str:
    return format(v, spec) if _finite(v) else "—"


def check_force_only_options(**given: bool) -> None:
    """Refuse options of the McKibben path given for an rPAM run (``name=was_given``)."""
    for name, was_given in given.items():
        if was_given:
            raise ModelError(f"--{name} applies to force runs (Eqs. 34-37), not to rPAM runs; leave it out.")


# --------------------------------------------------------------------------- the commands' rPAM branch


def _given(names: tuple[str, ...]) -> dict[str, bool]:
    """Which of the McKibben-only options the person typed (not their defaults)."""
    import click
    from click.core import ParameterSource

    ctx = click.get_current_context(silent=True)
    if ctx is None:
        return {}
    return {n.replace("_", "-"): ctx.get_parameter_source(n) == ParameterSource.COMMANDLINE for n in names}


def fit_command(run: Path, *, output: Path | None, protocol: str | None, plot: Path | None,
                as_json: bool, overrides: tuple[str, ...] = ()) -> None:
    """``labcli fit`` on an rPAM run: the stretch correction of a stretch-test run."""
    import click

    from ...errors import LabcliError

    try:
        check_force_only_options(**_given(("max_amplification",)))
        fit, out, name = fit_stretch_run(run, output=output, protocol=protocol, plot=plot, overrides=overrides)
    except LabcliError as e:
        raise click.ClickException(str(e)) from None
    if as_json:
        click.echo(json.dumps({"model_path": str(out), "recorded_in_run": True, "model_name": name,
                               "plot": str(plot) if plot else None, "fit": fit.to_dict()},
                              indent=2, allow_nan=False))
        return
    print_stretch_fit(fit, out, run, name, plot)


def validate_command(run: Path, *, model_path: Path | None, protocol: str | None, plot: Path | None,
                     as_json: bool, overrides: tuple[str, ...] = ()) -> None:
    """``labcli validate`` on an rPAM run: the joint map against the model (Fig. 8)."""
    import click

    from ...errors import LabcliError

    try:
        check_force_only_options(**_given(("mode",)))
        result = validate_joint_run(run, model_path=model_path, protocol=protocol, plot=plot,
                                    overrides=overrides)
    except LabcliError as e:
        raise click.ClickException(str(e)) from None
    if as_json:
        out = result.to_dict()
        out.update(run=str(run), model=str(model_path) if model_path else None, plot=str(plot) if plot else None)
        click.echo(json.dumps(out, indent=2, allow_nan=False))
        return
    print_joint_map(result, run, model_path, plot)
