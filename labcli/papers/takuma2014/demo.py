"""The whole paper on the simulated rig, unattended: what ``labcli demo`` runs.

Each stage is the same library call the individual commands make, on the
same files a lab would have after an afternoon at the rig:

1. ``force.h5``: the 108 pulley-weight trials of the shipped plan (Section 3.2),
   acquired unattended over ``sim://`` in virtual time; the plan's 90/18 split.
2. ``force.model.json``: the model ``labcli fit force.h5`` writes (the posture-aware form, the
   default) fitted on the 90 fit trials; the paper's Eqs. 34-37 fitted beside it
   (``force-paper.model.json``, ``labcli fit --form paper``'s) give Section 3.3's coefficients
   against the paper's.
3. ``fig7-accuracy.png``: the 18 validation trials, pressure-only (Figure 7), by that model.
   The same 108 trials on the ideal rig (``&ideal=1``, same seed: no friction, leak,
   heat, backlash or link weight), fitted and validated the same way, give the accuracy
   beside it: what the default rig's non-idealities cost (that run is not kept).
4. ``pushes.h5``: six simulated objects (three PET bottles, two aluminium cans,
   one steel can) pushed ten times each (Section 4).
5. ``fig9-stiffness.png``: their stiffness and category (Figure 9), by the same model, as a
   plain ``labcli classify pushes.h5 --model force.model.json --method bands`` gives them.
6. ``bent.h5``, ``bent.model.json``, ``fig7-bent.png``: the same trials on the arm resting
   bent (protocol takuma2014-bent, inside pair 0.40 / 0.20 MPa), the posture-aware form fitted
   and both forms validated on both protocols (``forms`` in the summary).
7. ``trials.csv``, ``pushes.csv`` and ``summary.json``.

The result is plain data (:class:`DemoResult`), so a notebook can run the demo
and read its numbers without the command line.
"""

from __future__ import annotations

import json
import tempfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ...core.demo import Progress, Stages, acquire_unattended, check_outdir, simulated_port
from ...core.figures import source_line
from ...core.modelfile import save_model
from .analyses import stamp_fitted
from .figures import figure7, figure9
from .models.classify import classify_file
from .models.inputs import load_trial_source
from .models.metrics import evaluate
from .models.posture import PostureModel
from .models.takuma import TakumaModel
from .records import load_pushes
from .sim.nonideal import REALISM_DEFAULT
from .tables import write_push_csv, write_trial_csv

FORCE_PROTOCOL = "takuma2014"
# The force and push runs re-pressurise (labcli.core.air): the chambers leak 0.2-2.6 kPa/min,
# and over the two runs (some 80 min of settles of five thermal time constants) a fast-leaking
# chamber loses half its air, moving the arm far from the operating point the model was fitted
# at; the steel can's 1.3 mm deformation is the first figure to go (k 1.66 of true on seed 3
# with the valves held shut, 0.88 with re-pressurising).
RUN_VALVES = "auto"
PUSH_PROTOCOL = "takuma2014-stiffness"
BENT_PROTOCOL = "takuma2014-bent"
# The regulators for the bent protocol (P_L1, P_R1, P_L2, P_R2, MPa), as protocols/takuma2014-bent.toml says.
BENT_SUPPLY = "0.15,0.15,0.45,0.15"

# Stage names in order, for progress displays.
STAGES = (
    "acquire force trials",
    "fit",
    "validate",
    "the same trials on the ideal rig",
    "acquire pushes",
    "classify",
    "bent arm",
    "export",
)
IDEAL = "&ideal=1"  # the sim:// option that turns every non-ideality of the rig off

OUTPUTS = (
    "force.h5",
    "force.model.json",
    "fig7-accuracy.png",
    "force-paper.model.json",
    "pushes.h5",
    "fig9-stiffness.png",
    "bent.h5",
    "bent.model.json",
    "fig7-bent.png",
    "trials.csv",
    "pushes.csv",
    "summary.json",
)


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
    accuracy_ideal: dict[str, dict[str, Any]] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)
    forms: dict[str, dict[str, Any]] = field(default_factory=dict)  # protocol -> form -> quantity -> metrics
    rig: dict[str, Any] = field(default_factory=dict)  # the simulated rig: its port and its realism

    def to_dict(self) -> dict[str, Any]:
        return {
            "outdir": str(self.outdir),
            "seed": self.seed,
            "files": {k: str(v) for k, v in self.files.items()},
            "timings_s": self.timings_s,
            "trials": self.trials,
            "coefficients": self.coefficients,
            "accuracy": self.accuracy,
            "accuracy_ideal_rig": self.accuracy_ideal,
            "objects": self.objects,
            "classify_method": self.classify_method,
            "notes": self.notes,
            "forms": self.forms,
            "rig": self.rig,
        }


def run_demo(outdir: str | Path, *, seed: int = 1, force: bool = False, progress: Progress | None = None) -> DemoResult:
    """Acquire, fit, validate, push and classify on the simulated rig; write everything to ``outdir``."""
    out = Path(outdir)
    check_outdir(out, OUTPUTS, force)
    out.mkdir(parents=True, exist_ok=True)
    files = {
        "force_run": out / "force.h5",
        "model": out / "force.model.json",
        "paper_model": out / "force-paper.model.json",
        "figure7": out / "fig7-accuracy.png",
        "push_run": out / "pushes.h5",
        "figure9": out / "fig9-stiffness.png",
        "trials_csv": out / "trials.csv",
        "pushes_csv": out / "pushes.csv",
        "summary": out / "summary.json",
        "bent_run": out / "bent.h5",
        "bent_model": out / "bent.model.json",
        "figure7_bent": out / "fig7-bent.png",
    }
    stages = Stages(STAGES, progress)
    port = simulated_port(seed)
    with stages.run(0, "acquire_force"):
        acquire_unattended(
            files["force_run"], port, "force run", STAGES[0], progress, protocol=FORCE_PROTOCOL, valves=RUN_VALVES
        )
    with stages.run(1, "fit"):
        src = load_trial_source(files["force_run"])
        # The model file is the one `labcli fit force.h5` writes (the default form): the figures, the
        # classification and a plain `labcli classify` of the pushes all use it.  The paper's
        # Eqs. 34-37 are fitted beside it for Section 3.3's coefficients.
        paper_model = TakumaModel(geometry=src.protocol.settings.rig, protocol=src.protocol.name).fit(
            src.table, source=str(files["force_run"])
        )
        stamp_fitted(paper_model, src, files["force_run"])
        save_model(paper_model.to_json(), files["paper_model"])  # the file alone: the run records the default
        model = _posture(src, files["force_run"])
        stamp_fitted(model, src, files["force_run"])
        save_model(model.to_json(), files["model"], run=files["force_run"], name=model.protocol)
    with stages.run(2, "validate"):
        evaluation = evaluate(model, src.table, "pressure-only", source=str(files["force_run"]))
        figure7(
            evaluation,
            files["figure7"],
            run=str(files["force_run"]),
            protocol=src.protocol.name,
            form=model.form,
            source=source_line(files["force_run"], src.protocol.name, files["model"]),
        )
    with stages.run(3, "ideal_rig"):
        ideal = _ideal_rig_accuracy(port + IDEAL, progress)
    with stages.run(4, "acquire_pushes"):
        # The same seed is the same rig (its actuators' variation): the model fitted above
        # describes this rig and no other.
        acquire_unattended(
            files["push_run"], port, "push run", STAGES[4], progress, protocol=PUSH_PROTOCOL, valves=RUN_VALVES
        )
    with stages.run(5, "classify"):
        # Categories from the protocol's stiffness bands: the pushed objects are labelled in
        # the run (their true class), and judging each against labels that include its own
        # would be circular for the lone steel can.  An object with every push flagged is reported
        # so, not an error (on the literature's rig of seed 5 the model is uncertain of the cans').
        report = classify_file(files["push_run"], model, method="bands", allow_unusable=True)
        figure9(report, files["figure9"], source=source_line(files["push_run"], PUSH_PROTOCOL, files["model"]))
    with stages.run(6, "bent_arm"):
        forms = {
            FORCE_PROTOCOL: {
                "posture": _accuracy(evaluation),
                "paper": _accuracy(evaluate(paper_model, src.table, "pressure-only")),
            },
            BENT_PROTOCOL: _bent_arm(port, files, progress),
        }
    with stages.run(7):
        write_trial_csv(src.table, files["trials_csv"])
        write_push_csv(load_pushes(files["push_run"]), files["pushes_csv"])
    result = _result(out, seed, files, stages.done(), src, paper_model, evaluation, report)
    result.accuracy_ideal = ideal
    result.forms = forms
    result.rig = {"port": port, "realism": REALISM_DEFAULT}  # which levels every figure above is from
    files["summary"].write_text(json.dumps(result.to_dict(), indent=2, allow_nan=False), encoding="utf-8")
    return result


def _ideal_rig_accuracy(port: str, progress: Progress | None) -> dict[str, dict[str, Any]]:
    """Validation accuracy of the same force run on the ideal rig ``port``, fitted and validated alike."""
    with tempfile.TemporaryDirectory(prefix="labcli-demo-") as tmp:
        path = Path(tmp) / "force-ideal.h5"
        acquire_unattended(
            path, port, "ideal-rig force run", STAGES[3], progress, protocol=FORCE_PROTOCOL, valves=RUN_VALVES
        )
        src = load_trial_source(path)
    return _accuracy(evaluate(_posture(src, path), src.table, "pressure-only", source=port))


def _accuracy(evaluation: dict[str, Any]) -> dict[str, dict[str, Any]]:
    keep = ("n", "rmse", "mae", "max_abs", "bias", "r2", "unit", "n_flagged", "pct_range", "rmse_all", "coverage95")
    return {q: {k: v for k, v in m.items() if k in keep} for q, m in evaluation["metrics"].items()}


def _posture(src: Any, run: Path) -> PostureModel:
    """The model `labcli fit RUN` writes (the default form, with the friction terms)."""
    from .analyses import _fit_form

    model = _fit_form("posture", src, str(run))
    assert isinstance(model, PostureModel)
    return model


def _bent_arm(port: str, files: dict[str, Path], progress: Progress | None) -> dict[str, Any]:
    """The bent-rest protocol: acquired, the posture form fitted and saved, Figure 7, both forms' metrics."""
    acquire_unattended(
        files["bent_run"], f"{port}&supply={BENT_SUPPLY}", "bent-arm run", STAGES[6], progress, protocol=BENT_PROTOCOL
    )
    bent = load_trial_source(files["bent_run"])
    model = _posture(bent, files["bent_run"])
    stamp_fitted(model, bent, files["bent_run"])
    save_model(model.to_json(), files["bent_model"], run=files["bent_run"], name=model.protocol)
    evaluation = evaluate(model, bent.table, "pressure-only", source=str(files["bent_run"]))
    figure7(
        evaluation,
        files["figure7_bent"],
        run=str(files["bent_run"]),
        protocol=bent.protocol.name,
        form=model.form,
        source=source_line(files["bent_run"], bent.protocol.name, files["bent_model"]),
    )
    paper = TakumaModel(geometry=bent.protocol.settings.rig, protocol=bent.protocol.name).fit(bent.table)
    return {"posture": _accuracy(evaluation), "paper": _accuracy(evaluate(paper, bent.table, "pressure-only"))}


def _result(
    out: Path,
    seed: int,
    files: dict[str, Path],
    timings: dict[str, float],
    src: Any,
    paper_model: Any,
    evaluation: dict[str, Any],
    report: Any,
) -> DemoResult:
    """The demo's numbers as plain data: Eqs. 34-37's coefficients against the paper's, the default
    form's accuracy, objects."""
    paper = dict(src.protocol.settings.paper_coefficients or {})
    coefficients = [
        {
            "name": name,
            "value": float(value),
            "standard_error": float(paper_model.standard_errors[name]),
            "paper": paper.get(name),
        }
        for name, value in paper_model.coefficients.items()
    ]
    accuracy = _accuracy(evaluation)
    rep = report.to_dict()
    sets = src.table["set"].value_counts().to_dict()
    return DemoResult(
        outdir=out,
        seed=seed,
        files=files,
        timings_s=timings,
        trials={
            "fit": int(sets.get("fit", 0)),
            "validation": int(sets.get("validation", 0)),
            "pushes": len(rep["pushes"]),
            "pushes_flagged": sum(p["flagged"] for p in rep["pushes"]),
        },
        coefficients=coefficients,
        accuracy=accuracy,
        objects=rep["objects"],
        classify_method=rep["method"],
        notes=[
            "Coefficients use the plus-sign reading with the paper's beta_theta2_R2 = -2.972 as listed "
            "(Eq. 35's printed minus is a misprint; docs/errata.md)."
        ],
    )
