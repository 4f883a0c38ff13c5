"""``labcli inspect``: what a run file holds, how complete it is, how the rig drifted."""

from __future__ import annotations

import json
from typing import Any

import click

from ..errors import LabcliError


def _ids(ids: list[int], limit: int = 10) -> str:
    shown = ", ".join(str(i) for i in ids[:limit])
    return shown + (f", ... ({len(ids) - limit} more)" if len(ids) > limit else "")


def format_summary(s: dict[str, Any]) -> str:
    """The summary as lines people read; units on every number."""
    rec = s["records"]
    lines = [
        f"{s['path']}: labcli run file, schema {s['schema_version']} (written by labcli {s['labcli_version']})",
        f"  kind        {s['kind']}, protocol {s['protocol']}" + (", imported from a table" if s["imported"] else ""),
    ]
    if s["device"] or s["port"]:
        lines.append(f"  rig         {s['device']} firmware {s['firmware']} on {s['port']}")
    lines.append(f"  operator    {s['operator'] or '(not given)'}, started {s['started']}")
    lines.append(f"  channels    {', '.join(s['channels'])}")
    rpam = s.get("rpam")
    if rpam is not None:
        # An rPAM run has no split and no McKibben baseline to drift: its grid instead.
        lines.extend(_rpam_lines(s, rpam))
        _settling_line(s, lines)
    else:
        planned = "" if s["planned"] is None else f", {s['planned']} planned"
        incomplete = f" ({_ids(s['incomplete_ids'])})" if s["incomplete"] else ""
        lines.append(f"  {rec:<11} {s['complete']} complete, {s['incomplete']} incomplete{incomplete}{planned}")
        _split_line(s, lines)
        _settling_line(s, lines)
        _drift_lines(s, lines)
    if s["models"]:
        lines.append(f"  models      {', '.join(s['models'])}")
    return "\n".join(lines)


def _range(span: list[float] | None, unit: str, fmt: str = ".1f") -> str:
    if span is None:
        return "none"
    # "+ 0.0" turns a -0.0 (a vented sensor's noise, rounded) into 0.0.
    lo, hi = (float(f"{v:{fmt}}") + 0.0 for v in span)
    return f"{lo:{fmt}} to {hi:{fmt}} {unit}"


def _rpam_lines(s: dict[str, Any], r: dict[str, Any]) -> list[str]:
    """Points of the run's experiment against its grid, and what the points cover."""
    incomplete = f" ({_ids(s['incomplete_ids'])})" if s["incomplete"] else ""
    of = "" if r["planned"] is None else f" of {r['planned']} planned"
    lines = [f"  experiment  {r['title']}",
             f"  points      {s['complete']}{of} complete, {s['incomplete']} incomplete{incomplete}"]
    if r["missing_ids"]:
        lines.append(f"  to record   {len(r['missing_ids'])} points ({_ids(r['missing_ids'])}); "
                     "labcli acquire --resume records them")
    lines.append(f"  pressures   P_A {_range(r['P_A_kPa'], 'kPa')}, P_B {_range(r['P_B_kPa'], 'kPa')} (measured)")
    if r["experiment"] == "stretch":
        payloads = ", ".join(f"{m:g}" for m in r["payloads_g"])
        lines.append(f"  payloads    {payloads + ' g' if payloads else 'none'}; "
                     f"stretch lambda {_range(r['lambda'], '(L / L0)', '.3f')}")
    else:
        lines.append(f"  deflection  alpha {_range(r['alpha_deg'], 'deg', '+.1f')} from the vented baseline")
    return lines


def _settling_line(s: dict[str, Any], lines: list[str]) -> None:
    rec = s["records"]
    st = s["settle"]
    if st and st["n"]:
        timeouts = f" ({_ids(st['timeout_ids'])})" if st["timeout_accepted"] else ""
        lines.append(f"  settling    median {st['median_s']:.2f} s, max {st['max_s']:.2f} s over {st['n']} {rec}; "
                     f"{st['timeout_accepted']} accepted on timeout{timeouts}")
    elif st and st["timeout_accepted"]:
        lines.append(f"  settling    {st['timeout_accepted']} accepted on timeout ({_ids(st['timeout_ids'])})")
    else:
        lines.append("  settling    no settle times recorded")


def _split_line(s: dict[str, Any], lines: list[str]) -> None:
    sp = s["split"]
    if sp is None:
        lines.append("  split       none (labcli split assigns one)")
    else:
        how = sp["strategy"] + ("" if sp["seed"] is None else f", seed {sp['seed']}")
        lines.append(f"  split       {sp['fit']} fit, {sp['validation']} validation, "
                     f"{sp['unassigned']} unassigned ({how})")


def _drift_lines(s: dict[str, Any], lines: list[str]) -> None:
    """How the baseline pressures of a force or push run moved over the records."""
    rec = s["records"]
    drift = s["baseline_drift"]
    if drift:
        lines.append(f"  baseline drift over {s['complete']} {rec} (recording order):")
        for name, d in drift.items():
            lines.append(f"    {name:<5} first {d['first_MPa']:.4f} MPa, last {d['last_MPa']:.4f} MPa, "
                         f"slope {d['slope_kPa_per_trial']:+.3f} kPa/{rec[:-1] if rec == 'trials' else 'push'}, "
                         f"max deviation {d['max_deviation_kPa']:.3f} kPa")
    else:
        lines.append("  baseline drift  needs at least 2 complete records")


@click.command("inspect")
@click.argument("run", type=click.Path(dir_okay=False))
@click.option("--json", "as_json", is_flag=True, help="Print the summary as JSON (SI units named in the keys).")
def inspect(run: str, as_json: bool) -> None:
    """Summarise RUN: metadata, complete/incomplete trials, split, baseline drift, settling.

    An rPAM run shows its experiment instead of split and drift: points complete
    against the protocol's grid, the pressures (kPa) and payloads (g) or
    deflections (deg) the points cover, and the settling times.

    \b
    Example:
        labcli inspect run.h5
        labcli inspect run.h5 --json | jq .baseline_drift
    """
    from ..core.store import RunFile

    try:
        with RunFile.open(run) as rf:
            summary = rf.summary()
    except LabcliError as e:
        raise click.ClickException(str(e)) from None
    if as_json:
        click.echo(json.dumps(summary, indent=2))
    else:
        click.echo(format_summary(summary))
