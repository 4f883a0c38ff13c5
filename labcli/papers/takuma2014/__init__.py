"""Takuma, Takamine & Masuda, Actuators 2014: force and angle sensing from the pressures of a
2-DoF McKibben joint (Sections 2-3) and object stiffness by pushing (Section 4).

``PAPER`` is what the core sees (:class:`labcli.core.paper.Paper`); it is
registered through the entry-point group ``labcli.papers``.  This module imports
nothing heavy (the registry imports it to learn the kinds it owns), so each method imports
what it needs when it is called: the sessions, models, figures and the simulated rig load on first use.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from ...core.paper import AcquireOptions, Analysis, Demo, RecordType, SimulatedRig
from .options import DEFAULT_PROTOCOLS, OPTIONS, PUSH_PROTOCOL, TRIAL_PROTOCOL, SensingOptions
from .protocol import CAPTURE_KINDS, PROTOCOL_KINDS, SINGLE_CAPTURES
from .sim.options import McKibbenRigOptions


class Takuma2014:
    name = "takuma2014"
    title = "Pressure-based force, angle and stiffness sensing, 2-DoF McKibben joint"
    paper = (
        'Takuma, Takamine & Masuda, "Sustainable multi-modal sensing by a single sensor utilizing '
        'the passivity of an elastic actuator", Actuators 2014'
    )
    protocol_kinds = PROTOCOL_KINDS
    shipped_protocols = (TRIAL_PROTOCOL, PUSH_PROTOCOL)
    run_kinds = ("force", "push", "sense")
    capture_kinds = CAPTURE_KINDS  # runs that take each load several times (acquisition.captures_per_load)
    single_captures = SINGLE_CAPTURES  # the words of the core's refusal for the others
    untagged_run_kind = "force"  # run files from before files named their kind held force trials
    sim_modes = ("mckibben",)
    default_sim_mode = "mckibben"
    sim_options = McKibbenRigOptions
    analysis_options = OPTIONS
    sensing_options = SensingOptions  # labcli sense with one of its model files
    default_protocols = DEFAULT_PROTOCOLS
    demo_protocol = TRIAL_PROTOCOL
    model_schemas = ("labcli-takuma-model",)  # what `labcli fit` writes (models/takuma.py SCHEMA)

    def record_type(self, run_kind: str) -> RecordType:
        from .records import RECORD_TYPES

        return RECORD_TYPES[run_kind]

    def make_rig(
        self,
        mode: str,
        *,
        seed: int = 0,
        noise: float = 1.0,
        drift: float | None = None,
        tau_s: float = 0.7,
        options: McKibbenRigOptions | None = None,
    ) -> SimulatedRig:
        from .sim.options import build_rig

        return build_rig(seed=seed, noise=noise, drift=drift, tau_s=tau_s, options=options or McKibbenRigOptions())

    def run_protocol(
        self, protocol: Any, choice: str | None, *, stored_kind: str | None = None, run_path: str = ""
    ) -> Any:
        return protocol  # a force or push run records with its protocol as it is

    def import_protocol(self, protocol: Any, choice: str | None, name: str) -> Any:
        return protocol

    def acquisition(self, protocol: Any, options: AcquireOptions) -> Any:
        from .acquisition import acquisition

        return acquisition(protocol, options)

    def analysis(self, name: str) -> Analysis | None:
        if name == "export-model":
            from .models import export_c  # numpy only

            return Analysis(export_c.export, export_c.show)
        if name == "predict":
            from . import predict

            return Analysis(predict.predict_file, predict.show_predict)
        if name not in self.analysis_options:
            return None
        from . import analyses  # numpy, pandas: only once an analysis runs

        pairs: dict[str, tuple[Callable[..., Any], Callable[..., None]]] = {
            "fit": (analyses.fit, analyses.show_fit),
            "validate": (analyses.validate, analyses.show_validation),
            "classify": (analyses.classify, analyses.show_classification),
        }
        run, show = pairs[name]
        return Analysis(run, show)

    def sensing_model(self, text: str, name: str, options: SensingOptions | None = None) -> Any:
        """The run-time estimator's view of a model file of this paper (None: not one of its files)."""
        from .sensing import sensing_model

        return sensing_model(text, name, options)

    def demo(self) -> Demo | None:
        from . import demo, report  # the whole toolkit: only once the demo runs

        return Demo(demo.STAGES, demo.run_demo, report.print_demo)


PAPER = Takuma2014()
