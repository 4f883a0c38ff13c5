"""Estimates for new data: a table of pressures (and rest postures), or a run file's records, and a model.

:func:`predict_file` is ``labcli predict``'s whole work: every row's theta1, theta2 (deg),
Fx, Fy (N), each with its standard error, and its flags, from the model applied exactly as
``labcli validate`` applies it (:class:`.sensing.TakumaSensing`, through
:func:`labcli.sensing.offline.predict_rows`).  The table needs the pressures only
(``P_L10..P_R20``, ``P_L1..P_R2`` in MPa) and takes the rest posture (``theta1_0_deg,
theta2_0_deg``) when it has one; the truth (``theta1_deg, theta2_deg, Fx_N, Fy_N``), ids and
any other columns are carried through, before the estimates.

A model with the sleeves' friction terms reads each row's motion into its baseline from the row
before it in trial order (row order without ids): that row's rest posture plus the deflections
the model reads from its pressures (``PostureModel.predict_table``'s pressure-only history), so
the rows of a run give what ``labcli validate`` gives them and what ``labcli sense`` gives the
same loads as they come.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ...core.cells import TableSpec
from ...core.files import RUN_FILE_SUFFIXES, atomic_write, check_output
from ...core.protocol import loads_protocol
from ...core.report import captures_warning, print_warnings
from ...core.tables import read_table
from ...core.words import count
from ...errors import ConfigError
from ...sensing.offline import predict_rows
from .captures import averaged, captures_of
from .models.posture import load_force_model, motion_into_baseline
from .options import PredictOptions
from .sensing import TakumaSensing
from .tables import BASELINE, LOADED, REST, REST_POSTURE

TRUTH = ("theta1_deg", "theta2_deg", "Fx_N", "Fy_N")
SUMMARY_FLAGS = ("unobservable", "out-of-range", "bad-input")  # the summary line's counts

# New data: the pressures are required; ids, the rest posture and the truth when known.
NEW_DATA = TableSpec(
    label="row",
    columns=(
        ("trial", "id", "omit-if-empty"),
        *((c, "pressure", "required") for c in BASELINE + LOADED),
        *REST_POSTURE,
        ("theta1_deg", "angle-or-empty", "omit-if-empty"),
        ("theta2_deg", "angle-or-empty", "omit-if-empty"),
        ("Fx_N", "force-or-empty", "omit-if-empty"),
        ("Fy_N", "force-or-empty", "omit-if-empty"),
    ),
    id_column="trial",
    pairs=(REST,),
)


@dataclass
class PredictResult:
    """The table of estimates (DataFrame), where it went, the model used, what to beware of."""

    table: Any
    output: Path | None
    model: str
    rows: int
    flagged: dict[str, int] = field(default_factory=dict)
    records: int = 0  # the captures the rows average (a run of several captures a load), else 0
    warnings: list[str] = field(default_factory=list)

    def to_dict(self) -> dict[str, Any]:
        return {
            "output": str(self.output) if self.output else None,
            "model": self.model,
            "rows": self.rows,
            "flagged": dict(self.flagged),
        }


def read_rows(path: Path) -> Any:
    """The rows of a run file (its trials or pushes) or of a CSV table of new data (DataFrame)."""
    return _read(path)[0]


def _read(path: Path) -> tuple[Any, tuple[str, Any] | None]:
    """The rows of ``path`` and, for a run file, its kind and embedded protocol (None: a run without
    one, imported from a table), from one opening of the file and one reading of the protocol."""
    if not path.exists():
        raise ConfigError(f"{path} does not exist; pass a table (.csv) of pressures or a run file (.h5).")
    if path.suffix.lower() not in RUN_FILE_SUFFIXES:
        return read_table(path, NEW_DATA), None
    from ...core.store import RunFile
    from .records import RECORD_TYPES

    with RunFile.open(path) as run:
        kind = run.kind
        if kind not in ("force", "push"):
            raise ConfigError(
                f"{path} is a run of kind '{kind}'; predict reads the trials or pushes of a McKibben run."
            )
        text, table = run.protocol_text, run.records.table(RECORD_TYPES[kind])
    protocol = loads_protocol(text, source=f"{path} (embedded protocol)") if text.strip() else None
    if kind == "push":
        return table, (kind, protocol)
    # One row per load of a run of several captures a load, as fit and validate read it (.captures);
    # the rows say how many captures each averages, for the model's intervals' warning.
    captures = captures_of(protocol) if protocol is not None else 1
    rows = averaged(table, captures)
    rows.attrs["captures_per_load"] = captures
    return rows, (kind, protocol)


def estimate_table(rows: Any, model: TakumaSensing) -> Any:
    """The rows with each one's estimates beside them (module docstring)."""
    import pandas as pd

    P0 = np.column_stack([np.asarray(rows[c], dtype=float) for c in BASELINE])
    P = np.column_stack([np.asarray(rows[c], dtype=float) for c in LOADED])
    if all(c in rows.columns for c in REST):
        rest = np.radians(np.column_stack([np.asarray(rows[c], dtype=float) for c in REST]))
        rest = np.where(np.isfinite(rest), rest, 0.0)  # an empty rest posture: the arm at (0, 0), as validate reads it
    else:
        rest = np.zeros((len(rows), 2))
    moved = None
    if model.uses_history:
        trial = np.asarray(rows["trial"], dtype=float) if "trial" in rows.columns else np.arange(len(rows), dtype=float)
        trial = np.where(np.isfinite(trial), trial, np.arange(len(rows)))
        moved = motion_into_baseline(trial, rest, model.deflections(P0, P))
    est = predict_rows(model, P0, P, rest, motion_in=moved)
    rows = rows.reset_index(drop=True)
    empty = [c for c in TRUTH if c in rows.columns and not np.isfinite(np.asarray(rows[c], dtype=float)).any()]
    carried = rows.drop(columns=empty).rename(columns={c: f"{c}_true" for c in TRUTH if c in rows.columns})
    return pd.concat([carried, pd.DataFrame(est.columns())], axis=1)


def count_flags(flags: Any) -> dict[str, int]:
    """How many rows' flags name each of :data:`SUMMARY_FLAGS` (``unobservable`` also counts
    ``unobservable:Fy``), the ones named at all in that order; a missing value names none.

    ``flags`` is the estimates' column of ``;``-joined flags; where the table carried a column of
    that name too, the estimates' is the last.  Counted over the column's few distinct values,
    each weighted by its rows: a row at a time took seconds at 10^6 rows."""
    import pandas as pd

    if isinstance(flags, pd.DataFrame):
        flags = flags.iloc[:, -1]
    counts = pd.Series(flags).value_counts(dropna=True)
    named = {f: sum(int(n) for v, n in counts.items() if f in v) for f in SUMMARY_FLAGS}
    return {f: n for f, n in named.items() if n}


def predict_file(
    table: Path, options: PredictOptions | None = None, *, model_path: Path, output: Path | None = None
) -> PredictResult:
    """Estimates for every row of ``table`` (a CSV of new data, or a run file) with the model file
    ``model_path``; written as CSV to ``output`` when given."""
    if output is not None:
        check_output(output, inputs=(table, model_path), what="the estimates to ")
    margin = (options or PredictOptions()).range_margin
    model = TakumaSensing(load_force_model(model_path), margin=margin)
    rows, run = _read(Path(table))
    records = int(rows.attrs.get("records", 0))  # set by captures.averaged, for the sentence
    captured = int(rows.attrs.get("captures_per_load", 1))  # a table's rows are taken as they are
    if run is not None:
        _check_rig(model, run, table, model_path)
    fitted = getattr(model.model, "captures_per_load", 1)
    warning = captures_warning(f"the model file {model_path}", fitted, f"the rows of {table}", captured)
    out = estimate_table(rows, model)
    flagged = count_flags(out["flags"])
    if output is not None:
        atomic_write(output, out.to_csv(index=False, float_format="%.10g").encode("utf-8"), what="the estimates to ")
    return PredictResult(out, output, str(model_path), len(out), flagged, records, [warning] if warning else [])


def _check_rig(model: TakumaSensing, run: tuple[str, Any], path: Path, model_path: Path) -> None:
    """A run (its kind and embedded protocol, from :func:`_read`) of another protocol or rig than the
    model's is refused, as validate and classify refuse it."""
    from .models.classify import check_force_model

    kind, protocol = run
    if protocol is None:
        return  # a run without its protocol (imported from a table): nothing to compare
    name = f"the model file {model_path}"
    if kind == "force":
        model.model.check_compatible(protocol.name, protocol.settings.rig, model_name=name, run_name=str(path))
    else:
        check_force_model(model.model, protocol, model_name=name, run_name=str(path))


def show_predict(result: PredictResult, *, as_json: bool = False) -> None:
    """One line: how many rows, where they went, how many are flagged."""
    import json

    print_warnings(result.warnings)
    if as_json:
        print(json.dumps(result.to_dict(), indent=2))
        return
    where = f" to {result.output}" if result.output else ""
    flags = ", ".join(f"{n} {f}" for f, n in result.flagged.items())
    what = (
        f"{count(result.rows, 'row')}"
        if not result.records
        else f"{count(result.rows, 'load')} (the means of {count(result.records, 'capture')})"
    )
    print(f"Estimated {what} with {result.model}{where}" + (f" ({flags})." if flags else "."))
