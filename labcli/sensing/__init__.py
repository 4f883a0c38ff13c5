"""Sensing at run time: a fitted model applied to the stream of a rig, and to tables of new data.

::

    from labcli.sensing import Estimator, load_model

    model = load_model("run.model.json")                 # the model `labcli fit` wrote
    est = Estimator(model, calibration=protocol.calibration, channels=device.info.channels, rate_hz=200)
    for item in est.update(device.read()):               # frames as the reader delivers them
        print(item.as_json())                            # an Estimate (one per block) or an Event

:class:`Estimator` does no I/O: it takes frames (raw counts and device time, converted with
the protocol's calibration) and gives back, per block of ``block_s`` (0.1 s), an
:class:`Estimate` of every quantity the model estimates with its standard error and flags,
and the :class:`Event` s it found (``load``, ``settled``, ``release``).  The sensing page of the docs
explains the detector, the baseline, the standard errors and the flags, with the figures
measured on the simulated rig.

Layers: this package sits between the core and the papers.  It imports ``labcli.errors``,
``labcli.core`` and itself, never a paper: the model it applies is a :class:`SensingModel`
(the seam, :mod:`.model`) that a paper provides from its model files
(``Paper.sensing_model``), found through the registry by :func:`load_model`.  The core never
imports this package; a paper may (its adapter returns :class:`Prediction`), and so may the
commands (tests/core/test_import_graph.py holds these rules).
"""

from __future__ import annotations

from .config import EstimatorConfig
from .estimator import Estimator, SettledHook
from .model import Prediction, SensingModel, SensingPaper, load_model, model_from_text
from .results import IDLE, LOAD, LOADED, LOADING, RELEASE, RELEASING, SETTLED, STARTING, STATES, Estimate, Event

__all__ = [
    "IDLE",
    "LOAD",
    "LOADED",
    "LOADING",
    "RELEASE",
    "RELEASING",
    "SETTLED",
    "STARTING",
    "STATES",
    "Estimate",
    "Estimator",
    "EstimatorConfig",
    "Event",
    "Prediction",
    "SensingModel",
    "SensingPaper",
    "SettledHook",
    "load_model",
    "model_from_text",
]
