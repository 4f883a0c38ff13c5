"""The whole paper on the simulated rig, unattended: what ``labcli demo`` runs.

Each stage is the same library call the individual commands make, on the
same files a lab would have after an afternoon at the rig:

1. ``force.h5``: the 108 pulley-weight trials of the shipped plan (Section 3.2),
   acquired unattended over ``sim://`` in virtual time; the plan's 90/18 split.
2. ``force.model.json``: Eqs. 34-37 fitted on the 90 fit trials (Section 3.3).
3. ``fig7-accuracy.png``: the 18 validation trials, pressure-only (Figure 7).
4. ``pushes.h5``: six simulated objects (three PET bottles, two aluminium cans,
   one steel can) pushed ten times each (Section 4).
5. ``fig9-stiffness.png``: their stiffness and category (Figure 9).
6. ``trials.csv``, ``pushes.csv`` and ``summary.json``.

The result is plain data (:class:`DemoResult`), so a notebook can run the demo
and read its numbers without the command line.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ...core.demo import Progress, Stages, acquire_unattended, check_outdir, simulated_port
from ...core.modelfile import save_model
from .figures import figure7, figure9
from .models.classify import classify_file
from .models.inputs import load_trial_source
from .models.metrics import evaluate
from .models.takuma import TakumaModel
from .records import load_pushes
from .tables import write_push_csv, write_trial_csv

FORCE_PROTOCOL = "takuma2014"
PUSH_PROTOCOL = "takuma2014-stiffness"

# Stage names in order, for progress displays.
STAGES = ("acquire force trials", "fit", "validate", "acquire pushes", "classify", "export")

OUTPUTS = ("force.h5", "force.model.json", "fig7-accuracy.png", "pushes.h5",
           "fig9-stiffness.png", "trials.csv", "pushes.csv", "summary.json")


@dataclass
class DemoResult:
    outdir: Path
    seed: int
    files: dict[str, Path]
    timings_s: dict[str, float]
    trials: dict[str, int]
    coefficients: list[dict[str, Any]]
    accuracy: dict[str, dict[str, Any]]
    objects: list[dict[str, Any]]
    classify_method: str
    notes: list[str] = field(default_factory=list)

    def to_dict(self) -> dict[str, Any]:
        return {
            "outdir": str(self.outdir),
            "seed": self.seed,
            "files": {k: str(v) for k, v in self.files.items()},
            "timings_s": self.timings_s,
            "trials": self.trials,
            "coefficients": self.coefficients,
            "accuracy": self.accuracy,
            "objects": self.objects,
            "classify_method": self.classify_method,
            "notes": self.notes,
        }


def run_demo(outdir: str | Path, *, seed: int = 1, force: bool = False,
             progress: Progress | None = None) -> DemoResult:
    """Acquire, fit, validate, push and classify on the simulated rig; write everything to ``outdir``."""
    out = Path(outdir)
    check_outdir(out, OUTPUTS, force)
    out.mkdir(parents=True, exist_ok=True)
    files = {
        "force_run": out / "force.h5", "model": out / "force.model.json",
        "figure7": out / "fig7-accuracy.png", "push_run": out / "pushes.h5",
        "figure9": out / "fig9-stiffness.png", "trials_csv": out / "trials.csv",
        "pushes_csv": out / "pushes.csv", "summary": out / "summary.json",
    }
    stages = Stages(STAGES, progress)
    port = simulated_port(seed)
    with stages.run(0, "acquire_force"):
        acquire_unattended(files["force_run"], port, "force run", STAGES[0], progress, protocol=FORCE_PROTOCOL)
    with stages.run(1, "fit"):
        src = load_trial_source(files["force_run"])
        model = TakumaModel(geometry=src.protocol.settings.rig, protocol=src.protocol.name).fit(
            src.table, source=str(files["force_run"]))
        save_model(model.to_json(), files["model"], run=files["force_run"], name=model.protocol)
    with stages.run(2, "validate"):
        evaluation = evaluate(model, src.table, "pressure-only", source=str(files["force_run"]))
        figure7(evaluation, files["figure7"])
    with stages.run(3, "acquire_pushes"):
        # The same seed is the same rig (its actuators' variation): the model fitted above
        # describes this rig and no other.
        acquire_unattended(files["push_run"], port, "push run", STAGES[3], progress, protocol=PUSH_PROTOCOL)
    with stages.run(4, "classify"):
        # Categories from the protocol's stiffness bands: the pushed objects are labelled in
        # the run (their true class), and judging each against labels that include its own
        # would be circular for the lone steel can.
        report = classify_file(files["push_run"], model, method="bands")
        figure9(report, files["figure9"])
    with stages.run(5):
        write_trial_csv(src.table, files["trials_csv"])
        write_push_csv(load_pushes(files["push_run"]), files["pushes_csv"])
    result = _result(out, seed, files, stages.done(), src, model, evaluation, report)
    files["summary"].write_text(json.dumps(result.to_dict(), indent=2, allow_nan=False), encoding="utf-8")
    return result


def _result(out: Path, seed: int, files: dict[str, Path], timings: dict[str, float], src: Any, model: Any,
            evaluation: dict[str, Any], report: Any) -> DemoResult:
    """The demo's numbers as plain data: coefficients against the paper's, accuracy, objects."""
    paper = dict(src.protocol.settings.paper_coefficients or {})
    coefficients = [
        {"name": name, "value": float(value), "standard_error": float(model.standard_errors[name]),
         "paper": paper.get(name)}
        for name, value in model.coefficients.items()
    ]
    keep = ("n", "rmse", "mae", "max_abs", "bias", "r2", "unit", "n_flagged", "pct_range")
    accuracy = {q: {k: v for k, v in m.items() if k in keep} for q, m in evaluation["metrics"].items()}
    rep = report.to_dict()
    sets = src.table["set"].value_counts().to_dict()
    return DemoResult(
        outdir=out, seed=seed, files=files, timings_s=timings,
        trials={"fit": int(sets.get("fit", 0)), "validation": int(sets.get("validation", 0)),
                "pushes": len(rep["pushes"]), "pushes_flagged": sum(p["flagged"] for p in rep["pushes"])},
        coefficients=coefficients, accuracy=accuracy, objects=rep["objects"],
        classify_method=rep["method"],
        notes=["Coefficients use the plus-sign reading with the paper's beta_theta2_R2 = -2.972 as listed "
               "(Eq. 35's printed minus is a misprint; docs/errata.md)."],
    )
