"""The rPAM joint paper (2015): a 1-DoF revolute joint driven by two reverse pneumatic
artificial muscles; its stretch test, joint map and link optimisation.

``PAPER`` is what the core sees (:class:`labcli.core.paper.Paper`); it is
registered through the entry-point group ``labcli.papers``.  This module imports
nothing heavy (the registry imports it to learn the kinds it owns), so each method imports
what it needs when it is called: the sessions, the model, the figures and the simulated rig load on first use.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from ...core.paper import AcquireOptions, Analysis, Demo, RecordType, SimulatedRig
from ...errors import ConfigError
from .options import DEFAULT_PROTOCOLS, OPTIONS, RPAM_PROTOCOL
from .protocol import EXPERIMENTS, PROTOCOL_KINDS, SINGLE_CAPTURES
from .sim.options import RpamRigOptions


class Rpam2015:
    name = "rpam2015"
    title = "rPAM antagonistic 1-DoF joint: stretch test, joint map, link optimisation"
    paper = '"Optimized Design of a Rigid Kinematic Module for Antagonistic Soft Actuation", 2015'
    protocol_kinds = PROTOCOL_KINDS
    shipped_protocols = (RPAM_PROTOCOL,)
    run_kinds = tuple(EXPERIMENTS.values())
    single_captures = SINGLE_CAPTURES  # each point once (core.acquisition.check_captures says so)
    untagged_run_kind = None
    sim_modes = ("rpam",)
    default_sim_mode = None
    sim_options = RpamRigOptions
    analysis_options = OPTIONS
    default_protocols = DEFAULT_PROTOCOLS
    demo_protocol = RPAM_PROTOCOL

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
        options: RpamRigOptions | None = None,
    ) -> SimulatedRig:
        from .sim.rig import RpamRig

        o = options or RpamRigOptions()
        experiment = o.experiment or "joint"  # the stand powers up on the joint unless told otherwise
        return RpamRig(
            seed=seed,
            noise=noise,
            drift=drift or 0.0,
            tau_s=tau_s,
            experiment=experiment,
            variation=not o.nominal,
            force_reading=o.reading,
        )

    def run_protocol(
        self, protocol: Any, choice: str | None, *, stored_kind: str | None = None, run_path: str = ""
    ) -> Any:
        from .session import acquisition_protocol

        return acquisition_protocol(protocol, choice, stored_kind=stored_kind, run_path=run_path)

    def import_protocol(self, protocol: Any, choice: str | None, name: str) -> Any:
        from .session import acquisition_protocol

        if choice is None:
            raise ConfigError(
                f"{name} is a protocol of kind 'rpam' with two experiments; labcli import reads "
                "its point tables with --experiment stretch (the stretch test) or --experiment joint "
                "(the joint map), and trial tables with a force protocol such as takuma2014."
            )
        return acquisition_protocol(protocol, choice)

    def acquisition(self, protocol: Any, options: AcquireOptions) -> Any:
        from .acquisition import acquisition

        return acquisition(protocol, options)

    def analysis(self, name: str) -> Analysis | None:
        if name not in self.analysis_options:
            return None
        from . import analyses  # numpy, scipy: only once an analysis runs

        pairs: dict[str, tuple[Callable[..., Any], Callable[..., None]]] = {
            "fit": (analyses.fit, analyses.show_fit),
            "validate": (analyses.validate, analyses.show_validation),
            "optimize": (analyses.optimize, analyses.show_optimum),
        }
        run, show = pairs[name]
        return Analysis(run, show)

    def demo(self) -> Demo | None:
        from . import demo, report  # the whole toolkit: only once the demo runs

        return Demo(demo.STAGES, demo.run_rpam_demo, report.print_demo)


PAPER = Rpam2015()
